// Fixed-radius neighbour search on a uniform hash grid (contact edges, point location fallback).
#pragma once

#include <cstdint>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

// All directed pairs (i, j), i != j, with |x_i - x_j| < radius, both directions, sorted by
// sender then receiver. `points` is [N, dim] (dim 1..3). If `exclude` is given (same N), pairs
// that are edges of `exclude` (e.g. the mesh graph) are dropped. Cost ~ O(N + pairs).
EdgeList radius_pairs(const RowMatrixXd& points, double radius, const CsrGraph* exclude = nullptr);

}  // namespace bsms
