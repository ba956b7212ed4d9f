// bsms experiment solver-frontier: the solver's own speed-error frontier, the line a learned
// simulator must beat at equal cost.
//
// Each trajectory of a split of a generated dataset (bsms generate: DATA/generate.json names the
// family, each trajectory's parameters its draw) is solved again by UMLS-MPM at its ground-truth
// settings and at cheaper ones (coarser background, larger CFL number, coarser particle spacing),
// each solve single-threaded as bsms generate solves, `threads` at once. Each solve is scored
// against the STORED frames as bsms rollout scores a model: the position MSE over all nodes at
// each predicted frame 2 .. T-1, RMSE-all the root of its mean over the steps of all
// trajectories, beside constant velocity (the first velocity extrapolated on free nodes) over the
// same trajectories. Its cost is the solve's wall time per frame (the stepping, as the dataset's
// solver_wall_s), the median over trajectories; the ground-truth settings are timed in the same
// run, so speed-ups are measured under one load. The ground-truth re-solve's RMSE (~0) checks
// that the re-solve reproduces the data.
//
// A setting that changes the particle spacing changes the mesh (particles are the mesh nodes):
// its solution is read at the stored nodes by piecewise-linear interpolation (node_interpolation:
// each stored node located in the re-solve's initial cells of the same body, its barycentric
// weights applied to the re-solve's positions at every frame). A re-solve that throws
// NumericalError is recorded as unstable with its message and left out of its setting's figures.
//
// Writes OUT/metrics.json (SolverFrontier, below) and OUT/solver_frontier.md.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/config.hpp"

namespace bsms {

struct SolverFrontierOptions {
  std::string data;  // dataset folder written by bsms generate
  std::string out;
  std::string split = "test";
  int64_t max_trajectories = 0;  // 0: all of the split
  int threads = 0;               // solves at once, each single-threaded (0: hardware threads)
  bool quiet = false;
  // "NAME=KEY=VALUE[,KEY=VALUE...]", KEY a key of the family file under scene. or sample. (e.g.
  // "coarse=scene.background.element_size=0.06"), or a bare NAME of one of
  // default_solver_settings (e.g. "another_mesh"); empty: all of default_solver_settings.
  std::vector<std::string> settings;
};

// A named change of the family: --set style assignments "scene.KEY=VALUE" / "sample.KEY=VALUE".
struct SolverSetting {
  std::string name;
  std::vector<std::string> assignments;
};

// Parses "NAME=KEY=VALUE[,KEY=VALUE...]" (commas inside [..], {..} or quotes belong to the value).
// InputError naming the text when NAME is empty or not of [A-Za-z0-9_.+-], or an assignment is
// not scene.KEY=VALUE / sample.KEY=VALUE.
SolverSetting parse_solver_setting(const std::string& text);

// The settings used when none is given, each one knob of the family `family` (its JSON, from
// `file`; its base scene read by the scene parser, InputError when malformed): the
// background element size x1.5 and x2, the CFL number x2 and x3 (capped at 1, the scene parser's
// bound; absent when the scene fixes its time step), every sample key named spacing or *_spacing
// x1.5 together; and kAnotherMesh. A knob the family lacks is skipped with a line in `notes`.
std::vector<SolverSetting> default_solver_settings(const Json& family, const std::string& file,
                                                   std::vector<std::string>& notes);

// The setting that solves at the same resolution on another background mesh (element size
// x kAnotherMeshFactor: gmsh places other nodes). Not a cheaper setting but the data's floor for a
// model: contact and wall forces act through the background nodes, so part of the truth depends on
// the exact mesh, which a model that does not see the background cannot know. Its RMSE-all is
// that part's size. A --setting of this name is treated the same.
inline constexpr const char* kAnotherMesh = "another_mesh";
inline constexpr double kAnotherMeshFactor = 1.014;

// One setting's solve of one trajectory.
struct FrontierTrajectory {
  int64_t trajectory = 0;  // position in the split
  int64_t index = 0;       // global index of its draw (bsms generate)
  bool unstable = false;
  std::string message;        // the solver's, when unstable
  double ms_per_frame = 0.0;  // solve wall time / (frames - 1); NaN when unstable
  double rmse_all = 0.0;      // against the stored frames; NaN when unstable
  double rmse_all_constant_velocity = 0.0;
  int64_t steps = 0;  // predicted frames scored (0 when unstable)
};

struct FrontierSetting {
  std::string name;
  std::vector<std::string> assignments;  // empty: the ground-truth settings
  bool interpolated = false;             // other mesh nodes: read at the stored nodes
  // Over the stable trajectories (NaN when none): median ms per frame, median of each
  // trajectory's ground-truth time over its time, RMSE-all, its ratio to constant velocity's
  // RMSE-all over the same trajectories, and the largest distance of a scored position from the
  // stored one (m).
  double ms_per_frame = 0.0, speedup_vs_ground_truth = 0.0;
  double rmse_all = 0.0, rmse_all_over_constant_velocity = 0.0, max_abs_diff_m = 0.0;
  int64_t unstable = 0;
  std::vector<FrontierTrajectory> per_trajectory;
};

// OUT/metrics.json, one writer and one strict reader.
struct SolverFrontier {
  std::string data, split, family;
  int64_t trajectories = 0;
  int64_t frames = 0;  // per trajectory
  int threads = 0;     // solves at once, each single-threaded
  int hardware_threads = 0;
  std::string cpu;  // cpu_model_name() of the machine that timed the solves
  double wall_s = 0.0;
  double rmse_all_constant_velocity = 0.0;  // over all trajectories
  // The dataset's own timing of these solves (bsms generate, the median of its per-trajectory
  // ms/frame; what bsms report's solver column shows); none when it has none.
  std::optional<double> stored_ms_per_frame;
  FrontierSetting ground_truth;
  std::vector<FrontierSetting> settings;
  std::vector<std::string> notes;  // default knobs skipped or capped
};

// The kAnotherMesh setting when the frontier has one with a score (stable on some trajectory),
// else null.
const FrontierSetting* another_mesh_setting(const SolverFrontier& frontier);
// One markdown paragraph on that setting (what its ratio means), or "" when it has none.
std::string another_mesh_paragraph(const SolverFrontier& frontier);

Json to_json(const SolverFrontier& frontier);
SolverFrontier solver_frontier_from_json(const Json& json, const std::string& file);
// Reads OUT/metrics.json, given OUT or the file; InputError naming it when missing or malformed.
SolverFrontier read_solver_frontier(const std::string& path);

// Runs the experiment described above; writes and returns OUT/metrics.json's content.
SolverFrontier solver_frontier_experiment(const SolverFrontierOptions& options);

}  // namespace bsms
