// The checks on a Mesh: validate_mesh (shapes, indices, finite positions, one cell size) and
// find_bad_cells (degenerate and inverted cells, repeated faces), kept apart from the reading of
// meshes in mesh.cpp.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/mesh.hpp"

namespace bsms {

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
// Determinant of the n x n (n <= 3) matrix m, closed form.
double small_determinant(const double (&m)[3][3], int n) {
  switch (n) {
    case 1:
      return m[0][0];
    case 2:
      return m[0][0] * m[1][1] - m[0][1] * m[1][0];
    case 3:
      return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
             m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
             m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    default:
      return 0.0;
  }
}

double relative_measure(const Mesh& mesh, int64_t c, bool signed_measure) {
  const int k = mesh.cell_dim, dim = mesh.dim;
  double jac[3][3] = {};  // jac[i][a]: coordinate i of edge vector a (from vertex 0)
  const int64_t v0 = mesh.cells(c, 0);
  for (int a = 0; a < k; ++a) {
    const int64_t va = mesh.cells(c, a + 1);
    for (int i = 0; i < dim; ++i) jac[i][a] = mesh.points(va, i) - mesh.points(v0, i);
  }
  double longest2 = 0.0;
  for (int a = 0; a <= k; ++a) {
    for (int b = a + 1; b <= k; ++b) {
      double sum = 0.0;
      for (int i = 0; i < dim; ++i) {
        const double d = mesh.points(mesh.cells(c, a), i) - mesh.points(mesh.cells(c, b), i);
        sum += d * d;
      }
      longest2 = std::max(longest2, sum);
    }
  }
  const double longest = std::sqrt(longest2);
  if (!(longest > 0.0)) return 0.0;
  const double unit = std::pow(longest, k);
  if (signed_measure) return small_determinant(jac, k) / unit;
  double gram[3][3] = {};
  for (int a = 0; a < k; ++a)
    for (int b = 0; b < k; ++b)
      for (int i = 0; i < dim; ++i) gram[a][b] += jac[i][a] * jac[i][b];
  return std::sqrt(std::max(0.0, small_determinant(gram, k))) / unit;
}

// A face of a cell in the bucket of its smallest vertex: the face's other vertices in ascending
// order (unused slot -1), the cell and the cell's vertex opposite the face.
struct CellFace {
  std::array<int64_t, 2> rest;
  int64_t cell;
  int64_t opposite;
  bool operator<(const CellFace& o) const {
    return rest < o.rest || (rest == o.rest && cell < o.cell);
  }
};

// The face of cell c (k nodes) without its vertex `skip`: its smallest vertex, and the rest.
CellFace face_of(const Mesh& mesh, int k, int64_t c, int skip, int64_t& smallest) {
  std::array<int64_t, 3> v = {-1, -1, -1};
  int m = 0;
  for (int a = 0; a < k; ++a)
    if (a != skip) v[m++] = mesh.cells(c, a);
  for (int a = 1; a < m; ++a)  // at most 3 entries (std::sort trips -Warray-bounds)
    for (int b = a; b > 0 && v[b] < v[b - 1]; --b) std::swap(v[b], v[b - 1]);
  smallest = v[0];
  return CellFace{{v[1], v[2]}, c, mesh.cells(c, skip)};
}

// The faces of the cells not marked in `kind`, bucketed by their smallest vertex (a counting
// sort, linear in the cells; a global sort of 6M faces took ~1 s): bucket v is
// faces[start[v]..start[v + 1]). Counting and filling are parallel over cells with atomic bucket
// cursors, so the order inside a bucket depends on the threads until the bucket is sorted.
struct FaceBuckets {
  std::vector<int64_t> start;
  std::vector<CellFace> faces;
};

FaceBuckets bucket_faces(const Mesh& mesh, const std::vector<char>& kind) {
  const int64_t C = mesh.num_cells();
  const int k = mesh.nodes_per_cell();
  const int64_t n = mesh.num_nodes();
  FaceBuckets b;
  std::vector<int64_t>& start = b.start;
  start.assign(n + 1, 0);
#pragma omp parallel for schedule(static) if (C > 65536)
  for (int64_t c = 0; c < C; ++c) {
    if (kind[c]) continue;
    for (int skip = 0; skip < k; ++skip) {
      int64_t smallest = 0;
      face_of(mesh, k, c, skip, smallest);
#pragma omp atomic
      ++start[smallest + 1];
    }
  }
  for (int64_t v = 0; v < n; ++v) start[v + 1] += start[v];
  std::vector<CellFace>& faces = b.faces;
  faces.resize(static_cast<size_t>(start[n]));
  std::vector<int64_t> fill(start.begin(), start.end() - 1);
#pragma omp parallel for schedule(static) if (C > 65536)
  for (int64_t c = 0; c < C; ++c) {
    if (kind[c]) continue;
    for (int skip = 0; skip < k; ++skip) {
      int64_t smallest = 0;
      const CellFace f = face_of(mesh, k, c, skip, smallest);
      int64_t at = 0;
#pragma omp atomic capture
      at = fill[smallest]++;
      faces[static_cast<size_t>(at)] = f;
    }
  }
  return b;
}

// Sign of vertex v relative to the hyperplane of face f (smallest vertex x0), in the face's own
// frame.
double face_side(const Mesh& mesh, int64_t x0, const CellFace& f, int64_t v) {
  const int d = mesh.dim;
  double m[3][3] = {};
  for (int i = 0; i < d; ++i) {
    for (int a = 1; a < d; ++a) m[i][a - 1] = mesh.points(f.rest[a - 1], i) - mesh.points(x0, i);
    m[i][d - 1] = mesh.points(v, i) - mesh.points(x0, i);
  }
  return small_determinant(m, d);
}

// A face two cells share with their opposite vertices on one side: the cell against the
// majority orientation (`majority` * measure < 0) is inverted. Found per bucket in parallel (each
// bucket sorted by (other vertices, cell) first, so the result does not depend on threads);
// cells may repeat.
std::vector<int64_t> folded_cells(const Mesh& mesh, FaceBuckets& buckets,
                                  const std::vector<double>& measure, double majority) {
  const int64_t C = mesh.num_cells();
  const int64_t n = mesh.num_nodes();
  std::vector<CellFace>& faces = buckets.faces;
  const std::vector<int64_t>& start = buckets.start;
  std::vector<int64_t> folded;
#pragma omp parallel if (C > 65536)
  {
    std::vector<int64_t> mine;
#pragma omp for schedule(dynamic, 4096) nowait
    for (int64_t v = 0; v < n; ++v) {
      const auto first = faces.begin() + start[v], last = faces.begin() + start[v + 1];
      std::sort(first, last);
      for (auto f = first; f + 1 < last; ++f) {
        if (f->rest != (f + 1)->rest) continue;
        const double s0 = face_side(mesh, v, *f, f->opposite);
        const double s1 = face_side(mesh, v, *f, (f + 1)->opposite);
        if (!(s0 * s1 > 0.0)) continue;  // opposite sides: a proper neighbour
        for (int64_t c : {f->cell, (f + 1)->cell})
          if (measure[c] * majority < 0.0) mine.push_back(c);
      }
    }
#pragma omp critical
    folded.insert(folded.end(), mine.begin(), mine.end());
  }
  return folded;
}

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
  const bool full = mesh.cell_dim == mesh.dim;
  std::vector<double> measure(C);
  std::vector<char> kind(C, 0);  // 1 zero-measure, 2 inverted
  int64_t positive = 0, degenerate = 0;
#pragma omp parallel for schedule(static) reduction(+ : positive, degenerate) if (C > 65536)
  for (int64_t c = 0; c < C; ++c) {
    measure[c] = relative_measure(mesh, c, full);
    if (!(std::abs(measure[c]) > kTol)) {
      kind[c] = 1;
      ++degenerate;
    } else if (measure[c] > 0.0) {
      ++positive;
    }
  }
  bad.degenerate = degenerate;
  if (full) {
    const double majority = 2 * positive >= C - bad.degenerate ? 1.0 : -1.0;
    FaceBuckets buckets = bucket_faces(mesh, kind);
    for (int64_t c : folded_cells(mesh, buckets, measure, majority))
      if (kind[c] == 0) {
        kind[c] = 2;
        ++bad.inverted;
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
