// bsms experiment predictability: how far a rollout must drift from the truth on a scene even
// with perfect physics, given one-step errors of a known size (where a target proves out
// of reach, this shows what would reach it).
//
// Each trajectory of a generated dataset (bsms generate: DATA/generate.json names the family, each
// trajectory's parameters its draw) is solved again by UMLS-MPM, once as stored (the reference)
// and then with kicks: at recorded frames, every free body (all its nodes of node_type normal)
// gets a random rigid velocity change whose displacement over one frame has, per component, the
// RMS `centre` (translation, N(0, centre^2) per component) and `rotation` (a spin about the
// body's node centroid, scaled so its nodes move by `rotation` RMS per component). A model that
// errs like this, with the solver's physics otherwise, makes exactly such acceleration errors, so
// the kicked solves' RMSE-all against the reference is what a model with that one-step body error
// reaches. Kick sizes are a list of scales of a base error, either given or read from a run's
// `bsms rollout --one-step` metrics (the centre and rotation parts of its one-step RMSE-all).
//
// Modes: "every, independent" kicks at each frame from frame 1 (the last frame a rollout is given)
// on, independent from frame to frame: the best rollout that size of one-step error allows.
// "every, persistent" draws the kicks as an AR(1) sequence per body whose correlation between
// frames matches how long a model's errors persist (a model errs alike in alike states, so its
// error at one frame says much of the next; measured on its one-step rollout, below): the rollout
// error that the model's one-step error size and persistence explain. "once" kicks at frame 1
// only, which measures how the scene amplifies one error (collisions, walls).
//
// Writes OUT/metrics.json, OUT/predictability.md and OUT/plots/predictability_rmse.png.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/config.hpp"

namespace bsms {

struct PredictabilityOptions {
  std::string data;  // dataset folder written by bsms generate
  std::string out;
  std::string split = "test";
  int64_t max_trajectories = 0;  // 0: all of the split
  // The base one-step error per frame, m (RMS per component): from `run`'s one-step rollout
  // (RUN/rollout_one_step/metrics.json) unless given (> 0 overrides; both <= 0 and no run is an
  // InputError). RUN/rollout/metrics.json, when present, is drawn beside the kicked solves.
  std::string run;
  double centre = 0.0, rotation = -1.0;  // rotation < 0: from the run, else 0
  std::vector<double> scales{0.25, 0.5, 1.0, 2.0};
  // Correlation of the kicks between consecutive frames for the "persistent" rows (an AR(1)
  // sequence): < 0 takes the run's (one_step_error_persistence of RUN/rollout_one_step/test.h5,
  // or of the split named there), and gives no persistent rows without a run; 0: none.
  double correlation = -1.0;
  int draws = 2;        // kick sequences per trajectory, scale and mode
  double target = 0.1;  // RMSE-all / constant velocity asked for; the report says what reaches it
  uint64_t seed = 1;
  int threads = 0;  // trajectories solved at once (0: hardware threads)
  bool quiet = false;
  // "scene.KEY=VALUE" changes to the family's scene for every re-solve (e.g.
  // scene.background.element_size=0.041: another background mesh). The altered solve is then the
  // kicked rows' reference, and a row "altered solver, no kicks" scores it against the stored
  // frames like a rollout: how much the data depend on that choice of the solver, a part of the
  // motion a model that cannot see it cannot predict.
  std::vector<std::string> solver_set;
};

// How long a model's one-step errors persist, from a teacher-forced rollout file (bsms rollout
// --one-step: world_pos predicted one step from the true frames, beside target_world_pos): each
// body's centre error (the mean of its nodes' errors) at each predicted frame, and its
// autocorrelation between frames L apart, pooled over bodies, components and trajectories:
// rho_L = sum e_f e_{f+L} / sqrt(sum_{f<n-L} e_f^2 * sum_{f>=L} e_f^2). The integrated
// autocorrelation time tau = 1 + 2 sum rho_L runs to the last lag before rho_L first drops to <= 0
// (at most max_lag); an AR(1) sequence with correlation (tau - 1) / (tau + 1) has the same tau,
// i.e. its sum over many frames has the same variance. InputError when the file is not a rollout.
struct ErrorPersistence {
  std::vector<double> autocorrelation;  // rho_1 ... rho_max_lag (NaN where too few frames)
  double tau = 1.0, rho_ar1 = 0.0;
  int64_t body_frames = 0;  // centre errors used
};
ErrorPersistence one_step_error_persistence(const std::string& rollout_h5, int max_lag = 10);

// Runs the experiment described above; returns what OUT/metrics.json holds.
Json predictability_experiment(const PredictabilityOptions& options);

// Where a rising curve crosses `target`, by linear interpolation in log(x) and log(y) between
// the first two consecutive points that bracket it; NaN when no pair does. x ascending, > 0.
double log_log_crossing(const std::vector<double>& x, const std::vector<double>& y, double target);

}  // namespace bsms
