// `bsms train`: training loop with validation, atomic checkpoints and exact resume.
#pragma once

#include <string>
#include <vector>

#include "pipeline/distributed/distributed.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_config.hpp"

namespace bsms {

struct TrainRequest {
  std::string config_path;
  std::vector<std::string> overrides;  // "key.path=value"
  std::string out;                     // run folder; empty: runs/<config file stem>
  bool resume = false;
  int64_t until = 0;  // > 0: stop (with a checkpoint) at this step; resumable
  int threads = 0;
  bool quiet = false;  // no progress bar (tests)
  // Data-parallel rank of this process (world 1: alone). Rank 0 writes the run folder.
  DistributedSettings distributed;
};

struct TrainResult {
  std::string run_dir;
  int64_t steps = 0;
  double final_loss = 0.0;
  double final_valid_loss = 0.0;
  double train_ms_per_step = 0.0;  // median
};

TrainResult train(const TrainRequest& request);

// The checks `train` makes on the config, the overrides and the training data before any work,
// for a launcher to report bad input once instead of once per rank.
void check_train_request(const TrainRequest& request);

}  // namespace bsms
