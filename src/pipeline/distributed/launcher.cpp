#include "pipeline/distributed/launcher.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <thread>

#include "core/error.hpp"
#include "pipeline/distributed/distributed.hpp"

namespace bsms {
namespace {

std::vector<pid_t> g_children;  // for the signal forwarder

void forward_signal(int sig) {
  for (pid_t p : g_children)
    if (p > 0) ::kill(p, sig);
}

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw IoError("cannot open a socket to find a free port");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
    port = ntohs(addr.sin_port);
  ::close(fd);
  if (port == 0) throw IoError("cannot find a free port on 127.0.0.1 (set MASTER_PORT)");
  return port;
}

std::string exit_text(int status) {
  if (WIFSIGNALED(status))
    return std::string("was killed by signal ") + std::to_string(WTERMSIG(status)) + " (" +
           strsignal(WTERMSIG(status)) + ")";
  return "exited with code " + std::to_string(WEXITSTATUS(status));
}

// This machine's part of the group: ranks node*nproc .. node*nproc+nproc-1 of `world`.
struct LocalGroup {
  int nproc = 1;
  int world = 1;
  int node = 0;
  std::string addr;
  int port = 0;
  int rank_of(int local) const { return node * nproc + local; }
};

// The group from --nproc and torchrun's variables; InputError for a contradiction.
LocalGroup local_group(int nproc) {
  if (nproc < 1 || nproc > 1024)
    throw InputError("--nproc " + std::to_string(nproc) + ": expected 1 to 1024");
  if (std::getenv("RANK"))
    throw InputError(
        "--nproc: environment variable RANK is set (this process is already one rank of a "
        "launched group, e.g. by torchrun); drop --nproc, or unset RANK and set NODE_RANK");
  LocalGroup g;
  g.nproc = nproc;
  const int world = g.world = static_cast<int>(environment_int("WORLD_SIZE", nproc, 1, 65536));
  const int node = g.node = static_cast<int>(environment_int("NODE_RANK", 0, 0, 65535));
  if (static_cast<int64_t>(node + 1) * nproc > world)
    throw InputError("WORLD_SIZE=" + std::to_string(world) + ", NODE_RANK=" + std::to_string(node) +
                     ", --nproc " + std::to_string(nproc) + ": this machine's ranks " +
                     std::to_string(node * nproc) + ".." + std::to_string((node + 1) * nproc - 1) +
                     " do not fit (WORLD_SIZE must be at least (NODE_RANK + 1) x nproc)");
  g.addr = environment_string("MASTER_ADDR", "127.0.0.1");
  if (std::getenv("MASTER_PORT")) {
    g.port = static_cast<int>(environment_int("MASTER_PORT", 29500, 1, 65535));
  } else {
    if (world != nproc)
      throw InputError("MASTER_PORT is not set: a run across machines (WORLD_SIZE=" +
                       std::to_string(world) + " > --nproc " + std::to_string(nproc) +
                       ") needs the same MASTER_ADDR and MASTER_PORT on every machine");
    g.port = free_port();
  }
  return g;
}

// Forks the ranks into g_children, each executing this program with `args` (null-terminated)
// and the rank's variables. A failed fork kills those started and throws IoError.
void spawn_ranks(const LocalGroup& g, std::vector<char*>& args) {
  for (int i = 0; i < g.nproc; ++i) {
    const pid_t pid = ::fork();
    if (pid < 0) {
      forward_signal(SIGKILL);
      throw IoError("cannot start rank " + std::to_string(g.rank_of(i)) +
                    " (fork: " + std::strerror(errno) + ")");
    }
    if (pid == 0) {
      setenv("WORLD_SIZE", std::to_string(g.world).c_str(), 1);
      setenv("RANK", std::to_string(g.rank_of(i)).c_str(), 1);
      setenv("LOCAL_RANK", std::to_string(i).c_str(), 1);
      setenv("LOCAL_WORLD_SIZE", std::to_string(g.nproc).c_str(), 1);
      setenv("MASTER_ADDR", g.addr.c_str(), 1);
      setenv("MASTER_PORT", std::to_string(g.port).c_str(), 1);
      setenv("BSMS_LAUNCHED", "1", 1);
      ::execv("/proc/self/exe", args.data());
      std::fprintf(stderr, "bsms: cannot start rank %d: %s\n", g.rank_of(i), std::strerror(errno));
      ::_exit(127);
    }
    g_children[i] = pid;
  }
}

// Past the grace period: the ranks still running are killed.
void kill_remaining(const LocalGroup& g, double grace_s) {
  for (int i = 0; i < g.nproc; ++i)
    if (g_children[i] > 0) {
      std::cerr << "bsms train: rank " << g.rank_of(i) << " did not stop within " << grace_s
                << " s; killing it\n";
      ::kill(g_children[i], SIGKILL);
    }
}

// The first rank that failed: its exit code (5 when killed by a signal), and one line naming it
// unless it reported bad input itself (then the others, waiting for it at the rendezvous, are
// stopped at once).
int first_failure(const LocalGroup& g, int local, pid_t pid, int status, int remaining,
                  double grace_s) {
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 5;
  const bool bad_input = WIFEXITED(status) && WEXITSTATUS(status) == 2;
  if (bad_input) forward_signal(SIGTERM);
  if (!bad_input)
    std::cerr << "bsms train: rank " << g.rank_of(local) << " (pid " << pid << ") "
              << exit_text(status)
              << (remaining ? "; the other ranks stop (or are killed after " +
                                  std::to_string(static_cast<int64_t>(grace_s)) + " s)"
                            : std::string())
              << "\n";
  return code;
}

// Waits for every rank; after the first failure the others get `grace_s` to stop before they
// are killed. Returns 0 or the first failing rank's code.
int wait_for_ranks(const LocalGroup& g, double grace_s) {
  int code = 0;
  int remaining = g.nproc;
  bool failed = false;
  auto deadline = std::chrono::steady_clock::time_point::max();
  while (remaining > 0) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, failed ? WNOHANG : 0);
    if (pid < 0 && errno == EINTR) continue;
    if (pid < 0) break;
    if (pid == 0) {  // failed: the others are stopping
      if (std::chrono::steady_clock::now() > deadline) {
        kill_remaining(g, grace_s);
        deadline = std::chrono::steady_clock::time_point::max();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      continue;
    }
    const auto it = std::find(g_children.begin(), g_children.end(), pid);
    if (it == g_children.end()) continue;
    const int local = static_cast<int>(it - g_children.begin());
    *it = 0;
    --remaining;
    const bool ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (!ok && !failed) {
      failed = true;
      code = first_failure(g, local, pid, status, remaining, grace_s);
      deadline = std::chrono::steady_clock::now() +
                 std::chrono::milliseconds(static_cast<int64_t>(grace_s * 1000));
    }
  }
  return code;
}

}  // namespace

int launch_local_ranks(const std::vector<std::string>& argv, int nproc, double grace_s) {
  const LocalGroup group = local_group(nproc);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::cout.flush();
  std::cerr.flush();
  g_children.assign(nproc, 0);
  struct sigaction forward {};
  forward.sa_handler = forward_signal;
  sigemptyset(&forward.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  sigaction(SIGINT, &forward, &old_int);
  sigaction(SIGTERM, &forward, &old_term);
  spawn_ranks(group, args);
  const int code = wait_for_ranks(group, grace_s);
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  return code;
}

}  // namespace bsms
