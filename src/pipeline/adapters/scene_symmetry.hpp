// The symmetries of a box scene (reflections and, where sides are equal, axis swaps about the
// box's centre), and their action on a model's state and predictions: `bsms rollout
// --symmetrize` averages a model's predictions over them (frame averaging), which makes the
// averaged predictor exactly equivariant to the scene's symmetries.
#pragma once

#include <torch/types.h>

#include <optional>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"

namespace bsms {

// A signed permutation of the axes about `centre`: axis i of the image takes axis source[i] of
// the original, times sign[i]: x'_i = centre_i + sign_i (x_{source_i} - centre_{source_i}).
struct BoxSymmetry {
  std::vector<int> source;
  std::vector<int> sign;
  std::vector<double> centre;

  int dim() const { return static_cast<int>(source.size()); }
  bool is_identity() const;
  // Positions [N, dim] mapped; vectors (velocities, accelerations) [N, dim] mapped and mapped back.
  torch::Tensor points(const torch::Tensor& x) const;
  torch::Tensor vectors(const torch::Tensor& v) const;
  torch::Tensor vectors_back(const torch::Tensor& v) const;
  // The mesh with its reference positions mapped (cells, node types and bodies kept; cell
  // orientation flips under a reflection, which nothing a model reads depends on).
  TrajectoryMesh mesh(const TrajectoryMesh& m) const;
};

// The symmetries of a dataset's scene (Dataset::parsed_scene; may be none) in `dim`
// dimensions: every signed axis permutation about the centre of its axis-aligned "box"
// background that maps the box onto itself (swapped axes have equal sides), each side onto a
// side with the same boundary type (or both without a boundary) and the gravity onto itself.
// Identity first. Only the identity when there is no such box of `dim` dimensions, the scene has
// a boundary that is not a side of it, or rotates it; `why` (optional) then says which.
std::vector<BoxSymmetry> scene_symmetries(const std::optional<mpm::Scene>& scene, int dim,
                                          std::string* why = nullptr);

}  // namespace bsms
