// Background meshes of the MPM solver: simplicial meshes (segments, triangles, tetrahedra) with
// cell location, ring-1 stencils and named node groups, or a regular lattice for the B-spline
// reference solver. All lengths are in metres.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/mesh.hpp"

namespace bsms::mpm {

template <int Dim>
using Vec = Eigen::Matrix<double, Dim, 1>;
template <int Dim>
using Mat = Eigen::Matrix<double, Dim, Dim>;

// An axis-aligned lattice of nodes: node (i, j, k) at origin + dx * (i, j, k), index i + n0 (j + n1
// k).
template <int Dim>
struct RegularGrid {
  Vec<Dim> origin = Vec<Dim>::Zero();
  double dx = 1.0;
  std::array<int32_t, Dim> counts{};
  int32_t index(const std::array<int32_t, Dim>& ijk) const {
    int32_t id = 0;
    for (int a = Dim - 1; a >= 0; --a) id = id * counts[a] + ijk[a];
    return id;
  }
};

// A named set of nodes with an outward unit normal per node (zero where none is defined) and the
// node's mirror image across the wall: the node itself for nodes on the wall, an interior point
// for ghost nodes beyond it (extra-layer copies, lattice nodes outside the box).
template <int Dim>
struct NodeGroup {
  std::vector<int32_t> nodes;
  std::vector<Vec<Dim>> normals;
  std::vector<Vec<Dim>> mirrors;
};

template <int Dim>
struct BackgroundMesh {
  static constexpr int kCellNodes = Dim + 1;
  using Cell = std::array<int32_t, kCellNodes>;

  std::vector<Vec<Dim>> points;  // [N] node positions, the extra outer layer included
  std::vector<Cell> cells;       // [C] simplices (empty for a lattice)
  int32_t num_domain_nodes = 0;  // nodes of the input mesh; layer nodes follow
  int32_t num_domain_cells = 0;  // cells of the input mesh; layer cells follow
  double h = 0.0;  // kernel unit (support 1.5 h): max(mean edge, longest edge / 1.45) of the input
                   // or the kernel_width given to make_background
  double min_height = 0.0;  // smallest simplex height (CFL of the linear FEM kernel)
  double mean_edge = 0.0;   // mean edge length of the input mesh
  std::map<std::string, NodeGroup<Dim>> groups;
  std::optional<RegularGrid<Dim>> grid;  // set for the B-spline lattice

  // Per cell: barycentric map λ_{1..Dim} = inv_jacobian (x - x_{cell[0]}), λ_0 = 1 - Σ.
  std::vector<Mat<Dim>> inv_jacobian;
  // neighbours[c][k]: cell across the face opposite vertex k, -1 on the outer boundary.
  std::vector<Cell> neighbours;
  // Ring-1 stencil of cell c: stencil_nodes[stencil_offsets[c] ..], its vertices first, then their
  // mesh neighbours (ascending). stencil_mask bit k: the node is cell vertex k or adjacent to it.
  std::vector<int32_t> stencil_offsets;  // [C + 1]
  std::vector<int32_t> stencil_nodes;
  std::vector<uint8_t> stencil_mask;
  int32_t max_stencil = 0;

  // Spatial hash of cells (fallback for the walk): buckets of size `bucket_size`.
  Vec<Dim> bucket_origin = Vec<Dim>::Zero();
  double bucket_size = 1.0;
  std::array<int32_t, Dim> bucket_counts{};
  std::vector<int32_t> bucket_offsets;
  std::vector<int32_t> bucket_cells;

  int32_t num_nodes() const { return static_cast<int32_t>(points.size()); }
  int32_t num_cells() const { return static_cast<int32_t>(cells.size()); }

  // Barycentric coordinates of x in cell c, [Dim + 1].
  Eigen::Matrix<double, Dim + 1, 1> barycentric(int32_t c, const Vec<Dim>& x) const;

  // Cell containing x, starting the walk at `hint` (any value; invalid hints use the hash), or -1
  // when x is outside the mesh. `bary` receives the barycentric coordinates in that cell.
  int32_t locate(const Vec<Dim>& x, int32_t hint, Eigen::Matrix<double, Dim + 1, 1>& bary) const;
};

// Builds the background from a simplicial mesh (mesh.dim == mesh.cell_dim == Dim). With `add_layer`
// one layer of elements of thickness h is extruded outward from the boundary, so that boundary
// particles keep a full ring of samples; nodes of a group on that boundary pass the group (and
// normal) to their extruded copies. `kernel_width` > 0 sets h instead of deriving it from the
// edges; it must be at least the longest edge / 1.5 (every vertex of a particle's cell inside the
// support). Throws InputError prefixed with `context`.
template <int Dim>
BackgroundMesh<Dim> make_background(const Mesh& mesh, bool add_layer, const std::string& context,
                                    double kernel_width = 0.0);

// The physical group of a box background's side: axis 0 "left"/"right", 1 "bottom"/"top", 2
// "back"/"front" (high = false: the side at the box's min). What scenes name in "boundaries".
inline const char* box_side_name(int axis, bool high) {
  static const char* const names[3][2] = {{"left", "right"}, {"bottom", "top"}, {"back", "front"}};
  return names[axis][high ? 1 : 0];
}

// A lattice covering [lo - ghost dx, hi + ghost dx] with spacing dx; groups "left"/"right" (x),
// "bottom"/"top" (y), "back"/"front" (z in 3D) hold the nodes on or beyond each side of [lo, hi].
template <int Dim>
BackgroundMesh<Dim> make_lattice(const Vec<Dim>& lo, const Vec<Dim>& hi, double dx, int ghost);

}  // namespace bsms::mpm
