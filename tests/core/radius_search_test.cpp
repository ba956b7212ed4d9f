#include "core/radius_search.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "core/error.hpp"

namespace bsms {
namespace {

TEST(RadiusSearch, MatchesBruteForceInOneTwoAndThreeDimensions) {
  std::mt19937 rng(3);
  for (int dim = 1; dim <= 3; ++dim) {
    for (int trial = 0; trial < 10; ++trial) {
      const int64_t n = 20 + 37 * trial;
      std::uniform_real_distribution<double> u(-2.0, 3.0);
      RowMatrixXd x(n, dim);
      for (int64_t i = 0; i < n; ++i)
        for (int c = 0; c < dim; ++c) x(i, c) = u(rng);
      const double r = 0.2 + 0.1 * trial;
      // Exclude a random graph's edges.
      std::vector<int64_t> pairs;
      for (int64_t i = 0; i + 1 < n; i += 2) pairs.insert(pairs.end(), {i, i + 1});
      const CsrGraph exclude = graph_from_pairs(n, pairs);
      const EdgeList got = radius_pairs(x, r, &exclude);
      std::vector<int64_t> expected;
      for (int64_t i = 0; i < n; ++i)
        for (int64_t j = 0; j < n; ++j) {
          if (i == j || (std::abs(i - j) == 1 && std::min(i, j) % 2 == 0)) continue;
          if ((x.row(i) - x.row(j)).squaredNorm() < r * r) expected.insert(expected.end(), {i, j});
        }
      ASSERT_EQ(got.data, expected) << "dim " << dim << " trial " << trial;
    }
  }
}

// A pair filter drops exactly the pairs it rejects, and point sets whose grid would have far
// more cells than points (searched by binary search instead of a cell table) give the same pairs.
TEST(RadiusSearch, FilterAndSparseGridsMatchBruteForce) {
  std::mt19937 rng(11);
  for (int dim = 1; dim <= 3; ++dim) {
    for (int trial = 0; trial < 6; ++trial) {
      const int64_t n = 30 + 41 * trial;
      // Clusters far apart: trial 0-2 on a dense grid, 3-5 spread so the grid has > 8 n + 4096
      // cells.
      const double spread = trial < 3 ? 1.0 : 5000.0;
      std::uniform_real_distribution<double> u(0.0, 1.0);
      std::uniform_int_distribution<int> cluster(0, 3);
      RowMatrixXd x(n, dim);
      for (int64_t i = 0; i < n; ++i) {
        const double offset = spread * cluster(rng);
        for (int c = 0; c < dim; ++c) x(i, c) = offset + u(rng);
      }
      const double r = 0.3;
      const PairFilter keep = [](int64_t i, int64_t j) { return (i + j) % 3 != 0; };
      for (bool filtered : {false, true}) {
        const EdgeList got = radius_pairs(x, r, nullptr, filtered ? keep : PairFilter{});
        std::vector<int64_t> expected;
        for (int64_t i = 0; i < n; ++i)
          for (int64_t j = 0; j < n; ++j) {
            if (i == j || (filtered && !keep(i, j))) continue;
            if ((x.row(i) - x.row(j)).squaredNorm() < r * r)
              expected.insert(expected.end(), {i, j});
          }
        ASSERT_EQ(got.data, expected)
            << "dim " << dim << " trial " << trial << " filtered " << filtered;
      }
    }
  }
}

// Coordinates far beyond any real scene (3e38, the float maximum's neighbourhood, +-1e300) or a
// radius tiny against the spread would make more cells per axis than an int64 key holds: the
// search widens the cells instead and still finds exactly the close pairs; a non-finite
// coordinate is refused by name.
TEST(RadiusSearch, ExtremeCoordinatesMatchBruteForceAndNonFiniteIsRefused) {
  for (int dim = 1; dim <= 3; ++dim) {
    for (double far : {3e38, 1e300, 1.7e308}) {
      const int64_t n = 12;
      RowMatrixXd x(n, dim);
      for (int64_t i = 0; i < n; ++i)
        for (int c = 0; c < dim; ++c)
          x(i, c) = (i % 3 == 0 ? far : i % 3 == 1 ? -far : 0.0) + 0.01 * (i / 3) + 0.001 * c;
      const double r = 0.015;
      const EdgeList got = radius_pairs(x, r);
      std::vector<int64_t> expected;
      for (int64_t i = 0; i < n; ++i)
        for (int64_t j = 0; j < n; ++j) {
          if (i == j) continue;
          double d2 = 0;
          for (int c = 0; c < dim; ++c) {
            const double d = x(i, c) - x(j, c);
            d2 += d * d;
          }
          if (d2 < r * r) expected.insert(expected.end(), {i, j});
        }
      ASSERT_EQ(got.data, expected) << "dim " << dim << " far " << far;
    }
    RowMatrixXd bad = RowMatrixXd::Zero(4, dim);
    bad(2, dim - 1) = std::numeric_limits<double>::infinity();
    try {
      radius_pairs(bad, 0.1);
      FAIL() << "an infinite coordinate was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("node 2"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("inf"), std::string::npos) << e.what();
    }
    bad(2, dim - 1) = std::nan("");
    EXPECT_THROW(radius_pairs(bad, 0.1), InputError);
  }
}

}  // namespace
}  // namespace bsms
