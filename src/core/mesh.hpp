// Simplicial meshes (line, triangle, tetrahedron) read through the gmsh library.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace bsms {

using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowMatrixXi64 = Eigen::Matrix<int64_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Mesh {
  int dim = 0;          // spatial dimension of `points` (1, 2 or 3)
  int cell_dim = 0;     // topological dimension of the cells: 1 line, 2 triangle, 3 tetrahedron
  RowMatrixXd points;   // [N, dim] node positions
  RowMatrixXi64 cells;  // [C, cell_dim + 1] node indices (0-based)
  std::vector<int64_t> node_tags;  // [N] gmsh node tag of each node (ascending)
  // Physical groups of any dimension: name -> sorted node indices (only nodes that are kept).
  std::map<std::string, std::vector<int64_t>> node_groups;

  int64_t num_nodes() const { return points.rows(); }
  int64_t num_cells() const { return cells.rows(); }
  int nodes_per_cell() const { return cell_dim + 1; }
};

// Largest mesh read_mesh generates from a geometry file (nodes, estimated before meshing).
constexpr double kMaxGeometryNodes = 5e7;

// Reads a mesh with gmsh (any format gmsh reads: .msh 2.2 / 4.1, ...). A geometry file (.geo,
// .step, .brep) is meshed first with its highest dimension, unless its element size would give
// more than kMaxGeometryNodes nodes (InputError with the estimate). The top dimension present
// decides the cells; nodes are numbered by ascending gmsh node tag and nodes no top-dimension cell
// uses are dropped. `dim` is 3 if any z coordinate is non-zero or cells are tetrahedra, else 2 if
// any y is non-zero or cells are triangles, else 1. Throws InputError naming the file and the
// problem.
Mesh read_mesh(const std::string& path);

// Builds a mesh from in-memory arrays (validated like a file); used by tests and scene builders.
Mesh make_mesh(int dim, RowMatrixXd points, RowMatrixXi64 cells);

// Checks finiteness, index ranges, degenerate cells; throws InputError prefixed with `context`.
void validate_mesh(const Mesh& mesh, const std::string& context);

// Cells with (near) zero measure or folded over a neighbour. `degenerate`: length, area or volume
// (Gram determinant, so a triangle in 3D counts) at most 1e-10 x (longest edge)^cell_dim, e.g. a
// collinear triangle. `inverted` (cells that fill their space, cell_dim == dim): across a face
// shared with a neighbour, both opposite vertices lie on the same side of it, so the two cells
// overlap; the cell of the two whose orientation differs from the mesh's majority is counted.
// The check is independent of the mesh's overall orientation. Linear in the cells (a sort).
struct BadCells {
  int64_t degenerate = 0;
  int64_t inverted = 0;
  int64_t first = -1;      // lowest index of a bad cell of either kind, -1 when none
  std::string first_kind;  // "zero-measure" or "inverted"
  int64_t count() const { return degenerate + inverted; }
  // One line: "3 bad cells (2 zero-measure, 1 inverted), first: cell 17 (zero-measure)".
  std::string describe() const;
};
BadCells find_bad_cells(const Mesh& mesh);

}  // namespace bsms
