#include "core/runtime.hpp"

#include <dlfcn.h>
#include <malloc.h>
#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

namespace bsms {

int hardware_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(n);
}

int set_num_threads(int requested) {
  const int threads = requested <= 0 ? hardware_threads() : requested;
  omp_set_num_threads(threads);
  return threads;
}

bool single_threaded_blas() {
  set_blas_threads(1);
  return blas_threads() > 0;
}

int blas_threads() {
  using GetThreads = int (*)();
  auto get = reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
  return get != nullptr ? get() : 0;
}

void set_blas_threads(int threads) {
  using SetThreads = void (*)(int);
  auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
  if (set != nullptr && threads > 0) set(threads);
}

std::string cpu_model_name() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) != 0) continue;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) break;
    const size_t begin = line.find_first_not_of(" \t", colon + 1);
    const size_t end = line.find_last_not_of(" \t\r");
    if (begin == std::string::npos || end < begin) break;
    return line.substr(begin, std::min<size_t>(end - begin + 1, 200));
  }
  return "unknown";
}

CpuFeatures cpu_features() {
  __builtin_cpu_init();
  CpuFeatures cpu;
  cpu.avx2 = __builtin_cpu_supports("avx2") != 0;
  cpu.fma = __builtin_cpu_supports("fma") != 0;
  cpu.avx512f = __builtin_cpu_supports("avx512f") != 0;
  cpu.avx512bw = __builtin_cpu_supports("avx512bw") != 0;
  cpu.avx512dq = __builtin_cpu_supports("avx512dq") != 0;
  cpu.avx512vl = __builtin_cpu_supports("avx512vl") != 0;
  cpu.avx512cd = __builtin_cpu_supports("avx512cd") != 0;
  return cpu;
}

namespace {
std::string openblas_string(const char* symbol) {
  using Getter = char* (*)();
  auto get = reinterpret_cast<Getter>(dlsym(RTLD_DEFAULT, symbol));
  if (get == nullptr) return "";
  const char* text = get();
  return text == nullptr ? "" : std::string(text);
}
}  // namespace

std::string blas_core() {
  return openblas_string("openblas_get_corename");
}
std::string blas_config() {
  return openblas_string("openblas_get_config");
}

std::string allocator_name() {
  // gperftools' malloc is an alias of its tc_malloc: the same address when it replaced libc's.
  void* tc_malloc = dlsym(RTLD_DEFAULT, "tc_malloc");
  if (tc_malloc == nullptr || dlsym(RTLD_DEFAULT, "malloc") != tc_malloc) return "system malloc";
  // tc_version(major, minor, patch string) returns "gperftools X.Y".
  using Version = const char* (*)(int*, int*, const char**);
  auto* version = reinterpret_cast<Version>(dlsym(RTLD_DEFAULT, "tc_version"));
  if (version == nullptr) return "gperftools tcmalloc";
  int major = 0, minor = 0;
  const char* patch = nullptr;
  const char* name = version(&major, &minor, &patch);
  return std::string(name != nullptr ? name : "gperftools") + " tcmalloc";
}

std::string blas_core_override(const std::string& detected_core, const CpuFeatures& cpu) {
  if (detected_core.empty()) return "";  // not OpenBLAS: nothing to steer
  std::string core = detected_core;
  std::transform(core.begin(), core.end(), core.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  // OpenBLAS's x86-64 kernel sets with AVX2 (Haswell; Zen reuses them) or AVX-512.
  static const char* const vector_cores[] = {"haswell", "zen", "skylakex", "cooperlake",
                                             "sapphirerapids"};
  for (const char* name : vector_cores)
    if (core == name) return "";
  if (cpu.avx512f && cpu.avx512bw && cpu.avx512dq && cpu.avx512vl && cpu.avx512cd)
    return "SkylakeX";
  if (cpu.avx2 && cpu.fma) return "Haswell";
  return "";
}

std::string glibc_tunables_with_huge_pages(const std::string& tunables) {
  if (tunables.find("glibc.malloc.hugetlb") != std::string::npos) return tunables;
  return tunables.empty() ? "glibc.malloc.hugetlb=1" : tunables + ":glibc.malloc.hugetlb=1";
}

bool prepare_process_environment() {
  bool changed = false;
  if (std::getenv("OMP_WAIT_POLICY") == nullptr && std::getenv("GOMP_SPINCOUNT") == nullptr) {
    setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
    setenv("GOMP_SPINCOUNT", "100000", 1);
    changed = true;
  }
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  const std::string with_huge_pages = glibc_tunables_with_huge_pages(tunables ? tunables : "");
  if (with_huge_pages != (tunables ? tunables : "")) {
    setenv("GLIBC_TUNABLES", with_huge_pages.c_str(), 1);
    changed = true;
  }
  if (std::getenv("OPENBLAS_CORETYPE") == nullptr) {
    const std::string core = blas_core_override(blas_core(), cpu_features());
    if (!core.empty()) {
      setenv("OPENBLAS_CORETYPE", core.c_str(), 1);
      changed = true;
    }
  }
  return changed;
}

void ensure_process_environment(char** argv) {
  if (prepare_process_environment()) execv("/proc/self/exe", argv);
}

bool load_blas_library() {
  return dlopen("libblas.so.3", RTLD_NOW | RTLD_GLOBAL) != nullptr;
}

void tune_allocator() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

double current_rss_mb() {
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  statm >> pages_total >> pages_resident;
  return static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) /
         (1024.0 * 1024.0);
}

ProgressBar::ProgressBar(std::string label, int64_t total)
    : label_(std::move(label)), total_(std::max<int64_t>(total, 1)), tty_(isatty(STDERR_FILENO)) {}

namespace {
std::string format_eta(double seconds) {
  char buf[32];
  const long s = static_cast<long>(seconds + 0.5);
  if (s >= 3600) {
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", s / 3600, (s / 60) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ldm%02lds", s / 60, s % 60);
  }
  return buf;
}
}  // namespace

void ProgressBar::update(int64_t done, const std::string& extra) {
  if (finished_) return;
  const double fraction = std::clamp(static_cast<double>(done) / total_, 0.0, 1.0);
  const double elapsed = clock_.seconds();
  std::ostringstream line;
  if (tty_) {
    if (elapsed - last_draw_ < 0.1 && done < total_) return;
    last_draw_ = elapsed;
    const int width = 30;
    const int filled = static_cast<int>(fraction * width);
    line << '\r' << label_ << " [" << std::string(filled, '#') << std::string(width - filled, ' ')
         << "] " << done << '/' << total_;
  } else {
    const int decile = static_cast<int>(fraction * 10);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    line << label_ << ": " << done << '/' << total_;
  }
  line << "  " << format_eta(elapsed);
  if (done > 0 && done < total_)
    line << " (eta " << format_eta(elapsed * (1.0 / fraction - 1.0)) << ')';
  if (!extra.empty()) line << "  " << extra;
  if (tty_) {
    line << "\x1b[K";
    std::cerr << line.str() << std::flush;
  } else {
    std::cerr << line.str() << '\n';
  }
}

void ProgressBar::finish(const std::string& extra) {
  if (finished_) return;
  if (!tty_ && last_decile_ == 10 && extra.empty()) {  // the 100% line is already out
    finished_ = true;
    return;
  }
  last_draw_ = -1.0;
  last_decile_ = -1;
  update(total_, extra);
  if (tty_) std::cerr << '\n';
  finished_ = true;
}

}  // namespace bsms
