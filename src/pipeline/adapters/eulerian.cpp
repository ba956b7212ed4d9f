#include "pipeline/adapters/eulerian.hpp"

#include <torch/torch.h>

#include <stdexcept>

#include "core/error.hpp"

namespace bsms {

std::vector<FieldInfo> EulerianSpec::state_fields() const {
  std::vector<FieldInfo> fields = {{"velocity", dim}};
  if (density) fields.push_back({"density", 1});
  return fields;
}

Json to_json(const EulerianSpec& s) {
  return Json{{"kind", "eulerian"},
              {"dim", s.dim},
              {"num_node_types", s.num_node_types},
              {"position_scale", s.position_scale},
              {"multilevel", s.multilevel},
              {"density", s.density},
              {"pressure", s.pressure}};
}

EulerianSpec eulerian_spec_from_json(const Json& json, const std::string& file) {
  EulerianSpec s;
  JsonObjectReader r(json, {file, "features_resolved"});
  const std::string kind = r.get<std::string>("kind");
  require(kind == "eulerian", r.context("kind"), "\"eulerian\"");
  s.dim = r.get<int>("dim");
  require(s.dim >= 1 && s.dim <= 3, r.context("dim"), "1, 2 or 3");
  s.num_node_types = r.get<int>("num_node_types");
  require(s.num_node_types >= 1 && s.num_node_types <= 64, r.context("num_node_types"), "in 1..64");
  s.position_scale = r.get<double>("position_scale");
  require(s.position_scale > 0, r.context("position_scale"), "> 0");
  s.multilevel = r.get<bool>("multilevel");
  s.density = r.get<bool>("density");
  s.pressure = r.get<bool>("pressure");
  r.finish();
  return s;
}

torch::Tensor read_eulerian_state(const Dataset& data, const EulerianSpec& spec, int64_t trajectory,
                                  int64_t t0, int64_t count) {
  const int64_t n = data.mesh(trajectory).num_nodes();
  std::vector<torch::Tensor> parts;
  for (const FieldInfo& f : spec.state_fields()) {
    auto raw = data.read(trajectory, f.name, t0, count);
    if (static_cast<int64_t>(raw.size()) != count * n * f.width)
      throw InputError(data.location() + ": trajectory " + std::to_string(trajectory) +
                       ": field '" + f.name + "' is not [T, " + std::to_string(n) + ", " +
                       std::to_string(f.width) + "]");
    parts.push_back(torch::from_blob(raw.data(), {count, n, f.width}, torch::kFloat32).clone());
  }
  return torch::cat(parts, 2);
}

torch::Tensor read_eulerian_pressure(const Dataset& data, const EulerianSpec& spec,
                                     int64_t trajectory, int64_t t0, int64_t count) {
  if (!spec.pressure) return {};
  const int64_t n = data.mesh(trajectory).num_nodes();
  auto raw = data.read(trajectory, "pressure", t0, count);
  if (static_cast<int64_t>(raw.size()) != count * n)
    throw InputError(data.location() + ": trajectory " + std::to_string(trajectory) +
                     ": field 'pressure' is not [T, " + std::to_string(n) + ", 1]");
  return torch::from_blob(raw.data(), {count, n, 1}, torch::kFloat32).clone();
}

bool is_eulerian_predicted_node(int32_t node_type) {
  return node_type == 0 || node_type == 5;  // NORMAL, OUTFLOW
}

Batch EulerianAdapter::make_batch(const std::vector<EulerianFrame>& frames,
                                  const std::vector<double>& noise_std,
                                  const std::vector<at::Generator*>& generators) const {
  const int width = spec_.state_size();
  if (!noise_std.empty() && static_cast<int>(noise_std.size()) != width)
    throw std::logic_error("EulerianAdapter: one noise scale per state component expected");
  if (generators.size() > 1 && generators.size() != frames.size())
    throw std::logic_error("EulerianAdapter: one noise generator per frame, or one for all");
  Batch b;
  std::vector<torch::Tensor> inputs, mesh_pos, masks, states, noises;
  std::vector<const MultilevelTensors*> graphs;
  const auto scale = noise_std.empty()
                         ? torch::Tensor()
                         : torch::tensor(std::vector<float>(noise_std.begin(), noise_std.end()));
  for (size_t k = 0; k < frames.size(); ++k) {
    const EulerianFrame& f = frames[k];
    at::Generator* generator =
        generators.empty() ? nullptr : generators[generators.size() == 1 ? 0 : k];
    const TrajectoryMesh& mesh = *f.mesh;
    const int64_t n = mesh.num_nodes();
    if (f.state.size(0) != n || f.state.size(1) != width)
      throw std::logic_error("EulerianAdapter: state shape does not match the mesh");
    std::vector<uint8_t> predicted(n);
    for (int64_t i = 0; i < n; ++i) predicted[i] = is_eulerian_predicted_node(mesh.node_type[i]);
    const auto mask = torch::from_blob(predicted.data(), {n}, torch::kUInt8).to(torch::kBool);
    torch::Tensor state = f.state;
    if (scale.defined() && generator) {
      // Training noise on NORMAL nodes only, as MeshGraphNets' dataset.py and BSMS-GNN add it:
      // OUTFLOW nodes are predicted and in the loss but see their true state.
      std::vector<float> noisy(n);
      for (int64_t i = 0; i < n; ++i) noisy[i] = mesh.node_type[i] == 0 ? 1.0f : 0.0f;
      const auto noise_mask = torch::from_blob(noisy.data(), {n, 1}, torch::kFloat32);
      const auto added = torch::randn({n, width}, *generator, torch::kFloat32) * scale * noise_mask;
      state = state + added;
      noises.push_back(added);
    }
    const auto types =
        torch::from_blob(const_cast<int32_t*>(mesh.node_type.data()), {n}, torch::kInt32)
            .to(torch::kInt64)
            .clamp(0, spec_.num_node_types - 1);
    inputs.push_back(
        torch::cat({state, torch::one_hot(types, spec_.num_node_types).to(torch::kFloat32)}, 1));
    mesh_pos.push_back(
        torch::from_blob(const_cast<float*>(mesh.mesh_pos.data()), {n, mesh.dim}, torch::kFloat32) /
        spec_.position_scale);
    masks.push_back(mask);
    states.push_back(state);
    graphs.push_back(&f.graphs->hierarchy);
  }
  b.inputs = torch::cat(inputs, 0);
  b.positions = {torch::cat(mesh_pos, 0)};
  b.mask = torch::cat(masks, 0);
  b.cur = torch::cat(states, 0);
  if (!noises.empty()) b.noise = torch::cat(noises, 0);
  b.graph = graphs.size() == 1 ? *graphs[0] : merge_multilevel_tensors(graphs);
  return b;
}

torch::Tensor EulerianAdapter::target(const Batch& batch, const torch::Tensor& next_state,
                                      const torch::Tensor& next_pressure,
                                      double noise_gamma) const {
  auto goal = next_state;
  if (noise_gamma != 1.0 && batch.noise.defined()) goal = goal + (1.0 - noise_gamma) * batch.noise;
  auto change = goal - batch.cur;
  if (!spec_.pressure) return change;
  return torch::cat({change, next_pressure}, 1);
}

std::pair<torch::Tensor, torch::Tensor> EulerianAdapter::integrate(
    const Batch& batch, const torch::Tensor& output, const torch::Tensor& truth_state,
    const torch::Tensor& truth_pressure) const {
  const int width = spec_.state_size();
  const auto mask = batch.mask.unsqueeze(1);
  auto state = torch::where(mask, batch.cur + output.slice(1, 0, width), truth_state);
  torch::Tensor pressure;
  if (spec_.pressure)
    pressure = torch::where(mask, output.slice(1, width, width + 1), truth_pressure);
  return {state, pressure};
}

TrainBatch EulerianAdapter::make_train_batch(const SampleRequest& request) const {
  const TrainConfig& config = request.config;
  TrainBatch b;
  const bool noisy = request.generators != nullptr;
  std::vector<EulerianFrame> frames;
  std::vector<torch::Tensor> nexts, pressures;
  std::vector<std::shared_ptr<const MeshGraphs>> owners;  // alive until the batch is made
  for (const SampleRef& ref : request.refs) {
    const TrajectoryMesh& mesh = request.data.mesh(ref.trajectory);
    const auto state = read_eulerian_state(request.data, spec_, ref.trajectory, ref.frame, 2);
    owners.push_back(request.store.get(mesh));
    frames.push_back({owners.back().get(), &mesh, state[0]});
    nexts.push_back(state[1]);
    if (spec_.pressure)
      pressures.push_back(
          read_eulerian_pressure(request.data, spec_, ref.trajectory, ref.frame + 1, 1)[0]);
  }
  std::vector<double> noise;
  std::vector<at::Generator*> per_frame;
  if (noisy) {
    noise.assign(spec_.dim, config.features.noise_std);
    if (spec_.density) noise.push_back(config.features.density_noise_std);
    for (auto& g : *request.generators) per_frame.push_back(&g);
  }
  b.batch = make_batch(frames, noise, per_frame);
  b.target = target(b.batch, torch::cat(nexts, 0),
                    pressures.empty() ? torch::Tensor() : torch::cat(pressures, 0),
                    noisy ? config.features.noise_gamma : 1.0);
  return b;
}

ModelShape EulerianAdapter::model_shape() const {
  ModelShape s;
  s.input_size = spec_.input_size();
  s.output_size = spec_.output_size();
  s.position_dims = {spec_.dim};
  s.edge_set_fields = {{0}};
  return s;
}

}  // namespace bsms
