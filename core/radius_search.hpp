// Fixed-radius neighbour search on a uniform hash grid (contact edges, point location fallback).
#pragma once

#include <cstdint>
#include <functional>

#include "core/graph.hpp"
#include "core/mesh.hpp"

namespace bsms {

// All directed pairs (i, j), i != j, with |x_i - x_j| < radius, both directions, sorted by
// sender then receiver. `points` is [N, dim] (dim 1..3). If `exclude` is given (same N), pairs
// that are edges of `exclude` (e.g. the mesh graph) are dropped; if `keep` is given, so are pairs
// within the radius for which keep(i, j) is false (it is called before the exclusion lookup, so a
// cheap test that rejects most pairs saves the rest of the work). Cost ~ O(N + pairs).
using PairFilter = std::function<bool(int64_t, int64_t)>;
EdgeList radius_pairs(const RowMatrixXd& points, double radius, const CsrGraph* exclude = nullptr,
                      const PairFilter& keep = {});

}  // namespace bsms
