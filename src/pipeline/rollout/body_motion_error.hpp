// Where a predicted frame's position error lies, body by body: in the body's centre (where it
// went), in its orientation about that centre (how it turned), or in its shape (how it deformed).
// On contact-rich scenes the direction in which bodies leave a collision is close to chaotic, and
// that error swamps RMSE-all; the deformation part is the one that measures the elastic physics.
//
// For each body (the nodes sharing a body_id) with errors e_i = p_i - q_i (predicted p, true q):
//   centre:      the body's mean error ē, counted once per node        n_b |ē|²
//   rotation:    what the best rotation R about the centre removes      Σ|p'_i - q'_i|² - D_b
//   deformation: what no rotation removes, D_b = min_R Σ|R p'_i - q'_i|²
// (p', q': positions about each body's centroid). The three parts are non-negative and sum to
// Σ|e_i|² exactly, so with every part divided by the number of values (nodes × components) they
// are mean squared errors that add up to the frame's position MSE. The minimum over rotations is
// in closed form: with H = Σ p'_i q'_iᵀ and its singular values s_1 ≥ … ≥ s_d,
// max_R tr(R H) = s_1 + … + s_{d-1} + sign(det H) s_d (Kabsch, reflections excluded).
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <vector>

namespace bsms {

struct BodyMotionError {
  double centre = 0.0, rotation = 0.0, deformation = 0.0;  // mean squared errors
  double total() const { return centre + rotation + deformation; }
  BodyMotionError& operator+=(const BodyMotionError& o) {
    centre += o.centre;
    rotation += o.rotation;
    deformation += o.deformation;
    return *this;
  }
};

// predicted, truth: [N, dim] positions of one frame (dim 1–3); body_id: [N] (empty: one body).
// Mean over the N × dim values, as the rollout's position MSE.
BodyMotionError body_motion_error(const torch::Tensor& predicted, const torch::Tensor& truth,
                                  const std::vector<int32_t>& body_id);

}  // namespace bsms
