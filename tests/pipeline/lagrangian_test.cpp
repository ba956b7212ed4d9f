// Features and targets of the Lagrangian adapter (issue 10's recipe): the strain channel, the
// contact pairs, the noise correction factor and the learning-rate schedule.
#include "pipeline/lagrangian.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <set>
#include <utility>

#include "core/graph.hpp"
#include "core/radius_search.hpp"
#include "models/layers.hpp"
#include "pipeline/train_config.hpp"
#include "plate_data.hpp"

namespace bsms {
namespace {

EdgeIndex plate_edges(const TrajectoryMesh& mesh) {
  std::vector<int64_t> pairs;
  for (int64_t c = 0; c < mesh.num_cells(); ++c)
    for (int k = 0; k < 3; ++k) {
      const int64_t a = mesh.cells[3 * c + k], b = mesh.cells[3 * c + (k + 1) % 3];
      pairs.insert(pairs.end(), {a, b, b, a});
    }
  auto t = torch::tensor(pairs, torch::kInt64).reshape({-1, 2});
  return EdgeIndex::from_pairs(t, mesh.num_nodes());
}

TEST(StrainChannel, UniformStretchAndRigidMotion) {
  const Trajectory plate = testing::dragged_plate(0, 1, 4);
  const int64_t n = plate.mesh.num_nodes();
  const auto X = torch::tensor(plate.mesh.mesh_pos).reshape({n, 2});
  const EdgeIndex edges = plate_edges(plate.mesh);
  const EdgeStretch stretch{0, 1, 10.0};
  // A uniform stretch by 1.03 reads 0.03 on every edge, times the scale.
  auto f = edge_features({X, 1.03 * X}, {0, 1}, edges, stretch);
  ASSERT_EQ(f.size(1), 7);  // [ΔX, |ΔX|, Δx, |Δx|, strain]
  EXPECT_NEAR(f.select(1, 6).min().item<double>(), 0.3, 1e-5);
  EXPECT_NEAR(f.select(1, 6).max().item<double>(), 0.3, 1e-5);
  // A rotation and a translation leave it at 0: the channel sees deformation only.
  const double c = std::cos(1.1), s = std::sin(1.1);
  const auto R = torch::tensor({c, s, -s, c}).reshape({2, 2}).to(torch::kFloat32);
  auto g = edge_features({X, X.matmul(R) + 0.4}, {}, edges, stretch);
  ASSERT_EQ(g.size(1), 1);
  EXPECT_LT(g.abs().max().item<double>(), 1e-5);
  // A stretch along x only: horizontal edges 0.05, vertical edges 0.
  auto sx = X.clone();
  sx.select(1, 0).mul_(1.05);
  auto h = edge_features({X, sx}, {}, edges, EdgeStretch{0, 1, 1.0}).squeeze(1);
  const auto d = X.index_select(0, edges.senders) - X.index_select(0, edges.receivers);
  const auto horizontal = d.select(1, 1).abs() < 1e-6, vertical = d.select(1, 0).abs() < 1e-6;
  EXPECT_NEAR(h.index({horizontal}).mean().item<double>(), 0.05, 1e-5);
  EXPECT_LT(h.index({vertical}).abs().max().item<double>(), 1e-6);
}

TEST(ContactPairs, JoinBodiesAndFarSelfContactOnly) {
  // Two bodies side by side: a row of 4 nodes each (bodies 0 and 1), 0.1 apart within a body,
  // 0.05 between the bodies; the mesh joins neighbours of a body.
  TrajectoryMesh mesh;
  mesh.dim = 2;
  RowMatrixXd points(8, 2);
  for (int i = 0; i < 8; ++i) {
    const double x = i < 4 ? 0.1 * i : 0.35 + 0.1 * (i - 4);
    points(i, 0) = x;
    points(i, 1) = 0.0;
    mesh.mesh_pos.insert(mesh.mesh_pos.end(), {static_cast<float>(x), 0.0f});
    mesh.node_type.push_back(0);
    mesh.body_id.push_back(i < 4 ? 0 : 1);
  }
  std::vector<int64_t> mesh_edges;
  for (int64_t i = 0; i < 7; ++i)
    if (i != 3) mesh_edges.insert(mesh_edges.end(), {i, i + 1});
  const CsrGraph graph = graph_from_pairs(8, mesh_edges);
  // Radius 0.12: within body 0, nodes 0 and 1 are mesh neighbours, 0 and 2 (0.2) too far.
  EdgeList c = contact_pairs(points, mesh, 0.12, graph);
  std::set<std::pair<int64_t, int64_t>> got;
  for (int64_t e = 0; e < c.size(); ++e) got.insert({c.sender(e), c.receiver(e)});
  const std::set<std::pair<int64_t, int64_t>> want = {{3, 4}, {4, 3}};  // 0.05 apart
  EXPECT_EQ(got, want);
  // One body folded onto itself: node 7 moved next to node 0, far in the reference mesh.
  for (auto& b : mesh.body_id) b = 0;
  points(7, 0) = 0.02;
  c = contact_pairs(points, mesh, 0.06, graph);
  got.clear();
  for (int64_t e = 0; e < c.size(); ++e) got.insert({c.sender(e), c.receiver(e)});
  EXPECT_TRUE(got.count({0, 7}) && got.count({7, 0}));
  EXPECT_FALSE(got.count({3, 4}));  // same body, 0.05 apart in the reference: not a contact
  // The brute force agrees: every kept pair is within the radius.
  const EdgeList all = radius_pairs(points, 0.06, &graph);
  EXPECT_LE(c.size(), all.size());
}

TEST(ContactRadius, FollowsTheSolversInteractionRange) {
  LagrangianSpec s;
  resolve_contact_radius(s, R"({"scene": {"background": {"type": "box", "element_size": 0.04}}})",
                         0.025);
  EXPECT_DOUBLE_EQ(s.contact_radius, 0.06);
  resolve_contact_radius(s, "{}", 0.025);  // no background: 1.5 mesh edges
  EXPECT_DOUBLE_EQ(s.contact_radius, 0.0375);
}

TEST(NoiseGamma, TargetsKeepPositionOrVelocity) {
  Trajectory plate = testing::dragged_plate(3, 4, 3);
  const int64_t n = plate.mesh.num_nodes();
  const auto frames = torch::tensor(plate.fields["world_pos"]).reshape({4, n, 2});
  LagrangianSpec spec;
  LagrangianAdapter adapter(spec);
  GraphStore store(Seeding::kCloseCenter, 1, {});
  FrameState state{&store.get(plate.mesh), &plate.mesh, frames[0], frames[1]};
  const auto noise = 1e-3 * torch::randn({n, 2});
  const Batch b = adapter.make_batch({state}, {noise});
  const auto mask = b.mask.unsqueeze(1);
  const auto applied = noise * mask.to(torch::kFloat32);
  // gamma 1: integrating the target from the noisy state lands on the true next position.
  const auto next1 = adapter.integrate(b, adapter.target(b, frames[2], 1.0), frames[2]);
  EXPECT_TRUE(torch::allclose(next1, frames[2], 1e-6, 1e-7));
  // gamma 0: it lands on next + noise, so the next velocity is the true one.
  const auto next0 = adapter.integrate(b, adapter.target(b, frames[2], 0.0), frames[2]);
  EXPECT_TRUE(torch::allclose(next0 - b.cur, frames[2] - frames[1], 1e-6, 1e-7));
  EXPECT_GT(applied.abs().sum().item<double>(), 0.0);
}

TEST(LearningRate, WarmsUpThenDecaysWithProgress) {
  OptimizerConfig o;
  o.lr = 1e-3;
  o.lr_final = 1e-5;
  o.warmup_steps = 100;
  EXPECT_NEAR(learning_rate(o, 0, 0.0), 1e-3 * (0.01 + 0.99 * 0.01), 1e-12);
  EXPECT_NEAR(learning_rate(o, 99, 0.0), 1e-3, 1e-12);
  EXPECT_NEAR(learning_rate(o, 500, 0.5), 1e-4, 1e-12);  // geometric middle
  EXPECT_NEAR(learning_rate(o, 500, 1.0), 1e-5, 1e-15);
  EXPECT_NEAR(learning_rate(o, 500, 3.0), 1e-5, 1e-15);  // past the end: the final rate
  o.warmup_steps = 0;
  EXPECT_NEAR(learning_rate(o, 0, 0.0), 1e-3, 1e-12);
}

}  // namespace
}  // namespace bsms
