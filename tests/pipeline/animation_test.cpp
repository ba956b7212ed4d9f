// The rollout animation's pieces: which edges it draws and the per-frame error it prints; and the
// GIF reader the report tests count frames with.
#include "pipeline/report/animation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>

#include "core/error.hpp"
#include "gif_frames.hpp"

namespace bsms {
namespace {

using Edge = std::pair<int32_t, int32_t>;

TEST(Animation, TwoDimensionalMeshDrawsEveryEdgeOnce) {
  TrajectoryMesh square;
  square.dim = 2;
  square.cell_size = 3;
  square.cells = {0, 1, 2, 2, 1, 3};  // two triangles sharing edge 1-2
  const auto edges = drawn_edges(square);
  const std::vector<Edge> expected = {{0, 1}, {0, 2}, {1, 2}, {1, 3}, {2, 3}};
  EXPECT_EQ(edges, expected);
}

TEST(Animation, TetrahedraDrawTheirBoundarySurfaceOnly) {
  // Two tetrahedra sharing face 1-2-3: that face is inside, the other six are the surface. The
  // shared face's edges still lie on surface triangles, so every edge is drawn; a cube split into
  // five tetrahedra has an inner tetrahedron whose edges are face diagonals and must be drawn,
  // while none of its faces is.
  TrajectoryMesh pair;
  pair.dim = 3;
  pair.cell_size = 4;
  pair.cells = {0, 1, 2, 3, 4, 3, 2, 1};
  EXPECT_EQ(drawn_edges(pair).size(), 9u);

  // Cube corners 0..7 (bit i of the index is coordinate i); the central tetrahedron 1-2-4-7 and
  // four corner tetrahedra. Boundary: 12 triangles on the 6 faces, 18 edges (12 sides and one
  // diagonal per face); an interior edge would be one through the cube, and there is none.
  TrajectoryMesh cube;
  cube.dim = 3;
  cube.cell_size = 4;
  cube.cells = {1, 2, 4, 7, 0, 1, 2, 4, 3, 1, 2, 7, 5, 1, 4, 7, 6, 2, 4, 7};
  const auto edges = drawn_edges(cube);
  EXPECT_EQ(edges.size(), 18u);
  for (const auto& [a, b] : edges) {
    const int differing = __builtin_popcount(static_cast<unsigned>(a ^ b));
    EXPECT_LE(differing, 2) << a << "-" << b << " runs through the cube";
  }
}

TEST(Animation, RmsDistanceIsOverNodes) {
  // Two 2-D nodes: one off by (3, 4), one exact: sqrt((25 + 0) / 2).
  EXPECT_DOUBLE_EQ(rms_distance({3, 4, 1, 1}, {0, 0, 1, 1}, 2), std::sqrt(12.5));
  EXPECT_DOUBLE_EQ(rms_distance({}, {}, 3), 0.0);
  EXPECT_THROW(rms_distance({1, 2}, {1, 2, 3}, 2), InputError);
}

TEST(Animation, GifFrameCounterReadsGnuplotsAnimations) {
  // A GIF made by hand: header, a 1x1 screen with a 2-colour table, then two images.
  const unsigned char gif[] = {
      'G',  'I',  'F', '8', '9', 'a', 1, 0, 1, 0, 0x80, 0, 0,  // screen, global table of 2
      0,    0,    0,   255, 255, 255,                          // the table
      0x21, 0xF9, 4,   0,   8,   0,   0, 0,                    // graphic control extension
      0x2C, 0,    0,   0,   0,   1,   0, 1, 0, 0, 2,    2, 0x4C, 0x01, 0,  // image 1
      0x21, 0xF9, 4,   0,   8,   0,   0, 0,                                //
      0x2C, 0,    0,   0,   0,   1,   0, 1, 0, 0, 2,    2, 0x4C, 0x01, 0,  // image 2
      0x3B};
  EXPECT_EQ(testing::gif_frames(std::string(std::begin(gif), std::end(gif))), 2);
  EXPECT_EQ(testing::gif_frames("GIF89a"), -1);  // truncated
  EXPECT_EQ(testing::gif_frames("PNG"), -1);
}

}  // namespace
}  // namespace bsms
