#include "core/mesh.hpp"

#include <gmsh.h>
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <new>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/msh_reader.hpp"

namespace bsms {

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
  if (parts.cell_types.size() == 1 && parts.cell_types[0] == simplex_type(parts.cell_dim)) {
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

namespace {

// Node tag -> position in MeshParts::node_tags: a table indexed by tag when the tags are dense
// (largest at most twice their count), else an open-addressing hash table. A tag listed twice
// keeps its first position; listed twice with different coordinates it is an InputError.
class NodeSlots {
 public:
  NodeSlots(const std::vector<std::size_t>& tags, const std::vector<double>& coords,
            const std::string& context) {
    const std::size_t m = tags.size();
    std::size_t largest = 0;
    for (std::size_t t : tags) largest = std::max(largest, t);
    dense_ = m > 0 && largest / 2 <= m;
    if (dense_) {
      slot_.assign(largest + 1, -1);
    } else {
      std::size_t capacity = 16;
      while (capacity < 2 * m) capacity <<= 1;
      slot_.assign(capacity, -1);
      key_.resize(capacity);
      mask_ = capacity - 1;
    }
    for (std::size_t i = 0; i < m; ++i) {
      int64_t& slot = dense_ ? slot_[tags[i]] : hashed(tags[i]);
      if (slot < 0) {
        slot = static_cast<int64_t>(i);
      } else if (std::memcmp(&coords[3 * slot], &coords[3 * i], 3 * sizeof(double)) != 0) {
        throw InputError(context + ": node tag " + std::to_string(tags[i]) +
                         " is listed twice with different coordinates");
      }
    }
  }

  // Position of `tag`, -1 when absent.
  int64_t find(std::size_t tag) const {
    if (dense_) return tag < slot_.size() ? slot_[tag] : -1;
    for (std::size_t h = hash(tag);; h = (h + 1) & mask_) {
      if (slot_[h] < 0) return -1;
      if (key_[h] == tag) return slot_[h];
    }
  }
  bool dense() const { return dense_; }
  // Dense only: positions by ascending tag (-1 for absent tags).
  const std::vector<int64_t>& by_tag() const { return slot_; }

 private:
  std::size_t hash(std::size_t tag) const {
    return static_cast<std::size_t>((tag * 0x9E3779B97F4A7C15ull) >> 17) & mask_;
  }
  int64_t& hashed(std::size_t tag) {
    std::size_t h = hash(tag);
    while (slot_[h] >= 0 && key_[h] != tag) h = (h + 1) & mask_;
    key_[h] = tag;
    return slot_[h];
  }

  bool dense_ = false;
  std::vector<int64_t> slot_;
  std::vector<std::size_t> key_;
  std::size_t mask_ = 0;
};

constexpr int64_t kParallelMin = 1 << 16;  // list length from which loops are split over threads

}  // namespace

Mesh assemble_mesh(MeshParts parts, const std::string& context) {
  const int cell_dim = parts.cell_dim;
  if (cell_dim == 0)
    throw InputError(context + ": empty mesh (no line, triangle or tetrahedron cells)");
  if (parts.cell_types.size() != 1 || parts.cell_types[0] != simplex_type(cell_dim)) {
    std::string found;
    for (int t : parts.cell_types) found += (found.empty() ? "" : ", ") + gmsh_element_name(t);
    throw InputError(context + ": unsupported or mixed cells of dimension " +
                     std::to_string(cell_dim) + " (" + found +
                     "); bsms needs only 2-node lines, 3-node triangles or 4-node tetrahedra");
  }
  if (parts.node_coords.size() != 3 * parts.node_tags.size())
    throw std::invalid_argument(context + ": MeshParts has " +
                                std::to_string(parts.node_coords.size()) + " coordinates for " +
                                std::to_string(parts.node_tags.size()) + " nodes");
  const int k = cell_dim + 1;
  int64_t num_cells = 0;
  for (std::size_t l : parts.cells) {
    if (parts.tag_lists.at(l).size() % k != 0)
      throw std::invalid_argument(context + ": MeshParts cell list not a multiple of " +
                                  std::to_string(k) + " nodes");
    num_cells += static_cast<int64_t>(parts.tag_lists[l].size()) / k;
  }

  // Every node tag list -> positions in node_tags, in place.
  const NodeSlots slots(parts.node_tags, parts.node_coords, context);
  std::vector<char> cell_list(parts.tag_lists.size(), 0);
  for (std::size_t l : parts.cells) cell_list[l] = 1;
  for (std::size_t l = 0; l < parts.tag_lists.size(); ++l) {
    std::vector<std::size_t>& list = parts.tag_lists[l];
    const auto n = static_cast<int64_t>(list.size());
    int64_t bad = n;
#pragma omp parallel for reduction(min : bad) if (n >= kParallelMin)
    for (int64_t i = 0; i < n; ++i) {
      const int64_t slot = slots.find(list[i]);
      if (slot < 0) {
        bad = std::min(bad, i);
      } else {
        list[i] = static_cast<std::size_t>(slot);
      }
    }
    if (bad < n)
      throw InputError(context + (cell_list[l] ? ": cell" : ": an element") +
                       " references node tag " + std::to_string(list[bad]) +
                       " that has no coordinates");
  }

  // Nodes the cells use, in ascending tag order.
  const std::size_t m = parts.node_tags.size();
  std::vector<char> used(m, 0);
  for (std::size_t l : parts.cells)
    for (std::size_t slot : parts.tag_lists[l]) used[slot] = 1;
  std::vector<int64_t> order;
  if (slots.dense()) {
    for (int64_t slot : slots.by_tag())
      if (slot >= 0 && used[slot]) order.push_back(slot);
  } else {
    for (std::size_t i = 0; i < m; ++i)
      if (used[i]) order.push_back(static_cast<int64_t>(i));
    std::sort(order.begin(), order.end(),
              [&](int64_t a, int64_t b) { return parts.node_tags[a] < parts.node_tags[b]; });
  }
  const auto n = static_cast<int64_t>(order.size());
  std::vector<int64_t> index_of(m, -1);
  for (int64_t i = 0; i < n; ++i) index_of[order[i]] = i;

  RowMatrixXd xyz(n, 3);
#pragma omp parallel for if (n >= kParallelMin)
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) xyz(i, c) = parts.node_coords[3 * order[i] + c];
  RowMatrixXi64 cells(num_cells, k);
  int64_t* out = cells.data();
  for (std::size_t l : parts.cells) {
    const std::vector<std::size_t>& list = parts.tag_lists[l];
    const auto len = static_cast<int64_t>(list.size());
#pragma omp parallel for if (len >= kParallelMin)
    for (int64_t i = 0; i < len; ++i) out[i] = index_of[list[i]];
    out += len;
  }

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
  mesh.node_tags.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    const std::size_t tag = parts.node_tags[order[i]];
    if (tag > static_cast<std::size_t>(std::numeric_limits<int64_t>::max()))
      throw InputError(context + ": node tag " + std::to_string(tag) + " is larger than 2^63-1");
    mesh.node_tags[i] = static_cast<int64_t>(tag);
  }

  // Physical groups: node sets by name (unnamed groups as "dim:tag"; equal names merged).
  for (const MeshParts::Group& group : parts.groups) {
    const std::string name = group.name.empty()
                                 ? std::to_string(group.dim) + ":" + std::to_string(group.tag)
                                 : group.name;
    std::vector<int64_t>& nodes = mesh.node_groups[name];
    std::size_t listed = 0;
    for (std::size_t l : group.lists) listed += parts.tag_lists.at(l).size();
    if (listed > static_cast<std::size_t>(n) / 8) {
      // Large groups: marks, read back in order (no sort).
      std::vector<char> in(n, 0);
      for (int64_t i : nodes) in[i] = 1;
      for (std::size_t l : group.lists)
        for (std::size_t slot : parts.tag_lists[l])
          if (index_of[slot] >= 0) in[index_of[slot]] = 1;
      nodes.clear();
      for (int64_t i = 0; i < n; ++i)
        if (in[i]) nodes.push_back(i);
    } else {
      for (std::size_t l : group.lists)
        for (std::size_t slot : parts.tag_lists[l])
          if (index_of[slot] >= 0) nodes.push_back(index_of[slot]);
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    }
  }
  validate_mesh(mesh, context);
  return mesh;
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

}  // namespace bsms
