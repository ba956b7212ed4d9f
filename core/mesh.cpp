#include "core/mesh.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <new>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

#include "core/error.hpp"
#include "core/gmsh_elements.hpp"

namespace bsms {

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

// The checks on `parts` before any work; returns the number of cells.
int64_t check_parts(const MeshParts& parts, const std::string& context) {
  const int cell_dim = parts.cell_dim;
  if (cell_dim == 0)
    throw InputError(context + ": empty mesh (no line, triangle or tetrahedron cells)");
  if (parts.cell_types.size() != 1 || parts.cell_types[0] != gmsh_simplex_type(cell_dim)) {
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
  return num_cells;
}

// Every node tag list -> positions in node_tags, in place.
void tags_to_slots(MeshParts& parts, const NodeSlots& slots, const std::string& context) {
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
}

// Slots of the nodes the cells use, in ascending tag order (tag lists already slots).
std::vector<int64_t> used_slots_by_tag(const MeshParts& parts, const NodeSlots& slots) {
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
  return order;
}

// The cells' node indices [num_cells, k]: the cell lists concatenated, slots -> `index_of`.
RowMatrixXi64 gather_cells(const MeshParts& parts, const std::vector<int64_t>& index_of,
                           int64_t num_cells, int k) {
  RowMatrixXi64 cells(num_cells, k);
  int64_t* out = cells.data();
  for (std::size_t l : parts.cells) {
    const std::vector<std::size_t>& list = parts.tag_lists[l];
    const auto len = static_cast<int64_t>(list.size());
#pragma omp parallel for if (len >= kParallelMin)
    for (int64_t i = 0; i < len; ++i) out[i] = index_of[list[i]];
    out += len;
  }
  return cells;
}

// 3 with tetrahedra or a non-zero z, else 2 with triangles or a non-zero y, else 1.
int mesh_dimension(int cell_dim, const RowMatrixXd& xyz) {
  const int64_t n = xyz.rows();
  if (cell_dim == 3 || (n > 0 && xyz.col(2).cwiseAbs().maxCoeff() > 0)) return 3;
  if (cell_dim == 2 || (n > 0 && xyz.col(1).cwiseAbs().maxCoeff() > 0)) return 2;
  return 1;
}

// Physical groups: node sets by name (unnamed groups as "dim:tag"; equal names merged).
void add_node_groups(const MeshParts& parts, const std::vector<int64_t>& index_of, int64_t n,
                     Mesh& mesh) {
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
}

}  // namespace

Mesh assemble_mesh(MeshParts parts, const std::string& context) {
  const int64_t num_cells = check_parts(parts, context);
  const int cell_dim = parts.cell_dim;
  const NodeSlots slots(parts.node_tags, parts.node_coords, context);
  tags_to_slots(parts, slots, context);

  // Nodes the cells use, in ascending tag order.
  const std::vector<int64_t> order = used_slots_by_tag(parts, slots);
  const auto n = static_cast<int64_t>(order.size());
  std::vector<int64_t> index_of(parts.node_tags.size(), -1);
  for (int64_t i = 0; i < n; ++i) index_of[order[i]] = i;

  RowMatrixXd xyz(n, 3);
#pragma omp parallel for if (n >= kParallelMin)
  for (int64_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) xyz(i, c) = parts.node_coords[3 * order[i] + c];
  RowMatrixXi64 cells = gather_cells(parts, index_of, num_cells, cell_dim + 1);

  const int dim = mesh_dimension(cell_dim, xyz);
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
  add_node_groups(parts, index_of, n, mesh);
  validate_mesh(mesh, context);
  return mesh;
}

Mesh make_mesh(int dim, RowMatrixXd points, RowMatrixXi64 cells, const std::string& context) {
  Mesh mesh;
  mesh.dim = dim;
  mesh.cell_dim = static_cast<int>(cells.cols()) - 1;
  mesh.points = std::move(points);
  mesh.cells = std::move(cells);
  mesh.node_tags.resize(mesh.points.rows());
  std::iota(mesh.node_tags.begin(), mesh.node_tags.end(), 1);
  validate_mesh(mesh, context);
  return mesh;
}

}  // namespace bsms