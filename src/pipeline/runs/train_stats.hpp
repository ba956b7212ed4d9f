// RUN/train_stats.json (docs/design.md "Runs") as a type with one writer (bsms train, at the end of
// each session) and one strict reader (bsms rollout copies its figures into the metrics; a resumed
// session keeps the first session's median and peak). Non-finite losses are written as null and
// read back as NaN; a missing or malformed key is an InputError naming the file and the key.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "core/config.hpp"

namespace bsms {

struct TrainStats {
  int64_t steps = 0;                         // optimizer steps of the run so far (all sessions)
  double train_ms_per_step = 0.0;            // median over the session's steps
  double peak_rss_mb_train = 0.0;            // the highest of every session
  int threads = 0;                           // LibTorch threads per rank
  int world_size = 1;                        // data-parallel ranks
  int64_t samples_per_step = 0;              // world_size × batch size
  double wall_s = 0.0;                       // the session's training time
  double final_loss = 0.0;                   // last training loss (NaN: none)
  double final_valid_loss = 0.0;             // last validation loss (NaN: none)
  double final_valid_zero_prediction = 0.0;  // its zero-prediction loss (NaN: none)
  int64_t num_parameters = 0;
  std::string valid_split = "valid";  // "valid", or "train" when the dataset has none
  // The BLAS build and kernels the session ran with (OpenBLAS's openblas_get_config, e.g.
  // "OpenBLAS 0.3.21 ... DYNAMIC_ARCH ... SkylakeX ..."); empty when not OpenBLAS or not recorded.
  std::string blas;
  // The library and instruction set of the models' float32 products (models/graph_ops.hpp
  // matmul_library, e.g. "oneDNN 2.6.3 sgemm, avx512_core_bf16"); empty when not recorded.
  std::string matmul;
  // The malloc the session ran with (core/runtime.hpp allocator_name); empty when not recorded.
  std::string allocator;
  // Data-parallel sessions: rank 0's time in the gradient all-reduce per step (waiting for slower
  // ranks included) and the all-reduce calls per step; none for a single process.
  std::optional<double> allreduce_ms_per_step, allreduce_calls_per_step;
  // The session's start-up: wall seconds from the start of training (the data opened, the model
  // resolved, the normalizers settled) to the first optimizer step; none without a step.
  std::optional<double> seconds_to_first_step;
  // The session's graph hierarchies (GraphStore): made (loaded from the disk cache or built),
  // evicted under graph_cache_mb, and the most held at once.
  std::optional<int64_t> graphs_made, graphs_evicted;
  std::optional<double> graph_cache_peak_mb;
  // Checkpoint selection by rollout (train config valid_rollout_every): the step of
  // RUN/checkpoints/best.h5 and its validation rollout's RMSE-all; none without selection.
  std::optional<int64_t> best_step;
  std::optional<double> best_valid_rollout_rmse;
};

Json to_json(const TrainStats& stats);
TrainStats train_stats_from_json(const Json& json, const std::string& file);
// Reads a stats file; InputError naming it when it is missing or malformed.
TrainStats read_train_stats(const std::string& file);

}  // namespace bsms
