// Constraint projection after a predicted step (core/physical_projection.hpp): a valid frame is
// left exactly as it is; walls, inverted cells and interpenetrating bodies are corrected, checked
// with the independent measures of core/physical_validity.hpp on constructed and random scenes;
// cell and contact corrections keep the nodes' mean position (equal masses: momentum).
#include "core/physical_projection.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "simplex_bodies.hpp"

namespace bsms {
namespace {

struct Mesh {
  int dim = 2;
  std::vector<float> x;
  std::vector<int32_t> cells, body;
  int64_t num_nodes() const { return static_cast<int64_t>(x.size()) / dim; }
  void add(const Mesh& other, int32_t id, const std::vector<double>& shift) {
    const int32_t offset = static_cast<int32_t>(num_nodes());
    for (size_t i = 0; i < other.x.size(); ++i)
      x.push_back(other.x[i] + static_cast<float>(shift[i % static_cast<size_t>(dim)]));
    for (const int32_t c : other.cells) cells.push_back(c + offset);
    body.resize(static_cast<size_t>(num_nodes()), id);
  }
  PhysicalProjection projection(const std::vector<float>& rest, ProjectionOptions o,
                                BoxWalls walls = {}) const {
    return PhysicalProjection(dim, cells, body, num_nodes(), rest.data(), walls, o);
  }
  FrameValidity validity(const std::vector<float>& at) const {
    return PhysicalValidity(dim, cells, body, num_nodes()).measure(at.data());
  }
  // Cells whose signed measure has flipped against `rest`, or fallen below `fraction` of it.
  int64_t cells_below(const std::vector<float>& rest, const std::vector<float>& at,
                      double fraction) const {
    const int k = dim + 1;
    auto measure = [&](const std::vector<float>& p, size_t c) {
      auto v = [&](int j, int a) {
        return static_cast<double>(p[static_cast<size_t>(cells[c * k + j]) * dim + a]) -
               static_cast<double>(p[static_cast<size_t>(cells[c * k]) * dim + a]);
      };
      if (dim == 2) return 0.5 * (v(1, 0) * v(2, 1) - v(1, 1) * v(2, 0));
      return (v(1, 0) * (v(2, 1) * v(3, 2) - v(2, 2) * v(3, 1)) -
              v(1, 1) * (v(2, 0) * v(3, 2) - v(2, 2) * v(3, 0)) +
              v(1, 2) * (v(2, 0) * v(3, 1) - v(2, 1) * v(3, 0))) /
             6.0;
    };
    int64_t below = 0;
    for (size_t c = 0; c < cells.size() / k; ++c) {
      const double r = measure(rest, c), now = measure(at, c);
      if (r * now <= 0 || std::fabs(now) < fraction * std::fabs(r) * (1 - 1e-6)) ++below;
    }
    return below;
  }
  std::vector<double> mean(const std::vector<float>& at) const {
    std::vector<double> m(static_cast<size_t>(dim), 0.0);
    for (size_t i = 0; i < at.size(); ++i) m[i % dim] += at[i];
    for (double& v : m) v /= static_cast<double>(num_nodes());
    return m;
  }
};

// One body as the test's mesh (float positions, body 0).
Mesh as_mesh(const simplex_bodies::Body& b, int dim) {
  Mesh m;
  m.dim = dim;
  m.x.assign(b.points.begin(), b.points.end());
  m.cells = b.cells;
  m.body.assign(static_cast<size_t>(m.num_nodes()), 0);
  return m;
}
Mesh square(int n) {
  return as_mesh(simplex_bodies::square(n), 2);
}
Mesh cube(int n) {
  return as_mesh(simplex_bodies::cube(n), 3);
}

ProjectionOptions all() {
  return parse_projection("all");
}

TEST(PhysicalProjection, ParsesConstraintLists) {
  const ProjectionOptions o = parse_projection("cells,walls");
  EXPECT_TRUE(o.cells && o.walls && !o.contact);
  EXPECT_EQ(projection_names(all()), (std::vector<std::string>{"walls", "cells", "contact"}));
  EXPECT_THROW(parse_projection("walls,wall"), std::invalid_argument);
  EXPECT_THROW(parse_projection(""), std::invalid_argument);
}

TEST(PhysicalProjection, LeavesAValidFrameExactlyAsItIs) {
  for (int dim : {2, 3}) {
    Mesh scene;
    scene.dim = dim;
    const Mesh body = dim == 2 ? square(4) : cube(2);
    scene.add(body, 0, std::vector<double>(dim, 0.1));
    scene.add(body, 7, std::vector<double>(dim, 1.3));  // apart from the first
    const BoxWalls walls{std::vector<double>(dim, 0.0), std::vector<double>(dim, 3.0)};
    const auto p = scene.projection(scene.x, all(), walls);
    std::vector<float> x = scene.x;
    const ProjectionCounts c = p.project(x.data());
    EXPECT_EQ(x, scene.x);
    EXPECT_TRUE(c.converged);
    EXPECT_EQ(c.passes, 1);
    EXPECT_EQ(c.shift_sq, 0.0);
  }
}

TEST(PhysicalProjection, ClampsNodesOntoTheWallsAndLeavesOpenSidesOpen) {
  Mesh m = square(2);
  const BoxWalls walls{{0.0, std::nan("")}, {0.7, 0.9}};
  ProjectionOptions o;
  o.walls = true;
  std::vector<float> x = {-0.5f, -2.0f, 0.8f, 1.0f, 0.3f, 0.4f};
  Mesh three;  // three free nodes, no cells
  three.x = x;
  three.body = {0, 0, 0};
  const auto free_nodes = three.projection(x, o, walls);
  const ProjectionCounts c = free_nodes.project(x.data());
  EXPECT_EQ(x, (std::vector<float>{0.0f, -2.0f, 0.7f, 0.9f, 0.3f, 0.4f}));
  EXPECT_EQ(c.nodes_clamped, 3);
  EXPECT_THROW(m.projection(m.x, o, BoxWalls{}), std::invalid_argument);
}

TEST(PhysicalProjection, RestoresInvertedCellsAndKeepsTheMeanPosition) {
  for (int dim : {2, 3}) {
    const Mesh m = dim == 2 ? square(4) : cube(3);
    ProjectionOptions o;
    o.cells = true;
    const auto p = m.projection(m.x, o);
    std::mt19937 rng(11);
    std::normal_distribution<float> jitter(0.0f, 0.12f);
    int inverted_before = 0;
    for (int trial = 0; trial < 40; ++trial) {
      std::vector<float> x = m.x;
      for (float& v : x) v += jitter(rng);  // ~half an edge: many cells flip
      inverted_before += m.cells_below(m.x, x, 0.0) > 0;
      const auto mean = m.mean(x);
      const ProjectionCounts c = p.project(x.data());
      ASSERT_TRUE(c.converged) << "dim " << dim << " trial " << trial;
      EXPECT_EQ(m.cells_below(m.x, x, o.min_measure_fraction), 0) << "dim " << dim;
      const auto after = m.mean(x);
      for (int a = 0; a < dim; ++a) EXPECT_NEAR(after[a], mean[a], 1e-5);
    }
    EXPECT_GT(inverted_before, 30) << "the jitter should invert cells in most trials";
  }
}

TEST(PhysicalProjection, PushesOverlappingBodiesApartAndKeepsTheMeanPosition) {
  for (int dim : {2, 3}) {
    const int n = dim == 2 ? 6 : 3;
    const Mesh body = dim == 2 ? square(n) : cube(n);
    // Rest: two bodies apart. Predicted: the second moved into the first by a fifth to half of a
    // cell, and sideways.
    Mesh rest;
    rest.dim = dim;
    rest.add(body, 0, std::vector<double>(dim, 0.0));
    rest.add(body, 1, std::vector<double>(dim, 0.0));
    std::vector<float> rest_x = rest.x;
    for (int64_t i = rest.num_nodes() / 2; i < rest.num_nodes(); ++i) rest_x[i * dim] += 1.5f;
    const auto p = rest.projection(
        rest_x, all(), BoxWalls{std::vector<double>(dim, -5.0), std::vector<double>(dim, 5.0)});
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> depth(0.2 / n, 0.5 / n), lateral(-0.3, 0.3);
    for (int trial = 0; trial < 10; ++trial) {
      std::vector<float> x = rest_x;
      std::vector<double> shift(dim, 0.0);
      shift[0] = -(0.5 + depth(rng));
      for (int a = 1; a < dim; ++a) shift[a] = lateral(rng);
      for (int64_t i = rest.num_nodes() / 2; i < rest.num_nodes(); ++i)
        for (int a = 0; a < dim; ++a) x[i * dim + a] += static_cast<float>(shift[a]);
      const FrameValidity before = rest.validity(x);
      ASSERT_GT(before.nodes_in_other_body, 0);
      const auto mean = rest.mean(x);
      const ProjectionCounts c = p.project(x.data());
      EXPECT_TRUE(c.converged) << "dim " << dim << " trial " << trial;
      const FrameValidity after = rest.validity(x);
      EXPECT_EQ(after.nodes_in_other_body, 0) << "dim " << dim << " trial " << trial;
      // What is left are slivers between the two surfaces' facets (no node inside).
      EXPECT_LT(after.overlap_fraction(), 0.5 * before.overlap_fraction())
          << "dim " << dim << " trial " << trial;
      EXPECT_EQ(rest.cells_below(rest_x, x, 0.0), 0);
      const auto m = rest.mean(x);
      for (int a = 0; a < dim; ++a) EXPECT_NEAR(m[a], mean[a], 1e-5);
    }
  }
}

TEST(PhysicalProjection, LeavesNonFiniteFramesToTheCaller) {
  const Mesh m = square(2);
  const auto p = m.projection(m.x, all(), BoxWalls{{0.0, 0.0}, {1.0, 1.0}});
  std::vector<float> x = m.x;
  x[3] = std::nanf("");
  x[0] = -4.0f;
  const ProjectionCounts c = p.project(x.data());
  EXPECT_EQ(x[0], -4.0f);
  EXPECT_EQ(c.passes, 0);
}

}  // namespace
}  // namespace bsms
