// RUN/rollout/metrics.json (docs/design.md "Runs") as a type with one writer and one strict reader:
// what bsms rollout writes is what bsms report and the experiments read. JSON has no NaN, so a
// non-finite measure is written as null and read back as NaN; an absent figure (std::nullopt) is
// written as null. A missing or malformed key is an InputError naming the file and the key.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/config.hpp"

namespace bsms {

// RMSE of each predicted field over some steps and "total", the RMS of the fields' RMSEs (fields
// have different units: compare totals only between models on one dataset).
struct FieldRmse {
  std::map<std::string, double> fields;  // "world_pos", "velocity" | "velocity", "density", ...
  double total = 0.0;
  double at(const std::string& field) const;  // NaN when the field is absent
};

// The references' rollout table (MeshGraphNets' cfd_eval.py and cloth_eval.py, BSMS-GNN's
// evaluation): per field, the RMSE over a trajectory's first h predicted steps (all of them when it
// has fewer), averaged over the trajectories with equal weight, for h in kRmseHorizons and "all".
// A step's squared error is the mean over all nodes and components, as theirs is.
inline constexpr int kRmseHorizons[] = {1, 10, 20, 50, 100, 200};
class HorizonRmse {
 public:
  // One trajectory: per field, the mean squared error at each predicted step (at least one).
  void add(const std::map<std::string, std::vector<double>>& step_mse);
  // "1", "10", ..., "200" up to the longest trajectory's steps, and "all"; empty without any
  // trajectory. "total" is the RMS of the fields' figures.
  std::map<std::string, FieldRmse> result() const;

 private:
  std::map<std::string, std::map<std::string, double>> sums_;  // horizon -> field -> sum of RMSE
  int64_t trajectories_ = 0;
  size_t longest_ = 0;
};

// RMSE-all split by where each body's error lies (pipeline/rollout/body_motion_error.hpp): its
// centre, its rotation about the centre and its deformation; the squares of the three add up to the
// square of the position RMSE-all.
struct MotionRmse {
  double centre = 0.0, rotation = 0.0, deformation = 0.0;
};

// Lagrangian, per test trajectory (in file order): its predicted steps and the position RMSE over
// them of the model and of constant velocity. RMSE-all is the step-weighted RMS of these.
struct TrajectoryRmse {
  std::vector<int64_t> steps;
  std::vector<double> model, constant_velocity;
  size_t size() const { return steps.size(); }
};

// An interval [lo, hi] of a ratio of two RMSE-alls from resampling test trajectories.
struct RatioInterval {
  double lo = 0.0, hi = 0.0;
};

// Percentile bootstrap of RMSE-all(a) / RMSE-all(b) over trajectories drawn with replacement,
// paired (each draw takes trajectory i of both): RMSE-all over a draw is
// sqrt(sum steps_i a_i^2 / sum steps_i). `level` (e.g. 0.95) is the central share of the
// `resamples` ratios the interval holds. Deterministic for a seed. None when there are fewer
// than 2 trajectories or b's RMSE-all over a draw can be 0. Throws std::invalid_argument on
// sizes that differ or a level outside (0, 1).
std::optional<RatioInterval> bootstrap_ratio_interval(const std::vector<int64_t>& steps,
                                                      const std::vector<double>& a,
                                                      const std::vector<double>& b,
                                                      double level = 0.95, int resamples = 4000,
                                                      uint64_t seed = 1);

// One physical-validity measure of a rollout (core/physical_validity.hpp): its mean over the
// trajectories at each predicted step, each trajectory's largest value over its steps (NaN for
// one without a predicted step) and the largest of those.
struct ValidityCurve {
  std::vector<double> per_step;
  std::vector<double> per_trajectory;
  double max = 0.0;
};

// The validity measures of a set of frames; each is absent where it does not apply: overlap and
// nodes inside other bodies need cells of the full dimension (triangles, tetrahedra), the walls
// a box scene with walls.
struct ValidityMeasures {
  std::optional<ValidityCurve> overlap;              // fraction of the cells' area / volume
  std::optional<ValidityCurve> nodes_in_other_body;  // fraction of the nodes
  std::optional<ValidityCurve> outside_walls;        // the farthest node's distance outside (m)
  std::optional<ValidityCurve> nodes_outside_walls;  // fraction of the nodes
};

// Of the predicted frames and of the true frames at the same steps (the reference: bodies the
// solver pressed together overlap at the mesh level too).
struct PhysicalValidityMetrics {
  ValidityMeasures model, truth;
};

// Constraints projected after each predicted step (bsms rollout --project,
// core/physical_projection.hpp; "projection"): which, and what they corrected, per predicted step
// on average over the rollout.
struct ProjectionMetrics {
  std::vector<std::string> constraints;  // "walls", "cells", "contact" in that order
  int64_t steps = 0;
  double nodes_clamped_per_step = 0.0, cells_restored_per_step = 0.0,
         nodes_pushed_out_per_step = 0.0, passes_per_step = 0.0;
  double shift_rms = 0.0;  // RMS over nodes and steps of how far the projection moved a node (m)
  int64_t unconverged_steps = 0;  // steps left with a violated constraint after the pass limit
};

struct DivergedTrajectory {
  int64_t trajectory = 0;
  int64_t frame = 0;  // the first frame with a non-finite prediction
};

struct RolloutMetrics {
  std::string model;      // "bsms" | "mgn"; an ensemble joins its members' with "+"
  bool eulerian = false;  // "kind": "eulerian"; Lagrangian files have no "kind"
  std::string split;
  std::string data;     // the dataset rolled out
  std::string seeding;  // of the multilevel graphs
  int64_t num_trajectories = 0;
  // The checkpoint rolled out ("checkpoint": "best" or "latest"; older files have none) and the
  // training step it was saved at ("checkpoint_step").
  std::string checkpoint;
  std::optional<int64_t> checkpoint_step;
  // Teacher forcing (bsms rollout --one-step): every step from the true frames, so the RMSE
  // figures are one-step errors and the references one step from the truth. "one_step": true.
  bool one_step = false;
  // Symmetries each prediction was averaged over (bsms rollout --symmetrize; "symmetries",
  // written when > 1); 1: the plain model.
  int symmetries = 1;
  // Constraints projected after each step (bsms rollout --project); none: the plain model.
  std::optional<ProjectionMetrics> projection;
  int levels = 1;
  int threads = 0;
  std::string cpu;  // cpu_model_name() of the machine that timed it ("cpu"; "" when unknown)
  // RMSE over the first 1, 50 and all predicted steps (none when no step was predicted), and the
  // RMSE of each predicted step per field (Lagrangian: world_pos only).
  std::optional<FieldRmse> rmse_1, rmse_50, rmse_all;
  std::map<std::string, std::vector<double>> rmse_per_step;
  // HorizonRmse's table ("rmse_trajectory_mean": {"1": {field: RMSE, ..., "total"}, ..., "all"}):
  // the figures comparable with the references', beside the pooled rmse_1/rmse_50/rmse_all above
  // (each (trajectory, step) pair weighted equally). Empty when no step was predicted.
  std::map<std::string, FieldRmse> rmse_trajectory_mean;
  // Lagrangian: RMSE-all of extrapolating the first velocity (the reference a model must beat),
  // and the fraction of predicted cells turned inside out against the first frame.
  std::optional<double> rmse_all_constant_velocity;
  std::vector<double> inverted_cells_per_step;
  double inverted_cells_max = 0.0;
  // Lagrangian: the position RMSE-all of the model and of constant velocity split into each
  // body's centre, rotation and deformation.
  std::optional<MotionRmse> rmse_all_parts, rmse_all_parts_constant_velocity;
  // The deformation part of holding each body's shape at the first frame (rigid bodies): what a
  // model of the elastic response must beat (constant velocity's deformation part also counts
  // the stretch that extrapolating a spinning body's nodes along straight lines makes).
  std::optional<double> rmse_all_deformation_rigid;
  // Lagrangian: each trajectory's RMSE ("per_trajectory"), and the 95 % bootstrap interval of
  // RMSE-all / constant velocity over the test trajectories ("rmse_all_ratio_interval"): how far
  // the ratio could move on another draw of test trajectories from the same family.
  std::optional<TrajectoryRmse> per_trajectory;
  std::optional<RatioInterval> rmse_all_ratio_interval;
  // Lagrangian in 2-D and 3-D: overlap between bodies and nodes outside the walls ("validity").
  std::optional<PhysicalValidityMetrics> validity;
  // Eulerian: the first frame held on the predicted nodes (no model). Lagrangian with a stress
  // output: rmse_all_persistence has the stress of the last true frame (1) held, field "stress".
  std::optional<FieldRmse> rmse_1_persistence, rmse_all_persistence;
  std::vector<DivergedTrajectory> diverged;
  double infer_ms_per_step = 0.0;  // median
  // From the dataset's solver timings; none when it has none (public data).
  std::optional<double> solver_ms_per_frame, speedup_vs_solver;
  double peak_rss_mb_infer = 0.0;
  double num_nodes_mean = 0.0;
  // From RUN/train_stats.json; none when no training session of the run has finished.
  std::optional<double> train_ms_per_step, peak_rss_mb_train;
  std::optional<int64_t> train_steps;

  // The field the tables show: world positions (m) for Lagrangian runs, velocity for Eulerian.
  std::string primary_field() const { return eulerian ? "velocity" : "world_pos"; }
  // RMSE of `field` in one of rmse_1, rmse_50, rmse_all; NaN when there is none.
  static double rmse(const std::optional<FieldRmse>& over, const std::string& field);
  // The per-step curve of `field` (empty when absent).
  const std::vector<double>& per_step(const std::string& field) const;
};

Json to_json(const RolloutMetrics& metrics);
// nlohmann's conversion hook: `Json j = metrics;`, and maps or vectors of metrics.
inline void to_json(Json& json, const RolloutMetrics& metrics) {
  json = to_json(metrics);
}
RolloutMetrics rollout_metrics_from_json(const Json& json, const std::string& file);
// Reads a metrics file; InputError naming it when it is missing or malformed.
RolloutMetrics read_rollout_metrics(const std::string& file);

}  // namespace bsms
