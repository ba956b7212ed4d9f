#include "pipeline/experiments/node_interpolation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <string>

#include "core/error.hpp"

namespace bsms {

namespace {

constexpr double kInside = -1e-9;  // weights down to this count as inside (rounding)

// Barycentric weights w [dim + 1] of p in the simplex with corners x [(dim + 1) * dim]; false for
// a simplex of (relatively) zero measure.
bool barycentric(const double* x, const double* p, int dim, double* w) {
  if (dim == 2) {
    const double ax = x[2] - x[0], ay = x[3] - x[1], bx = x[4] - x[0], by = x[5] - x[1];
    const double dx = p[0] - x[0], dy = p[1] - x[1];
    const double det = ax * by - ay * bx;
    const double scale = std::hypot(ax, ay) * std::hypot(bx, by);
    if (!(std::abs(det) > 1e-12 * scale)) return false;
    w[1] = (dx * by - dy * bx) / det;
    w[2] = (ax * dy - ay * dx) / det;
    w[0] = 1.0 - w[1] - w[2];
    return true;
  }
  double v[3][3], d[3];
  for (int k = 0; k < 3; ++k) {
    for (int a = 0; a < 3; ++a) v[k][a] = x[(k + 1) * 3 + a] - x[a];
    d[k] = p[k] - x[k];
  }
  const auto cross = [](const double* a, const double* b, double* c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
  };
  const auto dot = [](const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  };
  double c23[3], cd3[3], c2d[3];
  cross(v[1], v[2], c23);
  const double det = dot(v[0], c23);
  const double scale =
      std::sqrt(dot(v[0], v[0])) * std::sqrt(dot(v[1], v[1])) * std::sqrt(dot(v[2], v[2]));
  if (!(std::abs(det) > 1e-12 * scale)) return false;
  cross(d, v[2], cd3);
  cross(v[1], d, c2d);
  w[1] = dot(d, c23) / det;
  w[2] = dot(v[0], cd3) / det;
  w[3] = dot(v[0], c2d) / det;
  w[0] = 1.0 - w[1] - w[2] - w[3];
  return true;
}

// Distance from p to the point of the simplex with the weights w clamped to >= 0 and
// renormalised: 0 inside, close to the true distance for points just outside.
double clamped_distance(const double* x, const double* p, const double* w, int dim) {
  double sum = 0.0;
  for (int k = 0; k <= dim; ++k) sum += std::max(w[k], 0.0);
  double d2 = 0.0;
  for (int a = 0; a < dim; ++a) {
    double q = 0.0;
    for (int k = 0; k <= dim; ++k) q += std::max(w[k], 0.0) * x[k * dim + a];
    const double e = p[a] - q / sum;
    d2 += e * e;
  }
  return std::sqrt(d2);
}

// A uniform grid of bins over the cells' bounding box; each bin lists the cells whose bounding
// box overlaps it, so a point inside a cell finds it among a few candidates.
class CellGrid {
 public:
  CellGrid(const std::vector<double>& corners, int64_t cells, int dim) : dim_(dim) {
    const int k = dim + 1;
    lo_.assign(dim, std::numeric_limits<double>::infinity());
    std::vector<double> hi(dim, -std::numeric_limits<double>::infinity());
    for (int64_t c = 0; c < cells; ++c)
      for (int j = 0; j < k; ++j)
        for (int a = 0; a < dim; ++a) {
          const double v = corners[static_cast<size_t>((c * k + j) * dim + a)];
          lo_[a] = std::min(lo_[a], v);
          hi[a] = std::max(hi[a], v);
        }
    double volume = 1.0, longest = 0.0;
    for (int a = 0; a < dim; ++a) longest = std::max(longest, hi[a] - lo_[a]);
    if (!(longest > 0)) longest = 1.0;
    for (int a = 0; a < dim; ++a) volume *= std::max(hi[a] - lo_[a], 1e-6 * longest);
    // About one cell per bin.
    h_ = std::pow(volume / static_cast<double>(std::max<int64_t>(cells, 1)), 1.0 / dim);
    for (int a = 0; a < dim; ++a)
      n_[a] = std::clamp(static_cast<int64_t>(std::ceil((hi[a] - lo_[a]) / h_)), int64_t{1},
                         int64_t{1024});
    int64_t total = 1;
    for (int a = 0; a < dim; ++a) total *= n_[a];
    bins_.resize(static_cast<size_t>(total));
    for (int64_t c = 0; c < cells; ++c) {
      std::array<int64_t, 3> from{0, 0, 0}, to{0, 0, 0};
      for (int a = 0; a < dim; ++a) {
        double mn = std::numeric_limits<double>::infinity(), mx = -mn;
        for (int j = 0; j < k; ++j) {
          const double v = corners[static_cast<size_t>((c * k + j) * dim + a)];
          mn = std::min(mn, v);
          mx = std::max(mx, v);
        }
        from[a] = bin(a, mn);
        to[a] = bin(a, mx);
      }
      for (int64_t i = from[0]; i <= to[0]; ++i)
        for (int64_t j = from[1]; j <= to[1]; ++j)
          for (int64_t l = from[2]; l <= to[2]; ++l)
            bins_[static_cast<size_t>(index({i, j, l}))].push_back(c);
    }
  }

  const std::vector<int64_t>& candidates(const double* p) const {
    std::array<int64_t, 3> at{0, 0, 0};
    for (int a = 0; a < dim_; ++a) at[a] = bin(a, p[a]);
    return bins_[static_cast<size_t>(index(at))];
  }

 private:
  int64_t bin(int a, double v) const {
    const double f = std::floor((v - lo_[a]) / h_);
    return std::clamp(static_cast<int64_t>(std::isfinite(f) ? f : 0.0), int64_t{0}, n_[a] - 1);
  }
  int64_t index(const std::array<int64_t, 3>& at) const {
    return (at[0] * n_[1] + at[1]) * n_[2] + at[2];
  }
  int dim_;
  std::vector<double> lo_;
  double h_ = 1.0;
  std::array<int64_t, 3> n_{1, 1, 1};
  std::vector<std::vector<int64_t>> bins_;
};

}  // namespace

NodeInterpolation locate_points(const std::vector<float>& source,
                                const std::vector<int32_t>& source_body,
                                const std::vector<int32_t>& cells, const std::vector<float>& points,
                                const std::vector<int32_t>& point_body, int dim) {
  if (dim != 2 && dim != 3)
    throw InputError("node interpolation: dimension " + std::to_string(dim) + " (2 or 3 expected)");
  const int k = dim + 1;
  const int64_t n = static_cast<int64_t>(source_body.size());
  const int64_t p_count = static_cast<int64_t>(point_body.size());
  if (static_cast<int64_t>(source.size()) != n * dim ||
      static_cast<int64_t>(points.size()) != p_count * dim || cells.size() % k != 0)
    throw InputError("node interpolation: positions, bodies and cells disagree in size");
  // Cells of positive measure, their corners in double, listed by body.
  std::vector<double> corners;
  std::vector<int64_t> cell_ids;
  std::map<int32_t, std::vector<int64_t>> by_body;  // into cell_ids
  const int64_t source_cells = static_cast<int64_t>(cells.size()) / k;
  std::vector<double> x(static_cast<size_t>(k * dim)), w(static_cast<size_t>(k));
  const std::vector<double> origin(static_cast<size_t>(dim), 0.0);
  for (int64_t c = 0; c < source_cells; ++c) {
    for (int j = 0; j < k; ++j) {
      const int32_t i = cells[static_cast<size_t>(c * k + j)];
      if (i < 0 || i >= n) throw InputError("node interpolation: a cell names a missing node");
      for (int a = 0; a < dim; ++a)
        x[static_cast<size_t>(j * dim + a)] = source[static_cast<size_t>(i) * dim + a];
    }
    if (!barycentric(x.data(), origin.data(), dim, w.data())) continue;
    by_body[source_body[static_cast<size_t>(cells[static_cast<size_t>(c * k)])]].push_back(
        static_cast<int64_t>(cell_ids.size()));
    cell_ids.push_back(c);
    corners.insert(corners.end(), x.begin(), x.end());
  }
  const CellGrid grid(corners, static_cast<int64_t>(cell_ids.size()), dim);

  NodeInterpolation map;
  map.dim = dim;
  map.points = p_count;
  map.corners.resize(static_cast<size_t>(p_count * k));
  map.weights.resize(map.corners.size());
  std::vector<double> p(static_cast<size_t>(dim)), best_w(static_cast<size_t>(k));
  for (int64_t q = 0; q < p_count; ++q) {
    const int32_t body = point_body[static_cast<size_t>(q)];
    for (int a = 0; a < dim; ++a) p[a] = points[static_cast<size_t>(q * dim + a)];
    const auto own = by_body.find(body);
    if (own == by_body.end())
      throw InputError("node interpolation: body " + std::to_string(body) +
                       " has no cell in the source mesh");
    int64_t best = -1;
    double best_distance = std::numeric_limits<double>::infinity();
    const auto consider = [&](int64_t e) {
      const double* xe = &corners[static_cast<size_t>(e * k * dim)];
      if (!barycentric(xe, p.data(), dim, w.data())) return false;
      const double d = *std::min_element(w.begin(), w.end()) >= kInside
                           ? 0.0
                           : clamped_distance(xe, p.data(), w.data(), dim);
      if (d < best_distance) {
        best_distance = d;
        best = e;
        best_w = w;
      }
      return d == 0.0;
    };
    bool inside = false;
    for (int64_t e : grid.candidates(p.data()))
      if (source_body[static_cast<size_t>(cells[static_cast<size_t>(cell_ids[e] * k)])] == body &&
          consider(e)) {
        inside = true;
        break;
      }
    if (!inside) {
      for (int64_t e : own->second)
        if (consider(e)) break;
      if (best_distance > 0) {
        ++map.outside;
        map.farthest_outside = std::max(map.farthest_outside, best_distance);
      }
    }
    for (int j = 0; j < k; ++j) {
      map.corners[static_cast<size_t>(q * k + j)] =
          cells[static_cast<size_t>(cell_ids[best] * k + j)];
      map.weights[static_cast<size_t>(q * k + j)] = best_w[j];
    }
  }
  return map;
}

void interpolate_points(const NodeInterpolation& map, const float* source, float* out) {
  const int k = map.dim + 1;
  for (int64_t q = 0; q < map.points; ++q)
    for (int a = 0; a < map.dim; ++a) {
      double v = 0.0;
      for (int j = 0; j < k; ++j)
        v += map.weights[static_cast<size_t>(q * k + j)] *
             source[static_cast<size_t>(map.corners[static_cast<size_t>(q * k + j)]) * map.dim + a];
      out[q * map.dim + a] = static_cast<float>(v);
    }
}

}  // namespace bsms
