// Physical validity of one frame of a Lagrangian multi-body scene (what a learned simulator's
// rollout can break that an error against the truth does not show): bodies that interpenetrate
// and nodes that leave the box. Inverted cells are measured by the rollout itself.
//
// Overlap between bodies: the sum over unordered pairs of cells of different bodies of the area
// (2-D triangles) or volume (3-D tetrahedra) of their intersection, computed exactly (up to
// floating-point rounding): Sutherland-Hodgman clipping of one triangle by the other's three
// half-planes; in 3-D one tetrahedron clipped by the other's four face half-spaces as a convex
// polyhedron (Powell and Abel's r3d representation), then its volume from its faces. When no body
// overlaps itself (a mesh whose cells tile the body) this is the measure of the bodies' pairwise
// intersections; cells of one body never count. Inverted cells are taken with their unsigned
// shape.
//
// Broad phase: a uniform grid whose spacing is the median extent of the cells' bounding boxes;
// each cell is listed in every grid cell its box touches and a pair is tested only in the grid
// cell holding the lowest corner of the two boxes' intersection, so it is tested once. Cells
// larger than 4 grid spacings (a stretched prediction) are tested against every cell instead.
// The cost is ~linear in the cells for meshes of similar cell sizes, and grows with the contact
// area (pairs across it); a frame with one body flung far away coarsens the grid (its size is
// capped at ~8 x the cells) and costs more. Large frames are measured on the OpenMP threads, with
// sums taken in a fixed order: the figures do not depend on the thread count.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace bsms {

using Triangle2 = std::array<std::array<double, 2>, 3>;
using Tetrahedron3 = std::array<std::array<double, 3>, 4>;

// Exact area of the intersection of two triangles / volume of two tetrahedra (either
// orientation; degenerate ones give 0).
double triangle_overlap_area(const Triangle2& a, const Triangle2& b);
double tetrahedron_overlap_volume(const Tetrahedron3& a, const Tetrahedron3& b);
// Unsigned area / volume.
double triangle_area(const Triangle2& t);
double tetrahedron_volume(const Tetrahedron3& t);
// Whether p lies strictly inside the simplex (a point on its boundary does not).
bool strictly_inside(const Triangle2& t, const std::array<double, 2>& p);
bool strictly_inside(const Tetrahedron3& t, const std::array<double, 3>& p);

// Walls of a box scene: per axis the lower and upper wall coordinate, NaN where that side has no
// wall; empty: no walls.
struct BoxWalls {
  std::vector<double> lo, hi;
  bool empty() const { return lo.empty(); }
};

// The checks both a frame's measures and its projection (core/physical_projection.hpp) make of a
// multi-body simplex mesh: dimension 2 or 3, cells of dim + 1 nodes indexing the nodes, one body
// id per node (`body_id` empty: filled with body 0), walls of dim sides when given.
// std::invalid_argument naming `who` otherwise.
void check_simplex_bodies(const char* who, int dim, const std::vector<int32_t>& cells,
                          std::vector<int32_t>& body_id, int64_t num_nodes, const BoxWalls& walls);

struct FrameValidity {
  double cell_measure = 0.0;     // sum of the cells' unsigned areas / volumes
  double overlap_measure = 0.0;  // between cells of different bodies (see above)
  int64_t num_nodes = 0;
  // Nodes strictly inside a cell of another body (a node exactly on a face between two of its
  // cells, or on its boundary, is not: measure-zero cases for simulated positions).
  int64_t nodes_in_other_body = 0;
  int64_t nodes_outside_walls = 0;  // nodes beyond at least one wall
  double outside_walls_max = 0.0;   // the farthest node's distance to the walled region (0: none)
  int64_t candidate_pairs = 0;      // cell pairs of different bodies whose boxes overlap

  // overlap_measure / cell_measure (0 without cells); node counts / num_nodes.
  double overlap_fraction() const;
  double nodes_in_other_body_fraction() const;
  double nodes_outside_walls_fraction() const;
};

// The topology of a trajectory's mesh, measured frame by frame. Positions with a non-finite
// coordinate give NaN measures.
class PhysicalValidity {
 public:
  // `cells` [num_cells, dim + 1]: triangles (dim 2) or tetrahedra (dim 3) indexing the nodes;
  // `body_id` [num_nodes] (empty: one body); a cell belongs to the body of its first node.
  // `walls.lo/hi` have dim entries when not empty. std::invalid_argument on other shapes.
  PhysicalValidity(int dim, std::vector<int32_t> cells, std::vector<int32_t> body_id,
                   int64_t num_nodes, BoxWalls walls = {});

  // `x` [num_nodes, dim], row-major.
  FrameValidity measure(const float* x) const;
  FrameValidity measure(const double* x) const;

  int dim() const { return dim_; }
  int64_t num_cells() const { return static_cast<int64_t>(cells_.size()) / (dim_ + 1); }
  int64_t num_nodes() const { return num_nodes_; }
  bool has_walls() const { return !walls_.empty(); }

 private:
  template <class T>
  FrameValidity measure_frame(const T* x) const;
  int dim_;
  std::vector<int32_t> cells_, node_body_, cell_body_;
  int64_t num_nodes_;
  BoxWalls walls_;
  bool several_bodies_ = false;
};

}  // namespace bsms
