#include "core/physical_validity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/point3.hpp"

namespace bsms {

namespace {

using P2 = std::array<double, 2>;
using point3::cross;
using point3::dot;
using point3::P3;
using point3::sub;

// Twice the signed area of (o, a, b): > 0 when counter-clockwise.
double cross2(const P2& o, const P2& a, const P2& b) {
  return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

// Six times the signed volume of (a, b, c, d).
double orient3(const P3& a, const P3& b, const P3& c, const P3& d) {
  return dot(cross(sub(b, a), sub(c, a)), sub(d, a));
}

Triangle2 counter_clockwise(Triangle2 t) {
  if (cross2(t[0], t[1], t[2]) < 0) std::swap(t[1], t[2]);
  return t;
}
Tetrahedron3 positive(Tetrahedron3 t) {
  if (orient3(t[0], t[1], t[2], t[3]) < 0) std::swap(t[2], t[3]);
  return t;
}

// The point where the segment from p (side value sp) to q (sq) crosses side 0; sp and sq have
// opposite signs (one may be 0), so the denominator is not 0.
template <class P>
P crossing(const P& p, const P& q, double sp, double sq) {
  const double t = sp / (sp - sq);
  P out;
  for (size_t a = 0; a < out.size(); ++a) out[a] = p[a] + t * (q[a] - p[a]);
  return out;
}

// Both counter-clockwise and of positive area.
double clipped_area(const Triangle2& a, const Triangle2& b) {
  // A convex polygon cut by a half-plane gains at most one vertex: 3 -> 6 after three cuts.
  P2 buffers[2][8];
  int n = 3;
  for (int i = 0; i < 3; ++i) buffers[0][i] = a[i];
  int cur = 0;
  for (int e = 0; e < 3; ++e) {
    const P2& p = b[e];
    const P2& q = b[(e + 1) % 3];
    const P2* in = buffers[cur];
    P2* out = buffers[1 - cur];
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const P2& now = in[i];
      const P2& before = in[(i + n - 1) % n];
      const double s_now = cross2(p, q, now), s_before = cross2(p, q, before);
      if (s_now >= 0) {
        if (s_before < 0) out[m++] = crossing(before, now, s_before, s_now);
        out[m++] = now;
      } else if (s_before >= 0) {
        out[m++] = crossing(before, now, s_before, s_now);
      }
    }
    n = m;
    cur = 1 - cur;
    if (n < 3) return 0.0;
  }
  const P2* poly = buffers[cur];
  double twice = 0.0;
  for (int i = 0; i < n; ++i) {
    const P2& p = poly[i];
    const P2& q = poly[(i + 1) % n];
    twice += p[0] * q[1] - p[1] * q[0];
  }
  return std::max(0.0, 0.5 * twice);
}

// A half-space n . x >= w.
struct HalfSpace {
  P3 normal;
  double offset = 0.0;
  double side(const P3& x) const { return dot(normal, x) - offset; }
};

// The inner half-spaces of a tetrahedron's faces (face i opposite vertex i).
void face_planes(const Tetrahedron3& t, HalfSpace* planes) {
  for (int i = 0; i < 4; ++i) {
    const P3& o = t[(i + 1) % 4];
    P3 n = cross(sub(t[(i + 2) % 4], o), sub(t[(i + 3) % 4], o));
    if (dot(n, sub(t[i], o)) < 0) n = {-n[0], -n[1], -n[2]};
    planes[i] = {n, dot(n, o)};
  }
}

// A convex polyhedron in the representation of Powell and Abel's r3d (J. Comput. Phys. 297,
// 2015): every vertex has exactly three neighbours, in a cyclic order that makes the faces walks
// (arrive at a vertex from neighbour j, leave to neighbour j + 1). A plane cut puts a vertex on
// every cut edge and links the new vertices by walking the faces, so no face lists are kept and
// a vertex on the plane or a zero-length edge needs no special case. A tetrahedron cut by four
// planes has at most 8 faces, so 2 x 8 - 4 = 12 vertices, plus at most 18 cut edges while a cut
// is under way.
class Polyhedron {
 public:
  explicit Polyhedron(const Tetrahedron3& t) : count_(4) {
    const int links[4][3] = {{1, 3, 2}, {2, 3, 0}, {0, 3, 1}, {1, 2, 0}};
    for (int v = 0; v < 4; ++v) {
      position_[v] = t[v];
      for (int k = 0; k < 3; ++k) next_[v][k] = links[v][k];
    }
  }

  // Keeps the part where plane.side(x) >= 0; false when nothing is left.
  bool clip(const HalfSpace& plane) {
    double side[kCapacity];
    bool cut[kCapacity];
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int v = 0; v < count_; ++v) {
      side[v] = plane.side(position_[v]);
      cut[v] = side[v] < 0;
      lo = std::min(lo, side[v]);
      hi = std::max(hi, side[v]);
    }
    if (lo >= 0) return true;
    if (hi <= 0) {
      count_ = 0;
      return false;
    }
    const int old = count_;
    for (int v = 0; v < old; ++v) {
      if (cut[v]) continue;
      for (int k = 0; k < 3; ++k) {
        const int w = next_[v][k];
        if (!cut[w] || count_ >= kCapacity) continue;
        const int u = count_++;
        position_[u] = crossing(position_[v], position_[w], side[v], side[w]);
        next_[u][0] = v;
        next_[u][1] = next_[u][2] = -1;
        next_[v][k] = u;
        cut[u] = false;
      }
    }
    // Each new vertex walks its face (through kept vertices, whose links to cut ones now end at
    // new vertices) to the next new vertex: the two are joined along the new face.
    for (int u = old; u < count_; ++u) {
      int at = u, to = next_[u][0];
      do {
        int j = 0;
        while (j < 2 && next_[to][j] != at) ++j;
        at = to;
        to = next_[at][(j + 1) % 3];
      } while (at < old);
      next_[u][2] = at;
      next_[at][1] = u;
    }
    int index[kCapacity];
    int kept = 0;
    for (int v = 0; v < count_; ++v) {
      if (cut[v]) continue;
      position_[kept] = position_[v];
      for (int k = 0; k < 3; ++k) next_[kept][k] = next_[v][k];
      index[v] = kept++;
    }
    count_ = kept;
    for (int v = 0; v < count_; ++v)
      for (int k = 0; k < 3; ++k) next_[v][k] = index[next_[v][k]];
    return count_ > 0;
  }

  // Each face walked once and fanned from its first vertex, the fans' tetrahedra taken from the
  // first vertex of the polyhedron (not the origin: less cancellation).
  double volume() const {
    if (count_ < 4) return 0.0;
    bool walked[kCapacity][3] = {};
    const P3& apex = position_[0];
    double six = 0.0;
    for (int start = 0; start < count_; ++start)
      for (int k0 = 0; k0 < 3; ++k0) {
        if (walked[start][k0]) continue;
        walked[start][k0] = true;
        int at = next_[start][k0], from = start;
        for (;;) {
          int j = 0;
          while (j < 2 && next_[at][j] != from) ++j;
          const int k = (j + 1) % 3;
          walked[at][k] = true;
          const int to = next_[at][k];
          if (to == start) break;
          six += orient3(apex, position_[start], position_[at], position_[to]);
          from = at;
          at = to;
        }
      }
    return std::fabs(six) / 6.0;
  }

 private:
  static constexpr int kCapacity = 40;
  P3 position_[kCapacity];
  int next_[kCapacity][3];
  int count_;
};

// Of positive volume, with their faces' inner half-spaces. A face plane of either that leaves
// the other on its outer side separates them; planes of b that leave a on their inner side need
// no cut.
double clipped_volume(const Tetrahedron3& a, const HalfSpace* a_planes, const Tetrahedron3& b,
                      const HalfSpace* b_planes) {
  for (int i = 0; i < 4; ++i) {
    const HalfSpace& plane = a_planes[i];
    if (plane.side(b[0]) <= 0 && plane.side(b[1]) <= 0 && plane.side(b[2]) <= 0 &&
        plane.side(b[3]) <= 0)
      return 0.0;
  }
  const HalfSpace* cutting[4];
  int num_cutting = 0;
  for (int i = 0; i < 4; ++i) {
    const HalfSpace& plane = b_planes[i];
    bool any_in = false, any_out = false;
    for (const P3& v : a) {
      const double s = plane.side(v);
      any_in = any_in || s > 0;
      any_out = any_out || s < 0;
    }
    if (!any_in) return 0.0;
    if (any_out) cutting[num_cutting++] = &plane;
  }
  if (num_cutting == 0) return std::fabs(orient3(a[0], a[1], a[2], a[3])) / 6.0;
  Polyhedron part(a);
  for (int c = 0; c < num_cutting; ++c)
    if (!part.clip(*cutting[c])) return 0.0;
  return part.volume();
}

// Frames with fewer cells are measured on one thread (the threads would cost more than they
// save).
constexpr int64_t kParallelCells = 2000;

// One frame's cells: vertices (triangles counter-clockwise), bounding boxes, unsigned measures
// and, in 3-D, the faces' inner half-spaces.
struct FrameCells {
  int d = 0, k = 0;
  int64_t count = 0;
  std::vector<double> vertex;     // [count, k, d]
  std::vector<double> box;        // [count, 2, d]: lo[d], hi[d]
  std::vector<double> measure;    // [count]
  std::vector<HalfSpace> planes;  // [count, 4] in 3-D, else empty

  double* vertex_of(int64_t c, int j) { return &vertex[static_cast<size_t>((c * k + j) * d)]; }
  const double* vertex_of(int64_t c, int j) const {
    return &vertex[static_cast<size_t>((c * k + j) * d)];
  }
  double* lo_of(int64_t c) { return &box[static_cast<size_t>(c * 2 * d)]; }
  double* hi_of(int64_t c) { return &box[static_cast<size_t>(c * 2 * d + d)]; }
  const double* lo_of(int64_t c) const { return &box[static_cast<size_t>(c * 2 * d)]; }
  const double* hi_of(int64_t c) const { return &box[static_cast<size_t>(c * 2 * d + d)]; }
  Triangle2 triangle(int64_t c) const {
    Triangle2 t;
    for (int j = 0; j < 3; ++j) t[j] = {vertex_of(c, j)[0], vertex_of(c, j)[1]};
    return t;
  }
  Tetrahedron3 tetrahedron(int64_t c) const {
    Tetrahedron3 t;
    for (int j = 0; j < 4; ++j) t[j] = {vertex_of(c, j)[0], vertex_of(c, j)[1], vertex_of(c, j)[2]};
    return t;
  }
  // The exact measure of two cells' intersection.
  double overlap(int64_t c1, int64_t c2) const {
    if (!(measure[static_cast<size_t>(c1)] > 0) || !(measure[static_cast<size_t>(c2)] > 0))
      return 0.0;
    if (d == 2) return clipped_area(triangle(c1), triangle(c2));
    return clipped_volume(tetrahedron(c1), &planes[static_cast<size_t>(c1 * 4)], tetrahedron(c2),
                          &planes[static_cast<size_t>(c2 * 4)]);
  }
  // Boxes whose intersection has a positive measure (touching cells cannot overlap).
  bool boxes_overlap(int64_t c1, int64_t c2) const {
    const double *lo1 = lo_of(c1), *hi1 = hi_of(c1), *lo2 = lo_of(c2), *hi2 = hi_of(c2);
    for (int a = 0; a < d; ++a)
      if (!(std::max(lo1[a], lo2[a]) < std::min(hi1[a], hi2[a]))) return false;
    return true;
  }
  bool box_holds(int64_t c, const double* p) const {
    const double *lo = lo_of(c), *hi = hi_of(c);
    for (int a = 0; a < d; ++a)
      if (!(lo[a] < p[a] && p[a] < hi[a])) return false;
    return true;
  }
  bool node_inside(int64_t c, const double* p) const {
    if (d == 2) return strictly_inside(triangle(c), {p[0], p[1]});
    return strictly_inside(tetrahedron(c), {p[0], p[1], p[2]});
  }
};

// `cells` [count, dim + 1] at positions `x` [num_nodes, dim].
template <class T>
FrameCells frame_cells(int dim, const std::vector<int32_t>& cells, const T* x) {
  FrameCells f;
  const int d = f.d = dim, k = f.k = dim + 1;
  const int64_t num_cells = f.count = static_cast<int64_t>(cells.size()) / k;
  f.vertex.resize(static_cast<size_t>(num_cells * k * d));
  f.box.resize(static_cast<size_t>(num_cells * 2 * d));
  f.measure.resize(static_cast<size_t>(num_cells));
  f.planes.resize(d == 3 ? static_cast<size_t>(num_cells * 4) : 0);
#pragma omp parallel for schedule(static) if (num_cells >= kParallelCells)
  for (int64_t c = 0; c < num_cells; ++c) {
    double* lo = f.lo_of(c);
    double* hi = f.hi_of(c);
    for (int a = 0; a < d; ++a) {
      lo[a] = std::numeric_limits<double>::infinity();
      hi[a] = -lo[a];
    }
    for (int j = 0; j < k; ++j) {
      const int64_t node = cells[static_cast<size_t>(c * k + j)];
      double* p = f.vertex_of(c, j);
      for (int a = 0; a < d; ++a) {
        p[a] = static_cast<double>(x[node * d + a]);
        lo[a] = std::min(lo[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
      }
    }
    if (d == 2) {
      const Triangle2 t = f.triangle(c);
      const double twice = cross2(t[0], t[1], t[2]);
      f.measure[static_cast<size_t>(c)] = 0.5 * std::fabs(twice);
      if (twice < 0)
        for (int a = 0; a < d; ++a) std::swap(f.vertex_of(c, 1)[a], f.vertex_of(c, 2)[a]);
    } else {
      const Tetrahedron3 t = f.tetrahedron(c);
      f.measure[static_cast<size_t>(c)] = tetrahedron_volume(t);
      face_planes(t, &f.planes[static_cast<size_t>(c * 4)]);
    }
  }
  return f;
}

// Walls: each node's distance to the walled region (a box, open where a side has no wall).
template <class T>
void measure_walls(const T* x, int64_t num_nodes, int d, const BoxWalls& walls, FrameValidity& v) {
  for (int64_t i = 0; i < num_nodes; ++i) {
    double squared = 0.0;
    for (int a = 0; a < d; ++a) {
      const double p = static_cast<double>(x[i * d + a]);
      const double lo = walls.lo[a], hi = walls.hi[a];
      const double beyond = std::max(std::isnan(lo) ? 0.0 : lo - p, 0.0) +
                            std::max(std::isnan(hi) ? 0.0 : p - hi, 0.0);
      squared += beyond * beyond;
    }
    if (squared > 0) {
      ++v.nodes_outside_walls;
      v.outside_walls_max = std::max(v.outside_walls_max, std::sqrt(squared));
    }
  }
}

// The broad phase's uniform grid: normal cells listed in every grid cell their box touches
// (counting-sorted, `entries[start[g]..start[g + 1])`), large ones apart.
struct CellGrid {
  double spacing = 0.0;
  double lo[3] = {0, 0, 0};  // the normal cells' lowest corner
  int64_t size[3] = {1, 1, 1};
  int64_t count = 1;              // grid cells
  std::vector<int64_t> large;     // cells beyond 4 spacings, tested against every cell
  std::vector<char> is_large;     // [cells]
  std::vector<int64_t> first_of;  // [cells, 3]: the first grid corner each normal cell touches
  std::vector<int64_t> start;     // [count + 1]
  std::vector<int32_t> entries;

  // Grid coordinate of p along axis a, clamped to the grid (monotone in p, so a box's range of
  // coordinates holds those of every point in it).
  int64_t coordinate(double p, int a) const {
    const double t = std::floor((p - lo[a]) / spacing);
    if (!(t > 0)) return 0;
    if (t >= static_cast<double>(size[a] - 1)) return size[a] - 1;
    return static_cast<int64_t>(t);
  }
  int64_t flat(const int64_t* g) const { return (g[0] * size[1] + g[1]) * size[2] + g[2]; }
  // The grid cells cell c's box touches, as ranges; its first corner kept.
  template <class Visit>
  void for_each_touched(const FrameCells& cells, int64_t c, Visit&& visit) {
    const int d = cells.d;
    int64_t first[3] = {0, 0, 0}, last[3] = {0, 0, 0}, g[3];
    for (int a = 0; a < d; ++a) {
      first[a] = first_of[static_cast<size_t>(c * 3 + a)] = coordinate(cells.lo_of(c)[a], a);
      last[a] = coordinate(cells.hi_of(c)[a], a);
    }
    for (g[0] = first[0]; g[0] <= last[0]; ++g[0])
      for (g[1] = first[1]; g[1] <= last[1]; ++g[1])
        for (g[2] = first[2]; g[2] <= last[2]; ++g[2]) visit(flat(g));
  }
};

// Each cell's box extent (its largest side).
std::vector<double> cell_extents(const FrameCells& cells) {
  std::vector<double> extent(static_cast<size_t>(cells.count));
  for (int64_t c = 0; c < cells.count; ++c) {
    double e = 0.0;
    for (int a = 0; a < cells.d; ++a) e = std::max(e, cells.hi_of(c)[a] - cells.lo_of(c)[a]);
    extent[static_cast<size_t>(c)] = e;
  }
  return extent;
}

// Grid spacing: the median extent of the cells' boxes (the largest when that is 0); not > 0 when
// every cell is a point.
double median_spacing(const std::vector<double>& extent) {
  const size_t half = extent.size() / 2;
  std::vector<double> sorted = extent;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(half),
                   sorted.end());
  double spacing = sorted[half];
  if (!(spacing > 0)) spacing = *std::max_element(extent.begin(), extent.end());
  return spacing;
}

// Sets grid.large / is_large (cells beyond 4 spacings) and grid.lo, `hi` to the other cells'
// bounds.
void split_large_cells(const FrameCells& cells, const std::vector<double>& extent, CellGrid& grid,
                       double* hi) {
  const int d = cells.d;
  grid.is_large.assign(static_cast<size_t>(cells.count), 0);
  for (int a = 0; a < d; ++a) {
    grid.lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -grid.lo[a];
  }
  for (int64_t c = 0; c < cells.count; ++c) {
    if (extent[static_cast<size_t>(c)] > 4 * grid.spacing) {
      grid.large.push_back(c);
      grid.is_large[static_cast<size_t>(c)] = 1;
      continue;
    }
    for (int a = 0; a < d; ++a) {
      grid.lo[a] = std::min(grid.lo[a], cells.lo_of(c)[a]);
      hi[a] = std::max(hi[a], cells.hi_of(c)[a]);
    }
  }
}

// At most ~8 grid cells per mesh cell: a scene spread far apart gets a coarser grid.
void size_grid(int d, int64_t num_cells, const double* hi, CellGrid& grid) {
  const double max_grid = 8.0 * static_cast<double>(num_cells) + 64.0;
  for (;;) {
    double total = 1.0, along[3] = {1, 1, 1};
    for (int a = 0; a < d; ++a) {
      along[a] = std::floor((hi[a] - grid.lo[a]) / grid.spacing) + 1.0;
      total *= along[a];
    }
    if (total <= max_grid) {
      for (int a = 0; a < d; ++a) grid.size[a] = static_cast<int64_t>(along[a]);
      break;
    }
    if (!std::isfinite(grid.spacing)) break;  // coordinates too far apart for any grid: one cell
    grid.spacing *= std::max(1.01, std::pow(total / max_grid, 1.0 / d));
  }
  grid.count = grid.size[0] * grid.size[1] * grid.size[2];
}

// Counting sort of (grid cell, mesh cell) entries.
void list_cells(const FrameCells& cells, CellGrid& grid) {
  grid.first_of.assign(static_cast<size_t>(cells.count * 3), 0);
  grid.start.assign(static_cast<size_t>(grid.count + 1), 0);
  std::vector<int64_t>& start = grid.start;
  for (int64_t c = 0; c < cells.count; ++c)
    if (!grid.is_large[static_cast<size_t>(c)])
      grid.for_each_touched(cells, c, [&](int64_t g) { ++start[static_cast<size_t>(g + 1)]; });
  for (int64_t g = 0; g < grid.count; ++g)
    start[static_cast<size_t>(g + 1)] += start[static_cast<size_t>(g)];
  grid.entries.resize(static_cast<size_t>(start.back()));
  std::vector<int64_t> fill(start.begin(), start.end() - 1);
  for (int64_t c = 0; c < cells.count; ++c)
    if (!grid.is_large[static_cast<size_t>(c)])
      grid.for_each_touched(cells, c, [&](int64_t g) {
        grid.entries[static_cast<size_t>(fill[static_cast<size_t>(g)]++)] = static_cast<int32_t>(c);
      });
}

// The grid over `cells`; false when every cell is a point (nothing has a measure or an inside).
bool build_grid(const FrameCells& cells, CellGrid& grid) {
  const std::vector<double> extent = cell_extents(cells);
  grid.spacing = median_spacing(extent);
  if (!(grid.spacing > 0)) return false;
  double hi[3] = {0, 0, 0};
  split_large_cells(cells, extent, grid, hi);
  size_grid(cells.d, cells.count, hi, grid);
  list_cells(cells, grid);
  return true;
}

// Pairs of different bodies in one grid cell, each tested in the grid cell holding the lowest
// corner of the boxes' intersection: the coordinate of a maximum is the maximum of the
// coordinates (coordinate() is monotone), so the cells' first corners decide. Each grid cell's
// sum is kept apart and the sums added in grid order (a result independent of the threads).
void add_grid_overlaps(const FrameCells& cells, const CellGrid& grid,
                       const std::vector<int32_t>& cell_body, FrameValidity& v) {
  const int d = cells.d;
  const int64_t grid_cells = grid.count;
  const int64_t* size = grid.size;
  auto body_of = [&](int64_t c) { return cell_body[static_cast<size_t>(c)]; };
  std::vector<double> grid_overlap(static_cast<size_t>(grid_cells), 0.0);
  std::vector<int64_t> grid_pairs(static_cast<size_t>(grid_cells), 0);
#pragma omp parallel if (cells.count >= kParallelCells)
  {
    std::vector<int32_t> list;
#pragma omp for schedule(dynamic, 64)
    for (int64_t g = 0; g < grid_cells; ++g) {
      const int32_t* begin = grid.entries.data() + grid.start[static_cast<size_t>(g)];
      const int32_t* end = grid.entries.data() + grid.start[static_cast<size_t>(g + 1)];
      if (end - begin < 2) continue;
      // Most grid cells lie inside one body.
      if (std::all_of(begin + 1, end, [&](int32_t c) { return body_of(c) == body_of(*begin); }))
        continue;
      const int64_t g3[3] = {g / (size[1] * size[2]), (g / size[2]) % size[1], g % size[2]};
      // Grouped by body, so that only pairs of different bodies are enumerated.
      list.assign(begin, end);
      std::stable_sort(list.begin(), list.end(),
                       [&](int32_t a, int32_t b) { return body_of(a) < body_of(b); });
      const size_t count = list.size();
      double sum = 0.0;
      int64_t pairs = 0;
      size_t group_end = 0;
      for (size_t i = 0; i < count; ++i) {
        if (i == group_end)
          while (group_end < count && body_of(list[group_end]) == body_of(list[i])) ++group_end;
        const int64_t c1 = list[i];
        for (size_t j = group_end; j < count; ++j) {
          const int64_t c2 = list[j];
          if (!cells.boxes_overlap(c1, c2)) continue;
          bool here = true;
          for (int a = 0; a < d && here; ++a)
            here = std::max(grid.first_of[static_cast<size_t>(c1 * 3 + a)],
                            grid.first_of[static_cast<size_t>(c2 * 3 + a)]) == g3[a];
          if (!here) continue;
          ++pairs;
          sum += cells.overlap(c1, c2);
        }
      }
      grid_overlap[static_cast<size_t>(g)] = sum;
      grid_pairs[static_cast<size_t>(g)] = pairs;
    }
  }
  for (int64_t g = 0; g < grid_cells; ++g) {
    v.overlap_measure += grid_overlap[static_cast<size_t>(g)];
    v.candidate_pairs += grid_pairs[static_cast<size_t>(g)];
  }
}

// Large cells against every cell of another body (a pair of large cells once).
void add_large_overlaps(const FrameCells& cells, const CellGrid& grid,
                        const std::vector<int32_t>& cell_body, FrameValidity& v) {
  auto body_of = [&](int64_t c) { return cell_body[static_cast<size_t>(c)]; };
  for (const int64_t c1 : grid.large)
    for (int64_t c2 = 0; c2 < cells.count; ++c2) {
      if (c2 == c1 || (grid.is_large[static_cast<size_t>(c2)] && c2 < c1)) continue;
      if (body_of(c1) == body_of(c2) || !cells.boxes_overlap(c1, c2)) continue;
      ++v.candidate_pairs;
      v.overlap_measure += cells.overlap(c1, c2);
    }
}

// Nodes strictly inside a cell of another body: the cells listed in the node's grid cell hold
// every normal cell whose box holds the node.
template <class T>
int64_t count_nodes_in_other_body(const T* x, int64_t num_nodes,
                                  const std::vector<int32_t>& node_body,
                                  const std::vector<int32_t>& cell_body, const FrameCells& cells,
                                  const CellGrid& grid) {
  const int d = cells.d;
  const std::vector<int64_t>& large = grid.large;
  auto body_of = [&](int64_t c) { return cell_body[static_cast<size_t>(c)]; };
  int64_t inside_count = 0;
#pragma omp parallel for schedule(static) reduction(+ : inside_count) \
    if (cells.count >= kParallelCells)
  for (int64_t i = 0; i < num_nodes; ++i) {
    double p[3] = {0, 0, 0};
    int64_t g[3] = {0, 0, 0};
    for (int a = 0; a < d; ++a) {
      p[a] = static_cast<double>(x[i * d + a]);
      g[a] = grid.coordinate(p[a], a);
    }
    const int32_t body = node_body[static_cast<size_t>(i)];
    auto inside = [&](int64_t c) {
      return body_of(c) != body && cells.box_holds(c, p) && cells.node_inside(c, p);
    };
    const int64_t at = grid.flat(g);
    bool found = false;
    for (int64_t e = grid.start[static_cast<size_t>(at)];
         e < grid.start[static_cast<size_t>(at + 1)] && !found; ++e)
      found = inside(grid.entries[static_cast<size_t>(e)]);
    for (size_t l = 0; l < large.size() && !found; ++l) found = inside(large[l]);
    inside_count += found;
  }
  return inside_count;
}

}  // namespace

double triangle_area(const Triangle2& t) {
  return 0.5 * std::fabs(cross2(t[0], t[1], t[2]));
}

double tetrahedron_volume(const Tetrahedron3& t) {
  return std::fabs(orient3(t[0], t[1], t[2], t[3])) / 6.0;
}

double triangle_overlap_area(const Triangle2& a, const Triangle2& b) {
  if (!(triangle_area(a) > 0) || !(triangle_area(b) > 0)) return 0.0;
  return clipped_area(counter_clockwise(a), counter_clockwise(b));
}

double tetrahedron_overlap_volume(const Tetrahedron3& a, const Tetrahedron3& b) {
  if (!(tetrahedron_volume(a) > 0) || !(tetrahedron_volume(b) > 0)) return 0.0;
  HalfSpace a_planes[4], b_planes[4];
  face_planes(a, a_planes);
  face_planes(b, b_planes);
  return clipped_volume(a, a_planes, b, b_planes);
}

bool strictly_inside(const Triangle2& t, const std::array<double, 2>& p) {
  const Triangle2 c = counter_clockwise(t);
  return cross2(c[0], c[1], p) > 0 && cross2(c[1], c[2], p) > 0 && cross2(c[2], c[0], p) > 0;
}

bool strictly_inside(const Tetrahedron3& t, const std::array<double, 3>& p) {
  const Tetrahedron3 c = positive(t);
  // The barycentric coordinate of vertex i has the sign of the volume with p in its place.
  for (int i = 0; i < 4; ++i) {
    Tetrahedron3 with = c;
    with[i] = p;
    if (!(orient3(with[0], with[1], with[2], with[3]) > 0)) return false;
  }
  return true;
}

double FrameValidity::overlap_fraction() const {
  return cell_measure > 0 ? overlap_measure / cell_measure
                          : (std::isnan(overlap_measure) ? overlap_measure : 0.0);
}

double FrameValidity::nodes_in_other_body_fraction() const {
  return num_nodes > 0 ? static_cast<double>(nodes_in_other_body) / static_cast<double>(num_nodes)
                       : 0.0;
}

double FrameValidity::nodes_outside_walls_fraction() const {
  return num_nodes > 0 ? static_cast<double>(nodes_outside_walls) / static_cast<double>(num_nodes)
                       : 0.0;
}

void check_simplex_bodies(const char* who, int dim, const std::vector<int32_t>& cells,
                          std::vector<int32_t>& body_id, int64_t num_nodes, const BoxWalls& walls) {
  auto fail = [who](const std::string& what) {
    throw std::invalid_argument(std::string(who) + ": " + what);
  };
  if (dim != 2 && dim != 3) fail("dimension 2 or 3 (triangles or tetrahedra)");
  if (cells.size() % static_cast<size_t>(dim + 1) != 0) fail("cells of dim + 1 nodes");
  if (num_nodes < 0 || num_nodes > std::numeric_limits<int32_t>::max())
    fail("node count out of range");
  for (const int32_t i : cells)
    if (i < 0 || i >= num_nodes) fail("a cell's node index is out of range");
  if (body_id.empty()) body_id.assign(static_cast<size_t>(num_nodes), 0);
  if (static_cast<int64_t>(body_id.size()) != num_nodes) fail("one body id per node");
  if (!walls.empty() &&
      (static_cast<int>(walls.lo.size()) != dim || static_cast<int>(walls.hi.size()) != dim))
    fail("walls have one lower and upper side per axis");
}

PhysicalValidity::PhysicalValidity(int dim, std::vector<int32_t> cells,
                                   std::vector<int32_t> body_id, int64_t num_nodes, BoxWalls walls)
    : dim_(dim),
      cells_(std::move(cells)),
      node_body_(std::move(body_id)),
      num_nodes_(num_nodes),
      walls_(std::move(walls)) {
  check_simplex_bodies("PhysicalValidity", dim_, cells_, node_body_, num_nodes_, walls_);
  const size_t k = static_cast<size_t>(dim_ + 1);
  cell_body_.resize(cells_.size() / k);
  for (size_t c = 0; c < cell_body_.size(); ++c) cell_body_[c] = node_body_[cells_[c * k]];
  several_bodies_ = std::any_of(node_body_.begin(), node_body_.end(),
                                [&](int32_t b) { return b != node_body_.front(); });
}

FrameValidity PhysicalValidity::measure(const float* x) const {
  return measure_frame(x);
}

FrameValidity PhysicalValidity::measure(const double* x) const {
  return measure_frame(x);
}

template <class T>
FrameValidity PhysicalValidity::measure_frame(const T* x) const {
  FrameValidity v;
  v.num_nodes = num_nodes_;
  const int64_t num_coords = num_nodes_ * dim_;
  for (int64_t i = 0; i < num_coords; ++i)
    if (!std::isfinite(static_cast<double>(x[i]))) {
      const double nan = std::nan("");
      v.cell_measure = v.overlap_measure = v.outside_walls_max = nan;
      return v;
    }
  if (!walls_.empty()) measure_walls(x, num_nodes_, dim_, walls_, v);

  // Sums are taken in cell order so that the figures do not depend on the thread count.
  const FrameCells cells = frame_cells(dim_, cells_, x);
  for (const double m : cells.measure) v.cell_measure += m;
  if (!several_bodies_ || cells.count == 0) return v;

  CellGrid grid;
  if (!build_grid(cells, grid)) return v;
  add_grid_overlaps(cells, grid, cell_body_, v);
  add_large_overlaps(cells, grid, cell_body_, v);
  v.nodes_in_other_body =
      count_nodes_in_other_body(x, num_nodes_, node_body_, cell_body_, cells, grid);
  return v;
}

}  // namespace bsms
