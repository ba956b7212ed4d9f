// bsms-gmsh-worker: reads one file with the gmsh library for bsms (gmsh_worker.hpp) and writes
// the mesh, or the error, to file descriptor 3 (gmsh_result.hpp). Started by bsms only:
//
//   bsms-gmsh-worker --memory BYTES --cpu SECONDS --parent PID [--allow-commands] -- FILE
//
// Exit status 0 when the result is written; anything else (a script's Exit included) means no
// result, which bsms reports.
#include <errno.h>
#include <omp.h>
#include <signal.h>
#include <stddef.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#if defined(__linux__)
#include <fcntl.h>
#include <linux/audit.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#endif

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "core/error.hpp"
#include "core/gmsh_result.hpp"
#include "core/gmsh_session.hpp"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define BSMS_WORKER_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define BSMS_WORKER_SANITIZED 1
#endif
#endif

namespace {

constexpr int kResultFd = 3;

// The result is written once, by whichever of the reading, std::terminate or the memory watch
// comes first.
std::atomic<bool> answered{false};
[[noreturn]] void answer(const bsms::GmshResult& result) {
  if (answered.exchange(true)) {
    for (;;) ::pause();  // the other writer ends the process
  }
  ::_exit(bsms::write_gmsh_result(kResultFd, result) ? 0 : 74);
}

[[noreturn]] void fail(const char* what) {
  const std::string line = std::string("bsms-gmsh-worker: ") + what + "\n";
  (void)!::write(2, line.data(), line.size());
  ::_exit(64);
}

// Descriptors bsms had open without close-on-exec are not the worker's business.
void close_other_fds() {
#ifdef SYS_close_range
  if (::syscall(SYS_close_range, kResultFd + 1, ~0U, 0) == 0) return;
#endif
  const long max = ::sysconf(_SC_OPEN_MAX);
  for (long fd = kResultFd + 1; fd < (max > 0 ? std::min(max, 65536L) : 1024L); ++fd)
    ::close(static_cast<int>(fd));
}

void set_limit(int resource, rlim_t value) {
  rlimit limit{value, value};
  ::setrlimit(resource, &limit);
}

#if defined(__linux__) && (defined(__x86_64__) || defined(__aarch64__))
#if defined(__x86_64__)
constexpr uint32_t kArch = AUDIT_ARCH_X86_64;
#else
constexpr uint32_t kArch = AUDIT_ARCH_AARCH64;
#endif

// Calls the sandbox refuses with EPERM: running a program, creating or changing files and the file
// system, sockets, other processes' memory, mounts, bpf and io_uring.
constexpr long kDeniedCalls[] = {
    SYS_execve,
    SYS_execveat,
#ifdef SYS_fork
    SYS_fork,
    SYS_vfork,
#endif
#ifdef SYS_creat
    SYS_creat,
    SYS_mkdir,
    SYS_rmdir,
    SYS_unlink,
    SYS_rename,
    SYS_link,
    SYS_symlink,
    SYS_chmod,
    SYS_chown,
    SYS_lchown,
    SYS_mknod,
    SYS_utime,
    SYS_utimes,
    SYS_futimesat,
#endif
    SYS_mkdirat,
    SYS_unlinkat,
    SYS_renameat,
    SYS_renameat2,
    SYS_linkat,
    SYS_symlinkat,
    SYS_truncate,
    SYS_fchmod,
    SYS_fchmodat,
    SYS_fchown,
    SYS_fchownat,
    SYS_mknodat,
    SYS_utimensat,
    SYS_setxattr,
    SYS_lsetxattr,
    SYS_fsetxattr,
    SYS_removexattr,
    SYS_lremovexattr,
    SYS_fremovexattr,
    SYS_socket,
    SYS_socketpair,
    SYS_ptrace,
    SYS_process_vm_writev,
    SYS_name_to_handle_at,
    SYS_open_by_handle_at,
    SYS_mount,
    SYS_umount2,
    SYS_chroot,
    SYS_pivot_root,
    SYS_bpf,
#ifdef SYS_io_uring_setup
    SYS_io_uring_setup,
#endif
#ifdef SYS_openat2
    SYS_openat2,
#endif
};

constexpr uint32_t kDeny = SECCOMP_RET_ERRNO | (EPERM & SECCOMP_RET_DATA);

// A classic BPF program for seccomp, built in order.
struct FilterProgram {
  std::vector<sock_filter> code;
  void stmt(uint16_t op, uint32_t k) { code.push_back(BPF_STMT(op, k)); }
  void jump(uint16_t op, uint32_t k, uint8_t jt, uint8_t jf) {
    code.push_back(BPF_JUMP(op, k, jt, jf));
  }
};

// Loads the call number; other ABIs (i386, x32) get nothing.
void load_native_call(FilterProgram& f) {
  f.stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch));
  f.jump(BPF_JMP | BPF_JEQ | BPF_K, kArch, 1, 0);
  f.stmt(BPF_RET | BPF_K, kDeny);
  f.stmt(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr));
#if defined(__x86_64__)
  f.jump(BPF_JMP | BPF_JGE | BPF_K, 0x40000000u, 0, 1);
  f.stmt(BPF_RET | BPF_K, kDeny);
#endif
}

// open(path, flags) / openat(dir, path, flags) with its flags in argument `arg`: reading only.
// Ends the program for call `nr` (allowed or EACCES); other calls fall through.
void allow_reading_only(FilterProgram& f, long nr, int arg) {
  const uint32_t writes = O_WRONLY | O_RDWR | O_CREAT | O_TRUNC | O_APPEND;
  f.jump(BPF_JMP | BPF_JEQ | BPF_K, static_cast<uint32_t>(nr), 0, 4);
  f.stmt(BPF_LD | BPF_W | BPF_ABS,
         static_cast<uint32_t>(offsetof(seccomp_data, args) + 8 * arg));  // low 32 bits (LE)
  f.jump(BPF_JMP | BPF_JSET | BPF_K, writes, 0, 1);
  f.stmt(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | (EACCES & SECCOMP_RET_DATA));
  f.stmt(BPF_RET | BPF_K, SECCOMP_RET_ALLOW);
}

// The seccomp filter of a worker without --allow-geo-commands: gmsh may read files, but not run
// a program, write or create a file, change the file system or open a socket. Denied calls fail
// with EPERM (gmsh reports them as failed commands); threads (clone) stay allowed for OpenMP, and
// a fork can only run more of gmsh, under the same filter.
std::vector<sock_filter> sandbox_filter() {
  FilterProgram f;
  load_native_call(f);
  for (long nr : kDeniedCalls) {
    f.jump(BPF_JMP | BPF_JEQ | BPF_K, static_cast<uint32_t>(nr), 0, 1);
    f.stmt(BPF_RET | BPF_K, kDeny);
  }
#ifdef SYS_open
  allow_reading_only(f, SYS_open, 1);
#endif
  allow_reading_only(f, SYS_openat, 2);
  f.stmt(BPF_RET | BPF_K, SECCOMP_RET_ALLOW);
  return f.code;
}

bool install_sandbox() {
  std::vector<sock_filter> f = sandbox_filter();
  sock_fprog program{static_cast<unsigned short>(f.size()), f.data()};
  if (::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0) return false;
  return ::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &program) == 0;
}
#else
bool install_sandbox() {
  return false;
}
#endif

// An exception that cannot leave gmsh's code (an OpenMP region, a noexcept function) ends in
// std::terminate: a bad_alloc there is still the memory limit, and is reported as such.
[[noreturn]] void on_terminate() {
  bsms::GmshResult result;
  result.status = bsms::GmshResult::Status::Failure;
  if (const std::exception_ptr e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::bad_alloc&) {
      result.status = bsms::GmshResult::Status::OutOfMemory;
    } catch (const std::exception& x) {
      result.message = std::string("terminate: ") + x.what();
    } catch (...) {
      result.message = "terminate: an exception that is not a std::exception";
    }
  } else {
    result.message = "terminate without an exception";
  }
  answer(result);
}

#ifdef BSMS_WORKER_SANITIZED
// Sanitizer builds cannot limit the address space (their shadow memory reserves terabytes): the
// memory limit is watched on the resident size instead, every 20 ms.
void watch_memory(unsigned long long limit) {
  std::thread([limit] {
    const long page = ::sysconf(_SC_PAGESIZE);
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      long total = 0, resident = 0;
      if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
        if (std::fscanf(f, "%ld %ld", &total, &resident) != 2) resident = 0;
        std::fclose(f);
      }
      if (static_cast<unsigned long long>(resident) * static_cast<unsigned long long>(page) >
          limit) {
        bsms::GmshResult result;
        result.status = bsms::GmshResult::Status::OutOfMemory;
        answer(result);
      }
    }
  }).detach();
}
#endif

// OpenMP runtimes start on first use. LLVM's libomp then registers itself in
// /dev/shm/__KMP_REGISTERED_LIB_<pid>_<uid>: the sandbox would refuse that file (and libomp abort),
// and the worker's _exit would leave it behind. Started here, before the sandbox; the file is
// removed at once (libomp reads it only when a second copy of itself loads, which never happens
// here). libgomp (GCC) makes no such file.
void start_openmp() {
#pragma omp parallel num_threads(1)
  {}
  char name[96];
  std::snprintf(name, sizeof name, "/dev/shm/__KMP_REGISTERED_LIB_%d_%d",
                static_cast<int>(::getpid()), static_cast<int>(::getuid()));
  ::unlink(name);
}

unsigned long long number(const char* text, const char* what) {
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(text, &end, 10);
  if (end == text || *end != '\0' || errno != 0) fail(what);
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  close_other_fds();
  unsigned long long memory = 0, cpu = 0, parent = 0;
  bool allow_commands = false;
  const char* path = nullptr;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--memory" && i + 1 < argc) {
      memory = number(argv[++i], "--memory: expected bytes");
    } else if (a == "--cpu" && i + 1 < argc) {
      cpu = number(argv[++i], "--cpu: expected seconds");
    } else if (a == "--parent" && i + 1 < argc) {
      parent = number(argv[++i], "--parent: expected a process id");
    } else if (a == "--allow-commands") {
      allow_commands = true;
    } else if (a == "--" && i + 1 == argc - 1) {
      path = argv[++i];
    } else {
      fail(
          "usage: bsms-gmsh-worker --memory BYTES --cpu SECONDS --parent PID "
          "[--allow-commands] -- FILE (started by bsms)");
    }
  }
  if (path == nullptr || parent == 0) fail("no FILE or --parent (started by bsms)");
  // Dies with bsms; and not at all if bsms is already gone.
  ::prctl(PR_SET_PDEATHSIG, SIGKILL, 0, 0, 0);
  if (static_cast<unsigned long long>(::getppid()) != parent) ::_exit(65);
  set_limit(RLIMIT_CORE, 0);
  if (cpu > 0) {
    rlimit limit{static_cast<rlim_t>(cpu), static_cast<rlim_t>(cpu) + 5};
    ::setrlimit(RLIMIT_CPU, &limit);
  }
#ifndef BSMS_WORKER_SANITIZED
  if (memory > 0) set_limit(RLIMIT_AS, static_cast<rlim_t>(memory));
#else
  if (memory > 0) watch_memory(memory);
#endif
  start_openmp();
  if (!allow_commands) install_sandbox();  // where the kernel refuses, geo_scan's check remains
  std::set_terminate(on_terminate);

  bsms::GmshResult result;
  try {
    result.mesh = bsms::read_mesh_with_gmsh_here(path);
  } catch (const std::bad_alloc&) {
    result.status = bsms::GmshResult::Status::OutOfMemory;
  } catch (const bsms::InputError& e) {
    result.status = bsms::GmshResult::Status::InputError;
    result.message = e.what();
  } catch (const std::exception& e) {
    result.status = bsms::GmshResult::Status::Failure;
    result.message = e.what();
  } catch (...) {
    result.status = bsms::GmshResult::Status::Failure;
    result.message = "an exception that is not a std::exception";
  }
  // _exit: gmsh's own teardown is of no use here (and libgmsh 4.8 can crash in it).
  answer(result);
}
