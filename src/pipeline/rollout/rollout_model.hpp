// A trained Lagrangian run opened for prediction: what `bsms rollout` steps with, and what the
// Python module's bsms.Run predicts with.
#pragma once

#include <torch/types.h>

#include <memory>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/graphs/graph_store.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {

// The run's model (checkpoint loaded, in evaluation mode), its features with the walls of the
// data's scene, and its multilevel graphs (cached in DATA/multilevel and RUN/multilevel).
struct RolloutModel {
  std::string model_type;
  std::string checkpoint;  // "best" or "latest" (run_model_checkpoint)
  int64_t checkpoint_step = 0;
  LagrangianSpec spec;
  Seeding seeding = Seeding::kMinAve;
  std::shared_ptr<LearnedSimulator> simulator;
  std::unique_ptr<GraphStore> store;
  std::unique_ptr<LagrangianAdapter> adapter;
};

// Opens a Lagrangian run for rolling out on `data` (read from folder `data_dir`). `seeding`: the
// multilevel seeding at test time, empty for the training seeding; `checkpoint`: which of the
// run's checkpoints (run_model_checkpoint: "best", "latest", or "" for the best when there is one).
RolloutModel open_rollout_model(const RunFolder& folder, const Dataset& data,
                                const std::string& data_dir, const std::string& seeding,
                                const std::string& checkpoint = "");

// One predicted step: the positions at t+1 [N, dim] from `frames` (world positions [N, dim] at
// t - k, ..., t - 1, t; oldest first, at least 2), the nodes the model does not move taken from
// `prescribed` [N, dim]. Needs torch::InferenceMode or NoGradGuard in the caller.
torch::Tensor predict_step(RolloutModel& model, const TrajectoryMesh& mesh,
                           const std::vector<torch::Tensor>& frames,
                           const torch::Tensor& prescribed);

}  // namespace bsms
