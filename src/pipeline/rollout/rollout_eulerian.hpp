// `bsms rollout` of an Eulerian run (rollout.cpp dispatches here on "kind": "eulerian"): the
// state (velocity, density) advances by the predicted change on NORMAL and OUTFLOW nodes, every
// other node keeps its ground truth; pressure is read from the output. Metrics per field, beside
// persistence (the first frame held: no model).
#pragma once

#include <optional>

#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/train_config.hpp"
#include "pipeline/runs/train_stats.hpp"

namespace bsms {

// Rolls the run of `request` out with its validated config, resolved spec, level count and
// training stats (none before a session finished), and writes the predicted trajectories and
// metrics.json (rollout_outputs::out_dir).
RolloutMetrics rollout_eulerian(const RolloutRequest& request, const TrainConfig& config,
                                const EulerianSpec& spec, int levels,
                                const std::optional<TrainStats>& stats);

}  // namespace bsms
