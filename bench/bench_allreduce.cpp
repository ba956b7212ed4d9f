// All-reduce of a model's gradients over c10d/Gloo on loopback, against model size.
//
//   bench_allreduce [RANKS=2] [REPEATS=60]
//
// Forks RANKS processes that join one process group (as `bsms train --nproc` does) and all-reduce
// the gradients of BSMS models of latent 32 .. 256 (the parameter tensors of LearnedSimulator for
// the disks2d features, 5 levels) through Communicator::all_reduce_sum, bucketed as in training.
// Rank 0 prints, per model, the parameter count, the bytes, the buckets and the median and
// minimum ms per all-reduce over REPEATS (after 5 warm-up calls), and the effective bandwidth
// 2 (N - 1) / N x bytes / time of a ring.
#include <sys/wait.h>
#include <torch/torch.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "core/runtime.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/distributed/distributed.hpp"

namespace {

int run_rank(int rank, int world, int port, int repeats) {
  bsms::DistributedSettings s;
  s.world = world;
  s.rank = rank;
  s.master_port = port;
  s.timeout_s = 60;
  bsms::Communicator comm(s);
  for (int latent : {32, 64, 128, 256}) {
    bsms::ModelConfig config;
    config.type = "bsms";
    config.latent = latent;
    torch::manual_seed(1);
    bsms::LagrangianSpec spec;  // disks2d: 2-D, contact edges, strain channel
    spec.contact_radius = 0.035;
    spec.strain_scale = 0.01;
    bsms::LearnedSimulator model(bsms::LagrangianAdapter(spec).model_shape(), config, 5);
    std::vector<torch::Tensor> grads;
    int64_t values = 0;
    for (const auto& p : model.parameters()) {
      grads.push_back(torch::randn(p.sizes()));
      values += p.numel();
    }
    std::vector<double> ms;
    const int64_t calls_before = comm.collective_calls;
    for (int i = 0; i < repeats + 5; ++i) {
      bsms::Stopwatch clock;
      comm.all_reduce_sum(grads, i, "bench all-reduce");
      if (i >= 5) ms.push_back(clock.milliseconds());
    }
    const double buckets =
        static_cast<double>(comm.collective_calls - calls_before) / (repeats + 5);
    std::sort(ms.begin(), ms.end());
    if (rank == 0) {
      const double bytes = 4.0 * static_cast<double>(values);
      const double median = ms[ms.size() / 2];
      std::printf("%-7d %12lld %10.2f %8.0f %12.3f %12.3f %14.2f\n", latent,
                  static_cast<long long>(values), bytes / 1e6, buckets, median, ms.front(),
                  2.0 * (world - 1) / world * bytes / (median * 1e-3) / 1e9);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const int world = argc > 1 ? std::stoi(argv[1]) : 2;
  const int repeats = argc > 2 ? std::stoi(argv[2]) : 60;
  bsms::set_num_threads(1);
  const int port = 20000 + static_cast<int>(::getpid() % 20000);
  std::printf("ranks %d on loopback, 1 thread each, %d repeats (median, min)\n", world, repeats);
  std::printf("%-7s %12s %10s %8s %12s %12s %14s\n", "latent", "parameters", "MB", "buckets",
              "median_ms", "min_ms", "ring_GB/s");
  std::fflush(stdout);
  std::vector<pid_t> children;
  for (int r = 1; r < world; ++r) {
    const pid_t pid = ::fork();
    if (pid == 0) ::_exit(run_rank(r, world, port, repeats));
    children.push_back(pid);
  }
  int code = 0;
  try {
    code = run_rank(0, world, port, repeats);
  } catch (const std::exception& e) {
    std::cerr << "bench_allreduce: " << e.what() << "\n";
    code = 1;
  }
  for (pid_t pid : children) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) code = 1;
  }
  return code;
}
