// The Eulerian adapter (thesis Table 4.2; MeshGraphNets' CylinderFlow and Airfoil): fields live on
// a fixed mesh. Inputs per node: the state fields at t (velocity, and density when the data has
// it) and a one-hot node type; one edge set, the mesh edges, with mesh-space offsets X_ij, |X_ij|
// only. Outputs: the change of each state field to t+1 and, when the data has it, the pressure at
// t+1. The loss covers NORMAL and OUTFLOW nodes; in a rollout every other node (inflow, walls,
// the obstacle) keeps its ground truth.
#pragma once

#include <torch/types.h>

#include <string>
#include <vector>

#include "core/config.hpp"
#include "pipeline/adapters/adapter.hpp"
#include "pipeline/adapters/batch.hpp"
#include "pipeline/graphs/graph_store.hpp"

namespace bsms {

struct EulerianSpec {
  int dim = 2;                  // mesh dimension (velocity has dim components)
  int num_node_types = 9;       // MeshGraphNets' one-hot width
  double position_scale = 1.0;  // mesh positions are divided by it (mean mesh edge length)
  bool multilevel = true;       // false: level 0 only (MeshGraphNets)
  bool density = false;         // density is a state field (Airfoil)
  bool pressure = false;        // pressure is an output (Airfoil; CylinderFlow data has it too)

  int state_size() const { return dim + (density ? 1 : 0); }
  int input_size() const { return state_size() + num_node_types; }
  int output_size() const { return state_size() + (pressure ? 1 : 0); }
  // Dataset fields making up the state, in order, and their widths.
  std::vector<FieldInfo> state_fields() const;
};
Json to_json(const EulerianSpec& spec);
EulerianSpec eulerian_spec_from_json(const Json& json, const std::string& file);

// Whether a public node type is solved by the model (NORMAL 0, OUTFLOW 5).
bool is_eulerian_predicted_node(int32_t node_type);

// Frames [t0, t0 + count) of a trajectory's state fields, concatenated: [count, N, state_size].
torch::Tensor read_eulerian_state(const Dataset& data, const EulerianSpec& spec, int64_t trajectory,
                                  int64_t t0, int64_t count);
// Frames [t0, t0 + count) of the pressure: [count, N, 1]; undefined when spec.pressure is off.
torch::Tensor read_eulerian_pressure(const Dataset& data, const EulerianSpec& spec,
                                     int64_t trajectory, int64_t t0, int64_t count);

// One graph's fields at frame t.
struct EulerianFrame {
  const MeshGraphs* graphs = nullptr;
  const TrajectoryMesh* mesh = nullptr;
  torch::Tensor state;  // [N, state_size] float32
};

class EulerianAdapter : public DomainAdapter {
 public:
  explicit EulerianAdapter(EulerianSpec spec) : spec_(std::move(spec)) {}
  const EulerianSpec& spec() const { return spec_; }

  std::string kind() const override { return "eulerian"; }
  ModelShape model_shape() const override;
  Json spec_json() const override { return to_json(spec_); }
  // Predicting the fields at t+1 from those at t: noise (features.noise_std on the velocity,
  // density_noise_std on the density) on the NORMAL nodes' state, targets as target() makes them.
  TrainBatch make_train_batch(const SampleRequest& request) const override;

  // Batch.inputs = [state, one-hot], Batch.positions = {X / position_scale}, Batch.cur = the
  // state, Batch.mask = predicted nodes. With `noise_std` (one standard deviation per state
  // component) Gaussian noise is added to the state of NORMAL nodes (not OUTFLOW ones, which are
  // predicted too) and kept in Batch.noise,
  // drawn from `generators`: one per frame, or one for all frames.
  Batch make_batch(const std::vector<EulerianFrame>& frames,
                   const std::vector<double>& noise_std = {},
                   const std::vector<at::Generator*>& generators = {}) const;
  // [state change, pressure] targets for the batch from the next state [N, state_size] and the
  // next pressure [N, 1] (undefined without pressure). With noise n on the input, the target
  // change is next + (1 - gamma) n - (state + n): gamma 1 undoes the noise (MeshGraphNets).
  torch::Tensor target(const Batch& batch, const torch::Tensor& next_state,
                       const torch::Tensor& next_pressure, double noise_gamma = 1.0) const;
  // Next state: state + change on predicted nodes, `truth_state` elsewhere; pressure likewise
  // from the output and `truth_pressure` (undefined without pressure).
  std::pair<torch::Tensor, torch::Tensor> integrate(const Batch& batch, const torch::Tensor& output,
                                                    const torch::Tensor& truth_state,
                                                    const torch::Tensor& truth_pressure) const;

 private:
  EulerianSpec spec_;
};

}  // namespace bsms
