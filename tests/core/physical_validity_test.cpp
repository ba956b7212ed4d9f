// Physical validity of a multi-body frame (core/physical_validity.hpp): exact overlap areas and
// volumes of constructed scenes, nodes inside other bodies, distances outside the walls, the
// exact intersections' symmetry, rigid-motion invariance and bounds on random simplices, and the
// grid broad phase against an all-pairs computation on random meshes.
#include "core/physical_validity.hpp"

#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <random>
#include <vector>

#include "simplex_bodies.hpp"

namespace bsms {
namespace {

// A frame under construction: bodies appended one by one.
struct Scene {
  int dim = 2;
  std::vector<double> x;
  std::vector<int32_t> cells, body;
  int64_t num_nodes() const { return static_cast<int64_t>(x.size()) / dim; }
  // Appends a body of `points` ([n, dim]) and `body_cells` (local indices) under id `id`.
  void add(const std::vector<double>& points, const std::vector<int32_t>& body_cells, int32_t id) {
    const int32_t offset = static_cast<int32_t>(num_nodes());
    x.insert(x.end(), points.begin(), points.end());
    for (const int32_t c : body_cells) cells.push_back(c + offset);
    body.resize(static_cast<size_t>(num_nodes()), id);
  }
  FrameValidity measure(BoxWalls walls = {}) const {
    return PhysicalValidity(dim, cells, body, num_nodes(), walls).measure(x.data());
  }
};

using simplex_bodies::Body;
using simplex_bodies::cube;
using simplex_bodies::square;

// The unit cube as 5 tetrahedra: four corners and the regular one between them.
Body cube_of_five() {
  Body b;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) b.points.insert(b.points.end(), {1.0 * i, 1.0 * j, 1.0 * k});
  // Node i + 2j + 4k.
  b.cells = {0, 1, 2, 4, 3, 1, 2, 7, 5, 1, 4, 7, 6, 2, 4, 7, 1, 2, 4, 7};
  return b;
}

TEST(PhysicalValidity, SimplexMeasures) {
  EXPECT_DOUBLE_EQ(triangle_area({{{0, 0}, {2, 0}, {0, 3}}}), 3.0);
  EXPECT_DOUBLE_EQ(tetrahedron_volume({{{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 6}}}), 1.0);
  Body five = cube_of_five(), six = cube(1);
  for (const Body* b : {&five, &six}) {
    Scene s;
    s.dim = 3;
    s.add(b->points, b->cells, 0);
    EXPECT_NEAR(s.measure().cell_measure, 1.0, 1e-15);
  }
}

TEST(PhysicalValidity, TwoUnitSquaresHalfOverlapping) {
  Scene s;
  Body a = square(1), b = square(1);
  b.shift({0.5, 0.0});
  s.add(a.points, a.cells, 0);
  s.add(b.points, b.cells, 1);
  const FrameValidity v = s.measure();
  EXPECT_NEAR(v.overlap_measure, 0.5, 1e-15);
  EXPECT_NEAR(v.cell_measure, 2.0, 1e-15);
  EXPECT_NEAR(v.overlap_fraction(), 0.25, 1e-15);
  EXPECT_EQ(v.nodes_in_other_body, 0);  // every node lies on the other square's boundary
  // Finer meshes of the same squares, offset off the mesh lines: 0.7 x 0.8.
  Scene fine;
  Body c = square(7), e = square(5);
  e.shift({0.3, 0.2});
  fine.add(c.points, c.cells, 3);
  fine.add(e.points, e.cells, 8);
  const FrameValidity w = fine.measure();
  EXPECT_NEAR(w.overlap_measure, 0.56, 1e-12);
  EXPECT_GT(w.nodes_in_other_body, 0);
}

TEST(PhysicalValidity, TriangleIntersections) {
  // x + y <= 2 and y <= x over y >= 0: the triangle (0,0) (2,0) (1,1).
  EXPECT_NEAR(triangle_overlap_area({{{0, 0}, {2, 0}, {0, 2}}}, {{{0, 0}, {2, 0}, {2, 2}}}), 1.0,
              1e-15);
  // A triangle and its point reflection through its centroid: a hexagon of 2/3 its area.
  const double h = std::sqrt(3.0) / 2;
  const Triangle2 up = {{{-1, -h / 3}, {1, -h / 3}, {0, 2 * h / 3}}};
  const Triangle2 down = {{{1, h / 3}, {-1, h / 3}, {0, -2 * h / 3}}};
  EXPECT_NEAR(triangle_overlap_area(up, down), 2.0 / 3 * triangle_area(up), 1e-14);
  // Orientation does not matter; disjoint or touching triangles have none.
  const Triangle2 clockwise = {{{0, 0}, {0, 2}, {2, 0}}};
  EXPECT_NEAR(triangle_overlap_area(clockwise, {{{0, 0}, {2, 0}, {2, 2}}}), 1.0, 1e-15);
  EXPECT_EQ(triangle_overlap_area({{{0, 0}, {1, 0}, {0, 1}}}, {{{1, 0}, {2, 0}, {1, 1}}}), 0.0);
  EXPECT_EQ(triangle_overlap_area({{{0, 0}, {1, 0}, {0, 1}}}, {{{5, 5}, {6, 5}, {5, 6}}}), 0.0);
  EXPECT_EQ(triangle_overlap_area({{{0, 0}, {1, 0}, {2, 0}}}, {{{0, 0}, {2, 0}, {1, 1}}}), 0.0);
}

TEST(PhysicalValidity, TetrahedronInsideAnother) {
  const Tetrahedron3 big = {{{0, 0, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 3}}};
  const Tetrahedron3 small = {{{0.1, 0.1, 0.1}, {0.6, 0.1, 0.1}, {0.1, 0.6, 0.1}, {0.1, 0.1, 0.6}}};
  EXPECT_NEAR(tetrahedron_overlap_volume(big, small), 0.125 / 6, 1e-15);
  EXPECT_NEAR(tetrahedron_overlap_volume(small, big), 0.125 / 6, 1e-15);
  // A corner cut off by another tetrahedron's face: the unit corner tetrahedron against a cone
  // whose base lies in x + y + z = 1/2, wide enough that only the base cuts: (1 - 1/8) / 6.
  const Tetrahedron3 corner = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  const Tetrahedron3 cap = {
      {{20.5, -10, -10}, {-10, 20.5, -10}, {-10, -10, 20.5}, {100, 100, 100}}};
  EXPECT_NEAR(tetrahedron_overlap_volume(corner, cap), 7.0 / 48, 1e-15);
  EXPECT_EQ(tetrahedron_overlap_volume(corner, {{{2, 0, 0}, {3, 0, 0}, {2, 1, 0}, {2, 0, 1}}}),
            0.0);
}

TEST(PhysicalValidity, CubesOfTetrahedraOffsetByAKnownAmount) {
  // Overlap of two unit cubes offset by (a, b, c): (1 - a)(1 - b)(1 - c), whatever their meshes.
  struct Case {
    Body first, second;
    std::vector<double> offset;
  };
  const std::vector<Case> cases = {{cube_of_five(), cube(1), {0.3, 0.2, 0.1}},
                                   {cube(1), cube(1), {0.5, 0.0, 0.0}},
                                   {cube(3), cube_of_five(), {-0.25, 0.4, 0.7}},
                                   {cube(4), cube(3), {0.3, -0.2, 0.1}}};
  for (const Case& c : cases) {
    Scene s;
    s.dim = 3;
    Body moved = c.second;
    moved.shift(c.offset);
    s.add(c.first.points, c.first.cells, 0);
    s.add(moved.points, moved.cells, 1);
    const double expected =
        (1 - std::fabs(c.offset[0])) * (1 - std::fabs(c.offset[1])) * (1 - std::fabs(c.offset[2]));
    const FrameValidity v = s.measure();
    EXPECT_NEAR(v.overlap_measure, expected, 1e-12)
        << c.offset[0] << " " << c.offset[1] << " " << c.offset[2];
    EXPECT_NEAR(v.overlap_fraction(), expected / 2, 1e-12);
  }
}

TEST(PhysicalValidity, DisjointBodiesAndOneBodyOverlappingItselfHaveNone) {
  Scene s;
  Body a = square(3), b = square(2);
  b.shift({1.0, 0.0});  // touching along x = 1
  s.add(a.points, a.cells, 0);
  s.add(b.points, b.cells, 1);
  EXPECT_EQ(s.measure().overlap_measure, 0.0);
  // Two overlapping triangles of one body, far from the other body: nothing counts.
  Scene folded;
  folded.add({0, 0, 2, 0, 0, 2, 2, 2}, {0, 1, 2, 0, 1, 3}, 4);
  folded.add({10, 10, 11, 10, 10, 11}, {0, 1, 2}, 5);
  const FrameValidity v = folded.measure();
  EXPECT_EQ(v.overlap_measure, 0.0);
  EXPECT_EQ(v.candidate_pairs, 0);
  // One body alone (or no body ids) is never measured against itself.
  Scene alone;
  alone.add({0, 0, 2, 0, 0, 2, 2, 2}, {0, 1, 2, 0, 1, 3}, 0);
  EXPECT_EQ(alone.measure().overlap_measure, 0.0);
  EXPECT_EQ(PhysicalValidity(2, alone.cells, {}, 4).measure(alone.x.data()).overlap_measure, 0.0);
}

TEST(PhysicalValidity, NodesInsideAnotherBody) {
  Scene s;
  Body a = square(2);
  s.add(a.points, a.cells, 0);
  // A triangle with one vertex inside the square, one on its edge and one outside.
  s.add({0.3, 0.4, 1.0, 0.5, 1.5, 0.2}, {0, 1, 2}, 1);
  FrameValidity v = s.measure();
  EXPECT_EQ(v.nodes_in_other_body, 1);
  EXPECT_EQ(v.num_nodes, 12);
  EXPECT_NEAR(v.nodes_in_other_body_fraction(), 1.0 / 12, 1e-15);
  // A triangle holding the square's nodes (0.5, 0.5), (1, 0.5) and (1, 1), with a vertex inside
  // the square: both directions count.
  Scene t;
  t.add(a.points, a.cells, 0);
  t.add({0.4, 0.3, 1.6, 0.4, 1.0, 1.6}, {0, 1, 2}, 1);
  v = t.measure();
  EXPECT_EQ(v.nodes_in_other_body, 4);
  // 3-D: a small tetrahedron poking one vertex into a cube.
  Scene c;
  c.dim = 3;
  Body b = cube(2);
  c.add(b.points, b.cells, 0);
  c.add({0.9, 0.7, 0.3, 1.5, 0.7, 0.3, 1.5, 0.9, 0.3, 1.5, 0.7, 0.6}, {0, 1, 2, 3}, 1);
  v = c.measure();
  EXPECT_EQ(v.nodes_in_other_body, 1);
  EXPECT_GT(v.overlap_measure, 0.0);
}

TEST(PhysicalValidity, NodesOutsideTheWalls) {
  Scene s;
  // Inside, 0.3 left of x = 0, beyond the corner (1, 1) by (0.3, 0.4), and far up where the top
  // has no wall.
  s.add({0.5, 0.5, -0.3, 0.5, 1.3, 1.4, 0.5, 5.0}, {0, 1, 3}, 0);
  const double nan = std::nan("");
  FrameValidity v = s.measure(BoxWalls{{0.0, 0.0}, {1.0, nan}});
  EXPECT_EQ(v.nodes_outside_walls, 2);
  EXPECT_NEAR(v.outside_walls_max, 0.3, 1e-15);  // the top has no wall: (1.3, 1.4) is 0.3 out
  v = s.measure(BoxWalls{{0.0, 0.0}, {1.0, 1.0}});
  EXPECT_EQ(v.nodes_outside_walls, 3);
  EXPECT_NEAR(v.outside_walls_max, 4.0, 1e-15);
  EXPECT_NEAR(v.nodes_outside_walls_fraction(), 0.75, 1e-15);
  v = s.measure(BoxWalls{{-1.0, -1.0}, {2.0, 2.0}});
  EXPECT_EQ(v.nodes_outside_walls, 1);
  EXPECT_NEAR(v.outside_walls_max, 3.0, 1e-15);
  s.x[5] = 1.2;  // (1.3, 1.2) against walls at x <= 1, y <= 1: sqrt(0.3^2 + 0.2^2)
  s.x[7] = 0.5;
  v = s.measure(BoxWalls{{0.0, 0.0}, {1.0, 1.0}});
  EXPECT_NEAR(v.outside_walls_max, std::sqrt(0.13), 1e-15);
  EXPECT_EQ(s.measure().nodes_outside_walls, 0);  // no walls
}

TEST(PhysicalValidity, NonFinitePositionsGiveNaN) {
  Scene s;
  Body a = square(1), b = square(1);
  s.add(a.points, a.cells, 0);
  s.add(b.points, b.cells, 1);
  s.x[3] = std::nan("");
  const FrameValidity v = s.measure();
  EXPECT_TRUE(std::isnan(v.overlap_measure));
  EXPECT_TRUE(std::isnan(v.overlap_fraction()));
}

TEST(PhysicalValidity, RejectsMalformedTopology) {
  EXPECT_THROW(PhysicalValidity(4, {}, {}, 0), std::invalid_argument);
  EXPECT_THROW(PhysicalValidity(2, {0, 1}, {}, 3), std::invalid_argument);
  EXPECT_THROW(PhysicalValidity(2, {0, 1, 3}, {}, 3), std::invalid_argument);
  EXPECT_THROW(PhysicalValidity(2, {0, 1, 2}, {0, 0}, 3), std::invalid_argument);
  EXPECT_THROW(PhysicalValidity(2, {0, 1, 2}, {}, 3, BoxWalls{{0}, {1}}), std::invalid_argument);
}

// Random rotation (QR of a Gaussian matrix would do; here products of axis rotations).
std::vector<double> rotation(int dim, std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(0, 2 * M_PI);
  if (dim == 2) {
    const double t = angle(rng);
    return {std::cos(t), -std::sin(t), std::sin(t), std::cos(t)};
  }
  std::vector<double> r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int axis = 0; axis < 3; ++axis) {
    const double t = angle(rng), c = std::cos(t), s = std::sin(t);
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    std::vector<double> g = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    g[i * 3 + i] = c;
    g[i * 3 + j] = -s;
    g[j * 3 + i] = s;
    g[j * 3 + j] = c;
    std::vector<double> out(9, 0.0);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        for (int k = 0; k < 3; ++k) out[a * 3 + b] += g[a * 3 + k] * r[k * 3 + b];
    r = out;
  }
  return r;
}

template <class P>
P moved(const P& p, const std::vector<double>& r, const std::vector<double>& t) {
  const size_t d = p.size();
  P out;
  for (size_t a = 0; a < d; ++a) {
    out[a] = t[a];
    for (size_t b = 0; b < d; ++b) out[a] += r[a * d + b] * p[b];
  }
  return out;
}

TEST(PhysicalValidity, RandomSimplexPairsAreSymmetricBoundedAndRigidInvariant) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0), shift(-3.0, 3.0);
  int overlapping2 = 0, overlapping3 = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const auto r2 = rotation(2, rng), r3 = rotation(3, rng);
    const std::vector<double> t2 = {shift(rng), shift(rng)},
                              t3 = {shift(rng), shift(rng), shift(rng)};
    Triangle2 a, b;
    for (auto& p : a) p = {u(rng), u(rng)};
    for (auto& p : b) p = {u(rng), u(rng)};
    const double ab = triangle_overlap_area(a, b), ba = triangle_overlap_area(b, a);
    EXPECT_NEAR(ab, ba, 1e-13);
    EXPECT_LE(ab, std::min(triangle_area(a), triangle_area(b)) + 1e-13);
    EXPECT_GE(ab, 0.0);
    Triangle2 ma = a, mb = b;
    for (auto& p : ma) p = moved(p, r2, t2);
    for (auto& p : mb) p = moved(p, r2, t2);
    EXPECT_NEAR(triangle_overlap_area(ma, mb), ab, 1e-12);
    overlapping2 += ab > 0;

    Tetrahedron3 c, e;
    for (auto& p : c) p = {u(rng), u(rng), u(rng)};
    for (auto& p : e) p = {u(rng), u(rng), u(rng)};
    const double ce = tetrahedron_overlap_volume(c, e), ec = tetrahedron_overlap_volume(e, c);
    EXPECT_NEAR(ce, ec, 1e-13);
    EXPECT_LE(ce, std::min(tetrahedron_volume(c), tetrahedron_volume(e)) + 1e-13);
    EXPECT_GE(ce, 0.0);
    Tetrahedron3 mc = c, me = e;
    for (auto& p : mc) p = moved(p, r3, t3);
    for (auto& p : me) p = moved(p, r3, t3);
    EXPECT_NEAR(tetrahedron_overlap_volume(mc, me), ce, 1e-12);
    overlapping3 += ce > 0;
  }
  EXPECT_GT(overlapping2, 500);  // the draws exercise partial overlaps, not only disjoint pairs
  EXPECT_GT(overlapping3, 500);
}

// An independent estimate: the share of uniform points in the first tetrahedron's box that lie
// in both, within 5 standard errors.
TEST(PhysicalValidity, TetrahedronOverlapAgreesWithMonteCarlo) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 6; ++trial) {
    Tetrahedron3 a, b;
    for (auto& p : a) p = {u(rng), u(rng), u(rng)};
    for (auto& p : b) p = {0.3 + 0.7 * u(rng), 0.3 * u(rng), u(rng)};
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min({a[0][k], a[1][k], a[2][k], a[3][k]});
      hi[k] = std::max({a[0][k], a[1][k], a[2][k], a[3][k]});
    }
    const double box = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    const int n = 400000;
    int hits = 0;
    for (int s = 0; s < n; ++s) {
      std::array<double, 3> p;
      for (int k = 0; k < 3; ++k) p[k] = lo[k] + (hi[k] - lo[k]) * u(rng);
      hits += strictly_inside(a, p) && strictly_inside(b, p);
    }
    const double share = static_cast<double>(hits) / n;
    const double error = box * std::sqrt(share * (1 - share) / n);
    EXPECT_NEAR(tetrahedron_overlap_volume(a, b), box * share, 5 * error + 1e-12) << trial;
  }
}

// Bodies of jittered grid meshes, rotated and scattered so that they overlap; some frames stretch
// one node far away (large cells, a coarse grid).
Scene random_scene(int dim, std::mt19937& rng, bool stretched) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Scene s;
  s.dim = dim;
  const int bodies = 2 + static_cast<int>(rng() % 3);
  for (int id = 0; id < bodies; ++id) {
    Body b =
        dim == 2 ? square(2 + static_cast<int>(rng() % 4)) : cube(1 + static_cast<int>(rng() % 3));
    for (double& p : b.points) p += 0.05 * (u(rng) - 0.5);
    const auto r = rotation(dim, rng);
    std::vector<double> t(static_cast<size_t>(dim));
    for (double& c : t) c = 1.2 * u(rng);
    for (size_t i = 0; i < b.points.size(); i += static_cast<size_t>(dim)) {
      std::vector<double> p(b.points.begin() + static_cast<std::ptrdiff_t>(i),
                            b.points.begin() + static_cast<std::ptrdiff_t>(i) + dim);
      for (int a = 0; a < dim; ++a) {
        double v = t[static_cast<size_t>(a)];
        for (int k = 0; k < dim; ++k)
          v += r[static_cast<size_t>(a * dim + k)] * p[static_cast<size_t>(k)];
        b.points[i + static_cast<size_t>(a)] = v;
      }
    }
    s.add(b.points, b.cells, id * 7);
  }
  if (stretched) s.x[static_cast<size_t>(rng() % s.x.size())] += 5.0 + 50.0 * u(rng);
  return s;
}

TEST(PhysicalValidity, GridBroadPhaseMatchesAllPairs) {
  std::mt19937 rng(21);
  int overlapping = 0;
  for (int dim = 2; dim <= 3; ++dim)
    for (int trial = 0; trial < 40; ++trial) {
      const Scene s = random_scene(dim, rng, trial % 4 == 3);
      const FrameValidity v = s.measure();
      const int k = dim + 1;
      const int64_t cells = static_cast<int64_t>(s.cells.size()) / k;
      auto triangle = [&](int64_t c) {
        Triangle2 t;
        for (int j = 0; j < 3; ++j) {
          const int32_t n = s.cells[static_cast<size_t>(c * k + j)];
          t[j] = {s.x[static_cast<size_t>(n * 2)], s.x[static_cast<size_t>(n * 2 + 1)]};
        }
        return t;
      };
      auto tetrahedron = [&](int64_t c) {
        Tetrahedron3 t;
        for (int j = 0; j < 4; ++j) {
          const int32_t n = s.cells[static_cast<size_t>(c * k + j)];
          for (int a = 0; a < 3; ++a) t[j][a] = s.x[static_cast<size_t>(n * 3 + a)];
        }
        return t;
      };
      auto body_of = [&](int64_t c) {
        return s.body[static_cast<size_t>(s.cells[static_cast<size_t>(c * k)])];
      };
      double overlap = 0.0;
      for (int64_t c1 = 0; c1 < cells; ++c1)
        for (int64_t c2 = c1 + 1; c2 < cells; ++c2)
          if (body_of(c1) != body_of(c2))
            overlap += dim == 2 ? triangle_overlap_area(triangle(c1), triangle(c2))
                                : tetrahedron_overlap_volume(tetrahedron(c1), tetrahedron(c2));
      int64_t inside = 0;
      for (int64_t i = 0; i < s.num_nodes(); ++i) {
        bool found = false;
        for (int64_t c = 0; c < cells && !found; ++c) {
          if (body_of(c) == s.body[static_cast<size_t>(i)]) continue;
          if (dim == 2)
            found = strictly_inside(triangle(c), {s.x[static_cast<size_t>(2 * i)],
                                                  s.x[static_cast<size_t>(2 * i + 1)]});
          else
            found = strictly_inside(tetrahedron(c), {s.x[static_cast<size_t>(3 * i)],
                                                     s.x[static_cast<size_t>(3 * i + 1)],
                                                     s.x[static_cast<size_t>(3 * i + 2)]});
        }
        inside += found;
      }
      EXPECT_NEAR(v.overlap_measure, overlap, 1e-12 * (1 + overlap)) << dim << "-D trial " << trial;
      EXPECT_EQ(v.nodes_in_other_body, inside) << dim << "-D trial " << trial;
      overlapping += overlap > 0;
      // Float positions measure the same frame rounded to float.
      std::vector<float> xf(s.x.begin(), s.x.end());
      Scene rounded = s;
      rounded.x.assign(xf.begin(), xf.end());
      const FrameValidity vf =
          PhysicalValidity(dim, s.cells, s.body, s.num_nodes()).measure(xf.data());
      EXPECT_NEAR(vf.overlap_measure, rounded.measure().overlap_measure, 1e-12);
    }
  EXPECT_GT(overlapping, 40);  // most scenes overlap
}

// Frames large enough to be measured on several threads give the same figures, to the bit, on
// one.
TEST(PhysicalValidity, FiguresDoNotDependOnTheThreadCount) {
  for (int dim = 2; dim <= 3; ++dim) {
    Scene s;
    s.dim = dim;
    for (int id = 0; id < 4; ++id) {
      Body b = dim == 2 ? square(24) : cube(8);  // 1,152 / 3,072 cells each
      std::vector<double> by(static_cast<size_t>(dim), 0.0);
      by[0] = 0.93 * id;
      by[1] = 0.05 * id;
      b.shift(by);
      s.add(b.points, b.cells, id);
    }
    const PhysicalValidity validity(dim, s.cells, s.body, s.num_nodes());
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const FrameValidity one = validity.measure(s.x.data());
    omp_set_num_threads(4);
    const FrameValidity four = validity.measure(s.x.data());
    omp_set_num_threads(threads);
    EXPECT_GT(one.overlap_measure, 0.0);
    EXPECT_EQ(one.overlap_measure, four.overlap_measure);
    EXPECT_EQ(one.cell_measure, four.cell_measure);
    EXPECT_EQ(one.candidate_pairs, four.candidate_pairs);
    EXPECT_EQ(one.nodes_in_other_body, four.nodes_in_other_body);
    // Neighbours overlap over 0.07 x 0.95 (x 1 in 3-D), three times.
    EXPECT_NEAR(one.overlap_measure, 3 * 0.07 * 0.95, 1e-12);
  }
}

}  // namespace
}  // namespace bsms
