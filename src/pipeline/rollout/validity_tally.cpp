#include "pipeline/rollout/validity_tally.hpp"

#include <algorithm>
#include <cmath>

#include "pipeline/adapters/scene_features.hpp"

namespace bsms {

BoxWalls scene_walls(const std::optional<mpm::Scene>& scene, int dim) {
  LagrangianSpec spec;
  spec.dim = dim;
  resolve_walls(spec, scene, 1.0);
  if (!spec.has_walls()) return {};
  return {spec.wall_lo, spec.wall_hi};
}

std::optional<PhysicalValidity> validity_for_mesh(const TrajectoryMesh& mesh, int dim,
                                                  const BoxWalls& walls) {
  if (dim != 2 && dim != 3) return std::nullopt;
  const bool simplices = mesh.cell_size == dim + 1;
  return PhysicalValidity(dim, simplices ? mesh.cells : std::vector<int32_t>{}, mesh.body_id,
                          mesh.num_nodes(), walls);
}

void ValidityTally::Curve::start() {
  per_trajectory.push_back(std::nan(""));
}

void ValidityTally::Curve::add(size_t step, double value) {
  if (sum.size() <= step) {
    sum.resize(step + 1, 0.0);
    count.resize(step + 1, 0);
  }
  sum[step] += value;
  ++count[step];
  double& worst = per_trajectory.back();  // NaN until the trajectory's first step
  if (std::isnan(worst) || value > worst) worst = value;
}

ValidityCurve ValidityTally::Curve::curve() const {
  ValidityCurve c;
  for (size_t s = 0; s < sum.size(); ++s)
    c.per_step.push_back(count[s] > 0 ? sum[s] / static_cast<double>(count[s]) : std::nan(""));
  c.per_trajectory = per_trajectory;
  for (const double v : per_trajectory)
    if (!std::isnan(v)) c.max = std::max(c.max, v);
  return c;
}

void ValidityTally::start_trajectory() {
  for (Side* side : {&model_, &truth_})
    for (Curve* c : {&side->overlap, &side->inside, &side->outside, &side->nodes_outside})
      c->start();
}

void ValidityTally::add(size_t step, const FrameValidity& model, const FrameValidity& truth) {
  const std::pair<Side*, const FrameValidity*> sides[] = {{&model_, &model}, {&truth_, &truth}};
  for (const auto& [side, v] : sides) {
    if (cells_) {
      side->overlap.add(step, v->overlap_fraction());
      side->inside.add(step, v->nodes_in_other_body_fraction());
    }
    if (walls_) {
      side->outside.add(step, v->outside_walls_max);
      side->nodes_outside.add(step, v->nodes_outside_walls_fraction());
    }
  }
}

ValidityMeasures ValidityTally::measures(const Side& side) const {
  ValidityMeasures m;
  if (cells_) {
    m.overlap = side.overlap.curve();
    m.nodes_in_other_body = side.inside.curve();
  }
  if (walls_) {
    m.outside_walls = side.outside.curve();
    m.nodes_outside_walls = side.nodes_outside.curve();
  }
  return m;
}

std::optional<PhysicalValidityMetrics> ValidityTally::metrics() const {
  if (!cells_ && !walls_) return std::nullopt;
  return PhysicalValidityMetrics{measures(model_), measures(truth_)};
}

void ProjectionTally::add(const ProjectionCounts& counts, int64_t num_nodes) {
  ++steps_;
  node_steps_ += num_nodes;
  clamped_ += static_cast<double>(counts.nodes_clamped);
  restored_ += static_cast<double>(counts.cells_restored);
  pushed_ += static_cast<double>(counts.nodes_pushed_out);
  passes_ += counts.passes;
  shift_sq_ += counts.shift_sq;
  if (!counts.converged) ++unconverged_;
}

std::optional<ProjectionMetrics> ProjectionTally::metrics(
    std::vector<std::string> constraints) const {
  if (constraints.empty()) return std::nullopt;
  ProjectionMetrics m;
  m.constraints = std::move(constraints);
  m.steps = steps_;
  m.unconverged_steps = unconverged_;
  if (steps_ > 0) {
    const double per = 1.0 / static_cast<double>(steps_);
    m.nodes_clamped_per_step = clamped_ * per;
    m.cells_restored_per_step = restored_ * per;
    m.nodes_pushed_out_per_step = pushed_ * per;
    m.passes_per_step = passes_ * per;
  }
  if (node_steps_ > 0) m.shift_rms = std::sqrt(shift_sq_ / static_cast<double>(node_steps_));
  return m;
}

}  // namespace bsms
