#include "preprocess/contact_enhancement.hpp"

#include <gtest/gtest.h>

#include <set>

#include "core/error.hpp"
#include "test_graphs.hpp"

namespace bsms {
namespace {

// Random contact edges between spatially unrelated nodes (both directions, like contact search).
EdgeList random_contacts(int64_t n, int count, std::mt19937_64& rng) {
  std::uniform_int_distribution<int64_t> node(0, n - 1);
  EdgeList out;
  for (int c = 0; c < count; ++c) {
    const int64_t a = node(rng), b = node(rng);
    out.data.insert(out.data.end(), {a, b, b, a});
  }
  return out;
}

TEST(ContactEnhancement, EqualsDenseFormula) {
  std::mt19937_64 rng(71);
  for (const auto& g : test::random_test_graphs(24, 150, 72)) {
    SCOPED_TRACE(g.name);
    BuildOptions options;
    options.num_levels = 4;
    const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
    const EdgeList contact0 = random_contacts(g.graph.num_nodes, 6, rng);
    const auto all = enhance_contact_edges_all_levels(ml, contact0);
    ASSERT_EQ(static_cast<int>(all.size()), ml.num_levels());
    for (int k = 0; k + 1 < ml.num_levels(); ++k) {
      SCOPED_TRACE("level " + std::to_string(k));
      const auto a = test::dense_plus_identity(test::dense_adjacency(ml.levels[k].graph));
      const auto ac = test::dense_from_edges(ml.levels[k].num_nodes(), all[k]);
      const auto expected = test::dense_select(test::dense_product(test::dense_product(a, ac), a),
                                               ml.levels[k + 1].pooled);
      const EdgeList got = enhance_contact_edges(ml, k, all[k]);
      EXPECT_EQ(got.data, all[k + 1].data);
      EXPECT_EQ(test::dense_from_edges(ml.levels[k + 1].num_nodes(), got), expected);
      for (int64_t e = 1; e < got.size(); ++e) {
        EXPECT_TRUE(std::make_pair(got.sender(e - 1), got.receiver(e - 1)) <
                    std::make_pair(got.sender(e), got.receiver(e)));
      }
    }
  }
}

// Thesis §4.2 proof: every contact edge (i, j) at level k has kept i' in N[i], j' in N[j] with
// (i', j') a contact edge at level k+1; checked per case (which ends are kept).
TEST(ContactEnhancement, ConservesEveryContactEdgeInAllFourCases) {
  std::mt19937_64 rng(81);
  int cases[4] = {0, 0, 0, 0};
  for (const auto& g : test::random_test_graphs(60, 800, 82)) {
    SCOPED_TRACE(g.name);
    BuildOptions options;
    options.num_levels = 5;
    options.seeding = Seeding::kRandom;
    const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
    const auto all =
        enhance_contact_edges_all_levels(ml, random_contacts(g.graph.num_nodes, 40, rng));
    for (int k = 0; k + 1 < ml.num_levels(); ++k) {
      const CsrGraph& fine = ml.levels[k].graph;
      const auto& pooled = ml.levels[k + 1].pooled;
      std::vector<int64_t> coarse_index(fine.num_nodes, -1);
      for (size_t r = 0; r < pooled.size(); ++r) coarse_index[pooled[r]] = static_cast<int64_t>(r);
      std::set<std::pair<int64_t, int64_t>> coarse_edges;
      for (int64_t e = 0; e < all[k + 1].size(); ++e) {
        coarse_edges.insert({all[k + 1].sender(e), all[k + 1].receiver(e)});
      }
      auto kept_closed = [&](int64_t v) {
        std::vector<int64_t> out;
        if (coarse_index[v] >= 0) out.push_back(coarse_index[v]);
        for (const int64_t* u = fine.begin(v); u != fine.end(v); ++u) {
          if (coarse_index[*u] >= 0) out.push_back(coarse_index[*u]);
        }
        return out;
      };
      for (int64_t e = 0; e < all[k].size(); ++e) {
        const int64_t i = all[k].sender(e), j = all[k].receiver(e);
        const int which = (coarse_index[i] >= 0 ? 0 : 2) + (coarse_index[j] >= 0 ? 0 : 1);
        ++cases[which];
        bool survives = false;
        if (which == 0) {  // case 1: both kept, the edge itself survives
          survives = coarse_edges.count({coarse_index[i], coarse_index[j]}) > 0;
        } else {
          for (int64_t a : kept_closed(i)) {
            for (int64_t b : kept_closed(j)) survives |= coarse_edges.count({a, b}) > 0;
          }
        }
        ASSERT_TRUE(survives) << "contact edge (" << i << ", " << j << ") at level " << k
                              << " lost (case " << which + 1 << ")";
      }
    }
  }
  for (int c = 0; c < 4; ++c) EXPECT_GT(cases[c], 0) << "case " << c + 1 << " never exercised";
}

TEST(ContactEnhancement, RejectsBadInput) {
  std::mt19937_64 rng(3);
  const auto g = test::grid_triangles(4, 4, 0.0, 0.2, rng);
  BuildOptions options;
  options.num_levels = 2;
  const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, options);
  EdgeList bad;
  bad.data = {0, 1000};
  EXPECT_THROW(enhance_contact_edges(ml, 0, bad), InputError);
  EXPECT_THROW(enhance_contact_edges(ml, 1, EdgeList{}), InputError);  // no level 2
  EXPECT_EQ(enhance_contact_edges(ml, 0, EdgeList{}).size(), 0);
}

}  // namespace
}  // namespace bsms
