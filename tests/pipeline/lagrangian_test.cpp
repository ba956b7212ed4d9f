// Features and targets of the Lagrangian adapter: the strain channel, the
// contact pairs, the noise correction factor, the learning-rate schedule and momentum
// conservation on free bodies.
#include "pipeline/adapters/lagrangian.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <set>
#include <utility>

#include "core/graph.hpp"
#include "core/radius_search.hpp"
#include "data/generate/family.hpp"
#include "data/generate/trajectory_solver.hpp"
#include "models/layers.hpp"
#include "pipeline/adapters/scene_features.hpp"
#include "pipeline/runs/train_config.hpp"
#include "plate_data.hpp"
#include "scene_text.hpp"

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
  // One body (one mesh component) folded onto itself: node 7 moved next to node 0, far in the
  // reference mesh.
  for (auto& b : mesh.body_id) b = 0;
  std::vector<int64_t> chain;
  for (int64_t i = 0; i < 7; ++i) chain.insert(chain.end(), {i, i + 1});
  const CsrGraph one = graph_from_pairs(8, chain);
  points(7, 0) = 0.02;
  points(3, 0) = 0.35;  // node 3 next to 4 as before: mesh neighbours now
  c = contact_pairs(points, mesh, 0.06, one);
  got.clear();
  for (int64_t e = 0; e < c.size(); ++e) got.insert({c.sender(e), c.receiver(e)});
  EXPECT_TRUE(got.count({0, 7}) && got.count({7, 0}));
  EXPECT_EQ(got.size(), 2u);
  // The brute force agrees: every kept pair is within the radius.
  const EdgeList all = radius_pairs(points, 0.06, &one);
  EXPECT_LE(c.size(), all.size());
  // The same body id on two mesh components (public data carries no body ids: DeformingPlate's
  // actuator and plate): the components count as bodies, so 3 and 4 (0.05 apart) are a contact.
  points(3, 0) = 0.3;
  c = contact_pairs(points, mesh, 0.06, graph);
  got.clear();
  for (int64_t e = 0; e < c.size(); ++e) got.insert({c.sender(e), c.receiver(e)});
  EXPECT_TRUE(got.count({3, 4}) && got.count({4, 3}));
}

TEST(ContactRadius, FollowsTheSolversInteractionRange) {
  LagrangianSpec s;
  resolve_contact_radius(s, testing::typed_scene(R"({"scene": {"dim": 2, "background": {
      "type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.04},
      "solver": {"end_time": 1.0}}})"),
                         0.025);
  EXPECT_DOUBLE_EQ(s.contact_radius, 0.06);
  resolve_contact_radius(s, testing::typed_scene("{}"), 0.025);  // no background: 1.5 mesh edges
  EXPECT_DOUBLE_EQ(s.contact_radius, 0.0375);
}

TEST(NoiseGamma, TargetsKeepPositionOrVelocity) {
  Trajectory plate = testing::dragged_plate(3, 4, 3);
  const int64_t n = plate.mesh.num_nodes();
  const auto frames = torch::tensor(plate.fields["world_pos"]).reshape({4, n, 2});
  LagrangianSpec spec;
  LagrangianAdapter adapter(spec);
  GraphStore store(Seeding::kCloseCenter, 1, {});
  FrameState state{store.get(plate.mesh).get(), &plate.mesh, frames[0], frames[1], {}, {}};
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

// MeshGraphNets' DeformingPlate recipe: first-order output (the velocity x_{t+1} - x_t) and the
// next-step motion of prescribed nodes as an input, zero on the nodes the model solves.
TEST(FirstOrder, VelocityTargetIntegratesAndKinematicInputIsThePrescribedMotion) {
  Trajectory plate = testing::dragged_plate(3, 4, 3);
  const int64_t n = plate.mesh.num_nodes();
  const auto frames = torch::tensor(plate.fields["world_pos"]).reshape({4, n, 2});
  LagrangianSpec spec;
  spec.first_order = true;
  spec.kinematic_input = true;
  ASSERT_EQ(spec.input_size(), 2 + 4 + 2);
  LagrangianAdapter adapter(spec);
  GraphStore store(Seeding::kCloseCenter, 1, {});
  FrameState state{store.get(plate.mesh).get(), &plate.mesh, frames[0], frames[1], frames[2], {}};
  const auto noise = 1e-3 * torch::randn({n, 2});
  const Batch b = adapter.make_batch({state}, {noise});
  const auto target = adapter.target(b, frames[2], 1.0);
  // The target is a velocity: x_{t+1} - (x_t + noise) on solved nodes.
  EXPECT_TRUE(torch::allclose(target, frames[2] - b.cur, 1e-6, 1e-7));
  EXPECT_TRUE(torch::allclose(adapter.integrate(b, target, frames[2]), frames[2], 1e-6, 1e-7));
  // Inputs: [velocity, one-hot (4), motion (2)].
  const auto motion = b.inputs.slice(1, 6, 8);
  int64_t prescribed = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (b.mask[i].item<bool>()) {
      EXPECT_EQ(motion[i].abs().sum().item<double>(), 0.0) << i;
    } else {
      EXPECT_TRUE(torch::allclose(motion[i], frames[2][i] - frames[1][i])) << i;
      ++prescribed;
    }
  }
  EXPECT_GT(prescribed, 0);
  // Without the next frame the kinematic input cannot be formed: a logic error, not garbage.
  FrameState blind{store.get(plate.mesh).get(), &plate.mesh, frames[0], frames[1], {}, {}};
  EXPECT_THROW(adapter.make_batch({blind}), std::logic_error);
  // Round trip of the resolved features, and a file missing a key is refused by name.
  const LagrangianSpec back = lagrangian_spec_from_json(to_json(spec), "features.json");
  EXPECT_TRUE(back.first_order);
  EXPECT_TRUE(back.kinematic_input);
  const LagrangianSpec plain_back = lagrangian_spec_from_json(to_json(LagrangianSpec{}), "f.json");
  EXPECT_FALSE(plain_back.first_order);
  EXPECT_FALSE(plain_back.kinematic_input);
  Json missing = to_json(spec);
  missing.erase("output");
  try {
    lagrangian_spec_from_json(missing, "features.json");
    ADD_FAILURE() << "a features file without 'output' was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("output"), std::string::npos) << e.what();
  }
}

TEST(History, WidensTheInputAndRoundTrips) {
  LagrangianSpec spec;
  const int one = spec.input_size();
  spec.history = 4;
  EXPECT_EQ(spec.input_size(), one + 3 * spec.dim);
  const LagrangianSpec back = lagrangian_spec_from_json(to_json(spec), "features.json");
  EXPECT_EQ(back.history, 4);
  // The default reads back as one velocity; a bad value names the key.
  EXPECT_EQ(lagrangian_spec_from_json(to_json(LagrangianSpec{}), "f.json").history, 1);
  Json bad = to_json(spec);
  bad["history"] = 0;
  try {
    lagrangian_spec_from_json(bad, "f.json");
    ADD_FAILURE() << "history 0 was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("history"), std::string::npos) << e.what();
  }
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

// A batch of `groups` free groups of random nodes plus `bound` nodes outside any group.
Batch random_groups(int dim, int groups, int per_group, int bound, uint64_t seed) {
  torch::manual_seed(seed);
  const int64_t n = groups * per_group + bound;
  Batch b;
  b.cur = torch::rand({n, dim}, torch::kFloat64);
  b.mass = torch::rand({n}, torch::kFloat32) + 0.1;
  std::vector<int64_t> group(n, -1);
  for (int64_t i = 0; i < groups * per_group; ++i) group[i] = i / per_group;
  b.group = torch::tensor(group, torch::kInt64);
  b.num_groups = groups;
  return b;
}

// Linear and angular momentum rate of each group, brute force in double precision.
void expect_conserving(const Batch& b, const torch::Tensor& a, double tol) {
  const int dim = static_cast<int>(a.size(1));
  const auto x = b.cur.to(torch::kFloat64), m = b.mass.to(torch::kFloat64);
  const auto acc = a.to(torch::kFloat64);
  for (int64_t g = 0; g < b.num_groups; ++g) {
    const auto in = b.group == g;
    const auto mg = m.index({in}).unsqueeze(1), xg = x.index({in}), ag = acc.index({in});
    const auto centre = (mg * xg).sum(0) / mg.sum();
    const auto r = xg - centre;
    const double scale = (mg * ag.abs()).sum().item<double>();
    EXPECT_LT((mg * ag).sum(0).abs().max().item<double>(), tol * scale) << "group " << g;
    torch::Tensor torque;
    if (dim == 2) {
      torque =
          (mg.squeeze(1) * (r.select(1, 0) * ag.select(1, 1) - r.select(1, 1) * ag.select(1, 0)))
              .sum();
    } else {
      torque = (mg * torch::cross(r, ag, 1)).sum(0);
    }
    EXPECT_LT(torque.abs().max().item<double>(), tol * scale) << "group " << g;
  }
}

TEST(MomentumProjection, RemovesLinearAndAngularOnFreeGroupsOnly) {
  for (int dim : {2, 3}) {
    for (uint64_t seed = 0; seed < 20; ++seed) {
      SCOPED_TRACE("dim " + std::to_string(dim) + " seed " + std::to_string(seed));
      const Batch b = random_groups(dim, 3, 4 + static_cast<int>(seed % 5), 5, seed);
      const auto a = torch::randn({b.cur.size(0), dim}, torch::kFloat64);
      const auto p = project_momentum(b, a);
      expect_conserving(b, p, 1e-10);
      // Nodes outside the groups keep their acceleration.
      const auto outside = b.group < 0;
      EXPECT_TRUE(torch::equal(p.index({outside}), a.index({outside})));
      // A projection: idempotent, and orthogonal in the mass-weighted inner product (it removes
      // the least mass-weighted acceleration that breaks conservation).
      EXPECT_LT((project_momentum(b, p) - p).abs().max().item<double>(), 1e-12);
      const auto m = b.mass.to(torch::kFloat64).unsqueeze(1);
      EXPECT_LT(std::abs((m * (a - p) * p).sum().item<double>()), 1e-10);
      // A rigid motion's acceleration (uniform plus rotation) is removed entirely.
      auto rigid = torch::randn({1, dim}, torch::kFloat64).expand({b.cur.size(0), dim}).clone();
      if (dim == 2) {
        rigid += 0.7 * torch::stack({-b.cur.select(1, 1), b.cur.select(1, 0)}, 1);
      } else {
        const auto w = torch::randn({1, 3}, torch::kFloat64).expand({b.cur.size(0), 3});
        rigid += torch::cross(w, b.cur, 1);
      }
      const auto in = b.group >= 0;
      EXPECT_LT(project_momentum(b, rigid).index({in}).abs().max().item<double>(), 1e-12);
    }
  }
  // Degenerate groups stay finite: one node (2-D and 3-D), and 3-D nodes on a line.
  for (int dim : {2, 3}) {
    Batch one = random_groups(dim, 1, 1, 0, 5);
    const auto a = torch::randn({1, dim}, torch::kFloat64);
    EXPECT_LT(project_momentum(one, a).abs().max().item<double>(), 1e-12);  // nothing is free
  }
  Batch line = random_groups(3, 1, 4, 0, 6);
  line.cur = torch::linspace(0, 1, 4, torch::kFloat64).unsqueeze(1).expand({4, 3}).clone();
  EXPECT_TRUE(torch::isfinite(project_momentum(line, torch::randn({4, 3}, torch::kFloat64)))
                  .all()
                  .item<bool>());
  // Without groups the projection is the identity.
  Batch none;
  const auto a = torch::randn({4, 2});
  EXPECT_TRUE(torch::equal(project_momentum(none, a), a));
}

// Without gradients (rollouts, validation) the projection runs as loops over the nodes with
// double sums: the values of the differentiable tensor version the training loss uses, evaluated
// in float64 (float32 inputs: up to their rounding), with partial conservation, nodes outside every
// group and degenerate 3-D groups (two nodes, nodes on a line).
TEST(MomentumProjection, WithoutGradientsMatchesTheDifferentiableVersion) {
  for (int dim : {2, 3}) {
    for (uint64_t seed = 0; seed < 8; ++seed) {
      SCOPED_TRACE("dim " + std::to_string(dim) + " seed " + std::to_string(seed));
      Batch b = random_groups(dim, 4, 1 + static_cast<int>(seed % 6), 3, 300 + seed);
      if (seed % 2 == 1) {
        auto kept = torch::ones({4, dim + 1}, torch::kFloat32);
        kept[1][dim] = 0;
        kept[2][0] = 0;
        kept[3].zero_();
        b.conserved = kept;
      }
      if (dim == 3 && seed == 4)  // group 0's nodes on a line: a singular inertia tensor
        b.cur.slice(0, 0, 5).copy_(
            torch::linspace(0, 1, 5, torch::kFloat64).unsqueeze(1).expand({5, 3}));
      Batch bodies = b;
      bodies.body = b.group;
      bodies.num_bodies = b.num_groups;
      const auto a = torch::randn({b.cur.size(0), dim}, torch::kFloat64);
      const auto projected = project_momentum(b, a);
      const auto rigid = rigid_part(bodies, a);
      for (auto dtype : {torch::kFloat64, torch::kFloat32}) {
        const auto input = a.to(dtype);
        torch::NoGradGuard no_grad;
        const auto without = project_momentum(b, input);
        EXPECT_EQ(without.scalar_type(), dtype);
        const double tol = dtype == torch::kFloat64 ? 1e-12 : 2e-6;
        const double scale = 1.0 + a.abs().max().item<double>();
        EXPECT_LT((without.to(torch::kFloat64) - projected).abs().max().item<double>(),
                  tol * scale);
        EXPECT_LT(
            (rigid_part(bodies, input).to(torch::kFloat64) - rigid).abs().max().item<double>(),
            tol * scale);
      }
    }
  }
}

// The loss's rigid part: per body (nodes weighted equally), the orthogonal projection onto
// uniform motions plus rigid spins about the body's centroid.
TEST(RigidPart, IsTheOrthogonalProjectionOntoEachBodysRigidMotions) {
  for (int dim : {2, 3}) {
    for (uint64_t seed = 0; seed < 10; ++seed) {
      SCOPED_TRACE("dim " + std::to_string(dim) + " seed " + std::to_string(seed));
      Batch b = random_groups(dim, 3, 4 + static_cast<int>(seed % 4), 3, seed);
      b.body = b.group;
      b.num_bodies = b.num_groups;
      b.num_groups = 0;  // no momentum groups: only bodies
      const int64_t n = b.cur.size(0);
      const auto in = b.body >= 0;
      const auto v = torch::randn({n, dim}, torch::kFloat64);
      const auto r = rigid_part(b, v);
      // Zero off the bodies; idempotent; orthogonal with equal weights.
      EXPECT_EQ(r.index({~in}).abs().max().item<double>(), 0.0);
      EXPECT_LT((rigid_part(b, r) - r).abs().max().item<double>(), 1e-12);
      EXPECT_LT(std::abs(((v - r) * r).index({in}).sum().item<double>()), 1e-10);
      // What is left has no mean and no torque on any body (equal weights).
      Batch unit = b;
      unit.group = b.body;
      unit.num_groups = b.num_bodies;
      unit.mass = torch::ones({n}, torch::kFloat32);
      expect_conserving(unit, v - r, 1e-10);
      // A rigid motion of every body is its own rigid part.
      auto rigid = torch::randn({1, dim}, torch::kFloat64).expand({n, dim}).clone();
      if (dim == 2) {
        rigid += 0.7 * torch::stack({-b.cur.select(1, 1), b.cur.select(1, 0)}, 1);
      } else {
        const auto w = torch::randn({1, 3}, torch::kFloat64).expand({n, 3});
        rigid += torch::cross(w, b.cur, 1);
      }
      EXPECT_LT((rigid_part(b, rigid) - rigid).index({in}).abs().max().item<double>(), 1e-12);
    }
  }
  Batch none;
  EXPECT_EQ(rigid_part(none, torch::ones({3, 2})).abs().max().item<double>(), 0.0);
}

// Groups at slip walls keep only some momenta: the projection removes exactly those and is still
// the mass-weighted orthogonal projection.
TEST(MomentumProjection, KeepsOnlyTheMomentaEachGroupConserves) {
  for (int dim : {2, 3}) {
    for (uint64_t seed = 0; seed < 10; ++seed) {
      SCOPED_TRACE("dim " + std::to_string(dim) + " seed " + std::to_string(seed));
      Batch b = random_groups(dim, 4, 5, 3, 100 + seed);
      // Group 0 keeps everything, 1 the linear momentum along axis 0 only, 2 along all axes
      // but axis dim - 1, 3 nothing (a corner).
      auto kept = torch::zeros({4, dim + 1}, torch::kFloat32);
      kept[0].fill_(1);
      kept[1][0] = 1;
      kept[2].slice(0, 0, dim - 1).fill_(1);
      b.conserved = kept;
      const auto a = torch::randn({b.cur.size(0), dim}, torch::kFloat64);
      const auto p = project_momentum(b, a);
      const auto m = b.mass.to(torch::kFloat64).unsqueeze(1);
      for (int64_t g = 0; g < 4; ++g) {
        const auto in = b.group == g;
        const auto mg = m.index({in});
        const auto before = (mg * a.index({in})).sum(0) / mg.sum();
        const auto after = (mg * p.index({in})).sum(0) / mg.sum();
        for (int k = 0; k < dim; ++k) {
          if (kept[g][k].item<float>() > 0)
            EXPECT_LT(std::abs(after[k].item<double>()), 1e-12) << "group " << g << " axis " << k;
          else
            EXPECT_NEAR(after[k].item<double>(), before[k].item<double>(), 1e-12)
                << "group " << g << " axis " << k;
        }
        // Only the linear part leaves a group that does not keep its angular momentum: what
        // changed is uniform over the group.
        if (g > 0) {
          const auto change = (a - p).index({in});
          EXPECT_LT((change - change[0]).abs().max().item<double>(), 1e-12) << "group " << g;
        }
      }
      EXPECT_TRUE(torch::equal(p.index({b.group == 3}), a.index({b.group == 3})));
      EXPECT_TRUE(torch::equal(p.index({b.group < 0}), a.index({b.group < 0})));
      // Group 0 conserves both momenta, as without `conserved`.
      Batch all = b;
      all.conserved = torch::Tensor();
      const auto full = project_momentum(all, a);
      EXPECT_LT((p - full).index({b.group == 0}).abs().max().item<double>(), 1e-12);
      EXPECT_LT((project_momentum(b, p) - p).abs().max().item<double>(), 1e-12);  // idempotent
      EXPECT_LT(std::abs((m * (a - p) * p).sum().item<double>()), 1e-10);         // orthogonal
    }
  }
}

// Three bodies of 2 x 2 nodes (squares of side 0.05) in a walled unit box.
TrajectoryMesh three_squares() {
  TrajectoryMesh m;
  m.dim = 2;
  m.cell_size = 3;
  for (int b = 0; b < 3; ++b) {
    for (int k = 0; k < 4; ++k) {
      m.mesh_pos.push_back(0.05f * static_cast<float>(k % 2));
      m.mesh_pos.push_back(0.05f * static_cast<float>(k / 2));
      m.node_type.push_back(0);
      m.body_id.push_back(b);
    }
    const int o = 4 * b;
    m.cells.insert(m.cells.end(), {o, o + 1, o + 3, o, o + 3, o + 2});
  }
  return m;
}

torch::Tensor placed(const TrajectoryMesh& m, const std::vector<std::pair<double, double>>& at) {
  auto x = torch::tensor(m.mesh_pos).reshape({-1, 2}).to(torch::kFloat64);
  for (int b = 0; b < 3; ++b) {
    x.slice(0, 4 * b, 4 * b + 4).select(1, 0).add_(at[b].first);
    x.slice(0, 4 * b, 4 * b + 4).select(1, 1).add_(at[b].second);
  }
  return x.to(torch::kFloat32);
}

TEST(MomentumGroups, BodiesInRangeJoinWallsAndKinematicNodesRelease) {
  const auto scene = testing::typed_scene(R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.04},
      "boundaries": [{"group": "left", "type": "slip"}, {"group": "right", "type": "slip"},
                     {"group": "bottom", "type": "roller"}, {"group": "top", "type": "slip"}],
      "solver": {"end_time": 1.0}}})");
  LagrangianSpec spec;
  resolve_walls(spec, scene, 0.1);
  ASSERT_EQ(resolve_momentum(spec, scene, false), "");  // "free": groups near no wall only
  EXPECT_DOUBLE_EQ(spec.momentum_radius, 0.12);
  EXPECT_DOUBLE_EQ(spec.momentum_wall_range, 0.08);
  EXPECT_FALSE(spec.momentum_slip_walls);
  TrajectoryMesh mesh = three_squares();
  auto expect_keeps = [](const MomentumGroups& m, int64_t group, std::vector<float> kept) {
    ASSERT_GE(group, 0);
    ASSERT_LT(group, m.count);
    EXPECT_EQ(
        std::vector<float>(m.conserved.begin() + group * 3, m.conserved.begin() + group * 3 + 3),
        kept)
        << "group " << group;
  };
  // Bodies 0 and 1 are 0.10 apart (< 0.12): one group; body 2 is far: its own group.
  auto m = momentum_groups(spec, mesh, placed(mesh, {{0.3, 0.3}, {0.45, 0.3}, {0.3, 0.7}}));
  EXPECT_EQ(m.count, 2);
  EXPECT_EQ(m.conserved.size(), 6u);
  EXPECT_EQ(m.group[0], m.group[4]);
  EXPECT_NE(m.group[0], m.group[8]);
  for (int i = 0; i < 12; ++i) EXPECT_GE(m.group[i], 0);
  for (int64_t g = 0; g < m.count; ++g) expect_keeps(m, g, {1, 1, 1});
  // 0.13 apart: three groups.
  m = momentum_groups(spec, mesh, placed(mesh, {{0.3, 0.3}, {0.48, 0.3}, {0.3, 0.7}}));
  EXPECT_EQ(m.count, 3);
  // Body 2 within 0.08 of the top wall: released (the wall pushes it).
  m = momentum_groups(spec, mesh, placed(mesh, {{0.3, 0.3}, {0.48, 0.3}, {0.3, 0.88}}));
  EXPECT_EQ(m.count, 2);
  EXPECT_EQ(m.group[8], -1);
  // "auto" with slip and roller walls: body 2 keeps its momentum along the top wall (x) only;
  // bodies 0 and 1, joined and near the left wall (0.05 from it), keep theirs along y; body 2
  // in the top-left corner keeps none.
  ASSERT_EQ(resolve_momentum(spec, scene), "");
  EXPECT_TRUE(spec.momentum_slip_walls);
  m = momentum_groups(spec, mesh, placed(mesh, {{0.3, 0.3}, {0.48, 0.3}, {0.3, 0.88}}));
  EXPECT_EQ(m.count, 3);
  expect_keeps(m, m.group[0], {1, 1, 1});
  expect_keeps(m, m.group[8], {1, 0, 0});
  m = momentum_groups(spec, mesh, placed(mesh, {{0.05, 0.3}, {0.2, 0.3}, {0.02, 0.9}}));
  EXPECT_EQ(m.count, 1);
  EXPECT_EQ(m.group[0], m.group[4]);
  expect_keeps(m, m.group[0], {0, 1, 0});
  EXPECT_EQ(m.group[8], -1);
  // A fixed boundary anywhere: walls are not slip, a group near one is left out again.
  const auto fixed = testing::typed_scene(R"({"scene": {"dim": 2,
      "background": {"type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.04},
      "boundaries": [{"group": "left", "type": "slip"}, {"group": "top", "type": "fixed"}],
      "solver": {"end_time": 1.0}}})");
  LagrangianSpec sticky;
  resolve_walls(sticky, fixed, 0.1);
  ASSERT_EQ(resolve_momentum(sticky, fixed), "");
  EXPECT_FALSE(sticky.momentum_slip_walls);
  EXPECT_EQ(
      momentum_groups(sticky, mesh, placed(mesh, {{0.3, 0.3}, {0.48, 0.3}, {0.3, 0.88}})).group[8],
      -1);
  // A fixed node in body 1 releases body 1 and, once joined, body 0 with it.
  mesh.node_type[5] = static_cast<int32_t>(NodeType::kFixed);
  m = momentum_groups(spec, mesh, placed(mesh, {{0.3, 0.3}, {0.45, 0.3}, {0.3, 0.7}}));
  EXPECT_EQ(m.count, 1);
  EXPECT_EQ(m.group[0], -1);
  EXPECT_EQ(m.group[4], -1);
  EXPECT_EQ(m.group[8], 0);
  // Lumped masses share each triangle's area: 0.05^2 per body.
  const auto mass = lumped_masses(mesh);
  double total = 0;
  for (float v : mass) total += v;
  EXPECT_NEAR(total, 3 * 0.0025, 1e-7);
  EXPECT_NEAR(mass[0], 0.0025 / 3.0, 1e-7);  // corner in two triangles: 2 x area/3 / 2
}

// features.noise_rigid_scale: the training noise's rigid part on each body (what rigid_part
// finds) is scaled, its deformation part, the prescribed nodes' noise and the older velocities'
// columns are left as they were.
TEST(RigidNoise, ScalesOnlyEachBodysRigidPart) {
  TrajectoryMesh mesh = three_squares();
  mesh.node_type[5] = static_cast<int32_t>(NodeType::kFixed);  // body 1: one prescribed node
  const auto cur = placed(mesh, {{0.2, 0.2}, {0.5, 0.6}, {0.8, 0.3}});
  const FrameState state{nullptr, &mesh, cur, cur, {}, {}};
  const int64_t n = mesh.num_nodes();
  LagrangianSpec spec;
  const LagrangianAdapter adapter(spec);
  Batch b;  // the bodies as make_batch numbers them, for rigid_part
  b.cur = cur.to(torch::kFloat64);
  b.body = torch::tensor(std::vector<int64_t>(mesh.body_id.begin(), mesh.body_id.end()));
  b.body[5] = -1;
  b.num_bodies = 3;
  const auto predicted = (b.body >= 0).unsqueeze(1);
  // float32 noise of 2e-3: rounding ~1e-10 per value, so 2e-8 is ~1e-3 of the rigid part.
  for (uint64_t seed = 0; seed < 5; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    torch::manual_seed(seed);
    const auto noise = 2e-3 * torch::randn({n, 4}, torch::kFloat32);  // x_t's and one older
    EXPECT_TRUE(adapter.scale_rigid_noise(state, noise, 1.0).equal(noise));
    const auto x_t = noise.narrow(1, 0, 2).to(torch::kFloat64);
    const auto rigid = rigid_part(b, x_t);
    ASSERT_GT(rigid.abs().max().item<double>(), 1e-5);
    for (double scale : {0.0, 0.5}) {
      SCOPED_TRACE("scale " + std::to_string(scale));
      const auto out = adapter.scale_rigid_noise(state, noise, scale);
      ASSERT_EQ(out.sizes(), noise.sizes());
      const auto out_t = out.narrow(1, 0, 2).to(torch::kFloat64);
      // The rigid part scales; the deformation part stays.
      EXPECT_LT((rigid_part(b, out_t) - scale * rigid).abs().max().item<double>(), 2e-8);
      EXPECT_LT(((out_t - rigid_part(b, out_t)) - (x_t - rigid)).abs().max().item<double>(), 2e-8);
      // Off the bodies and in the older columns: unchanged.
      EXPECT_TRUE(out.narrow(1, 2, 2).equal(noise.narrow(1, 2, 2)));
      EXPECT_TRUE(out[5].equal(noise[5]));
      if (scale == 0.0) {  // no body keeps a mean
        for (int64_t body = 0; body < 3; ++body) {
          const auto mine = (b.body == body).unsqueeze(1).to(torch::kFloat64);
          EXPECT_LT((out_t * mine).sum(0).abs().max().item<double>(), 2e-8);
        }
      }
    }
  }
  EXPECT_EQ(predicted.sum().item<int64_t>(), n - 1);
}

TEST(MomentumAuto, OnlyForScenesWithoutExternalForces) {
  const std::string walls =
      R"("boundaries": [{"group": "left", "type": "fixed"}, {"group": "right", "type": "fixed"}])";
  // `scene`: a stored scene text.
  auto why = [&](const std::string& scene, bool with_walls = true) {
    LagrangianSpec s;
    if (with_walls) {
      s.wall_lo = {0.0, std::nan("")};
      s.wall_hi = {1.0, std::nan("")};
      s.wall_radius = 0.1;
    }
    return resolve_momentum(s, testing::typed_scene(scene));
  };
  // A family's base scene with these keys.
  auto base = [](const std::string& keys) {
    return R"({"scene": {"dim": 2, "solver": {"end_time": 1.0}, )" + keys + "}}";
  };
  const std::string box =
      R"("background": {"type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.04})";
  EXPECT_EQ(why(base(box + ", " + walls)), "");
  EXPECT_EQ(why(base(box + ", " + walls + R"(, "gravity": [0.0, 0.0])")), "");
  EXPECT_NE(why(base(box + ", " + walls + R"(, "gravity": [0.0, -9.81])")).find("gravity"),
            std::string::npos);
  // Gravity that is no list of numbers is refused where the scene is read, never taken for none.
  EXPECT_THROW(why(base(box + ", " + walls + R"(, "gravity": [0.0, [-9.81, -4.0]])")), InputError);
  EXPECT_NE(
      why(base(box + R"(, "boundaries": [{"point": [0, 0], "normal": [-1, 0], "type": "fixed"}])"))
          .find("boundary"),
      std::string::npos);
  EXPECT_NE(why(base(box + ", " + walls), false).find("wall"), std::string::npos);
  EXPECT_NE(why(base(R"("background": {"type": "mesh", "path": "m.msh"})")).find("box"),
            std::string::npos);
  EXPECT_NE(why("{}").find("box"), std::string::npos);  // public data: no scene
  // The shipped default scene family and the cantilever scene.
  const std::string root = std::string(BSMS_SOURCE_DIR) + "/configs/";
  auto file = [](const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(why(file(root + "families/disks2d.json")), "");
  EXPECT_NE(why(file(root + "scenes/cantilever.json")), "");
}

// The physics the projection relies on: in UMLS-MPM (FLIP) trajectories of the default scene,
// the true accelerations of free groups conserve linear momentum to float round-off, and angular
// momentum to a few per cent (FLIP is not exactly angular-momentum conserving); a group at one
// slip wall keeps its linear momentum along the wall to round-off while the wall changes it
// along the normal.
TEST(MomentumProjection, MpmDisksConserveMomentumOnFreeGroupsAndAlongSlipWalls) {
  const std::string family_file = std::string(BSMS_SOURCE_DIR) + "/configs/families/disks2d.json";
  const generate::FamilyConfig family = generate::load_family(family_file, {"frames=48"});
  std::ifstream in(family_file);
  const auto scene = testing::typed_scene(std::string(std::istreambuf_iterator<char>(in), {}));
  LagrangianSpec spec;
  resolve_walls(spec, scene, 0.1);
  ASSERT_EQ(resolve_momentum(spec, scene), "");
  ASSERT_TRUE(spec.momentum_slip_walls);
  double kept_linear = 0, off = 0, all = 0, normal = 0, at_walls = 0;
  int free_groups = 0, wall_groups = 0;
  for (int64_t index = 0; index < 6; ++index) {
    const Trajectory t =
        generate::generate_trajectory(family, 11, index, 6, "/tmp/bsms_momentum_unused");
    const int64_t n = t.mesh.num_nodes();
    const auto x = torch::tensor(t.fields.at("world_pos")).reshape({t.num_frames, n, 2});
    for (int64_t f = 1; f + 1 < t.num_frames; ++f) {
      Batch b;
      MomentumGroups found = momentum_groups(spec, t.mesh, x[f]);
      b.num_groups = found.count;
      if (b.num_groups == 0) continue;
      b.group = torch::tensor(found.group, torch::kInt64);
      b.mass = torch::tensor(lumped_masses(t.mesh));
      b.cur = x[f].to(torch::kFloat64);
      b.conserved = torch::from_blob(found.conserved.data(), {found.count, 3}).clone();
      const auto kept = b.conserved.to(torch::kFloat64);  // [G, 3]
      const auto walled = (kept.select(1, 2) == 0).to(torch::kFloat64).unsqueeze(1);
      free_groups += static_cast<int>(found.count - walled.sum().item<double>());
      wall_groups += static_cast<int>(walled.sum().item<double>());
      const auto a = (x[f + 1] - 2 * x[f] + x[f - 1]).to(torch::kFloat64);
      const auto m = (b.mass.to(torch::kFloat64) * (b.group >= 0)).unsqueeze(1);
      // The mass-weighted mean of each group along the axes it keeps, and along the others.
      const auto g = b.group.clamp_min(0);
      const auto mean = torch::zeros({b.num_groups, 2}, torch::kFloat64).index_add(0, g, m * a) /
                        torch::zeros({b.num_groups, 1}, torch::kFloat64).index_add(0, g, m);
      const auto axes = kept.slice(1, 0, 2);
      kept_linear += (m * (mean * axes).index_select(0, g).square()).sum().item<double>();
      normal += (m * (mean * (1 - axes)).index_select(0, g).square()).sum().item<double>();
      at_walls += (m * walled.index_select(0, g) * a.square()).sum().item<double>();
      off += (m * (a - project_momentum(b, a)).square()).sum().item<double>();
      all += (m * a.square()).sum().item<double>();
    }
  }
  ASSERT_GT(free_groups, 5);
  ASSERT_GT(wall_groups, 10);
  ASSERT_GT(all, 0);
  EXPECT_LT(std::sqrt(kept_linear / all), 1e-3);
  EXPECT_LT(std::sqrt(off / all), 0.02);
  // The walls' push is real: the normal part is a sizeable share of the wall groups' motion.
  EXPECT_GT(std::sqrt(normal / at_walls), 0.05);
}

}  // namespace
}  // namespace bsms
