// The gmsh library in this process (gmsh_session.hpp): kept apart from mesh.cpp so that programs
// that never call gmsh do not link it (loading libgmsh costs ~80 ms of symbol relocation).
#include "core/gmsh_session.hpp"

#include <gmsh.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/error.hpp"
#include "core/gmsh_elements.hpp"

namespace bsms {

namespace {

std::mutex& gmsh_mutex() {
  static std::mutex m;
  return m;
}

// gmsh is initialised lazily and re-initialised after a failed read: a reader exception can
// leave its global state unusable for the next file.
bool gmsh_initialised = false;

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
  } catch (const std::bad_alloc&) {
    throw;  // the gmsh worker's memory limit, reported as such
  } catch (const std::exception& e) {
    throw InputError(path + ": gmsh failed to mesh the curves of this geometry (" +
                     std::string(e.what()) + ")");
  }
  std::vector<std::size_t> tags, nodes, node_tags;
  std::vector<double> coords, parametric;
  gmsh::model::mesh::getElementsByType(gmsh_simplex_type(1), tags, nodes);
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
  // gmsh asks questions (GetValue, "uncompress this file?") on stdin unless told not to.
  gmsh::option::setNumber("General.NoPopup", 1);
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
  MeshParts parts;
  // Top dimension with elements decides the cells.
  for (int d = 3; d >= 1 && parts.cell_dim == 0; --d) {
    gmsh::model::mesh::getElementTypes(parts.cell_types, d);
    if (!parts.cell_types.empty()) parts.cell_dim = d;
  }
  // Arrays are fetched only when assemble_mesh will accept the cells.
  if (parts.cell_types.size() == 1 && parts.cell_types[0] == gmsh_simplex_type(parts.cell_dim)) {
    std::vector<std::size_t> element_tags, element_nodes;
    gmsh::model::mesh::getElementsByType(parts.cell_types[0], element_tags, element_nodes);
    parts.cells.push_back(parts.tag_lists.size());
    parts.tag_lists.push_back(std::move(element_nodes));
    // Nodes on an entity's boundary come twice (includeBoundary); assemble_mesh keeps one.
    std::vector<double> parametric;
    gmsh::model::mesh::getNodes(parts.node_tags, parts.node_coords, parametric, -1, -1, true,
                                false);
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups);
    for (const auto& [gdim, gtag] : groups) {
      MeshParts::Group group;
      group.dim = gdim;
      group.tag = gtag;
      gmsh::model::getPhysicalName(gdim, gtag, group.name);
      std::vector<std::size_t> tags;
      std::vector<double> group_coords;
      gmsh::model::mesh::getNodesForPhysicalGroup(gdim, gtag, tags, group_coords);
      group.lists.push_back(parts.tag_lists.size());
      parts.tag_lists.push_back(std::move(tags));
      parts.groups.push_back(std::move(group));
    }
  }
  return assemble_mesh(std::move(parts), context);
}

Mesh read_mesh_with_gmsh_here(const std::string& path) {
  GmshSession session;
  try {
    gmsh::open(path);
  } catch (const std::bad_alloc&) {
    throw;  // the gmsh worker's memory limit, reported as such
  } catch (...) {
    // gmsh's own words (a script's syntax error names its line), cut to one short line.
    std::string why;
    try {
      gmsh::logger::getLastError(why);
    } catch (...) {
    }
    std::replace(why.begin(), why.end(), '\n', ' ');
    if (why.size() > 200) why = why.substr(0, 200) + "...";
    session.reset();
    throw InputError(path + ": gmsh cannot read this file" +
                     (why.empty() ? std::string(" (malformed or truncated?)") : " (" + why + ")"));
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
    } catch (const std::bad_alloc&) {
      throw;
    } catch (const std::exception& e) {
      throw InputError(path + ": gmsh failed to mesh this geometry (" + std::string(e.what()) +
                       ")");
    }
  }
  return session.extract_mesh(path);
}

}  // namespace bsms
