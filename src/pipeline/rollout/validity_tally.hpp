// The physical validity of a Lagrangian rollout (core/physical_validity.hpp), frame by frame for
// the prediction and the truth, tallied over trajectories into RolloutMetrics::validity.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/physical_projection.hpp"
#include "core/physical_validity.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/runs/rollout_metrics.hpp"

namespace bsms {

// The walls of a dataset's scene (Dataset::parsed_scene; may be none): a box background whose
// sides are named boundaries (see scene_features.hpp resolve_walls), or none.
BoxWalls scene_walls(const std::optional<mpm::Scene>& scene, int dim);

// The measures a trajectory's frames get: none in 1-D; overlap and nodes inside other bodies
// when the cells are triangles (2-D) or tetrahedra (3-D); the walls when there are walls.
std::optional<PhysicalValidity> validity_for_mesh(const TrajectoryMesh& mesh, int dim,
                                                  const BoxWalls& walls);

class ValidityTally {
 public:
  ValidityTally(bool cells, bool walls) : cells_(cells), walls_(walls) {}
  void start_trajectory();
  // The measures of the predicted and the true frame of predicted step `step` (0-based) of the
  // current trajectory.
  void add(size_t step, const FrameValidity& model, const FrameValidity& truth);
  // None when nothing applies.
  std::optional<PhysicalValidityMetrics> metrics() const;

 private:
  struct Curve {  // one measure of one side
    std::vector<double> sum;
    std::vector<int64_t> count;
    std::vector<double> per_trajectory;  // largest over steps; NaN: no step yet
    void start();
    void add(size_t step, double value);
    ValidityCurve curve() const;
  };
  struct Side {
    Curve overlap, inside, outside, nodes_outside;
  };
  ValidityMeasures measures(const Side& side) const;
  bool cells_, walls_;
  Side model_, truth_;
};

// What the constraints projected after each predicted step corrected, over a rollout.
class ProjectionTally {
 public:
  // The counts of one step's projection on a frame of `num_nodes` nodes.
  void add(const ProjectionCounts& counts, int64_t num_nodes);
  // None when `constraints` is empty (no projection).
  std::optional<ProjectionMetrics> metrics(std::vector<std::string> constraints) const;

 private:
  int64_t steps_ = 0, node_steps_ = 0, unconverged_ = 0;
  double clamped_ = 0, restored_ = 0, pushed_ = 0, passes_ = 0, shift_sq_ = 0;
};

}  // namespace bsms
