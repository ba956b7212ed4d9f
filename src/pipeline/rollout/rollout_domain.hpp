// What one domain adds to the rollout loop (rollout.cpp): the loop walks the trajectories, times
// the steps, stops a trajectory at its first non-finite frame, pools the errors, writes the
// predicted and true frames and metrics.json; a RolloutDomain opens the run's model(s), predicts
// each next frame and scores it, and adds its references (constant velocity, persistence) and its
// own measures to the metrics. Lagrangian (lagrangian_rollout.cpp) and Eulerian
// (eulerian_rollout.cpp) are its two peers.
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "pipeline/rollout/rollout_request.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {

// One scored field of a rollout.
struct ScoredField {
  std::string name;
  bool in_total = true;  // counts in FieldRmse::total
  bool per_step = true;  // has a curve in metrics.rmse_per_step
};

// A domain's frames and fields.
struct RolloutLayout {
  int64_t given_frames = 1;         // true frames a trajectory's rollout starts from
  int dim = 2;                      // the written dataset's dimension
  std::vector<FieldInfo> frame;     // a frame's columns, in order: written as NAME, target_NAME
  std::vector<ScoredField> scored;  // pooled into rmse_1, rmse_50, rmse_all
};

// One field's error at one predicted step: its squared-error sum and what it is divided by.
struct FieldError {
  std::string name;
  double sum = 0.0;
  double weight = 1.0;
};

// Squared errors per predicted step and field, pooled over the trajectories: at each step, the
// sums added divided by the weights added.
class FieldCurves {
 public:
  explicit FieldCurves(std::vector<ScoredField> fields) : fields_(std::move(fields)) {}
  void add(size_t step, const FieldError& error);
  // Pooled over the first `steps` steps; "total" the RMS over the fields in_total. None without
  // a step.
  std::optional<FieldRmse> rmse_over(size_t steps) const;
  // sqrt(sum / weight) at each step.
  std::vector<double> per_step(const std::string& field) const;
  size_t steps() const { return steps_; }

 private:
  std::vector<ScoredField> fields_;
  std::map<std::string, std::vector<double>> sum_, weight_;
  size_t steps_ = 0;
};

class RolloutDomain {
 public:
  virtual ~RolloutDomain() = default;
  const RolloutLayout& layout() const { return layout_; }
  const Dataset& data() const { return *data_; }

  // Trajectory t's first `frames` frames: reads the truth, returns it as [frames, N, width]
  // (the layout's columns).
  virtual torch::Tensor start(int64_t t, int64_t frames) = 0;
  // The prediction of frame f + 1 [N, width] from the frames up to f (the first given_frames
  // true, then predicted); may be non-finite (the loop then ends the trajectory).
  virtual torch::Tensor step(int64_t f) = 0;
  // The prediction step() made is kept: the next step starts from it. Its errors per scored
  // field.
  virtual std::vector<FieldError> accept(int64_t f) = 0;
  // The trajectory ended after `steps` kept predictions.
  virtual void end_trajectory(int64_t steps) = 0;
  // The domain's part of the metrics (model name, references, its own measures), after the
  // loop has set the pooled errors; returns the result in words for the command's last line
  // ("RMSE-all ...").
  virtual std::string finish(RolloutMetrics& metrics) const = 0;

  Seeding seeding = Seeding::kMinAve;  // of the run's graphs in this rollout
  int levels = 1;
  int threads = 1;
  std::string checkpoint;  // the run's checkpoint rolled out: "best" or "latest"
  int64_t checkpoint_step = 0;

 protected:
  RolloutLayout layout_;
  std::optional<Dataset> data_;  // opened by the domain, after what it checks first
};

// The domains, for `request` on the run of `folder`: opens the data and the model(s) and checks
// that they fit; InputError when not (an option the domain does not take, a missing field).
std::unique_ptr<RolloutDomain> lagrangian_rollout(const RolloutRequest& request,
                                                  const RunFolder& folder);
std::unique_ptr<RolloutDomain> eulerian_rollout(const RolloutRequest& request,
                                                const RunFolder& folder);

}  // namespace bsms
