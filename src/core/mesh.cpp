#include "core/mesh.hpp"

#include <gmsh.h>
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <numeric>
#include <unordered_map>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

std::mutex& gmsh_mutex() {
  static std::mutex m;
  return m;
}

// gmsh is initialised lazily and re-initialised after a failed read: a reader exception can
// leave its global state unusable for the next file.
bool gmsh_initialised = false;

// gmsh element type codes of the simplices bsms accepts, by topological dimension.
constexpr int kGmshLine2 = 1, kGmshTriangle3 = 2, kGmshTetrahedron4 = 4;

int simplex_type(int cell_dim) {
  switch (cell_dim) {
    case 1:
      return kGmshLine2;
    case 2:
      return kGmshTriangle3;
    case 3:
      return kGmshTetrahedron4;
    default:
      return -1;
  }
}

std::string element_name(int type) {
  try {
    std::string name;
    int dim = 0, order = 0, num_nodes = 0, num_primary = 0;
    std::vector<double> local;
    gmsh::model::mesh::getElementProperties(type, name, dim, order, num_nodes, local, num_primary);
    return name;
  } catch (...) {
    return "gmsh element type " + std::to_string(type);
  }
}

// A geometry file whose element size would make a huge mesh (e.g. a size in m typed for mm) is
// refused before its surfaces or volumes are meshed: the curves are meshed first (cheap, linear
// in their length over the size), their mean element length s gives the size, and the nodes of
// the top dimension are estimated as the entities' bounding-box measure times the node density
// of equilateral simplices of edge s (an upper estimate for non-box shapes).
void refuse_huge_geometry(const std::string& path) {
  const int dim = gmsh::model::getDimension();
  if (dim < 2) return;
  try {
    gmsh::model::mesh::generate(1);
  } catch (const std::exception& e) {
    throw InputError(path + ": gmsh failed to mesh the curves of this geometry (" +
                     std::string(e.what()) + ")");
  }
  std::vector<std::size_t> tags, nodes, node_tags;
  std::vector<double> coords, parametric;
  gmsh::model::mesh::getElementsByType(kGmshLine2, tags, nodes);
  gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, true, false);
  if (tags.empty()) return;
  std::unordered_map<std::size_t, size_t> at;
  at.reserve(node_tags.size() * 2);
  for (size_t i = 0; i < node_tags.size(); ++i) at.emplace(node_tags[i], i);
  double length = 0.0;
  for (size_t e = 0; e < tags.size(); ++e) {
    const auto a = at.find(nodes[2 * e]), b = at.find(nodes[2 * e + 1]);
    if (a == at.end() || b == at.end()) continue;
    double sum = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double d = coords[3 * a->second + c] - coords[3 * b->second + c];
      sum += d * d;
    }
    length += std::sqrt(sum);
  }
  const double size = length / static_cast<double>(tags.size());
  if (!(size > 0.0)) return;
  gmsh::vectorpair entities;
  gmsh::model::getEntities(entities, dim);
  double measure = 0.0;
  for (const auto& [edim, etag] : entities) {
    double box[6];
    gmsh::model::getBoundingBox(edim, etag, box[0], box[1], box[2], box[3], box[4], box[5]);
    std::array<double, 3> extent{box[3] - box[0], box[4] - box[1], box[5] - box[2]};
    std::sort(extent.begin(), extent.end(), std::greater<double>());
    double m = 1.0;
    for (int a = 0; a < dim; ++a) m *= std::max(extent[a], size);
    measure += m;
  }
  const double density = dim == 2 ? 1.1547 / (size * size) : 1.4142 / (size * size * size);
  const double estimate = measure * density;
  if (estimate > kMaxGeometryNodes) {
    char text[256];
    std::snprintf(text, sizeof text,
                  ": the geometry would mesh to about %.2g nodes (%dD measure %.3g at element "
                  "size %.3g from its curve mesh), limit %.2g; refused before meshing",
                  estimate, dim, measure, size, kMaxGeometryNodes);
    throw InputError(path + text);
  }
}

}  // namespace

// gmsh sets OpenMP's thread count itself (General.NumThreads): the session restores the
// caller's count when it ends, so work after reading a mesh keeps all its threads.
struct GmshSession::Lock {
  std::unique_lock<std::mutex> guard{gmsh_mutex()};
  int omp_threads = omp_get_max_threads();
};

GmshSession::GmshSession() : lock_(std::make_unique<Lock>()) {
  if (!gmsh_initialised) {
    gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
    gmsh_initialised = true;
  }
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("General.Verbosity", 1);
  gmsh::clear();
}

void GmshSession::reset() {
  try {
    gmsh::finalize();
  } catch (...) {
    // A broken state is discarded either way; the next session initialises afresh.
  }
  gmsh_initialised = false;
}

GmshSession::~GmshSession() {
  if (gmsh_initialised) {
    try {
      gmsh::clear();
    } catch (...) {
      // Nothing sensible to do in a destructor; the next session clears again.
    }
  }
  omp_set_num_threads(lock_->omp_threads);
}

Mesh GmshSession::extract_mesh(const std::string& context) const {
  // Top dimension with elements decides the cells.
  int cell_dim = 0;
  std::vector<int> types;
  for (int d = 3; d >= 1 && cell_dim == 0; --d) {
    gmsh::model::mesh::getElementTypes(types, d);
    if (!types.empty()) cell_dim = d;
  }
  if (cell_dim == 0)
    throw InputError(context + ": empty mesh (no line, triangle or tetrahedron cells)");
  if (types.size() != 1 || types[0] != simplex_type(cell_dim)) {
    std::string found;
    for (int t : types) found += (found.empty() ? "" : ", ") + element_name(t);
    throw InputError(context + ": unsupported or mixed cells of dimension " +
                     std::to_string(cell_dim) + " (" + found +
                     "); bsms needs only 2-node lines, 3-node triangles or 4-node tetrahedra");
  }
  std::vector<std::size_t> element_tags, element_nodes;
  gmsh::model::mesh::getElementsByType(types[0], element_tags, element_nodes);

  std::vector<std::size_t> node_tags;
  std::vector<double> coords, parametric;
  gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, true, false);

  // Used nodes in ascending tag order.
  std::vector<std::size_t> used(element_nodes.begin(), element_nodes.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  std::unordered_map<std::size_t, int64_t> index_of;
  index_of.reserve(used.size() * 2);
  for (size_t i = 0; i < used.size(); ++i) index_of.emplace(used[i], static_cast<int64_t>(i));
  std::unordered_map<std::size_t, size_t> coord_of;
  coord_of.reserve(node_tags.size() * 2);
  for (size_t i = 0; i < node_tags.size(); ++i) coord_of.emplace(node_tags[i], i);

  const int64_t n = static_cast<int64_t>(used.size());
  RowMatrixXd xyz(n, 3);
  for (int64_t i = 0; i < n; ++i) {
    const auto it = coord_of.find(used[i]);
    if (it == coord_of.end())
      throw InputError(context + ": cell references node tag " + std::to_string(used[i]) +
                       " that has no coordinates");
    for (int c = 0; c < 3; ++c) xyz(i, c) = coords[3 * it->second + c];
  }
  const int k = cell_dim + 1;
  const int64_t num_cells = static_cast<int64_t>(element_tags.size());
  RowMatrixXi64 cells(num_cells, k);
  for (int64_t c = 0; c < num_cells; ++c)
    for (int a = 0; a < k; ++a) cells(c, a) = index_of.at(element_nodes[c * k + a]);

  int dim = 1;
  if (cell_dim == 3 || (n > 0 && xyz.col(2).cwiseAbs().maxCoeff() > 0)) {
    dim = 3;
  } else if (cell_dim == 2 || (n > 0 && xyz.col(1).cwiseAbs().maxCoeff() > 0)) {
    dim = 2;
  }
  Mesh mesh;
  mesh.dim = dim;
  mesh.cell_dim = cell_dim;
  mesh.points = xyz.leftCols(dim);
  mesh.cells = std::move(cells);
  mesh.node_tags.assign(used.begin(), used.end());

  // Physical groups: node sets by name (unnamed groups as "dim:tag").
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups);
  for (const auto& [gdim, gtag] : groups) {
    std::string name;
    gmsh::model::getPhysicalName(gdim, gtag, name);
    if (name.empty()) name = std::to_string(gdim) + ":" + std::to_string(gtag);
    std::vector<std::size_t> tags;
    std::vector<double> group_coords;
    gmsh::model::mesh::getNodesForPhysicalGroup(gdim, gtag, tags, group_coords);
    auto& nodes = mesh.node_groups[name];
    for (std::size_t t : tags) {
      const auto it = index_of.find(t);
      if (it != index_of.end()) nodes.push_back(it->second);
    }
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  }
  validate_mesh(mesh, context);
  return mesh;
}

Mesh read_mesh(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path + ": mesh file not found");
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a folder, expected a mesh file");
  {
    std::ifstream probe(path);
    if (!probe) throw InputError(path + ": mesh file is not readable");
    if (fs::file_size(path, ec) == 0) throw InputError(path + ": mesh file is empty");
  }
  GmshSession session;
  try {
    gmsh::open(path);
  } catch (...) {
    session.reset();
    throw InputError(path + ": gmsh cannot read this mesh (malformed or truncated?)");
  }
  gmsh::vectorpair entities;
  gmsh::model::getEntities(entities);
  if (entities.empty())
    throw InputError(path + ": gmsh found neither a mesh nor a geometry in this file");
  // Geometry files come without a mesh: mesh them with their own highest dimension.
  std::vector<int> types;
  gmsh::model::mesh::getElementTypes(types);
  if (types.empty() && gmsh::model::getDimension() > 0) {
    refuse_huge_geometry(path);
    try {
      gmsh::model::mesh::generate(gmsh::model::getDimension());
    } catch (const std::exception& e) {
      throw InputError(path + ": gmsh failed to mesh this geometry (" + std::string(e.what()) +
                       ")");
    }
  }
  return session.extract_mesh(path);
}

Mesh make_mesh(int dim, RowMatrixXd points, RowMatrixXi64 cells) {
  Mesh mesh;
  mesh.dim = dim;
  mesh.cell_dim = static_cast<int>(cells.cols()) - 1;
  mesh.points = std::move(points);
  mesh.cells = std::move(cells);
  mesh.node_tags.resize(mesh.points.rows());
  std::iota(mesh.node_tags.begin(), mesh.node_tags.end(), 1);
  validate_mesh(mesh, "mesh");
  return mesh;
}

void validate_mesh(const Mesh& mesh, const std::string& context) {
  if (mesh.dim < 1 || mesh.dim > 3 || mesh.points.cols() != mesh.dim)
    throw InputError(context + ": positions must have 1 to 3 columns");
  if (mesh.cell_dim < 1 || mesh.cell_dim > 3 || mesh.cell_dim > mesh.dim)
    throw InputError(context +
                     ": cells must be lines, triangles or tetrahedra in a space of at "
                     "least their dimension");
  if (mesh.num_cells() == 0 || mesh.num_nodes() == 0)
    throw InputError(context + ": empty mesh (no cells)");
  for (int64_t i = 0; i < mesh.num_nodes(); ++i) {
    for (int c = 0; c < mesh.dim; ++c) {
      if (!std::isfinite(mesh.points(i, c))) {
        const auto tag = i < static_cast<int64_t>(mesh.node_tags.size()) ? mesh.node_tags[i] : i;
        throw InputError(context + ": node tag " + std::to_string(tag) +
                         " has a non-finite coordinate (NaN or infinity)");
      }
    }
  }
  const int k = mesh.nodes_per_cell();
  for (int64_t c = 0; c < mesh.num_cells(); ++c) {
    for (int a = 0; a < k; ++a) {
      const int64_t v = mesh.cells(c, a);
      if (v < 0 || v >= mesh.num_nodes())
        throw InputError(context + ": cell " + std::to_string(c) + " references node " +
                         std::to_string(v) + " outside 0.." + std::to_string(mesh.num_nodes() - 1));
      for (int b = 0; b < a; ++b)
        if (mesh.cells(c, b) == v)
          throw InputError(context + ": cell " + std::to_string(c) + " repeats node " +
                           std::to_string(v) + " (degenerate cell)");
    }
  }
}

namespace {

// Signed measure of cell c in units of its own (longest edge)^cell_dim when cell_dim == dim,
// else the unsigned Gram measure in the same units; `scale` receives the longest edge.
double relative_measure(const Mesh& mesh, int64_t c, bool signed_measure) {
  const int k = mesh.cell_dim;
  Eigen::MatrixXd jac(mesh.dim, k);
  const auto x0 = mesh.points.row(mesh.cells(c, 0));
  for (int a = 0; a < k; ++a) jac.col(a) = (mesh.points.row(mesh.cells(c, a + 1)) - x0).transpose();
  double longest = 0.0;
  for (int a = 0; a <= k; ++a)
    for (int b = a + 1; b <= k; ++b)
      longest = std::max(
          longest, (mesh.points.row(mesh.cells(c, a)) - mesh.points.row(mesh.cells(c, b))).norm());
  if (!(longest > 0.0)) return 0.0;
  const double unit = std::pow(longest, k);
  if (signed_measure) return jac.determinant() / unit;
  return std::sqrt(std::max(0.0, (jac.transpose() * jac).determinant())) / unit;
}

// A face (sorted vertex list, unused slots -1) of a cell, with the cell's opposite vertex.
struct CellFace {
  std::array<int64_t, 3> key;
  int64_t cell;
  int64_t opposite;
  bool operator<(const CellFace& o) const { return key < o.key || (key == o.key && cell < o.cell); }
};

}  // namespace

std::string BadCells::describe() const {
  std::string s = std::to_string(count()) + " bad cell" + (count() == 1 ? "" : "s") + " (" +
                  std::to_string(degenerate) + " zero-measure, " + std::to_string(inverted) +
                  " inverted)";
  if (first >= 0) s += ", first: cell " + std::to_string(first) + " (" + first_kind + ")";
  return s;
}

BadCells find_bad_cells(const Mesh& mesh) {
  constexpr double kTol = 1e-10;
  BadCells bad;
  const int64_t C = mesh.num_cells();
  const int k = mesh.nodes_per_cell();
  const bool full = mesh.cell_dim == mesh.dim;
  std::vector<double> measure(C);
  std::vector<char> kind(C, 0);  // 1 zero-measure, 2 inverted
  int64_t positive = 0;
  for (int64_t c = 0; c < C; ++c) {
    measure[c] = relative_measure(mesh, c, full);
    if (!(std::abs(measure[c]) > kTol)) {
      kind[c] = 1;
      ++bad.degenerate;
    } else if (measure[c] > 0.0) {
      ++positive;
    }
  }
  if (full) {
    const double majority = 2 * positive >= C - bad.degenerate ? 1.0 : -1.0;
    std::vector<CellFace> faces;
    faces.reserve(static_cast<size_t>(C) * k);
    for (int64_t c = 0; c < C; ++c) {
      if (kind[c]) continue;
      for (int skip = 0; skip < k; ++skip) {
        CellFace f{{-1, -1, -1}, c, mesh.cells(c, skip)};
        int n = 0;
        for (int a = 0; a < k; ++a)
          if (a != skip) f.key[n++] = mesh.cells(c, a);
        for (int a = 1; a < n; ++a)  // at most 3 entries (std::sort trips -Warray-bounds)
          for (int b = a; b > 0 && f.key[b] < f.key[b - 1]; --b) std::swap(f.key[b], f.key[b - 1]);
        faces.push_back(f);
      }
    }
    std::sort(faces.begin(), faces.end());
    const int d = mesh.dim;
    auto side = [&](const CellFace& f, int64_t v) {
      // Sign of the opposite vertex relative to the face hyperplane, in the face's own frame.
      Eigen::MatrixXd m(d, d);
      const auto x0 = mesh.points.row(f.key[0]);
      for (int a = 1; a < d; ++a) m.col(a - 1) = (mesh.points.row(f.key[a]) - x0).transpose();
      m.col(d - 1) = (mesh.points.row(v) - x0).transpose();
      return m.determinant();
    };
    for (size_t i = 0; i + 1 < faces.size(); ++i) {
      if (faces[i].key != faces[i + 1].key) continue;
      const double s0 = side(faces[i], faces[i].opposite);
      const double s1 = side(faces[i], faces[i + 1].opposite);
      if (!(s0 * s1 > 0.0)) continue;  // opposite sides: a proper neighbour
      for (int64_t c : {faces[i].cell, faces[i + 1].cell})
        if (kind[c] == 0 && measure[c] * majority < 0.0) {
          kind[c] = 2;
          ++bad.inverted;
        }
    }
  }
  for (int64_t c = 0; c < C && bad.first < 0; ++c)
    if (kind[c]) {
      bad.first = c;
      bad.first_kind = kind[c] == 1 ? "zero-measure" : "inverted";
    }
  return bad;
}

}  // namespace bsms
