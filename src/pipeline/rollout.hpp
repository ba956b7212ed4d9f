// `bsms rollout`: autoregressive prediction over whole trajectories, metrics.json and predicted
// trajectories (HDF5 + XDMF) in RUN/rollout/.
#pragma once

#include <cstdint>
#include <string>

#include "pipeline/rollout_metrics.hpp"

namespace bsms {

struct RolloutRequest {
  std::string run;
  std::string split = "test";
  std::string data;              // dataset folder; empty: the run's training data folder
  std::string seeding;           // multilevel seeding at test time; empty: the training seeding
  std::string out;               // output folder; empty: RUN/rollout
  int64_t max_trajectories = 0;  // 0: all
  int64_t max_steps = 0;         // 0: whole trajectories
  int threads = 0;
  bool quiet = false;
};

// Returns the metrics written to RUN/rollout/metrics.json (DESIGN.md "Runs").
RolloutMetrics rollout(const RolloutRequest& request);

}  // namespace bsms
