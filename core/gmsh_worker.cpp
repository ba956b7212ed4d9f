#include "core/gmsh_worker.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/geo_scan.hpp"
#include "core/gmsh_result.hpp"
#include "core/hdf5_file.hpp"
#include "core/mesh.hpp"
#include "core/msh_reader.hpp"

extern char** environ;

namespace bsms {
namespace fs = std::filesystem;

namespace {

std::mutex& limits_mutex() {
  static std::mutex m;
  return m;
}
std::optional<GmshLimits>& current_limits() {
  static std::optional<GmshLimits> limits;
  return limits;
}

// A positive finite number from an environment variable, or nullopt when unset or empty.
std::optional<double> positive_env(const char* name, const char* unit) {
  const char* text = std::getenv(name);
  if (text == nullptr || *text == '\0') return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || errno != 0 || !std::isfinite(v) || v <= 0.0) {
    std::string shown(text);
    if (shown.size() > 32) shown = shown.substr(0, 32) + "...";
    throw InputError(std::string("environment variable ") + name + "='" + shown +
                     "': expected a number > 0 (" + unit + ")");
  }
  return v;
}

// The checks every mesh file passes before it is parsed (their messages are part of the CLI).
void check_mesh_file(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path + ": mesh file not found");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a folder, expected a mesh file");
  std::ifstream probe(path);
  if (!probe) throw InputError(path + ": mesh file is not readable");
  if (fs::file_size(path, ec) == 0) throw InputError(path + ": mesh file is empty");
  register_input(path);
}

// The first bytes of a file (enough for its $MeshFormat line).
std::string file_head(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  return head;
}

// An anonymous file: memory-backed where the kernel has memfd_create, else unlinked in TMPDIR.
int anonymous_file(const char* name) {
#ifdef SYS_memfd_create
  const int fd = static_cast<int>(syscall(SYS_memfd_create, name, 1u /* MFD_CLOEXEC */));
  if (fd >= 0) return fd;
#else
  (void)name;
#endif
  std::error_code ec;
  const fs::path dir = fs::temp_directory_path(ec);
  const int tmp = ::open((ec ? std::string("/tmp") : dir.string()).c_str(),
                         O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (tmp < 0)
    throw IoError(std::string("cannot make a temporary file for the gmsh worker (") +
                  std::strerror(errno) + ")");
  return tmp;
}

// Owns a file descriptor (moved above the standard ones, close-on-exec).
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {
    if (fd_ >= 0 && fd_ < 10) {
      const int high = ::fcntl(fd_, F_DUPFD_CLOEXEC, 10);
      ::close(fd_);
      fd_ = high;
    }
    if (fd_ < 0)
      throw IoError(std::string("gmsh worker: no file descriptor (") + std::strerror(errno) + ")");
  }
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// The whole content of an anonymous file.
std::string read_all(int fd, std::size_t max_bytes) {
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size <= 0) return {};
  const auto size = static_cast<std::size_t>(st.st_size);
  const std::size_t from = size > max_bytes ? size - max_bytes : 0;
  std::string out(size - from, '\0');
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n =
        ::pread(fd, out.data() + done, out.size() - done, static_cast<off_t>(from + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    done += static_cast<std::size_t>(n);
  }
  out.resize(done);
  return out;
}

// The last non-empty line of a child's stderr, printable and short (for one-line messages).
std::string last_line(const std::string& text) {
  std::size_t end = text.size();
  while (end > 0 && (text[end - 1] == '\n' || text[end - 1] == '\r' || text[end - 1] == ' ')) --end;
  const std::size_t begin = text.rfind('\n', end == 0 ? 0 : end - 1);
  std::string line = text.substr(begin == std::string::npos ? 0 : begin + 1,
                                 end - (begin == std::string::npos ? 0 : begin + 1));
  for (char& c : line)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  if (line.size() > 160) line = line.substr(0, 160) + "...";
  return line;
}

std::string format_number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

std::string signal_name(int sig) {
  const char* name = sigabbrev_np(sig);
  return name != nullptr ? std::string("SIG") + name : "signal " + std::to_string(sig);
}

struct Outcome {
  bool timed_out = false;
  int wait_status = 0;
  std::string result;  // the result file's bytes
  std::string stderr_tail;
};

// Spawns the worker on `path` and waits for it, at most the time limit.
Outcome run_worker(const std::string& path, const GmshLimits& limits) {
  const std::string worker = gmsh_worker_path();
  const Fd result(anonymous_file("bsms-gmsh-result"));
  const Fd errors(anonymous_file("bsms-gmsh-stderr"));

  const double memory_gib =
      limits.memory_limit_gib > 0.0 ? limits.memory_limit_gib : default_gmsh_memory_gib();
  const double memory_bytes = std::min(memory_gib * 1073741824.0, 9.0e18);
  const long cpus = std::max(1L, ::sysconf(_SC_NPROCESSORS_ONLN));
  const double cpu_seconds =
      std::min(std::ceil(limits.time_limit_s * static_cast<double>(cpus)) + 2.0, 1.0e9);
  std::vector<std::string> args = {worker,
                                   "--memory",
                                   std::to_string(static_cast<unsigned long long>(memory_bytes)),
                                   "--cpu",
                                   std::to_string(static_cast<unsigned long long>(cpu_seconds)),
                                   "--parent",
                                   std::to_string(::getpid())};
  if (limits.allow_geo_commands) args.push_back("--allow-commands");
  args.push_back("--");
  args.push_back(path);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&actions);
  posix_spawnattr_init(&attr);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, errors.get(), 2);
  posix_spawn_file_actions_adddup2(&actions, result.get(), 3);
  sigset_t none, all;
  sigemptyset(&none);
  sigfillset(&all);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setsigdefault(&attr, &all);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr,
                           POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  const int spawned = posix_spawn(&pid, worker.c_str(), &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (spawned != 0)
    throw IoError("cannot start the gmsh worker " + worker + " (" + std::strerror(spawned) +
                  "); build the bsms-gmsh-worker target, or set BSMS_GMSH_WORKER");

  // Wait for the child's exit without reaping it, so that its process group id stays its own
  // until the group is killed (programs a script started, with --allow-geo-commands).
  Outcome outcome;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(std::min(limits.time_limit_s, 1.0e7));
#ifdef SYS_pidfd_open
  const int pidfd = static_cast<int>(syscall(SYS_pidfd_open, pid, 0));
#else
  const int pidfd = -1;
#endif
  int sleep_us = 200;
  while (true) {
    siginfo_t info{};
    const int w = ::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOHANG | WNOWAIT);
    if (w == 0 && info.si_pid == pid) break;
    if (w != 0 && errno != EINTR) break;  // not our child any more: nothing to wait for
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::steady_clock::duration::zero()) {
      outcome.timed_out = true;
      break;
    }
    const auto left_ms = std::chrono::duration_cast<std::chrono::milliseconds>(left).count() + 1;
    if (pidfd >= 0) {
      pollfd p{pidfd, POLLIN, 0};
      ::poll(&p, 1, static_cast<int>(std::min<long long>(left_ms, 1000)));
    } else {
      ::usleep(static_cast<useconds_t>(std::min<long long>(sleep_us, left_ms * 1000)));
      sleep_us = std::min(sleep_us * 2, 20000);
    }
  }
  if (pidfd >= 0) ::close(pidfd);
  ::kill(-pid, SIGKILL);
  ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  outcome.wait_status = status;
  outcome.result = read_all(result.get(), static_cast<std::size_t>(-1));
  outcome.stderr_tail = last_line(read_all(errors.get(), 4096));
  return outcome;
}

}  // namespace

double default_gmsh_memory_gib() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 4.0;
  return std::max(1.0, static_cast<double>(pages) * static_cast<double>(page) / 2.0 / 1073741824.0);
}

GmshLimits gmsh_limits_from_environment() {
  GmshLimits limits;
  if (const auto t = positive_env("BSMS_GEO_TIME_LIMIT", "seconds")) limits.time_limit_s = *t;
  if (const auto m = positive_env("BSMS_GEO_MEMORY_LIMIT", "GiB")) limits.memory_limit_gib = *m;
  return limits;
}

void set_gmsh_limits(const GmshLimits& limits) {
  std::lock_guard<std::mutex> lock(limits_mutex());
  current_limits() = limits;
}

GmshLimits gmsh_limits() {
  std::lock_guard<std::mutex> lock(limits_mutex());
  if (!current_limits()) current_limits() = gmsh_limits_from_environment();
  return *current_limits();
}

std::string gmsh_worker_path() {
  if (const char* env = std::getenv("BSMS_GMSH_WORKER"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path beside = self.parent_path() / "bsms-gmsh-worker";
    if (::access(beside.c_str(), X_OK) == 0) return beside.string();
  }
#ifdef BSMS_GMSH_WORKER_PATH
  return BSMS_GMSH_WORKER_PATH;
#else
  return "bsms-gmsh-worker";
#endif
}

Mesh read_mesh(const std::string& path) {
  check_mesh_file(path);
  if (is_direct_msh(file_head(path))) {
    try {
      return read_msh(path);
    } catch (const MshNotHandled&) {
      // Valid MSH with a feature the direct reader leaves to gmsh (documented in mesh.hpp).
    }
  }
  return read_mesh_with_gmsh(path);
}

Mesh read_mesh_with_gmsh(const std::string& path) {
  check_mesh_file(path);
  const GmshLimits limits = gmsh_limits();
  // gmsh would offer to run `gunzip -c FILE > FILE_WITHOUT_GZ` (and, unanswered, parse the
  // compressed bytes as a script).
  if (fs::path(path).extension() == ".gz")
    throw InputError(path + ": a gzip-compressed file; uncompress it first");
  if (!limits.allow_geo_commands && is_gmsh_script(path)) check_geo_script(path);

  const Outcome out = run_worker(path, limits);
  const double memory_gib =
      limits.memory_limit_gib > 0.0 ? limits.memory_limit_gib : default_gmsh_memory_gib();
  const std::string memory = format_number(memory_gib) + " GiB";
  const std::string tail = out.stderr_tail.empty() ? "" : ": " + out.stderr_tail;
  if (out.timed_out)
    throw InputError(path + ": gmsh did not finish within " + format_number(limits.time_limit_s) +
                     " s (--geo-time-limit or BSMS_GEO_TIME_LIMIT); a loop that does not end, or "
                     "a geometry too fine?");
  if (WIFSIGNALED(out.wait_status)) {
    const int sig = WTERMSIG(out.wait_status);
    if (sig == SIGXCPU)
      throw InputError(path + ": gmsh used more CPU time than the limit of " +
                       format_number(limits.time_limit_s) +
                       " s allows (--geo-time-limit or BSMS_GEO_TIME_LIMIT)");
    throw InputError(path + ": gmsh crashed on this file (" + signal_name(sig) + tail +
                     "); with a large geometry the memory limit (" + memory +
                     ", --geo-memory-limit or BSMS_GEO_MEMORY_LIMIT) can be the cause");
  }
  const int code = WIFEXITED(out.wait_status) ? WEXITSTATUS(out.wait_status) : -1;
  if (code != 0 || out.result.empty())
    throw InputError(path + ": gmsh stopped before it gave a mesh (exit status " +
                     std::to_string(code) + tail + "); a script's Exit, or a fatal gmsh error");
  GmshResult result;
  try {
    result = parse_gmsh_result(out.result);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  switch (result.status) {
    case GmshResult::Status::Mesh:
      validate_mesh(result.mesh, path);
      return std::move(result.mesh);
    case GmshResult::Status::InputError:
      throw InputError(result.message);
    case GmshResult::Status::OutOfMemory:
      throw InputError(path + ": gmsh ran out of its memory limit of " + memory +
                       " (--geo-memory-limit or BSMS_GEO_MEMORY_LIMIT) reading or meshing this "
                       "file");
    case GmshResult::Status::Failure:
      break;
  }
  std::string why = result.message;
  if (why.size() > 200) why = why.substr(0, 200) + "...";
  throw InputError(path + ": gmsh failed on this file (" + why + ")");
}

}  // namespace bsms
