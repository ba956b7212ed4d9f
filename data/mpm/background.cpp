#include "data/mpm/background.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/error.hpp"

namespace bsms::mpm {

namespace {

template <int Dim>
Vec<Dim> bary_gradient(const Mat<Dim>& inv_jacobian, int k) {
  if (k > 0) return inv_jacobian.row(k - 1).transpose();
  return -inv_jacobian.colwise().sum().transpose();
}

// Face k of a cell: its vertices except vertex k, sorted (the key shared by both sides).
template <int Dim>
std::array<int32_t, Dim> face_key(const typename BackgroundMesh<Dim>::Cell& cell, int k) {
  std::array<int32_t, Dim> key{};
  int n = 0;
  for (int i = 0; i <= Dim; ++i)
    if (i != k) key[n++] = cell[i];
  std::sort(key.begin(), key.end());
  return key;
}

struct FaceRecord {
  int32_t cell;
  int32_t local;
};

// Pairs faces of neighbouring cells; returns (key, cell, local) of faces without a partner.
template <int Dim>
void pair_faces(BackgroundMesh<Dim>& bg,
                std::vector<std::pair<std::array<int32_t, Dim>, FaceRecord>>* boundary) {
  std::vector<std::pair<std::array<int32_t, Dim>, FaceRecord>> faces;
  faces.reserve(bg.cells.size() * (Dim + 1));
  for (int32_t c = 0; c < bg.num_cells(); ++c)
    for (int k = 0; k <= Dim; ++k) faces.push_back({face_key<Dim>(bg.cells[c], k), {c, k}});
  std::sort(faces.begin(), faces.end(), [](const auto& a, const auto& b) {
    return a.first < b.first || (a.first == b.first && a.second.cell < b.second.cell);
  });
  bg.neighbours.assign(bg.cells.size(), {});
  for (auto& n : bg.neighbours) n.fill(-1);
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && faces[j].first == faces[i].first) ++j;
    if (j - i == 2) {
      const FaceRecord a = faces[i].second, b = faces[i + 1].second;
      bg.neighbours[a.cell][a.local] = b.cell;
      bg.neighbours[b.cell][b.local] = a.cell;
    } else if (j - i == 1) {
      if (boundary) boundary->push_back(faces[i]);
    } else {
      throw InputError("background mesh: a face is shared by " + std::to_string(j - i) +
                       " cells (non-manifold mesh)");
    }
    i = j;
  }
}

template <int Dim>
void compute_geometry(BackgroundMesh<Dim>& bg, const std::string& context) {
  bg.inv_jacobian.resize(bg.cells.size());
  double min_height = std::numeric_limits<double>::infinity();
  for (int32_t c = 0; c < bg.num_cells(); ++c) {
    Mat<Dim> jac;
    for (int k = 0; k < Dim; ++k)
      jac.col(k) = bg.points[bg.cells[c][k + 1]] - bg.points[bg.cells[c][0]];
    const double det = jac.determinant();
    double scale = 0.0;
    for (int k = 0; k < Dim; ++k) scale = std::max(scale, jac.col(k).norm());
    if (!(std::abs(det) > 1e-12 * std::pow(scale, Dim)))
      throw InputError(context + ": degenerate background cell " + std::to_string(c));
    bg.inv_jacobian[c] = jac.inverse();
    for (int k = 0; k <= Dim; ++k)
      min_height = std::min(min_height, 1.0 / bary_gradient<Dim>(bg.inv_jacobian[c], k).norm());
  }
  bg.min_height = min_height;
}

template <int Dim>
void build_stencils(BackgroundMesh<Dim>& bg) {
  // Node adjacency (CSR, sorted) from the cells.
  const int32_t n = bg.num_nodes();
  std::vector<std::vector<int32_t>> adjacency(n);
  for (const auto& cell : bg.cells)
    for (int a = 0; a <= Dim; ++a)
      for (int b = 0; b <= Dim; ++b)
        if (a != b) adjacency[cell[a]].push_back(cell[b]);
  for (auto& list : adjacency) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  }
  bg.stencil_offsets.assign(bg.cells.size() + 1, 0);
  bg.stencil_nodes.clear();
  bg.stencil_mask.clear();
  bg.max_stencil = 0;
  std::vector<int32_t> ring;
  for (int32_t c = 0; c < bg.num_cells(); ++c) {
    const auto& cell = bg.cells[c];
    ring.clear();
    for (int k = 0; k <= Dim; ++k)
      ring.insert(ring.end(), adjacency[cell[k]].begin(), adjacency[cell[k]].end());
    std::sort(ring.begin(), ring.end());
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
    ring.erase(std::remove_if(
                   ring.begin(), ring.end(),
                   [&](int32_t v) { return std::find(cell.begin(), cell.end(), v) != cell.end(); }),
               ring.end());
    for (int k = 0; k <= Dim; ++k) {
      bg.stencil_nodes.push_back(cell[k]);
      bg.stencil_mask.push_back(static_cast<uint8_t>((1u << (Dim + 1)) - 1));  // η = Σ B = 1 on N⁰
    }
    for (int32_t v : ring) {
      uint8_t mask = 0;
      for (int k = 0; k <= Dim; ++k)
        if (std::binary_search(adjacency[cell[k]].begin(), adjacency[cell[k]].end(), v))
          mask |= 1u << k;
      bg.stencil_nodes.push_back(v);
      bg.stencil_mask.push_back(mask);
    }
    bg.stencil_offsets[c + 1] = static_cast<int32_t>(bg.stencil_nodes.size());
    bg.max_stencil = std::max(bg.max_stencil, bg.stencil_offsets[c + 1] - bg.stencil_offsets[c]);
  }
}

template <int Dim>
void build_hash(BackgroundMesh<Dim>& bg) {
  Vec<Dim> lo = Vec<Dim>::Constant(std::numeric_limits<double>::infinity());
  Vec<Dim> hi = -lo;
  for (const auto& p : bg.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  bg.bucket_size = std::max(bg.h, 1e-12);
  bg.bucket_origin = lo;
  for (int a = 0; a < Dim; ++a)
    bg.bucket_counts[a] =
        std::max(1, static_cast<int32_t>(std::ceil((hi[a] - lo[a]) / bg.bucket_size)) + 1);
  int64_t total = 1;
  for (int a = 0; a < Dim; ++a) total *= bg.bucket_counts[a];
  auto bucket_range = [&](int32_t c, std::array<int32_t, Dim>& b0, std::array<int32_t, Dim>& b1) {
    Vec<Dim> clo = bg.points[bg.cells[c][0]], chi = clo;
    for (int k = 1; k <= Dim; ++k) {
      clo = clo.cwiseMin(bg.points[bg.cells[c][k]]);
      chi = chi.cwiseMax(bg.points[bg.cells[c][k]]);
    }
    for (int a = 0; a < Dim; ++a) {
      b0[a] = std::clamp(static_cast<int32_t>(std::floor((clo[a] - lo[a]) / bg.bucket_size)), 0,
                         bg.bucket_counts[a] - 1);
      b1[a] = std::clamp(static_cast<int32_t>(std::floor((chi[a] - lo[a]) / bg.bucket_size)), 0,
                         bg.bucket_counts[a] - 1);
    }
  };
  auto for_each_bucket = [&](int32_t c, auto&& fn) {
    std::array<int32_t, Dim> b0, b1, b;
    bucket_range(c, b0, b1);
    b = b0;
    while (true) {
      int64_t id = 0;
      for (int a = Dim - 1; a >= 0; --a) id = id * bg.bucket_counts[a] + b[a];
      fn(id);
      int a = 0;
      while (a < Dim && ++b[a] > b1[a]) b[a] = b0[a], ++a;
      if (a == Dim) break;
    }
  };
  bg.bucket_offsets.assign(total + 1, 0);
  for (int32_t c = 0; c < bg.num_cells(); ++c)
    for_each_bucket(c, [&](int64_t id) { ++bg.bucket_offsets[id + 1]; });
  std::partial_sum(bg.bucket_offsets.begin(), bg.bucket_offsets.end(), bg.bucket_offsets.begin());
  bg.bucket_cells.assign(bg.bucket_offsets.back(), 0);
  std::vector<int32_t> fill(bg.bucket_offsets.begin(), bg.bucket_offsets.end() - 1);
  for (int32_t c = 0; c < bg.num_cells(); ++c)
    for_each_bucket(c, [&](int64_t id) { bg.bucket_cells[fill[id]++] = c; });
}

// Outward offset of a boundary node: the vector o with o·n_f ≈ h for every adjacent boundary
// face normal n_f (least squares, pseudo-inverse), so corners get a mitred layer of thickness h.
template <int Dim>
Vec<Dim> layer_offset(const Mat<Dim>& nnt, const Vec<Dim>& nsum, double h) {
  Eigen::SelfAdjointEigenSolver<Mat<Dim>> eig(nnt);
  const double top = eig.eigenvalues().maxCoeff();
  Vec<Dim> o = Vec<Dim>::Zero();
  for (int i = 0; i < Dim; ++i) {
    const double lambda = eig.eigenvalues()[i];
    if (lambda > 1e-3 * top) {
      const Vec<Dim> e = eig.eigenvectors().col(i);
      o += e * (e.dot(nsum) / lambda);
    }
  }
  o *= h;
  if (o.norm() > 3.0 * h) o *= 3.0 * h / o.norm();
  return o;
}

}  // namespace

template <int Dim>
Eigen::Matrix<double, Dim + 1, 1> BackgroundMesh<Dim>::barycentric(int32_t c,
                                                                   const Vec<Dim>& x) const {
  Eigen::Matrix<double, Dim + 1, 1> b;
  b.template tail<Dim>() = inv_jacobian[c] * (x - points[cells[c][0]]);
  b[0] = 1.0 - b.template tail<Dim>().sum();
  return b;
}

template <int Dim>
int32_t BackgroundMesh<Dim>::locate(const Vec<Dim>& x, int32_t hint,
                                    Eigen::Matrix<double, Dim + 1, 1>& bary) const {
  constexpr double kTol = -1e-12;
  if (hint >= 0 && hint < num_cells()) {
    int32_t c = hint;
    for (int step = 0; step < 64; ++step) {
      bary = barycentric(c, x);
      int k;
      if (bary.minCoeff(&k) >= kTol) return c;
      const int32_t next = neighbours[c][k];
      if (next < 0) break;
      c = next;
    }
  }
  std::array<int32_t, Dim> b{};
  for (int a = 0; a < Dim; ++a) {
    const double t = std::floor((x[a] - bucket_origin[a]) / bucket_size);
    if (!(t >= 0.0 && t < bucket_counts[a])) return -1;
    b[a] = static_cast<int32_t>(t);
  }
  int64_t id = 0;
  for (int a = Dim - 1; a >= 0; --a) id = id * bucket_counts[a] + b[a];
  int32_t best = -1;
  double best_min = -std::numeric_limits<double>::infinity();
  for (int32_t i = bucket_offsets[id]; i < bucket_offsets[id + 1]; ++i) {
    const int32_t c = bucket_cells[i];
    const auto bc = barycentric(c, x);
    if (bc.minCoeff() > best_min) {
      best_min = bc.minCoeff();
      best = c;
    }
  }
  if (best < 0 || best_min < kTol) return -1;
  bary = barycentric(best, x);
  return best;
}

namespace {

// The mesh's nodes and cells as a background mesh without geometry (checks its dimensions).
template <int Dim>
BackgroundMesh<Dim> copy_mesh(const Mesh& mesh, const std::string& context) {
  if (mesh.dim != Dim || mesh.cell_dim != Dim)
    throw InputError(context + ": background mesh must be " + std::to_string(Dim) +
                     "D simplices, got dim " + std::to_string(mesh.dim) + " with " +
                     std::to_string(mesh.cell_dim) + "D cells");
  BackgroundMesh<Dim> bg;
  bg.points.resize(mesh.num_nodes());
  for (int64_t i = 0; i < mesh.num_nodes(); ++i)
    bg.points[i] = mesh.points.row(i).transpose().template head<Dim>();
  bg.cells.resize(mesh.num_cells());
  for (int64_t c = 0; c < mesh.num_cells(); ++c)
    for (int k = 0; k <= Dim; ++k) bg.cells[c][k] = static_cast<int32_t>(mesh.cells(c, k));
  bg.num_domain_nodes = bg.num_nodes();
  bg.num_domain_cells = bg.num_cells();
  if (bg.cells.empty()) throw InputError(context + ": background mesh has no cells");
  return bg;
}

// Sets bg.h and bg.mean_edge from the edge lengths (or the scene's kernel_width, when > 0).
template <int Dim>
void choose_kernel_width(BackgroundMesh<Dim>& bg, const std::string& context, double kernel_width) {
  // h: the smallest unit that keeps every vertex of every cell inside the support 1.5 h (with a
  // margin: longest edge / 1.45), and at least the mean edge length. Using the longest edge itself
  // (an outlier ~1.5x the target size on Delaunay meshes) over-smooths the kernel: the cantilever
  // then deflects 25 % too far and depends on the mesh rotation by ~15 % (see the test report).
  double max_edge = 0.0, sum_edge = 0.0;
  int64_t edges = 0;
  for (const auto& cell : bg.cells)
    for (int a = 0; a <= Dim; ++a)
      for (int b = a + 1; b <= Dim; ++b) {
        const double len = (bg.points[cell[a]] - bg.points[cell[b]]).norm();
        max_edge = std::max(max_edge, len);
        sum_edge += len;
        ++edges;
      }
  // The longest edge is a single outlier of the Delaunay mesh, and gmsh's tessellation is not a
  // continuous function of its input (an element size changed by 1e-9 relative gives another
  // mesh), so this h jumps by up to ~6 % between equivalent meshes and moves the cantilever's
  // tip response by up to ~1.7 %. A scene that compares meshes can hold h fixed (kernel_width).
  bg.h = std::max(sum_edge / static_cast<double>(edges), max_edge / 1.45);
  if (kernel_width > 0.0) {
    if (!(kernel_width >= max_edge / 1.5))
      throw InputError(context + ": kernel_width " + std::to_string(kernel_width) +
                       " m is below the longest edge / 1.5 = " + std::to_string(max_edge / 1.5) +
                       " m (a cell vertex would fall outside the kernel support)");
    bg.h = kernel_width;
  }
  bg.mean_edge = sum_edge / static_cast<double>(edges);
}

template <int Dim>
using BoundaryFaces = std::vector<std::pair<std::array<int32_t, Dim>, FaceRecord>>;

// Unit outward normal of each boundary face.
template <int Dim>
std::vector<Vec<Dim>> outward_normals(const BackgroundMesh<Dim>& bg,
                                      const BoundaryFaces<Dim>& boundary) {
  std::vector<Vec<Dim>> face_normal(boundary.size());
  for (size_t f = 0; f < boundary.size(); ++f) {
    const FaceRecord r = boundary[f].second;
    face_normal[f] = -bary_gradient<Dim>(bg.inv_jacobian[r.cell], r.local).normalized();
  }
  return face_normal;
}

// The mesh's node groups with the outward normals of the input boundary at their nodes.
template <int Dim>
void add_node_groups(BackgroundMesh<Dim>& bg, const Mesh& mesh, const BoundaryFaces<Dim>& boundary,
                     const std::vector<Vec<Dim>>& face_normal) {
  for (const auto& [name, nodes] : mesh.node_groups) {
    NodeGroup<Dim> group;
    std::vector<char> member(bg.num_nodes(), 0);
    for (int64_t v : nodes) member[v] = 1;
    std::vector<Vec<Dim>> normal(bg.num_nodes(), Vec<Dim>::Zero());
    for (size_t f = 0; f < boundary.size(); ++f) {
      const auto& key = boundary[f].first;
      if (std::all_of(key.begin(), key.end(), [&](int32_t v) { return member[v] != 0; }))
        for (int32_t v : key) normal[v] += face_normal[f];
    }
    for (int64_t v : nodes) {
      group.nodes.push_back(static_cast<int32_t>(v));
      const double len = normal[v].norm();
      group.normals.push_back(len > 1e-12 ? Vec<Dim>(normal[v] / len) : Vec<Dim>::Zero());
      group.mirrors.push_back(bg.points[v]);
    }
    bg.groups[name] = std::move(group);
  }
}

// Copies every boundary node outwards by layer_offset; returns each node's copy (-1: none).
template <int Dim>
std::vector<int32_t> add_layer_nodes(BackgroundMesh<Dim>& bg, const BoundaryFaces<Dim>& boundary,
                                     const std::vector<Vec<Dim>>& face_normal) {
  const int32_t n0 = bg.num_nodes();
  std::vector<Mat<Dim>> nnt(n0, Mat<Dim>::Zero());
  std::vector<Vec<Dim>> nsum(n0, Vec<Dim>::Zero());
  std::vector<int32_t> copy(n0, -1);
  for (size_t f = 0; f < boundary.size(); ++f)
    for (int32_t v : boundary[f].first) {
      nnt[v] += face_normal[f] * face_normal[f].transpose();
      nsum[v] += face_normal[f];
      copy[v] = 0;
    }
  for (int32_t v = 0; v < n0; ++v) {
    if (copy[v] < 0) continue;
    copy[v] = bg.num_nodes();  // ascending originals get ascending copies (prism split rule)
    bg.points.push_back(bg.points[v] + layer_offset<Dim>(nnt[v], nsum[v], bg.h));
  }
  return copy;
}

// An extra outer layer of cells over the boundary (each face extruded to its nodes' copies), with
// the node groups extended to the copies (mirrored through the originals).
template <int Dim>
void add_outer_layer(BackgroundMesh<Dim>& bg, const BoundaryFaces<Dim>& boundary,
                     const std::vector<Vec<Dim>>& face_normal, const std::string& context) {
  const std::vector<int32_t> copy = add_layer_nodes<Dim>(bg, boundary, face_normal);
  for (const auto& face : boundary) {
    const auto& k = face.first;  // sorted ascending
    if constexpr (Dim == 1) {
      bg.cells.push_back({k[0], copy[k[0]]});
    } else if constexpr (Dim == 2) {
      const int32_t a = k[0], b = k[1];
      bg.cells.push_back({a, b, copy[b]});
      bg.cells.push_back({a, copy[b], copy[a]});
    } else {
      // Prism a<b<c under a'<b'<c': each quad's diagonal leaves its lowest node, which makes
      // the split of a face shared by two prisms agree.
      const int32_t a = k[0], b = k[1], c = k[2];
      bg.cells.push_back({a, b, c, copy[c]});
      bg.cells.push_back({a, b, copy[b], copy[c]});
      bg.cells.push_back({a, copy[a], copy[b], copy[c]});
    }
  }
  for (auto& [name, group] : bg.groups) {
    const size_t count = group.nodes.size();
    for (size_t i = 0; i < count; ++i) {
      const int32_t v = group.nodes[i];
      if (copy[v] >= 0) {
        group.nodes.push_back(copy[v]);
        group.normals.push_back(group.normals[i]);
        group.mirrors.push_back(2.0 * bg.points[v] - bg.points[copy[v]]);
      }
    }
  }
  compute_geometry(bg, context + " (extra outer layer: the boundary is too concave)");
  pair_faces<Dim>(bg, nullptr);
}

}  // namespace

template <int Dim>
BackgroundMesh<Dim> make_background(const Mesh& mesh, bool add_layer, const std::string& context,
                                    double kernel_width) {
  BackgroundMesh<Dim> bg = copy_mesh<Dim>(mesh, context);
  choose_kernel_width(bg, context, kernel_width);
  compute_geometry(bg, context);

  BoundaryFaces<Dim> boundary;
  pair_faces<Dim>(bg, &boundary);
  const std::vector<Vec<Dim>> face_normal = outward_normals<Dim>(bg, boundary);
  add_node_groups<Dim>(bg, mesh, boundary, face_normal);
  if (add_layer) add_outer_layer<Dim>(bg, boundary, face_normal, context);
  build_stencils(bg);
  build_hash(bg);
  return bg;
}

template <int Dim>
BackgroundMesh<Dim> make_lattice(const Vec<Dim>& lo, const Vec<Dim>& hi, double dx, int ghost) {
  BackgroundMesh<Dim> bg;
  RegularGrid<Dim> grid;
  grid.dx = dx;
  grid.origin = lo - Vec<Dim>::Constant(ghost * dx);
  int64_t total = 1;
  for (int a = 0; a < Dim; ++a) {
    grid.counts[a] = static_cast<int32_t>(std::ceil((hi[a] - lo[a]) / dx - 1e-9)) + 1 + 2 * ghost;
    total *= grid.counts[a];
  }
  bg.points.resize(total);
  const double tol = 1e-9 * dx;
  for (int64_t id = 0; id < total; ++id) {
    int64_t rest = id;
    Vec<Dim> x;
    for (int a = 0; a < Dim; ++a) {
      x[a] = grid.origin[a] + dx * static_cast<double>(rest % grid.counts[a]);
      rest /= grid.counts[a];
    }
    bg.points[id] = x;
    for (int a = 0; a < Dim; ++a)
      for (int s = 0; s < 2; ++s) {
        const bool beyond = s == 0 ? x[a] <= lo[a] + tol : x[a] >= hi[a] - tol;
        if (!beyond) continue;
        auto& group = bg.groups[box_side_name(a, s != 0)];
        group.nodes.push_back(static_cast<int32_t>(id));
        Vec<Dim> n = Vec<Dim>::Zero();
        n[a] = s == 0 ? -1.0 : 1.0;
        group.normals.push_back(n);
        Vec<Dim> mirror = x;
        mirror[a] = 2.0 * (s == 0 ? lo[a] : hi[a]) - x[a];
        group.mirrors.push_back(mirror);
      }
  }
  bg.num_domain_nodes = bg.num_nodes();
  bg.h = dx;
  bg.min_height = dx;
  bg.mean_edge = dx;
  bg.grid = grid;
  return bg;
}

template struct BackgroundMesh<1>;
template struct BackgroundMesh<2>;
template struct BackgroundMesh<3>;
template BackgroundMesh<1> make_background<1>(const Mesh&, bool, const std::string&, double);
template BackgroundMesh<2> make_background<2>(const Mesh&, bool, const std::string&, double);
template BackgroundMesh<3> make_background<3>(const Mesh&, bool, const std::string&, double);
template BackgroundMesh<2> make_lattice<2>(const Vec<2>&, const Vec<2>&, double, int);
template BackgroundMesh<3> make_lattice<3>(const Vec<3>&, const Vec<3>&, double, int);

}  // namespace bsms::mpm
