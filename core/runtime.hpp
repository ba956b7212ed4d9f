// Process-level runtime helpers: thread counts, timing, memory, progress display.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace bsms {

// Resolves a requested thread count (<= 0: hardware threads) and applies it to OpenMP.
// LibTorch's own count is set by models/ (torch::set_num_threads) from the same value.
int set_num_threads(int requested);
int hardware_threads();

// Makes OpenBLAS single-threaded when the process has loaded it (looked up with dlsym, so any
// BLAS or none may be linked): the LibTorch layer (models/graph_ops.hpp configure_threads) splits
// GEMMs over OpenMP's passive pool instead, and a second pool of spinning BLAS threads would
// compete with it for the cores. Returns whether OpenBLAS was found.
bool single_threaded_blas();
// OpenBLAS's own thread count (0 when the process has not loaded OpenBLAS), and setting it (no-op
// without OpenBLAS): what single_threaded_blas changes, for callers that restore it afterwards.
int blas_threads();
void set_blas_threads(int threads);

// Keeps large freed blocks in the process instead of returning them to the system (glibc:
// mmap threshold 256 MiB, trim threshold 1 GiB). Training allocates and frees the same large
// tensors every step; without this, each step maps and unmaps them again (measured: 20% of the
// CPU time in the kernel, training step 326 -> 275 ms on the 2.6K-node benchmark mesh). Under
// tcmalloc (allocator_name), which keeps freed spans itself, mallopt does nothing.
void tune_allocator();

// The CPU features that decide which OpenBLAS kernels can run (GCC's __builtin_cpu_supports,
// which also checks that the OS saves the AVX / AVX-512 registers).
struct CpuFeatures {
  bool avx2 = false, fma = false;
  bool avx512f = false, avx512bw = false, avx512dq = false, avx512vl = false, avx512cd = false;
};
CpuFeatures cpu_features();

// The CPU's name as the kernel reports it (/proc/cpuinfo "model name", e.g. "AMD EPYC 9R14"),
// written beside timed figures: this project's machines come as Intel or AMD on different days,
// and a time means little without its CPU. "unknown" where the file or the field is missing.
std::string cpu_model_name();

// OpenBLAS's kernel set in this process (openblas_get_corename, e.g. "SkylakeX", "Haswell",
// "Zen", "Prescott") and its build line (openblas_get_config); "" when no OpenBLAS is loaded.
std::string blas_core();
std::string blas_config();

// The malloc this process runs: "gperftools 2.10 tcmalloc" when gperftools' tcmalloc replaced
// libc's (the LibTorch executables link it, CMake option BSMS_TCMALLOC), else "system malloc".
std::string allocator_name();

// OpenBLAS built with DYNAMIC_ARCH (Debian's) picks its kernels from the CPU's family and model
// when it loads. A model it does not know falls back to Prescott, SSE3 kernels at a fraction of
// the speed: Debian 12's OpenBLAS 0.3.21 on this machine kind's Intel Xeon (family 6, model 207)
// ran the 2.6K-node BSMS training step in 626-662 ms against 243-249 ms with the AVX-512 kernels
// (bench_models train/bsms/2.6K, 2 threads). Returns the OPENBLAS_CORETYPE to force when the
// detected kernels use neither AVX2 nor AVX-512 although the CPU has them: "SkylakeX" (AVX-512
// F/BW/DQ/VL/CD), else "Haswell" (AVX2 + FMA); "" when OpenBLAS's own choice stands (an AVX2 or
// AVX-512 core, a CPU without AVX2 + FMA, or no OpenBLAS).
std::string blas_core_override(const std::string& detected_core, const CpuFeatures& cpu);

// GLIBC_TUNABLES with glibc.malloc.hugetlb=1 added (kept as it is when it sets that tunable
// already): glibc's malloc then asks for transparent huge pages (madvise) on the memory it
// maps, which Debian's kernels grant only on request. A 1M-node `bsms preprocess` (front end,
// glibc's malloc) took 143,000 page faults without it and 9,500 with it: 6.4-7.1 s -> 4.4-5.3 s
// wall on a Zen 5 VM, whose page faults are slow. tcmalloc, where linked, ignores the tunable.
std::string glibc_tunables_with_huge_pages(const std::string& tunables);

// Environment that must be in place before libgomp, OpenBLAS and glibc start, so the program
// re-executes itself (argv, via /proc/self/exe) when it has to change any of it:
// - libgomp's wait policy: unless the user set OMP_WAIT_POLICY or GOMP_SPINCOUNT, sets
//   OMP_WAIT_POLICY=PASSIVE and GOMP_SPINCOUNT=100000: an idle worker spins ~1 ms, then sleeps.
//   GNU's default (3 ms of spinning, throttled) stole the second core from the original model's
//   serial work (1.8x slower training, docs/design.md); pure PASSIVE (no spin) pays a futex wake-up
//   at every parallel region. Measured on 2 cores, in alternating runs: the 2.6K-node BSMS
//   training step 271-301 ms (PASSIVE) -> 223-243 ms, inference 68-78 -> 59-64 ms, a 2D UMLS-MPM
//   step 1.19-1.31 -> 0.81-0.94 ms.
// - OpenBLAS's kernels: unless the user set OPENBLAS_CORETYPE (which is also how to opt out),
//   sets blas_core_override's choice when there is one.
// - glibc's malloc on transparent huge pages (glibc_tunables_with_huge_pages), unless the user's
//   GLIBC_TUNABLES names glibc.malloc.hugetlb.
// Returns only when nothing had to change or the re-exec failed (then: slower, still correct).
void ensure_process_environment(char** argv);
// The same settings without the re-exec, for a program about to execute another (the bsms front
// end starting bsms-torch): returns whether it changed any. The OpenBLAS choice needs OpenBLAS
// loaded in this process (linked, or load_blas_library).
bool prepare_process_environment();

// Loads the system BLAS (libblas.so.3, which Debian points at OpenBLAS) into a process that does
// not link it, for blas_core / blas_config to name the kernels that LibTorch's programs get.
// Returns whether it loaded.
bool load_blas_library();

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  void reset() { start_ = std::chrono::steady_clock::now(); }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }
  double milliseconds() const { return seconds() * 1e3; }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Peak resident set size of this process so far, in MiB.
double peak_rss_mb();
// Current resident set size, in MiB.
double current_rss_mb();

// A progress bar on stderr: redrawn in place on a terminal (at most ~10 times a second), a line
// every 10% otherwise. `extra` is appended (e.g. "loss 1.2e-3, 14 steps/s").
class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total);
  void update(int64_t done, const std::string& extra = "");
  void finish(const std::string& extra = "");

 private:
  std::string label_;
  int64_t total_;
  bool tty_;
  int last_decile_ = -1;
  bool finished_ = false;
  Stopwatch clock_;
  double last_draw_ = -1.0;
};

}  // namespace bsms
