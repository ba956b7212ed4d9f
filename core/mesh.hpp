// Simplicial meshes (line, triangle, tetrahedron) read from gmsh MSH files (directly, see
// msh_reader.hpp) or through the gmsh library (other formats, geometry files).
#pragma once

#include <Eigen/Core>
#include <cstddef>
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

// Reads a mesh file. A file whose first non-blank line is $MeshFormat with version 2.2 or 4.1
// (ASCII or binary) is parsed by the direct reader (read_msh, msh_reader.hpp), except for the MSH
// features it leaves to gmsh (partitioned meshes, byte-swapped binary, polygons; MshNotHandled);
// every other file is read by read_mesh_with_gmsh. Both give the same Mesh (assemble_mesh).
// Throws InputError naming the file and the problem.
Mesh read_mesh(const std::string& path);

// Reads a mesh with the gmsh library (any format gmsh reads). A geometry file (.geo, .step,
// .brep) is meshed first with its highest dimension, unless its element size would give more
// than kMaxGeometryNodes nodes (InputError with the estimate). The semantics are assemble_mesh's.
// gmsh runs in a child process, the gmsh worker (gmsh_worker.hpp), under a time and a memory limit;
// a script's commands that reach outside the model are refused first (geo_scan.hpp).
Mesh read_mesh_with_gmsh(const std::string& path);

// A mesh in gmsh's terms, as a gmsh model or an MSH file holds it, before bsms' rules apply.
// Node tag arrays live in `tag_lists`; cells and groups refer to them by index, so that an
// element block shared by the cells and a physical group is stored once.
struct MeshParts {
  std::vector<std::size_t> node_tags;               // [M] every node (any order)
  std::vector<double> node_coords;                  // [M, 3] their x, y, z
  std::vector<std::vector<std::size_t>> tag_lists;  // node tags of element blocks or groups
  int cell_dim = 0;                // highest entity dimension (1..3) with elements; 0: none
  std::vector<int> cell_types;     // gmsh element types present in that dimension
  std::vector<std::size_t> cells;  // tag_lists whose concatenation is the cells' node tags
  struct Group {
    int dim = 0;
    int tag = 0;
    std::string name;                // empty: unnamed, reported as "dim:tag"
    std::vector<std::size_t> lists;  // tag_lists holding the group's nodes (repeats allowed)
  };
  std::vector<Group> groups;
};

// The rules read_mesh applies to a gmsh model or an MSH file, defined once: `cell_dim` decides
// the cells, which must all be 2-node lines, 3-node triangles or 4-node tetrahedra (else
// InputError "unsupported or mixed cells of dimension ..."); nodes no cell uses are dropped and
// the others numbered by ascending node tag; `dim` is 3 if any kept z coordinate is non-zero or
// cells are tetrahedra, else 2 if any y is non-zero or cells are triangles, else 1; each physical
// group (any dimension) gives name -> sorted kept node indices (groups sharing a name are
// merged); then validate_mesh. A node tag listed twice with different coordinates, or an element
// node without coordinates, is an InputError. `context` prefixes messages (the file name).
Mesh assemble_mesh(MeshParts parts, const std::string& context);

// Builds a mesh from in-memory arrays (validated like a file; `context` prefixes messages); used by
// tests, scene builders and the Python module.
Mesh make_mesh(int dim, RowMatrixXd points, RowMatrixXi64 cells,
               const std::string& context = "mesh");

// Checks finiteness, index ranges, degenerate cells (mesh_checks.cpp); InputError with `context`.
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
