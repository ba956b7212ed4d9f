// What `bsms rollout` is asked to do (rollout.hpp): the run, the data, the outputs and the
// options of the rollout loop and its domains.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/physical_projection.hpp"

namespace bsms {

struct RolloutRequest {
  std::string run;
  std::string split = "test";
  std::string data;     // dataset folder; empty: the run's training data folder
  std::string seeding;  // multilevel seeding at test time; empty: the training seeding
  std::string out;      // output folder; empty: RUN/rollout
  // The run's checkpoint: "best" (selected by validation rollouts), "latest", or empty for the
  // best one when the run has it (run_model_checkpoint).
  std::string checkpoint;
  int64_t max_trajectories = 0;  // 0: all
  int64_t max_steps = 0;         // 0: whole trajectories
  int threads = 0;
  bool quiet = false;
  // Teacher forcing (Lagrangian runs): every step starts from the true frames, so the errors are
  // one-step errors along the trajectory, not a rollout's. Writes to RUN/rollout_one_step by
  // default and marks its metrics "one_step" (bsms report refuses them).
  bool one_step = false;
  // Further Lagrangian runs whose predicted accelerations are averaged with RUN's at every step
  // (an ensemble; each member sees the same state through its own features and graphs). Writes
  // to RUN/rollout_ensemble (RUN/rollout_one_step_ensemble) by default.
  std::vector<std::string> ensemble;
  // Frame averaging: every model's prediction averaged over the symmetries of the data's box
  // scene (scene_symmetries: reflections and equal-side axis swaps that keep the walls' types
  // and the gravity), each state mapped, predicted and the acceleration mapped back, so the
  // averaged model is exactly equivariant to them. Default output RUN/rollout[...]_symmetric.
  bool symmetrize = false;
  // Constraints projected after each predicted step (core/physical_projection.hpp): nodes
  // inside the walls of the data's box scene, cells that keep their orientation, bodies that do
  // not pass into one another; the next step sees the projected state. Default output
  // RUN/rollout[...]_<names joined by +>, e.g. RUN/rollout_walls+cells+contact.
  ProjectionOptions projection;
};

}  // namespace bsms
