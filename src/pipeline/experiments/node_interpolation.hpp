// Piecewise-linear interpolation from one simplex mesh to points of another body by body: each
// point is located in a cell of the source mesh's same body in their reference positions and
// keeps that cell's barycentric weights, which then map any later source positions to the point.
// Used where a solve on another particle spacing (other mesh nodes) is compared with stored
// frames: the coarse solution is read at the stored nodes.
//
// A point inside a cell (all weights >= -1e-9) takes that cell. A point outside every cell of its
// body (a fine mesh's boundary nodes on a curved boundary lie just outside the coarse polygon)
// takes the nearest cell, nearness being the distance to the cell's point with the clamped and
// renormalised weights, and keeps that cell's unclamped weights: linear extrapolation, so an
// affine motion of the source is reproduced exactly at every point.
#pragma once

#include <cstdint>
#include <vector>

namespace bsms {

struct NodeInterpolation {
  int dim = 0;
  int64_t points = 0;
  std::vector<int32_t> corners;   // [points, dim + 1] source node of each weight
  std::vector<double> weights;    // [points, dim + 1] barycentric, summing to 1
  int64_t outside = 0;            // points outside every cell of their body
  double farthest_outside = 0.0;  // largest distance of such a point to its cell (m)
};

// Locates `points` [P, dim] (with `point_body` [P]) in the simplices `cells` [C, dim + 1] of a
// source mesh at positions `source` [N, dim] (with `source_body` [N]; a cell's body is its first
// node's). dim 2 (triangles) or 3 (tetrahedra). InputError when a point's body has no cell of
// positive measure in the source or the arrays disagree in size.
NodeInterpolation locate_points(const std::vector<float>& source,
                                const std::vector<int32_t>& source_body,
                                const std::vector<int32_t>& cells, const std::vector<float>& points,
                                const std::vector<int32_t>& point_body, int dim);

// Positions of the points for source positions `source` [N, dim] (e.g. one frame): out [P, dim].
void interpolate_points(const NodeInterpolation& map, const float* source, float* out);

}  // namespace bsms
