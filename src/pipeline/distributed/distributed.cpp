#include "pipeline/distributed/distributed.hpp"

#include <glog/logging.h>
#include <unistd.h>
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#include <torch/csrc/distributed/c10d/TCPStore.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "core/error.hpp"
#include "core/runtime.hpp"

namespace bsms {

int64_t environment_int(const char* name, int64_t fallback, int64_t lo, int64_t hi) {
  const char* v = std::getenv(name);
  if (!v) return fallback;
  char* end = nullptr;
  errno = 0;
  const long long x = std::strtoll(v, &end, 10);
  if (errno || end == v || *end || x < lo || x > hi)
    throw InputError(std::string("environment variable ") + name + "='" + v +
                     "': expected an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  return x;
}

std::string environment_string(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : fallback;
}

namespace {

std::string first_line(const std::string& s) {
  std::string line = s.substr(0, s.find('\n'));
  return line.size() > 300 ? line.substr(0, 300) + "..." : line;
}

bool is_loopback(const std::string& addr) {
  return addr == "localhost" || addr.rfind("127.", 0) == 0 || addr == "::1";
}

std::chrono::milliseconds to_ms(double seconds) {
  return std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000.0));
}

// State letter of a process in /proc (R, S, T for stopped ...), or 0 when it is gone.
char process_state(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string text;
  if (!std::getline(stat, text)) return 0;
  const size_t close = text.rfind(')');
  if (close == std::string::npos || close + 2 >= text.size()) return 0;
  return text[close + 2];
}

std::string host_name() {
  char buffer[256] = {};
  if (::gethostname(buffer, sizeof buffer - 1) != 0) return "?";
  return buffer;
}

// c10d's rendezvous logs through glog (e.g. three lines for a port in use) what bsms reports in
// one line of its own: glog is kept to fatal messages while it runs.
class QuietGlog {
 public:
  QuietGlog() : saved_(FLAGS_minloglevel) { FLAGS_minloglevel = google::GLOG_FATAL; }
  ~QuietGlog() { FLAGS_minloglevel = saved_; }
  QuietGlog(const QuietGlog&) = delete;
  QuietGlog& operator=(const QuietGlog&) = delete;

 private:
  int saved_;
};

}  // namespace

DistributedSettings distributed_from_environment(double timeout_s) {
  DistributedSettings s;
  s.timeout_s = timeout_s;
  if (!std::getenv("WORLD_SIZE")) {
    for (const char* name : {"RANK", "LOCAL_RANK"})
      if (std::getenv(name) && environment_int(name, 0, 0, 0) != 0)
        throw InputError(std::string("environment variable ") + name +
                         " is set but WORLD_SIZE is not: set both (torchrun's conventions) or "
                         "neither");
    return s;
  }
  s.world = static_cast<int>(environment_int("WORLD_SIZE", 1, 1, 65536));
  if (s.world > 1 && !std::getenv("RANK"))
    throw InputError("environment variable WORLD_SIZE=" + std::to_string(s.world) +
                     ": RANK is not set (each process needs its rank in [0, WORLD_SIZE))");
  s.rank = static_cast<int>(environment_int("RANK", 0, 0, s.world - 1));
  s.local_rank = static_cast<int>(environment_int("LOCAL_RANK", s.rank, 0, s.world - 1));
  s.master_addr = environment_string("MASTER_ADDR", "127.0.0.1");
  s.master_port = static_cast<int>(environment_int("MASTER_PORT", 29500, 1, 65535));
  return s;
}

struct Communicator::Impl {
  c10::intrusive_ptr<c10d::TCPStore> store;
  c10::intrusive_ptr<c10d::ProcessGroupGloo> group;
  std::vector<std::string> hosts;  // per rank
  std::vector<pid_t> pids;         // per rank
};

Communicator::Communicator(const DistributedSettings& settings)
    : settings_(settings), impl_(std::make_unique<Impl>()) {
  const std::string where = settings_.master_addr + ":" + std::to_string(settings_.master_port);
  const std::string timeout = std::to_string(static_cast<int64_t>(settings_.timeout_s)) + " s";
  c10d::TCPStoreOptions options;
  options.port = static_cast<uint16_t>(settings_.master_port);
  options.isServer = settings_.rank == 0;
  options.numWorkers = static_cast<size_t>(settings_.world);
  options.waitWorkers = true;
  options.timeout = to_ms(settings_.timeout_s);
  const QuietGlog quiet;
  try {
    impl_->store = c10::make_intrusive<c10d::TCPStore>(settings_.master_addr, options);
  } catch (const std::exception& e) {
    const std::string why = first_line(e.what());
    if (settings_.rank == 0 && why.find("in use") != std::string::npos)
      throw InputError("MASTER_PORT=" + std::to_string(settings_.master_port) +
                       ": the port is already in use on " + settings_.master_addr +
                       " (another run?); set MASTER_PORT to a free port");
    if (settings_.rank == 0)
      throw InputError("MASTER_ADDR:MASTER_PORT=" + where + ": rank 0 cannot host the rendezvous" +
                       " or not all " + std::to_string(settings_.world) + " ranks joined within " +
                       timeout + " (" + why + ")");
    throw InputError("MASTER_ADDR:MASTER_PORT=" + where + ": rank " +
                     std::to_string(settings_.rank) + " cannot reach the master within " + timeout +
                     " (" + why + "); is rank 0 running and the address reachable?");
  }
  try {
    auto gloo = c10d::ProcessGroupGloo::Options::create(to_ms(settings_.timeout_s));
    if (const char* ifname = std::getenv("GLOO_SOCKET_IFNAME"))
      gloo->devices.push_back(c10d::ProcessGroupGloo::createDeviceForInterface(ifname));
    else if (is_loopback(settings_.master_addr))
      gloo->devices.push_back(c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1"));
    else
      gloo->devices.push_back(c10d::ProcessGroupGloo::createDefaultDevice());
    gloo->threads = 1;
    impl_->group = c10::make_intrusive<c10d::ProcessGroupGloo>(impl_->store, settings_.rank,
                                                               settings_.world, gloo);
    // Who is who, to name a rank that died or stopped on this machine when a collective fails.
    const std::string me = host_name() + " " + std::to_string(::getpid());
    impl_->store->set("bsms/rank/" + std::to_string(settings_.rank),
                      std::vector<uint8_t>(me.begin(), me.end()));
    for (int r = 0; r < settings_.world; ++r) {
      const auto v = impl_->store->get("bsms/rank/" + std::to_string(r));
      std::istringstream in(std::string(v.begin(), v.end()));
      std::string host;
      long pid = 0;
      in >> host >> pid;
      impl_->hosts.push_back(host);
      impl_->pids.push_back(static_cast<pid_t>(pid));
    }
  } catch (const std::exception& e) {
    throw DistributedError("rank " + std::to_string(settings_.rank) +
                           ": cannot set up the process group (Gloo) with the others through " +
                           where + " (" + first_line(e.what()) + ")");
  }
}

Communicator::~Communicator() = default;

namespace {

// "rank R, step S: WHAT failed: CAUSE" with the local ranks that are gone or stopped.
std::string describe_failure(const DistributedSettings& s, const std::vector<std::string>& hosts,
                             const std::vector<pid_t>& pids, int64_t step, const std::string& what,
                             const std::string& error) {
  std::ostringstream m;
  m << "rank " << s.rank << ", step " << step << ": " << what << " failed: ";
  const std::string lower = [&] {
    std::string l = error;
    std::transform(l.begin(), l.end(), l.begin(), [](unsigned char c) { return std::tolower(c); });
    return l;
  }();
  if (lower.find("timed out") != std::string::npos || lower.find("timeout") != std::string::npos)
    m << "no reply from the other ranks within " << s.timeout_s << " s (a rank hung or died)";
  else if (lower.find("closed") != std::string::npos || lower.find("reset") != std::string::npos ||
           lower.find("broken pipe") != std::string::npos)
    m << "a peer closed its connection (a rank died or stopped)";
  else
    m << "a collective with the other ranks broke";
  const std::string here = host_name();
  std::vector<std::string> lost;
  for (size_t r = 0; r < pids.size(); ++r) {
    if (static_cast<int>(r) == s.rank || hosts[r] != here) continue;
    const char state = process_state(pids[r]);
    if (state == 0 || state == 'Z')
      lost.push_back("rank " + std::to_string(r) + " (pid " + std::to_string(pids[r]) +
                     ") is gone");
    else if (state == 'T' || state == 't')
      lost.push_back("rank " + std::to_string(r) + " (pid " + std::to_string(pids[r]) +
                     ") is stopped");
  }
  for (const auto& l : lost) m << "; " << l;
  m << " [" << first_line(error) << "]; the last checkpoint is intact: continue with --resume";
  return m.str();
}

// Tensors grouped into buckets: same dtype, at most `bytes` each (a larger tensor alone).
std::vector<std::vector<size_t>> make_buckets(const std::vector<torch::Tensor>& tensors,
                                              int64_t bytes) {
  std::map<int, std::vector<std::vector<size_t>>> by_type;
  std::map<int, int64_t> filled;
  for (size_t i = 0; i < tensors.size(); ++i) {
    const int type = static_cast<int>(tensors[i].scalar_type());
    auto& list = by_type[type];
    const int64_t size = tensors[i].numel() * static_cast<int64_t>(tensors[i].element_size());
    if (list.empty() || filled[type] + size > bytes) {
      list.emplace_back();
      filled[type] = 0;
    }
    list.back().push_back(i);
    filled[type] += size;
  }
  std::vector<std::vector<size_t>> buckets;
  for (auto& [type, list] : by_type)
    for (auto& b : list) buckets.push_back(std::move(b));
  return buckets;
}

}  // namespace

// Packs `tensors` into buckets, starts an all-reduce (sum) or a broadcast from rank 0 on each,
// all in flight together, waits, and writes the results back into the tensors.
void Communicator::bucketed(const std::vector<torch::Tensor>& tensors, int64_t step,
                            const std::string& what, bool broadcast) {
  Stopwatch clock;
  const auto buckets = make_buckets(tensors, bucket_bytes);
  std::vector<torch::Tensor> flats;
  std::vector<c10::intrusive_ptr<c10d::Work>> works;
  try {
    for (const auto& bucket : buckets) {
      std::vector<torch::Tensor> parts;
      for (size_t i : bucket) parts.push_back(tensors[i].detach().reshape({-1}));
      flats.push_back(torch::cat(parts));
      std::vector<torch::Tensor> one{flats.back()};
      if (broadcast) {
        c10d::BroadcastOptions options;
        options.rootRank = 0;
        works.push_back(impl_->group->broadcast(one, options));
      } else {
        works.push_back(impl_->group->allreduce(one));
      }
      ++collective_calls;
    }
    for (auto& w : works) w->wait(to_ms(settings_.timeout_s));
  } catch (const std::exception& e) {
    throw DistributedError(
        describe_failure(settings_, impl_->hosts, impl_->pids, step, what, e.what()));
  }
  torch::NoGradGuard no_grad;
  for (size_t b = 0; b < buckets.size(); ++b) {
    int64_t offset = 0;
    for (size_t i : buckets[b]) {
      const int64_t n = tensors[i].numel();
      tensors[i].copy_(flats[b].narrow(0, offset, n).view(tensors[i].sizes()));
      offset += n;
    }
  }
  collective_ms += clock.milliseconds();
}

void Communicator::all_reduce_sum(const std::vector<torch::Tensor>& tensors, int64_t step,
                                  const std::string& what) {
  bucketed(tensors, step, what, /*broadcast=*/false);
}

void Communicator::broadcast(const std::vector<torch::Tensor>& tensors, int64_t step,
                             const std::string& what) {
  bucketed(tensors, step, what, /*broadcast=*/true);
}

std::string Communicator::share(const std::string& key, const std::string& bytes) {
  const std::string full = "bsms/share/" + key;
  try {
    if (settings_.rank == 0) {
      impl_->store->set(full, std::vector<uint8_t>(bytes.begin(), bytes.end()));
      return bytes;
    }
    const auto v = impl_->store->get(full);
    return std::string(v.begin(), v.end());
  } catch (const std::exception& e) {
    throw DistributedError(describe_failure(settings_, impl_->hosts, impl_->pids, 0,
                                            "receiving '" + key + "' from rank 0", e.what()));
  }
}

}  // namespace bsms
