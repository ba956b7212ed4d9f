// The domain-adapter interface (docs/design.md, "Domain adapters and the rollout loop"): what
// turns a dataset of one physical domain into the learned simulator's batches and targets.
// Lagrangian (meshes that move: world positions) and Eulerian (fields on a fixed mesh) are its two
// peers, lagrangian.hpp and eulerian.hpp. The trainer, the rollout loop and the learned simulator
// see only this interface and Batch.
#pragma once

#include <ATen/core/Generator.h>
#include <torch/types.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "data/dataset/dataset.hpp"
#include "models/layers.hpp"
#include "pipeline/adapters/batch.hpp"
#include "pipeline/graphs/graph_store.hpp"
#include "pipeline/runs/train_config.hpp"

namespace bsms {

// What the graph model sees and returns, as an adapter defines it.
struct ModelShape {
  int input_size = 0;
  int output_size = 0;
  std::vector<int64_t> position_dims;                 // per position field
  std::vector<std::vector<int64_t>> edge_set_fields;  // per edge set: the position fields used
  std::vector<EdgeStretch> edge_set_stretch;          // per edge set (optional)
};

// One training sample: frame t of a trajectory (predicting t+1 from t and the frames before).
struct SampleRef {
  int64_t trajectory;
  int64_t frame;  // t
};

// One training or validation batch and its target.
struct TrainBatch {
  Batch batch;
  torch::Tensor target;
};

// The model's prediction for a batch (raw output), without gradient.
using Predictor = std::function<torch::Tensor(const Batch&)>;

// What a training or validation batch is made of: samples of `data`, the noise of refs[k] drawn
// from generators[k] (no noise without generators), and the model (`predictor`, may be null)
// for adapters that train on states the model itself reached (Lagrangian pushforward).
struct SampleRequest {
  const TrainConfig& config;
  const Dataset& data;
  GraphStore& store;
  const std::vector<SampleRef>& refs;
  std::vector<at::Generator>* generators = nullptr;
  const Predictor* predictor = nullptr;
};

class DomainAdapter {
 public:
  virtual ~DomainAdapter() = default;
  // "lagrangian" or "eulerian": the "kind" of a run's features_resolved.
  virtual std::string kind() const = 0;
  virtual ModelShape model_shape() const = 0;
  // The resolved features, as a run's config.json keeps them (features_resolved).
  virtual Json spec_json() const = 0;
  // The samples' batch and its target.
  virtual TrainBatch make_train_batch(const SampleRequest& request) const = 0;
};

}  // namespace bsms
