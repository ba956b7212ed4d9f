#include "core/physical_projection.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "core/point3.hpp"

namespace bsms {

namespace {

using point3::cross;
using point3::dot;
using point3::P3;
using point3::sub;

P3 load(const double* x, int64_t node, int d) {
  P3 p = {0, 0, 0};
  for (int a = 0; a < d; ++a) p[a] = x[node * d + a];
  return p;
}

// Signed area (2-D) or volume (3-D) of cell `c` and, when `grad` is given, its gradient with
// respect to each of the cell's nodes (dim + 1 points).
double signed_measure(const double* x, const int32_t* c, int d, P3* grad) {
  const P3 x0 = load(x, c[0], d);
  const P3 e1 = sub(load(x, c[1], d), x0), e2 = sub(load(x, c[2], d), x0);
  if (d == 2) {
    const double v = 0.5 * (e1[0] * e2[1] - e1[1] * e2[0]);
    if (grad) {
      grad[1] = {0.5 * e2[1], -0.5 * e2[0], 0};
      grad[2] = {-0.5 * e1[1], 0.5 * e1[0], 0};
      grad[0] = {-grad[1][0] - grad[2][0], -grad[1][1] - grad[2][1], 0};
    }
    return v;
  }
  const P3 e3 = sub(load(x, c[3], d), x0);
  const double v = dot(e1, cross(e2, e3)) / 6.0;
  if (grad) {
    const P3 g1 = cross(e2, e3), g2 = cross(e3, e1), g3 = cross(e1, e2);
    for (int a = 0; a < 3; ++a) {
      grad[1][a] = g1[a] / 6.0;
      grad[2][a] = g2[a] / 6.0;
      grad[3][a] = g3[a] / 6.0;
      grad[0][a] = -(grad[1][a] + grad[2][a] + grad[3][a]);
    }
  }
  return v;
}

// Whether p lies strictly inside the cell (each barycentric coordinate positive).
bool inside_cell(const double* x, const int32_t* c, int d, const P3& p) {
  const double whole = signed_measure(x, c, d, nullptr);
  if (whole == 0) return false;
  std::array<double, 4 * 3> corners{};
  for (int j = 0; j <= d; ++j) {
    const P3 q = load(x, c[j], d);
    for (int a = 0; a < d; ++a) corners[static_cast<size_t>(j * d + a)] = q[a];
  }
  const int32_t local[4] = {0, 1, 2, 3};
  for (int j = 0; j <= d; ++j) {
    std::array<double, 4 * 3> with = corners;
    for (int a = 0; a < d; ++a) with[static_cast<size_t>(j * d + a)] = p[a];
    const double part = signed_measure(with.data(), local, d, nullptr);
    if (!(part * whole > 0)) return false;
  }
  return true;
}

// The point of segment (a, b) nearest to p, as weights of a and b.
std::array<double, 3> nearest_on_segment(const P3& p, const P3& a, const P3& b) {
  const P3 ab = sub(b, a);
  const double len_sq = dot(ab, ab);
  double t = len_sq > 0 ? dot(sub(p, a), ab) / len_sq : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return {1.0 - t, t, 0.0};
}

// The point of triangle (a, b, c) nearest to p, as barycentric weights (Ericson, Real-Time
// Collision Detection, 2005, 5.1.5: the Voronoi region of p among the vertices, edges and face).
std::array<double, 3> nearest_on_triangle(const P3& p, const P3& a, const P3& b, const P3& c) {
  const P3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const P3 bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const P3 cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = va + vb + vc;
  if (!(std::fabs(denom) > 0)) return {1, 0, 0};  // a degenerate triangle: its first corner
  const double v = vb / denom, w = vc / denom;
  return {1 - v - w, v, w};
}

// A uniform grid over the bounding boxes of simplices (`k` nodes each: cells or boundary facets):
// the simplices whose box holds a point are those listed in the point's grid cell plus the few
// stretched ones kept aside.
class CellGrid {
 public:
  CellGrid(const double* x, const std::vector<int32_t>& cells, int k, int d) : d_(d) {
    const int64_t n = static_cast<int64_t>(cells.size()) / k;
    box_.resize(static_cast<size_t>(n * 2 * d));
    std::vector<double> extent(static_cast<size_t>(n));
    for (int a = 0; a < d; ++a) {
      lo_[a] = std::numeric_limits<double>::infinity();
      hi_[a] = -lo_[a];
    }
    for (int64_t c = 0; c < n; ++c) {
      double* b = &box_[static_cast<size_t>(c * 2 * d)];
      for (int a = 0; a < d; ++a) {
        b[a] = std::numeric_limits<double>::infinity();
        b[d + a] = -b[a];
      }
      for (int j = 0; j < k; ++j)
        for (int a = 0; a < d; ++a) {
          const double v = x[cells[static_cast<size_t>(c * k + j)] * d + a];
          b[a] = std::min(b[a], v);
          b[d + a] = std::max(b[d + a], v);
        }
      double e = 0;
      for (int a = 0; a < d; ++a) e = std::max(e, b[d + a] - b[a]);
      extent[static_cast<size_t>(c)] = e;
    }
    if (n == 0) return;
    std::vector<double> sorted = extent;
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    spacing_ = sorted[static_cast<size_t>(n / 2)];
    if (!(spacing_ > 0)) spacing_ = *std::max_element(extent.begin(), extent.end());
    if (!(spacing_ > 0)) spacing_ = 1.0;
    std::vector<char> large(static_cast<size_t>(n), 0);
    for (int64_t c = 0; c < n; ++c) {
      if (extent[static_cast<size_t>(c)] > 4 * spacing_) {
        large[static_cast<size_t>(c)] = 1;
        large_.push_back(static_cast<int32_t>(c));
        continue;
      }
      const double* b = &box_[static_cast<size_t>(c * 2 * d)];
      for (int a = 0; a < d; ++a) {
        lo_[a] = std::min(lo_[a], b[a]);
        hi_[a] = std::max(hi_[a], b[d + a]);
      }
    }
    if (large_.size() == static_cast<size_t>(n)) return;
    // At most ~8 grid cells per mesh cell: a scene spread far apart gets a coarser grid.
    const double max_grid = 8.0 * static_cast<double>(n) + 64.0;
    for (;;) {
      double total = 1.0, along[3] = {1, 1, 1};
      for (int a = 0; a < d; ++a) {
        along[a] = std::floor((hi_[a] - lo_[a]) / spacing_) + 1.0;
        total *= along[a];
      }
      if (total <= max_grid || !std::isfinite(spacing_)) {
        for (int a = 0; a < d; ++a)
          size_[a] = std::isfinite(total) ? static_cast<int64_t>(along[a]) : 1;
        break;
      }
      spacing_ *= std::max(1.01, std::pow(total / max_grid, 1.0 / d));
    }
    const int64_t grid = size_[0] * size_[1] * size_[2];
    start_.assign(static_cast<size_t>(grid + 1), 0);
    auto each_touched = [&](int64_t c, auto&& visit) {
      const double* b = &box_[static_cast<size_t>(c * 2 * d)];
      int64_t first[3] = {0, 0, 0}, last[3] = {0, 0, 0};
      for (int a = 0; a < d; ++a) {
        first[a] = coordinate(b[a], a);
        last[a] = coordinate(b[d + a], a);
      }
      for (int64_t i = first[0]; i <= last[0]; ++i)
        for (int64_t j = first[1]; j <= last[1]; ++j)
          for (int64_t l = first[2]; l <= last[2]; ++l) visit((i * size_[1] + j) * size_[2] + l);
    };
    for (int64_t c = 0; c < n; ++c)
      if (!large[static_cast<size_t>(c)]) each_touched(c, [&](int64_t g) { ++start_[g + 1]; });
    for (int64_t g = 0; g < grid; ++g) start_[g + 1] += start_[g];
    listed_.resize(static_cast<size_t>(start_[grid]));
    std::vector<int64_t> fill(start_.begin(), start_.end() - 1);
    for (int64_t c = 0; c < n; ++c)
      if (!large[static_cast<size_t>(c)])
        each_touched(c, [&](int64_t g) { listed_[fill[g]++] = static_cast<int32_t>(c); });
  }

  // Calls visit(c) for every cell whose bounding box holds p.
  template <class Visit>
  void for_each_holding(const P3& p, Visit&& visit) const {
    auto holds = [&](int32_t c) {
      const double* b = &box_[static_cast<size_t>(c) * 2 * d_];
      for (int a = 0; a < d_; ++a)
        if (!(b[a] <= p[a] && p[a] <= b[d_ + a])) return false;
      return true;
    };
    for (const int32_t c : large_)
      if (holds(c)) visit(c);
    if (start_.empty()) return;
    int64_t g[3] = {0, 0, 0};
    for (int a = 0; a < d_; ++a) {
      if (!(p[a] >= lo_[a] && p[a] <= hi_[a])) return;
      g[a] = coordinate(p[a], a);
    }
    const int64_t flat = (g[0] * size_[1] + g[1]) * size_[2] + g[2];
    for (int64_t i = start_[flat]; i < start_[flat + 1]; ++i)
      if (holds(listed_[static_cast<size_t>(i)])) visit(listed_[static_cast<size_t>(i)]);
  }

  // Calls visit(c) for every simplex listed in a grid cell at Chebyshev distance `r` from the one
  // nearest to p (a simplex in several grid cells is visited once per cell), and for the
  // stretched ones when r == 0. Any simplex not visited for r' <= r lies farther than r spacings
  // from p. False when no grid cell is that far (the whole grid has been visited).
  template <class Visit>
  bool for_each_in_shell(const P3& p, int64_t r, Visit&& visit) const {
    if (r == 0)
      for (const int32_t c : large_) visit(c);
    if (start_.empty()) return false;
    int64_t g[3] = {0, 0, 0}, lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    bool inside = false;
    for (int a = 0; a < 3; ++a) {
      g[a] = a < d_ ? coordinate(p[a], a) : 0;
      lo[a] = std::max<int64_t>(0, g[a] - r);
      hi[a] = std::min<int64_t>(size_[a] - 1, g[a] + r);
      inside = inside || g[a] - r >= 0 || g[a] + r <= size_[a] - 1;
    }
    if (!inside && r > 0) return false;
    for (int64_t i = lo[0]; i <= hi[0]; ++i)
      for (int64_t j = lo[1]; j <= hi[1]; ++j)
        for (int64_t l = lo[2]; l <= hi[2]; ++l) {
          const int64_t far =
              std::max({std::abs(i - g[0]), std::abs(j - g[1]), std::abs(l - g[2])});
          if (far != r) continue;
          const int64_t flat = (i * size_[1] + j) * size_[2] + l;
          for (int64_t e = start_[flat]; e < start_[flat + 1]; ++e)
            visit(listed_[static_cast<size_t>(e)]);
        }
    return true;
  }
  double spacing() const { return spacing_; }

 private:
  int64_t coordinate(double p, int a) const {
    const double t = std::floor((p - lo_[a]) / spacing_);
    if (!(t > 0)) return 0;
    if (t >= static_cast<double>(size_[a] - 1)) return size_[a] - 1;
    return static_cast<int64_t>(t);
  }

  int d_;
  std::vector<double> box_;
  std::vector<int32_t> large_, listed_;
  std::vector<int64_t> start_;
  double lo_[3] = {0, 0, 0}, hi_[3] = {0, 0, 0};
  double spacing_ = 1.0;
  int64_t size_[3] = {1, 1, 1};
};

}  // namespace

ProjectionOptions parse_projection(const std::string& list) {
  ProjectionOptions o;
  std::stringstream in(list);
  std::string word;
  bool any = false;
  while (std::getline(in, word, ',')) {
    any = true;
    if (word == "walls") {
      o.walls = true;
    } else if (word == "cells") {
      o.cells = true;
    } else if (word == "contact") {
      o.contact = true;
    } else if (word == "all") {
      o.walls = o.cells = o.contact = true;
    } else {
      throw std::invalid_argument("'" + word +
                                  "' is not a constraint (expected walls, cells, contact or all, "
                                  "comma-separated)");
    }
  }
  if (!any)
    throw std::invalid_argument("no constraint named (expected walls, cells, contact or all)");
  return o;
}

std::vector<std::string> projection_names(const ProjectionOptions& o) {
  std::vector<std::string> names;
  if (o.walls) names.push_back("walls");
  if (o.cells) names.push_back("cells");
  if (o.contact) names.push_back("contact");
  return names;
}

PhysicalProjection::PhysicalProjection(int dim, std::vector<int32_t> cells,
                                       std::vector<int32_t> body_id, int64_t num_nodes,
                                       const float* rest, BoxWalls walls, ProjectionOptions options,
                                       std::vector<uint8_t> movable)
    : dim_(dim),
      cells_(std::move(cells)),
      node_body_(std::move(body_id)),
      num_nodes_(num_nodes),
      walls_(std::move(walls)),
      options_(options) {
  check_simplex_bodies("PhysicalProjection", dim_, cells_, node_body_, num_nodes_, walls_);
  const int k = dim_ + 1;
  if (!movable.empty() && static_cast<int64_t>(movable.size()) != num_nodes_)
    throw std::invalid_argument("PhysicalProjection: one movable flag per node");
  weight_.assign(static_cast<size_t>(num_nodes_), 1.0);
  for (size_t i = 0; i < movable.size(); ++i) weight_[i] = movable[i] ? 1.0 : 0.0;
  if (options_.walls && walls_.empty())
    throw std::invalid_argument("PhysicalProjection: walls asked for in a scene without walls");
  if (!(options_.min_measure_fraction >= 0 && options_.min_measure_fraction < 1) ||
      options_.max_passes < 1)
    throw std::invalid_argument("PhysicalProjection: min_measure_fraction in [0, 1), passes >= 1");
  // Dense body indices.
  std::map<int32_t, int32_t> dense;
  for (int32_t& b : node_body_) {
    const auto it = dense.emplace(b, static_cast<int32_t>(dense.size())).first;
    b = it->second;
  }
  num_bodies_ = std::max<int32_t>(1, static_cast<int32_t>(dense.size()));
  const int64_t num_cells = static_cast<int64_t>(cells_.size()) / k;
  cell_body_.resize(static_cast<size_t>(num_cells));
  for (int64_t c = 0; c < num_cells; ++c)
    cell_body_[static_cast<size_t>(c)] = node_body_[static_cast<size_t>(cells_[c * k])];

  std::vector<double> x(static_cast<size_t>(num_nodes_ * dim_));
  for (size_t i = 0; i < x.size(); ++i) x[i] = static_cast<double>(rest[i]);
  rest_measure_.resize(static_cast<size_t>(num_cells));
  double edge_sum = 0.0;
  int64_t edge_count = 0;
  for (int64_t c = 0; c < num_cells; ++c) {
    const int32_t* cell = &cells_[static_cast<size_t>(c * k)];
    rest_measure_[static_cast<size_t>(c)] = signed_measure(x.data(), cell, dim_, nullptr);
    for (int i = 0; i < k; ++i)
      for (int j = i + 1; j < k; ++j) {
        const P3 e = sub(load(x.data(), cell[i], dim_), load(x.data(), cell[j], dim_));
        const double len = std::sqrt(dot(e, e));
        if (std::isfinite(len)) {
          edge_sum += len;
          ++edge_count;
        }
      }
  }
  margin_ = edge_count > 0 ? 1e-3 * edge_sum / static_cast<double>(edge_count) : 0.0;

  // Boundary facets: faces (the cell without one of its nodes) that only one cell has.
  struct Face {
    int count = 0;
    std::vector<int32_t> nodes;
    int32_t inner = 0;
  };
  std::map<std::vector<int32_t>, Face> faces;
  for (int64_t c = 0; c < num_cells; ++c) {
    const int32_t* cell = &cells_[static_cast<size_t>(c * k)];
    for (int skip = 0; skip < k; ++skip) {
      std::vector<int32_t> face;
      for (int j = 0; j < k; ++j)
        if (j != skip) face.push_back(cell[j]);
      std::vector<int32_t> key = face;
      std::sort(key.begin(), key.end());
      Face& entry = faces[key];
      ++entry.count;
      entry.nodes = face;
      entry.inner = cell[skip];
    }
  }
  std::vector<std::vector<int32_t>> by_body(static_cast<size_t>(num_bodies_)),
      inner_by_body(static_cast<size_t>(num_bodies_));
  for (const auto& [key, entry] : faces)
    if (entry.count == 1) {
      const size_t b = static_cast<size_t>(node_body_[static_cast<size_t>(key[0])]);
      by_body[b].insert(by_body[b].end(), entry.nodes.begin(), entry.nodes.end());
      inner_by_body[b].push_back(entry.inner);
    }
  facet_begin_.push_back(0);
  for (size_t b = 0; b < by_body.size(); ++b) {
    facets_.insert(facets_.end(), by_body[b].begin(), by_body[b].end());
    facet_inner_.insert(facet_inner_.end(), inner_by_body[b].begin(), inner_by_body[b].end());
    facet_begin_.push_back(static_cast<int64_t>(facets_.size()) / dim_);
  }
}

int PhysicalProjection::restore_cells(double* x, ProjectionCounts& counts) const {
  const int d = dim_, k = dim_ + 1;
  int violated = 0;
  P3 grad[4];
  const int64_t num_cells = static_cast<int64_t>(rest_measure_.size());
  for (int64_t c = 0; c < num_cells; ++c) {
    const double rest = rest_measure_[static_cast<size_t>(c)];
    if (!(rest != 0)) continue;  // a flat rest cell has no orientation to keep
    const int32_t* cell = &cells_[static_cast<size_t>(c * k)];
    const double sign = rest > 0 ? 1.0 : -1.0;
    const double v = sign * signed_measure(x, cell, d, grad);
    const double floor = options_.min_measure_fraction * std::fabs(rest);
    if (v >= floor) continue;
    // Restored a little above the floor, so that rounding does not leave it just below.
    const double constraint = v - floor - 0.01 * options_.min_measure_fraction * std::fabs(rest);
    ++violated;
    double norm = 0.0;
    for (int j = 0; j < k; ++j)
      norm += weight_[static_cast<size_t>(cell[j])] * dot(grad[j], grad[j]);
    // Every node on one point, or every movable one: no direction to restore along.
    if (!(norm > 0)) continue;
    const double lambda = -constraint / norm * sign;
    for (int j = 0; j < k; ++j) {
      const double w = weight_[static_cast<size_t>(cell[j])];
      for (int a = 0; a < d; ++a) x[cell[j] * d + a] += w * lambda * grad[j][a];
    }
    ++counts.cells_restored;
  }
  return violated;
}

int PhysicalProjection::push_out(double* x, ProjectionCounts& counts) const {
  if (num_bodies_ < 2) return 0;
  const int d = dim_, k = dim_ + 1;
  // Which other body each node is strictly inside of, from the positions at the pass's start.
  const CellGrid grid(x, cells_, k, d);
  std::vector<std::pair<int64_t, int32_t>> inside;  // node, body
  for (int64_t i = 0; i < num_nodes_; ++i) {
    const P3 p = load(x, i, d);
    const int32_t own = node_body_[static_cast<size_t>(i)];
    int32_t found = -1;
    grid.for_each_holding(p, [&](int32_t c) {
      if (found >= 0 || cell_body_[static_cast<size_t>(c)] == own) return;
      if (inside_cell(x, &cells_[static_cast<size_t>(c) * k], d, p))
        found = cell_body_[static_cast<size_t>(c)];
    });
    if (found >= 0) inside.push_back({i, found});
  }
  if (inside.empty()) return 0;
  // The boundary facets on a grid of their own (boxes at the pass's start; the distances below use
  // the current positions), searched in shells of growing distance around each node.
  const CellGrid facet_grid(x, facets_, d, d);
  std::vector<int64_t> seen(facets_.size() / static_cast<size_t>(d), -1);
  for (const auto& [node, body] : inside) {
    const P3 p = load(x, node, d);
    double best = std::numeric_limits<double>::infinity();
    int64_t best_facet = -1;
    std::array<double, 3> best_w{};
    auto consider = [&](int32_t f) {
      if (f < facet_begin_[body] || f >= facet_begin_[body + 1] ||
          seen[static_cast<size_t>(f)] == node)
        return;
      seen[static_cast<size_t>(f)] = node;
      const int32_t* facet = &facets_[static_cast<size_t>(f) * d];
      const std::array<double, 3> w =
          d == 2 ? nearest_on_segment(p, load(x, facet[0], d), load(x, facet[1], d))
                 : nearest_on_triangle(p, load(x, facet[0], d), load(x, facet[1], d),
                                       load(x, facet[2], d));
      P3 q = {0, 0, 0};
      for (int j = 0; j < d; ++j) {
        const P3 v = load(x, facet[j], d);
        for (int a = 0; a < d; ++a) q[a] += w[j] * v[a];
      }
      const P3 gap = sub(q, p);
      const double dist = dot(gap, gap);
      if (dist < best) {
        best = dist;
        best_facet = f;
        best_w = w;
      }
    };
    for (int64_t r = 0;; ++r) {
      if (!facet_grid.for_each_in_shell(p, r, consider)) break;
      const double reach = static_cast<double>(r) * facet_grid.spacing();
      if (best <= reach * reach) break;
    }
    if (best_facet < 0 || !(best > 0)) continue;
    const int32_t* facet = &facets_[static_cast<size_t>(best_facet * d)];
    P3 q = {0, 0, 0};
    for (int j = 0; j < d; ++j) {
      const P3 v = load(x, facet[j], d);
      for (int a = 0; a < d; ++a) q[a] += best_w[j] * v[a];
    }
    // An earlier correction of this pass may have moved the node out already (it was on a facet
    // that was pushed): then the nearest point lies inward, and it stays where it is.
    {
      const P3 f0 = load(x, facet[0], d);
      P3 normal;
      if (d == 2) {
        const P3 e = sub(load(x, facet[1], d), f0);
        normal = {e[1], -e[0], 0};
      } else {
        normal = cross(sub(load(x, facet[1], d), f0), sub(load(x, facet[2], d), f0));
      }
      const P3 inward = sub(load(x, facet_inner_[static_cast<size_t>(best_facet)], d), f0);
      const double outward = dot(normal, inward) > 0 ? -1.0 : 1.0;
      if (outward * dot(normal, sub(p, q)) > 0) continue;
    }
    const double dist = std::sqrt(best);
    P3 move;
    for (int a = 0; a < 3; ++a) move[a] = (q[a] - p[a]) * (1.0 + margin_ / dist);
    const double w_node = weight_[static_cast<size_t>(node)];
    double w_facet[3] = {0, 0, 0}, weights_sq = w_node;
    for (int j = 0; j < d; ++j) {
      w_facet[j] = weight_[static_cast<size_t>(facet[j])];
      weights_sq += w_facet[j] * best_w[j] * best_w[j];
    }
    if (!(weights_sq > 0)) continue;  // the node and the surface are both fixed
    const double share = 1.0 / weights_sq;
    for (int a = 0; a < d; ++a) {
      x[node * d + a] += w_node * share * move[a];
      for (int j = 0; j < d; ++j) x[facet[j] * d + a] -= w_facet[j] * share * best_w[j] * move[a];
    }
    ++counts.nodes_pushed_out;
  }
  return static_cast<int>(inside.size());
}

int PhysicalProjection::clamp_walls(double* x, ProjectionCounts& counts) const {
  int violated = 0;
  for (int64_t i = 0; i < num_nodes_; ++i)
    for (int a = 0; a < dim_; ++a) {
      if (weight_[static_cast<size_t>(i)] == 0) continue;  // a fixed node goes where it is driven
      double& v = x[i * dim_ + a];
      const double lo = walls_.lo[static_cast<size_t>(a)], hi = walls_.hi[static_cast<size_t>(a)];
      if (!std::isnan(lo) && v < lo) {
        v = lo;
        ++violated;
      } else if (!std::isnan(hi) && v > hi) {
        v = hi;
        ++violated;
      }
    }
  counts.nodes_clamped += violated;
  return violated;
}

ProjectionCounts PhysicalProjection::project(double* x) const {
  ProjectionCounts counts;
  const int64_t n = num_nodes_ * dim_;
  for (int64_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) return counts;
  const std::vector<double> before(x, x + n);
  counts.converged = false;
  for (int pass = 0; pass < options_.max_passes; ++pass) {
    int violated = 0;
    if (options_.contact) violated += push_out(x, counts);
    if (options_.cells) violated += restore_cells(x, counts);
    if (options_.walls) violated += clamp_walls(x, counts);
    counts.passes = pass + 1;
    if (violated == 0) {
      counts.converged = true;
      break;
    }
  }
  for (int64_t i = 0; i < n; ++i)
    counts.shift_sq +=
        (x[i] - before[static_cast<size_t>(i)]) * (x[i] - before[static_cast<size_t>(i)]);
  return counts;
}

ProjectionCounts PhysicalProjection::project(float* x) const {
  const int64_t n = num_nodes_ * dim_;
  for (int64_t i = 0; i < n; ++i)
    if (!std::isfinite(x[i])) return {};
  std::vector<double> wide(x, x + n);
  const ProjectionCounts counts = project(wide.data());
  for (int64_t i = 0; i < n; ++i) {
    float v = static_cast<float>(wide[static_cast<size_t>(i)]);
    if (options_.walls && weight_[static_cast<size_t>(i / dim_)] > 0) {  // after rounding too
      const double lo = walls_.lo[static_cast<size_t>(i % dim_)];
      const double hi = walls_.hi[static_cast<size_t>(i % dim_)];
      if (!std::isnan(lo) && static_cast<double>(v) < lo)
        v = std::nextafter(v, std::numeric_limits<float>::infinity());
      if (!std::isnan(hi) && static_cast<double>(v) > hi)
        v = std::nextafter(v, -std::numeric_limits<float>::infinity());
    }
    x[i] = v;
  }
  return counts;
}

}  // namespace bsms
