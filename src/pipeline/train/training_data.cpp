#include "pipeline/train/training_data.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <set>
#include <stdexcept>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "models/layers.hpp"

namespace bsms {

SampleRef draw_sample(const Dataset& data, uint64_t seed, int64_t step, int slot) {
  const uint64_t h = splitmix64(seed * 0x100000001b3ull ^ splitmix64(step * 4096 + slot));
  const int64_t t = static_cast<int64_t>(h % static_cast<uint64_t>(data.num_trajectories()));
  const int64_t frames = data.num_frames(t);
  const int64_t f = 1 + static_cast<int64_t>(splitmix64(h) % static_cast<uint64_t>(frames - 2));
  return {t, f};
}

uint64_t noise_seed(uint64_t seed, int64_t step, int slot) {
  return splitmix64(splitmix64(seed ^ (0x1234567ull + static_cast<uint64_t>(step))) ^
                    static_cast<uint64_t>(slot));
}

namespace {

std::string position_field(const Dataset& data) {
  if (data.has_field("world_pos")) return "world_pos";
  throw InputError(data.location() + ": a Lagrangian model needs the field world_pos");
}

struct LoadedSample {
  FrameState state;
  torch::Tensor next;
  torch::Tensor truth;  // [before + 3, N, dim]: the true frames t-1-before .. t+1
  std::shared_ptr<const MeshGraphs> graphs;  // keeps state.graphs alive (the store may evict)
};

// Sample `ref` (frame t) with the state at frames t-1-before and t-before (the truth; before > 0
// for pushforward, which rolls it on to t) and the true next frame t+1; with `history` > 1 also
// the history - 1 frames before t-1-before that the trajectory has (FrameState::older).
LoadedSample load_sample(const Dataset& data, GraphStore& store, const SampleRef& ref,
                         int64_t before = 0, int history = 1) {
  const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
  const int64_t n = mesh.num_nodes();
  const int dim = data.dim();
  const int64_t first = ref.frame - 1 - before;
  const int64_t extra = std::min<int64_t>(history - 1, first);
  auto frames = data.read(ref.trajectory, position_field(data), first - extra, extra + before + 3);
  const auto all =
      torch::from_blob(frames.data(), {extra + before + 3, n, dim}, torch::kFloat32).clone();
  LoadedSample s;
  s.truth = all.narrow(0, extra, before + 3);
  s.graphs = store.get(mesh);
  s.state.graphs = s.graphs.get();
  s.state.mesh = &mesh;
  s.state.prev = s.truth[0];
  s.state.cur = s.truth[1];
  s.state.next = s.truth[2];
  for (int64_t k = extra - 1; k >= 0; --k) s.state.older.push_back(all[k]);
  s.next = s.truth[before + 2];
  return s;
}

// Sample `ref` as the model reaches it: from the truth at frames t-1-u and t-u (u = min(unroll,
// t-1)), u steps of the predictor, with the truth on the nodes it does not predict.
LoadedSample pushed_forward_sample(const LagrangianAdapter& adapter, const Dataset& data,
                                   GraphStore& store, const SampleRef& ref, int unroll,
                                   const Predictor& predictor) {
  const int64_t u = std::min<int64_t>(unroll, ref.frame - 1);
  const int history = adapter.spec().history;
  LoadedSample s = load_sample(data, store, ref, u, history);
  const auto& x = s.truth;  // x[i] is frame t-1-u+i: x[u+1] is t
  for (int64_t i = 0; i < u; ++i) {
    const Batch b = adapter.make_batch({s.state});
    torch::Tensor predicted = adapter.integrate(b, predictor(b), x[i + 2]);
    if (!torch::isfinite(predicted).all().item<bool>())
      throw NumericalError("pushforward: the model's rollout of training trajectory " +
                           std::to_string(ref.trajectory) + " reached a non-finite position at " +
                           "frame " + std::to_string(ref.frame - u + i + 1) + " (sample frame " +
                           std::to_string(ref.frame) + ")");
    if (history > 1) {
      s.state.older.insert(s.state.older.begin(), s.state.prev);
      if (static_cast<int>(s.state.older.size()) > history - 1) s.state.older.pop_back();
    }
    s.state.prev = s.state.cur;
    s.state.cur = predicted;
    s.state.next = x[i + 3];
  }
  return s;
}

// RMS strain |x_ij| / |X_ij| - 1 over the mesh edges of up to 64 training frames (deterministic
// in the seed); 0 when the data does not deform (the strain channel is then left out).
double rms_strain(const Dataset& data, GraphStore& store, uint64_t seed) {
  double sum = 0;
  int64_t count = 0;
  for (int i = 0; i < 64; ++i) {
    const SampleRef ref = draw_sample(data, seed ^ 0x9e3779b97f4a7c15ull, -3, i);
    const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
    const auto graphs_owner = store.get(mesh);
    const MeshGraphs& graphs = *graphs_owner;
    const int64_t n = mesh.num_nodes();
    auto frame = data.read(ref.trajectory, position_field(data), ref.frame, 1);
    const auto x = torch::from_blob(frame.data(), {n, data.dim()}, torch::kFloat32);
    const auto X =
        torch::from_blob(const_cast<float*>(mesh.mesh_pos.data()), {n, mesh.dim}, torch::kFloat32);
    const auto& edges = graphs.hierarchy.edge_sets[0][0];
    if (edges.num_edges() == 0) continue;
    const auto strain = edge_features({X, x}, {}, edges, EdgeStretch{0, 1, 1.0});
    sum += strain.square().sum().item<double>();
    count += strain.size(0);
  }
  const double rms = count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  return rms > 1e-6 ? rms : 0.0;
}

// Momentum "auto" keeps conservation only when the data holds it to this relative residual.
constexpr double kMomentumTolerance = 0.05;

// Relative residual sqrt(sum m |a - P a|^2 / sum m |a|^2) of the true accelerations of the
// momentum groups (P = project_momentum; groups at slip walls included when the spec keeps their
// tangential momentum) over up to 64 training frames; NaN when no frame has a group.
double momentum_residual(const Dataset& data, GraphStore& store, const LagrangianSpec& spec,
                         uint64_t seed) {
  LagrangianAdapter adapter(spec);
  double off = 0, all = 0;
  for (int i = 0; i < 64; ++i) {
    const SampleRef ref = draw_sample(data, seed ^ 0x7f4a7c159e3779b9ull, -4, i);
    LoadedSample s = load_sample(data, store, ref);
    const Batch batch = adapter.make_batch({s.state});
    if (batch.num_groups == 0) continue;
    const auto a = adapter.target(batch, s.next).to(torch::kFloat64);
    const auto m = (batch.mass.to(torch::kFloat64) * (batch.group >= 0)).unsqueeze(1);
    off += (m * (a - project_momentum(batch, a)).square()).sum().item<double>();
    all += (m * a.square()).sum().item<double>();
  }
  return all > 0 ? std::sqrt(off / all) : std::nan("");
}

}  // namespace

ResolvedModel resolve_model(const TrainConfig& config, const Dataset& train_data) {
  ResolvedModel r;
  if (!train_data.has_field("world_pos")) {
    if (!train_data.has_field("velocity"))
      throw InputError(train_data.location() +
                       ": needs the field world_pos (a Lagrangian model) or velocity (an "
                       "Eulerian model)");
    r.eulerian = true;
    if (config.features.pushforward > 0)
      throw InputError("features.pushforward: " + std::to_string(config.features.pushforward) +
                       " needs Lagrangian data (world_pos); " + train_data.location() +
                       " is Eulerian (velocity): set it to 0");
    if (config.features.history > 1)
      throw InputError("features.history: " + std::to_string(config.features.history) +
                       " needs Lagrangian data (world_pos); " + train_data.location() +
                       " is Eulerian (velocity): set it to 1");
    if (config.features.augment != "off")
      throw InputError("features.augment: \"" + config.features.augment +
                       "\" maps Lagrangian states (world_pos); " + train_data.location() +
                       " is Eulerian (velocity): set it to \"off\"");
  }
  const bool public_layout = train_data.is_public_layout();
  const int mesh_dim = train_data.mesh(0).dim;
  int max_type = 0;
  bool several_bodies = false;
  for (int64_t t = 0; t < train_data.num_trajectories(); ++t) {
    const auto& m = train_data.mesh(t);
    if (m.dim != mesh_dim)
      throw InputError(train_data.location() + ": trajectory " + std::to_string(t) +
                       " has mesh dimension " + std::to_string(m.dim) + ", expected " +
                       std::to_string(mesh_dim));
    if (train_data.num_frames(t) < 3)
      throw InputError(train_data.location() + ": trajectory " + std::to_string(t) +
                       " has fewer than 3 frames");
    for (int32_t v : m.node_type) max_type = std::max(max_type, v);
    std::set<int32_t> bodies(m.body_id.begin(), m.body_id.end());
    several_bodies = several_bodies || bodies.size() > 1;
  }
  if (config.features.num_node_types > 0 && config.features.num_node_types <= max_type)
    throw InputError("features.num_node_types: " + std::to_string(config.features.num_node_types) +
                     " one-hot classes, and " + train_data.location() + " has node types up to " +
                     std::to_string(max_type) + ": set it to at least " +
                     std::to_string(max_type + 1) + ", or 0 (auto)");
  // Public data: MeshGraphNets' one-hot of width 9 (NORMAL 0 ... WALL_BOUNDARY 6).
  const int num_node_types = config.features.num_node_types > 0 ? config.features.num_node_types
                             : public_layout                    ? std::max(max_type + 1, 9)
                                                                : std::max(max_type + 1, 4);
  // Position scale: mean mesh edge length of the first training mesh.
  GraphStore probe(Seeding::kCloseCenter, 1, {});
  const double edge = probe.get(train_data.mesh(0))->mean_edge_length;
  if (config.model.type == "mgn") {
    r.levels = 1;
  } else {
    r.levels = config.model.levels > 0 ? config.model.levels
                                       : auto_levels(train_data.mesh(0), config.model.seeding);
    const auto& blocks = config.model.level_blocks;
    if (!blocks.empty() && static_cast<int>(blocks.size()) != r.levels)
      throw InputError("model.mp_per_level: lists " + std::to_string(blocks.size()) +
                       " block counts, expected one per level (" + std::to_string(r.levels) +
                       " levels" + (config.model.levels > 0 ? "" : ", from levels \"auto\"") + ")");
  }
  if (r.eulerian) {
    EulerianSpec& e = r.eulerian_spec;
    e.dim = mesh_dim;
    const auto fields = train_data.fields();
    for (const auto& f : fields)
      if (f.name == "velocity" && f.width != mesh_dim)
        throw InputError(train_data.location() + ": velocity has " + std::to_string(f.width) +
                         " components, the mesh " + std::to_string(mesh_dim) + " dimensions");
    e.num_node_types = num_node_types;
    e.position_scale = edge > 0 ? edge : 1.0;
    e.multilevel = config.model.type == "bsms";
    e.density = train_data.has_field("density");
    e.pressure = train_data.has_field("pressure");
    return r;
  }
  LagrangianSpec& s = r.spec;
  s.dim = train_data.dim();
  s.mesh_dim = mesh_dim;
  s.public_layout = public_layout;
  s.multilevel = config.model.type == "bsms";
  s.num_node_types = num_node_types;
  s.position_scale = edge > 0 ? edge : 1.0;
  s.first_order = config.features.output == "velocity";
  s.stress = config.features.stress == "auto" && train_data.has_field("stress");
  if (s.stress) {
    for (const auto& f : train_data.fields())
      if (f.name == "stress" && f.width != 1)
        throw InputError(train_data.location() + ": field stress has " + std::to_string(f.width) +
                         " components; a stress output needs one per node (von Mises), or set "
                         "features.stress to \"off\"");
  }
  s.kinematic_input = config.features.kinematic_input == "on" ||
                      (config.features.kinematic_input == "auto" && public_layout);
  s.velocity_input = config.features.velocity_input == "on" ||
                     (config.features.velocity_input == "auto" && !s.first_order);
  if (config.features.history > 1 && !s.velocity_input)
    throw InputError("features.history: " + std::to_string(config.features.history) +
                     " needs the velocity input, which is off here (features.velocity_input, or "
                     "output velocity): set history to 1");
  if (config.features.history_noise == "walk" && config.features.history == 1)
    throw InputError(
        "features.history_noise: \"walk\" puts noise on the velocities before x_t - x_{t-1}, "
        "and features.history is 1 (none): set history > 1 or history_noise \"off\"");
  s.history = config.features.history;
  if (config.features.contact_radius < 0) {
    // Public data states the radius of its world edges (DeformingPlate's collision_radius).
    if (train_data.collision_radius() > 0)
      s.contact_radius = train_data.collision_radius();
    else if (several_bodies)
      resolve_contact_radius(s, train_data.scene(), edge);
  } else {
    s.contact_radius = config.features.contact_radius;
  }
  if (config.features.strain == "auto") {
    // The strain channel compares the lengths of an edge in mesh_pos and world_pos, in one
    // space: cloth (2-D mesh_pos, 3-D world_pos) has none to offer it.
    if (s.mesh_dim != s.dim)
      throw InputError(
          "features.strain: \"auto\" (the default) adds the strain channel, which "
          "needs mesh_pos and world_pos of one dimension; " +
          train_data.location() + " has " + std::to_string(s.mesh_dim) + "-D mesh_pos and " +
          std::to_string(s.dim) + "-D world_pos: set features.strain to \"off\"");
    s.strain_scale = rms_strain(train_data, probe, config.seed);
  }
  // Walls: nodes see them from 4 mesh edges away (~2-4 frames of travel at the demo's speeds).
  if (config.features.walls == "auto") resolve_walls(s, train_data.scene(), 4.0 * s.position_scale);
  if (config.features.momentum != "off") {
    r.momentum_note = resolve_momentum(s, train_data.scene(), config.features.momentum == "auto");
    if (s.has_momentum()) {
      const double residual = momentum_residual(train_data, probe, s, config.seed);
      if (!(residual <= kMomentumTolerance)) {
        r.momentum_note = std::isnan(residual)
                              ? std::string("the training data has no momentum group")
                              : "the training data's momentum groups do not conserve it (" +
                                    std::to_string(100.0 * residual) + " % residual)";
        s.momentum_radius = s.momentum_wall_range = 0.0;
        s.momentum_slip_walls = false;
      } else {
        r.momentum_residual = residual;
      }
    }
  }
  if (config.features.augment == "symmetries") {
    std::string why;
    r.augment = scene_symmetries(train_data.scene(), s.dim, &why);
    if (r.augment.size() < 2)
      throw InputError("features.augment: \"symmetries\" and " + train_data.location() + ": " +
                       why + ", so there is no symmetry to augment with: set it to \"off\"");
    if (s.mesh_dim != s.dim)
      throw InputError(
          "features.augment: \"symmetries\" maps mesh positions with the world's, "
          "and " +
          train_data.location() + " has " + std::to_string(s.mesh_dim) +
          "-dimensional mesh positions in a " + std::to_string(s.dim) +
          "-dimensional world: set it to \"off\"");
  }
  return r;
}

TrainBatch make_train_batch(const ResolvedModel& r, const TrainConfig& config, const Dataset& data,
                            GraphStore& store, const std::vector<SampleRef>& refs,
                            std::vector<at::Generator>* generators, const Predictor* predictor) {
  TrainBatch b;
  const bool noisy = generators != nullptr;
  if (noisy && generators->size() != refs.size())
    throw std::logic_error("make_train_batch: one generator per sample expected");
  if (r.eulerian) {
    const EulerianAdapter adapter(r.eulerian_spec);
    std::vector<EulerianFrame> frames;
    std::vector<torch::Tensor> nexts, pressures;
    std::vector<std::shared_ptr<const MeshGraphs>> owners;  // alive until the batch is made
    for (const SampleRef& ref : refs) {
      const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
      const auto state = read_eulerian_state(data, r.eulerian_spec, ref.trajectory, ref.frame, 2);
      owners.push_back(store.get(mesh));
      frames.push_back({owners.back().get(), &mesh, state[0]});
      nexts.push_back(state[1]);
      if (r.eulerian_spec.pressure)
        pressures.push_back(
            read_eulerian_pressure(data, r.eulerian_spec, ref.trajectory, ref.frame + 1, 1)[0]);
    }
    std::vector<double> noise;
    std::vector<at::Generator*> per_frame;
    if (noisy) {
      noise.assign(r.eulerian_spec.dim, config.features.noise_std);
      if (r.eulerian_spec.density) noise.push_back(config.features.density_noise_std);
      for (auto& g : *generators) per_frame.push_back(&g);
    }
    b.batch = adapter.make_batch(frames, noise, per_frame);
    b.target = adapter.target(b.batch, torch::cat(nexts, 0),
                              pressures.empty() ? torch::Tensor() : torch::cat(pressures, 0),
                              noisy ? config.features.noise_gamma : 1.0);
    return b;
  }
  const LagrangianAdapter adapter(r.spec);
  const int unroll = noisy && predictor ? config.features.pushforward : 0;
  // Columns of noise per coordinate: x_t's, and the older velocities' random walk (history_noise).
  const int64_t noise_width = config.features.history_noise == "walk" ? r.spec.history : 1;
  std::vector<FrameState> states;
  std::vector<torch::Tensor> nexts, noise, drifts, truth_prevs, truth_curs;
  std::deque<TrajectoryMesh> mapped_meshes;  // augmented samples' meshes (stable addresses)
  std::vector<std::shared_ptr<const MeshGraphs>> owners;  // alive until the batch is made
  for (size_t k = 0; k < refs.size(); ++k) {
    LoadedSample s = unroll > 0
                         ? pushed_forward_sample(adapter, data, store, refs[k], unroll, *predictor)
                         : load_sample(data, store, refs[k], 0, r.spec.history);
    // x_t's noise (and the older velocities' walk), drawn before the augmentation's symmetry
    torch::Tensor raw;
    if (noisy)
      raw = torch::randn({s.state.cur.size(0), s.state.cur.size(1) * noise_width}, (*generators)[k],
                         torch::kFloat32) *
            config.features.noise_std;
    if (noisy && !r.augment.empty()) {
      // One symmetry of the scene, uniform over the group (the identity included). The raw noise
      // is isotropic and independent per node, so it needs no map; its rigid part is taken on
      // the mapped state below.
      const auto pick = torch::randint(static_cast<int64_t>(r.augment.size()), {1},
                                       (*generators)[k], torch::kInt64)
                            .item<int64_t>();
      const BoxSymmetry& g = r.augment[static_cast<size_t>(pick)];
      if (!g.is_identity()) {
        mapped_meshes.push_back(g.mesh(*s.state.mesh));
        s.state.mesh = &mapped_meshes.back();
        if (unroll > 0)  // the truth is read again only by pushforward's drift and target
          s.truth = g.points(s.truth.reshape({-1, s.truth.size(-1)})).view(s.truth.sizes());
        s.state.prev = g.points(s.state.prev);
        s.state.cur = g.points(s.state.cur);
        s.state.next = g.points(s.state.next);
        for (auto& older : s.state.older) older = g.points(older);
        s.next = g.points(s.next);
      }
    }
    if (noisy)
      noise.push_back(adapter.scale_rigid_noise(s.state, raw, config.features.noise_rigid_scale));
    owners.push_back(s.graphs);
    states.push_back(s.state);
    nexts.push_back(s.next);
    if (unroll > 0) {  // the truth at t-1 and t, and how far the rollout drifted from it
      const int64_t frames = s.truth.size(0);
      truth_prevs.push_back(s.truth[frames - 3]);
      truth_curs.push_back(s.truth[frames - 2]);
      drifts.push_back(s.state.cur - truth_curs.back());
    }
  }
  b.batch = adapter.make_batch(states, noise);
  if (!drifts.empty() && config.features.pushforward_target == "acceleration") {
    // The frame's true (noise-corrected) target, as if the state had not drifted: the target
    // formula applied to the truth plus the same noise.
    Batch truth = b.batch;
    truth.prev = torch::cat(truth_prevs, 0);
    truth.cur = torch::cat(truth_curs, 0) + b.batch.noise;
    b.target = adapter.target(truth, torch::cat(nexts, 0), config.features.noise_gamma);
  } else {
    if (!drifts.empty()) b.batch.noise = b.batch.noise + torch::cat(drifts, 0);
    b.target =
        adapter.target(b.batch, torch::cat(nexts, 0), noisy ? config.features.noise_gamma : 1.0);
  }
  if (r.spec.stress) {
    // The next frame's stress, a per-node scalar: the same under the augmentation's symmetries.
    std::vector<torch::Tensor> stresses;
    for (const SampleRef& ref : refs) {
      const int64_t n = data.mesh(ref.trajectory).num_nodes();
      auto values = data.read(ref.trajectory, "stress", ref.frame + 1, 1);
      stresses.push_back(torch::from_blob(values.data(), {n, 1}, torch::kFloat32).clone());
    }
    b.target = torch::cat({b.target, torch::cat(stresses, 0)}, 1);
  }
  return b;
}

}  // namespace bsms
