// Constraints projected onto a learned simulator's predicted positions after each step, so that a
// rollout keeps what the solver guarantees by construction: nodes inside the box walls, cells
// that keep their orientation (the solver stops on J <= 0), and bodies that do not pass into one
// another (the solver's bodies meet on one background grid). A model that learned the dynamics
// well leaves them nearly idle; a model that drifts over a long rollout is held physical.
//
// Each is a position-based constraint (Mueller et al., "Position based dynamics", J. Vis. Commun.
// Image Represent. 18, 2007), projected Gauss-Seidel until none is violated
// or the pass limit is reached:
//   cells    s_c V_c(x) >= alpha |V_c(rest)|, V_c the signed area / volume, s_c its rest sign;
//            moved along the gradient of V_c (which sums to zero over the cell's nodes, so the
//            cell's centroid stays);
//   contact  a node strictly inside a cell of another body is moved to the nearest point of that
//            body's surface (its boundary edges / triangles) and the surface toward it, split by
//            the point's barycentric weights so the pair's momentum is unchanged;
//   walls    each coordinate clamped to the walled interval, what slip walls do to the solver's
//            particles (last in each pass, so the walls hold exactly).
// Nodes marked fixed (kinematic) do not move; the others have equal masses. Linear momentum
// changes only through the walls and fixed nodes. Positions with a non-finite coordinate are left
// as they are (the rollout reports them as diverged).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/physical_validity.hpp"

namespace bsms {

struct ProjectionOptions {
  bool walls = false, cells = false, contact = false;
  // A cell is restored when its measure falls below this fraction of its rest measure: above 0
  // so that a restored cell is not left flat, well below the compression elastic bodies reach.
  double min_measure_fraction = 0.05;
  int max_passes = 50;
};

// Parses "walls", "cells", "contact" or "all", comma-separated; std::invalid_argument naming the
// unknown word.
ProjectionOptions parse_projection(const std::string& list);
// The enabled constraints in a fixed order ("walls", "cells", "contact").
std::vector<std::string> projection_names(const ProjectionOptions& options);

// What one call to PhysicalProjection::project corrected.
struct ProjectionCounts {
  int64_t nodes_clamped = 0;     // node-wall corrections
  int64_t cells_restored = 0;    // cell corrections
  int64_t nodes_pushed_out = 0;  // node-surface corrections
  double shift_sq = 0.0;         // sum over nodes of the squared distance each node moved
  int passes = 0;
  bool converged = true;  // false: a constraint was still violated after max_passes
};

class PhysicalProjection {
 public:
  // `cells` [num_cells, dim + 1] triangles (dim 2) or tetrahedra (dim 3); `body_id` one per node
  // (empty: one body; a cell belongs to its first node's body); `rest` [num_nodes, dim] the
  // positions whose cell orientations and measures are kept (a trajectory's first frame); walls
  // as PhysicalValidity's. std::invalid_argument on other shapes, or when walls are asked for
  // without walls.
  // `movable` one flag per node (empty: all): a node that is not (a kinematic one, driven by
  // the scene) keeps its position, as if its mass were infinite.
  PhysicalProjection(int dim, std::vector<int32_t> cells, std::vector<int32_t> body_id,
                     int64_t num_nodes, const float* rest, BoxWalls walls,
                     ProjectionOptions options, std::vector<uint8_t> movable = {});

  // Projects `x` [num_nodes, dim] in place.
  ProjectionCounts project(float* x) const;
  ProjectionCounts project(double* x) const;

  const ProjectionOptions& options() const { return options_; }

 private:
  int restore_cells(double* x, ProjectionCounts& counts) const;
  int push_out(double* x, ProjectionCounts& counts) const;
  int clamp_walls(double* x, ProjectionCounts& counts) const;

  int dim_;
  std::vector<int32_t> cells_, node_body_, cell_body_;
  std::vector<double> weight_;  // inverse mass: 1 movable, 0 fixed
  int64_t num_nodes_;
  BoxWalls walls_;
  ProjectionOptions options_;
  std::vector<double> rest_measure_;  // signed
  // Boundary facets (edges in 2-D, triangles in 3-D: faces of exactly one cell), dim nodes each,
  // grouped by body: facets of body b are facet_begin_[b] .. facet_begin_[b + 1].
  std::vector<int32_t> facets_;
  std::vector<int32_t> facet_inner_;  // per facet: its cell's node off the facet (inside)
  std::vector<int64_t> facet_begin_;
  int32_t num_bodies_ = 1;
  double margin_ = 0.0;  // pushed-out nodes end this far outside (a small fraction of an edge)
};

}  // namespace bsms
