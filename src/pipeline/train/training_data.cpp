#include "pipeline/train/training_data.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "data/mpm/scene_config.hpp"
#include "models/layers.hpp"
#include "pipeline/adapters/lagrangian_training.hpp"
#include "pipeline/adapters/scene_features.hpp"

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
    auto frame = data.read(ref.trajectory, "world_pos", ref.frame, 1);
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

namespace {

// What every domain's features take from the training data.
struct DataFacts {
  bool eulerian = false;  // fields on a fixed mesh (velocity, no world_pos)
  bool public_layout = false;
  int mesh_dim = 0;
  int num_node_types = 0;
  double mean_edge = 0.0;       // mean mesh edge length of the first training mesh
  double position_scale = 1.0;  // the same, 1 when it is 0
  bool several_bodies = false;  // some training trajectory has more than one body
};

// Options that need Lagrangian data, refused on Eulerian data.
void check_eulerian_options(const TrainConfig& config, const Dataset& data) {
  if (config.features.pushforward > 0)
    throw InputError("features.pushforward: " + std::to_string(config.features.pushforward) +
                     " needs Lagrangian data (world_pos); " + data.location() +
                     " is Eulerian (velocity): set it to 0");
  if (config.features.history > 1)
    throw InputError("features.history: " + std::to_string(config.features.history) +
                     " needs Lagrangian data (world_pos); " + data.location() +
                     " is Eulerian (velocity): set it to 1");
  if (config.features.augment != "off")
    throw InputError("features.augment: \"" + config.features.augment +
                     "\" maps Lagrangian states (world_pos); " + data.location() +
                     " is Eulerian (velocity): set it to \"off\"");
}

DataFacts data_facts(const TrainConfig& config, const Dataset& data, GraphStore& probe) {
  DataFacts facts;
  if (!data.has_field("world_pos")) {
    if (!data.has_field("velocity"))
      throw InputError(data.location() +
                       ": needs the field world_pos (a Lagrangian model) or velocity (an "
                       "Eulerian model)");
    facts.eulerian = true;
    check_eulerian_options(config, data);
  }
  facts.public_layout = data.is_public_layout();
  facts.mesh_dim = data.mesh(0).dim;
  int max_type = 0;
  for (int64_t t = 0; t < data.num_trajectories(); ++t) {
    const auto& m = data.mesh(t);
    if (m.dim != facts.mesh_dim)
      throw InputError(data.location() + ": trajectory " + std::to_string(t) +
                       " has mesh dimension " + std::to_string(m.dim) + ", expected " +
                       std::to_string(facts.mesh_dim));
    if (data.num_frames(t) < 3)
      throw InputError(data.location() + ": trajectory " + std::to_string(t) +
                       " has fewer than 3 frames");
    for (int32_t v : m.node_type) max_type = std::max(max_type, v);
    std::set<int32_t> bodies(m.body_id.begin(), m.body_id.end());
    facts.several_bodies = facts.several_bodies || bodies.size() > 1;
  }
  const int asked = config.features.num_node_types;
  if (asked > 0 && asked <= max_type)
    throw InputError("features.num_node_types: " + std::to_string(asked) +
                     " one-hot classes, and " + data.location() + " has node types up to " +
                     std::to_string(max_type) + ": set it to at least " +
                     std::to_string(max_type + 1) + ", or \"auto\"");
  // Public data: MeshGraphNets' one-hot of width 9 (NORMAL 0 ... WALL_BOUNDARY 6).
  facts.num_node_types = asked > 0             ? asked
                         : facts.public_layout ? std::max(max_type + 1, 9)
                                               : std::max(max_type + 1, 4);
  facts.mean_edge = probe.get(data.mesh(0))->mean_edge_length;
  facts.position_scale = facts.mean_edge > 0 ? facts.mean_edge : 1.0;
  return facts;
}

int resolve_levels(const TrainConfig& config, const Dataset& data) {
  if (config.model.type == "mgn") return 1;
  const int levels = config.model.levels > 0 ? config.model.levels
                                             : auto_levels(data.mesh(0), config.model.seeding);
  const auto& blocks = config.model.mp_per_level_list;
  if (!blocks.empty() && static_cast<int>(blocks.size()) != levels)
    throw InputError("model.mp_per_level: lists " + std::to_string(blocks.size()) +
                     " block counts, expected one per level (" + std::to_string(levels) +
                     " levels" + (config.model.levels > 0 ? "" : ", from levels \"auto\"") + ")");
  return levels;
}

EulerianSpec resolve_eulerian(const TrainConfig& config, const Dataset& data,
                              const DataFacts& facts) {
  EulerianSpec e;
  e.dim = facts.mesh_dim;
  for (const auto& f : data.fields())
    if (f.name == "velocity" && f.width != facts.mesh_dim)
      throw InputError(data.location() + ": velocity has " + std::to_string(f.width) +
                       " components, the mesh " + std::to_string(facts.mesh_dim) + " dimensions");
  e.num_node_types = facts.num_node_types;
  e.position_scale = facts.position_scale;
  e.multilevel = config.model.type == "bsms";
  e.density = data.has_field("density");
  e.pressure = data.has_field("pressure");
  return e;
}

// The Lagrangian model's outputs and node inputs: first order, stress, kinematic and velocity
// inputs, history.
void resolve_lagrangian_io(const TrainConfig& config, const Dataset& data, LagrangianSpec& s) {
  s.first_order = config.features.output == "velocity";
  s.stress = config.features.stress == "auto" && data.has_field("stress");
  if (s.stress) {
    for (const auto& f : data.fields())
      if (f.name == "stress" && f.width != 1)
        throw InputError(data.location() + ": field stress has " + std::to_string(f.width) +
                         " components; a stress output needs one per node (von Mises), or set "
                         "features.stress to \"off\"");
  }
  s.kinematic_input = config.features.kinematic_input == "on" ||
                      (config.features.kinematic_input == "auto" && s.public_layout);
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
}

// Contact edges and the strain channel.
void resolve_lagrangian_edges(const TrainConfig& config, const Dataset& data,
                              const DataFacts& facts, GraphStore& probe, LagrangianSpec& s) {
  if (config.features.contact_radius < 0) {
    // Public data states the radius of its world edges (DeformingPlate's collision_radius).
    if (data.collision_radius() > 0)
      s.contact_radius = data.collision_radius();
    else if (facts.several_bodies)
      resolve_contact_radius(s, data.parsed_scene(), facts.mean_edge);
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
          data.location() + " has " + std::to_string(s.mesh_dim) + "-D mesh_pos and " +
          std::to_string(s.dim) + "-D world_pos: set features.strain to \"off\"");
    s.strain_scale = rms_strain(data, probe, config.seed);
  }
}

// Walls and momentum conservation: from the scene, momentum kept only where the training data
// holds it.
void resolve_lagrangian_walls(const TrainConfig& config, const Dataset& data, GraphStore& probe,
                              ResolvedModel& r) {
  LagrangianSpec& s = r.spec;
  // Walls: nodes see them from 4 mesh edges away (~2-4 frames of travel at the demo's speeds).
  if (config.features.walls == "auto")
    resolve_walls(s, data.parsed_scene(), 4.0 * s.position_scale);
  if (config.features.momentum == "off") return;
  r.momentum_note = resolve_momentum(s, data.parsed_scene(), config.features.momentum == "auto");
  if (!s.has_momentum()) return;
  const double residual = momentum_residual(data, probe, s, config.seed);
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

std::vector<BoxSymmetry> resolve_augment(const TrainConfig& config, const Dataset& data,
                                         const LagrangianSpec& s) {
  if (config.features.augment != "symmetries") return {};
  std::string why;
  std::vector<BoxSymmetry> augment = scene_symmetries(data.parsed_scene(), s.dim, &why);
  if (augment.size() < 2)
    throw InputError("features.augment: \"symmetries\" and " + data.location() + ": " + why +
                     ", so there is no symmetry to augment with: set it to \"off\"");
  if (s.mesh_dim != s.dim)
    throw InputError(
        "features.augment: \"symmetries\" maps mesh positions with the world's, "
        "and " +
        data.location() + " has " + std::to_string(s.mesh_dim) +
        "-dimensional mesh positions in a " + std::to_string(s.dim) +
        "-dimensional world: set it to \"off\"");
  return augment;
}

}  // namespace

ResolvedModel resolve_model(const TrainConfig& config, const Dataset& train_data) {
  ResolvedModel r;
  GraphStore probe(Seeding::kCloseCenter, 1, {});
  const DataFacts facts = data_facts(config, train_data, probe);
  r.levels = resolve_levels(config, train_data);
  if (facts.eulerian) {
    r.adapter = std::make_shared<EulerianAdapter>(resolve_eulerian(config, train_data, facts));
    return r;
  }
  LagrangianSpec& s = r.spec;
  s.dim = train_data.dim();
  s.mesh_dim = facts.mesh_dim;
  s.public_layout = facts.public_layout;
  s.multilevel = config.model.type == "bsms";
  s.num_node_types = facts.num_node_types;
  s.position_scale = facts.position_scale;
  resolve_lagrangian_io(config, train_data, s);
  resolve_lagrangian_edges(config, train_data, facts, probe, s);
  resolve_lagrangian_walls(config, train_data, probe, r);
  r.augment = resolve_augment(config, train_data, s);
  r.adapter = std::make_shared<LagrangianAdapter>(s, r.augment);
  return r;
}

TrainBatch make_train_batch(const ResolvedModel& r, const TrainConfig& config, const Dataset& data,
                            GraphStore& store, const std::vector<SampleRef>& refs,
                            std::vector<at::Generator>* generators, const Predictor* predictor) {
  if (generators != nullptr && generators->size() != refs.size())
    throw std::logic_error("make_train_batch: one generator per sample expected");
  return r.adapter->make_train_batch({config, data, store, refs, generators, predictor});
}

}  // namespace bsms
