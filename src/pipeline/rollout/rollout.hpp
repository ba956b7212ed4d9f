// `bsms rollout`: autoregressive prediction over whole trajectories, metrics.json and predicted
// trajectories (HDF5 + XDMF) in RUN/rollout/.
#pragma once

#include "pipeline/rollout/rollout_request.hpp"
#include "pipeline/runs/rollout_metrics.hpp"

namespace bsms {

// Returns the metrics written to RUN/rollout/metrics.json (docs/design.md "Runs").
RolloutMetrics rollout(const RolloutRequest& request);

}  // namespace bsms
