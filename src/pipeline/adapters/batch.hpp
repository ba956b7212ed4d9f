// What a domain adapter (adapter.hpp) hands the learned simulator: a block-diagonal batch of
// graphs with their node inputs, positions and multilevel edges, the nodes the loss covers, and
// the adapter's own constraints on the model's output. The simulator reads nothing else, so it
// knows no domain.
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <vector>

#include "pipeline/graphs/multilevel_tensors.hpp"

namespace bsms {

struct Batch;
// A map of the model's raw output [N, output_size] (or of its first motion channels) that the
// adapter attaches to a batch.
using BatchMap = torch::Tensor (*)(const Batch& batch, const torch::Tensor& output);

struct Batch {
  torch::Tensor inputs;                  // [N, input_size] raw (unnormalised) node features
  std::vector<torch::Tensor> positions;  // the position fields the edges are measured in
  torch::Tensor mask;                    // [N] bool: predicted nodes (the loss covers them)
  // [N, width] the state the inputs were made from (Lagrangian: positions at t and t-1, noise
  // added; Eulerian: the fields at t in `cur`)
  torch::Tensor cur, prev;
  // [N, width] how far cur is from the truth: the noise added to it, plus the drift of a
  // pushed-forward training sample (undefined without noise)
  torch::Tensor noise;
  MultilevelTensors graph;
  int64_t contact_edges = 0;  // level-0 contact edges found

  // The adapter's constraints (null: none). `project`: the raw output projected onto what the
  // physics allows (applied to predictions and, in the loss, to both prediction and target);
  // `rigid_part`: the rigid part of a motion [N, cur width] per body, for the loss's rigid
  // weight.
  BatchMap project = nullptr;
  BatchMap rigid_part = nullptr;

  // Lagrangian data for those constraints. Momentum groups: each node's group (-1: none; ids
  // unique in the batch), its lumped mass (reference cell volume / (dim + 1) per vertex; a
  // uniform density cancels in the projection), and which momenta each group keeps (undefined:
  // all of them).
  torch::Tensor group;      // [N] int64
  torch::Tensor mass;       // [N] float32
  torch::Tensor conserved;  // [num_groups, dim + 1] float32, 1 = kept
  int64_t num_groups = 0;
  // Each predicted node's body (mesh body_id, unique in the batch; -1: not predicted).
  torch::Tensor body;  // [N] int64
  int64_t num_bodies = 0;
};

}  // namespace bsms
