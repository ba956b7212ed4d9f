#include "core/mesh.hpp"

#include <gmsh.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
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

}  // namespace bsms
