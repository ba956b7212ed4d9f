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

// Keeps large freed blocks in the process instead of returning them to the system (glibc:
// mmap threshold 256 MiB, trim threshold 1 GiB). Training allocates and frees the same large
// tensors every step; without this, each step maps and unmaps them again (measured: 20% of the
// CPU time in the kernel, training step 326 -> 275 ms on the 2.6K-node benchmark mesh).
void tune_allocator();

// libgomp reads its wait policy once, when it loads. Unless the user set OMP_WAIT_POLICY or
// GOMP_SPINCOUNT, re-executes the program (argv, via /proc/self/exe) with OMP_WAIT_POLICY=PASSIVE
// and GOMP_SPINCOUNT=100000: an idle worker spins ~1 ms, then sleeps. GNU's default (3 ms of
// spinning, throttled) stole the second core from the original model's serial work (1.8x slower
// training, DESIGN.md); pure PASSIVE (no spin) pays a futex wake-up at every parallel region.
// Measured on 2 cores, in alternating runs: the 2.6K-node BSMS training step 271-301 ms (PASSIVE)
// -> 223-243 ms, inference 68-78 -> 59-64 ms, a 2D UMLS-MPM step 1.19-1.31 -> 0.81-0.94 ms.
// Returns only when nothing had to change or the re-exec failed (then: slower, still correct).
void ensure_omp_wait_policy(char** argv);

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
