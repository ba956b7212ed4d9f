// Data-parallel training across processes and machines on PyTorch's distributed engine: c10d
// with the Gloo backend, rendezvous through a TCPStore served by rank 0. Ranks find each other by
// torchrun's environment variables (MASTER_ADDR, MASTER_PORT, WORLD_SIZE, RANK, LOCAL_RANK);
// `bsms train --nproc N` sets them for N local ranks (pipeline/distributed/launcher.hpp).
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace bsms {

struct DistributedSettings {
  int world = 1;  // WORLD_SIZE
  int rank = 0;   // RANK: 0 writes the run folder
  int local_rank = 0;
  std::string master_addr = "127.0.0.1";
  int master_port = 29500;
  double timeout_s = 300.0;  // a rank silent this long (dead or hung) stops the others
  bool enabled() const { return world > 1; }
};

// torchrun's variables, read by the ranks and by the launcher: an integer in [lo, hi], or
// `fallback` when unset (InputError naming the variable otherwise); a string, or `fallback` when
// unset or empty.
int64_t environment_int(const char* name, int64_t fallback, int64_t lo, int64_t hi);
std::string environment_string(const char* name, const std::string& fallback);

// The settings of this process from the environment (torchrun's variables); world 1 when
// WORLD_SIZE is unset. A malformed or contradictory value is an InputError naming the variable.
DistributedSettings distributed_from_environment(double timeout_s);

// One process's membership of the group. Collectives throw DistributedError naming this rank,
// the step and the cause when a peer dies, closes its connection or stays silent past the timeout.
class Communicator {
 public:
  // Rendezvous: rank 0 listens on MASTER_PORT (InputError, exit 2, when the port is taken); the
  // others connect (InputError when the master cannot be reached within the timeout).
  explicit Communicator(const DistributedSettings& settings);
  ~Communicator();
  Communicator(const Communicator&) = delete;
  Communicator& operator=(const Communicator&) = delete;

  int rank() const { return settings_.rank; }
  int world() const { return settings_.world; }
  const DistributedSettings& settings() const { return settings_; }

  // Sums `tensors` over the ranks in place. The tensors are packed by dtype into flat buckets of
  // at most bucket_bytes (one all-reduce each, all in flight together), not one call per tensor.
  void all_reduce_sum(const std::vector<torch::Tensor>& tensors, int64_t step,
                      const std::string& what);
  // Rank 0's values of `tensors` on every rank (same bucketing).
  void broadcast(const std::vector<torch::Tensor>& tensors, int64_t step, const std::string& what);
  // Rank 0's `bytes` (ignored elsewhere) on every rank, through the store: checkpoints and the
  // start-up verdict of rank 0, which alone sees the run folder.
  std::string share(const std::string& key, const std::string& bytes);

  int64_t bucket_bytes = 8 << 20;
  // All-reduce calls and the time spent in collectives (packing included), for the figures.
  int64_t collective_calls = 0;
  double collective_ms = 0.0;

 private:
  // Both collectives: tensors packed into buckets, one call per bucket, results written back.
  void bucketed(const std::vector<torch::Tensor>& tensors, int64_t step, const std::string& what,
                bool broadcast);
  struct Impl;
  DistributedSettings settings_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bsms
