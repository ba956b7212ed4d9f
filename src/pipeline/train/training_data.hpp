// What bsms train takes from its data (trainer.cpp): the model the training data decides
// (kind, dimensions, node types, position scale, contact, walls, momentum, levels), the samples
// of a step (deterministic in seed, step and slot, so that a resumed or data-parallel run draws
// what one uninterrupted rank would) and their batch and target.
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
#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/scene_symmetry.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/graphs/graph_store.hpp"
#include "pipeline/runs/train_config.hpp"

namespace bsms {

// Deterministic in (seed, step, slot): a resumed run draws exactly the samples it would have.
// Data-parallel rank r of N draws slots r*b .. r*b+b-1 of the N*b of a step, so that N ranks of
// batch size b train on the samples (and noise: noise_seed) of one rank of batch size N*b.
SampleRef draw_sample(const Dataset& data, uint64_t seed, int64_t step, int slot);

// The training noise of slot `slot` of step `step`: one generator per sample.
uint64_t noise_seed(uint64_t seed, int64_t step, int slot);

// What the data decides: the kind of model, dimensions, node types, position scale, contact,
// walls, momentum conservation, levels.
struct ResolvedModel {
  LagrangianSpec spec;  // Lagrangian data: the resolved features (the adapter holds a copy)
  int levels = 1;
  std::string momentum_note;      // why momentum conservation is off ("" when on or not asked)
  double momentum_residual = -1;  // measured on the training data when on
  // features.augment "symmetries": the data's scene symmetries (identity first), one of which
  // maps each noisy training sample; empty when off.
  std::vector<BoxSymmetry> augment;

  // The domain's adapter for these features: what makes the training batches.
  std::shared_ptr<const DomainAdapter> adapter;

  Json spec_json() const { return adapter->spec_json(); }
  ModelShape shape() const { return adapter->model_shape(); }
};
// InputError when the training data cannot train a model (no world_pos or velocity field, mixed
// mesh dimensions, trajectories shorter than 3 frames) or cannot be augmented as asked (an
// Eulerian dataset, or a scene with no symmetry but the identity).
ResolvedModel resolve_model(const TrainConfig& config, const Dataset& train_data);

// Samples of a dataset -> a batch and its target, through the resolved adapter
// (DomainAdapter::make_train_batch). The noise of refs[k] is drawn from generators[k] (no noise
// without generators); `predictor` for pushforward (Lagrangian data).
TrainBatch make_train_batch(const ResolvedModel& r, const TrainConfig& config, const Dataset& data,
                            GraphStore& store, const std::vector<SampleRef>& refs,
                            std::vector<at::Generator>* generators,
                            const Predictor* predictor = nullptr);

}  // namespace bsms
