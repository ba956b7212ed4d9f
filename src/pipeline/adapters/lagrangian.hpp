// The Lagrangian adapter (adapter.hpp): turns dataset frames into model inputs and a prediction
// into the next state. Inputs per node: velocity x_t - x_{t-1}, a one-hot node type and, in a
// walled box, the clipped distances to the walls; positions:
// mesh X and world x (both divided by `position_scale`); edge sets: mesh edges (X and x offsets)
// plus, when strain_scale > 0, the edge strain |x_ij| / |X_ij| - 1 over strain_scale) and, when the
// scene has contact, contact edges (x offsets) carried to every level by A·Aᶜ·A. Contact edges
// join nodes of different bodies (or of one body, far apart in the reference configuration).
// Output: the acceleration x_{t+1} - 2 x_t + x_{t-1} (m per frame²), or with first_order the
// velocity x_{t+1} - x_t. Public MeshGraphNets data (cloth: 2-D mesh X, 3-D world x; the plate:
// an actuator whose next-step motion is an input) uses the same adapter.
#pragma once

#include <torch/types.h>

#include <string>
#include <utility>
#include <vector>

#include "core/config.hpp"
#include "pipeline/adapters/adapter.hpp"
#include "pipeline/adapters/batch.hpp"
#include "pipeline/adapters/scene_symmetry.hpp"
#include "pipeline/graphs/graph_store.hpp"

namespace bsms {

struct LagrangianSpec {
  int dim = 2;       // world positions x
  int mesh_dim = 0;  // mesh positions X (cloth: 2-D X, 3-D x); 0 = dim
  // Output x_{t+1} - x_t integrated at first order (MeshGraphNets' DeformingPlate) instead of
  // the acceleration x_{t+1} - 2 x_t + x_{t-1}.
  bool first_order = false;
  // One more output: the stress at t+1 (a per-node scalar; MeshGraphNets' DeformingPlate), after
  // the dim motion channels.
  bool stress = false;
  // Nodes that follow a prescribed path get their next-step motion x_{t+1} - x_t as dim more
  // inputs (0 on predicted nodes): an actuator's motion is known to the model, as in
  // MeshGraphNets. FrameState::next must then be set.
  bool kinematic_input = false;
  // The velocity x_t - x_{t-1} as an input on the nodes the model solves. Off: zero there (as
  // MeshGraphNets' DeformingPlate: a quasi-static body's state is its shape, and training noise
  // on a velocity far smaller than the noise only hides it); prescribed nodes keep theirs.
  bool velocity_input = true;
  // Velocities in the input: x_t - x_{t-1} and the history - 1 before it (FrameState::older).
  int history = 1;
  int num_node_types = 4;
  double position_scale = 1.0;  // m; positions are divided by it (mean mesh edge length)
  double contact_radius = 0.0;  // m; 0 = the model has no contact edge set
  // RMS strain of the training data's mesh edges: mesh edges get the strain channel divided by
  // it (0 = no strain channel: data that does not deform, or features.strain "off").
  double strain_scale = 0.0;
  bool public_layout = false;  // node-type codes of public MeshGraphNets data
  bool multilevel = true;      // false: level 0 only (MeshGraphNets)
  // Walls of the domain: per axis, the lower and upper wall coordinate (NaN: no wall on that
  // side). With wall_radius > 0 every node gets 2 x dim inputs: its distance to each wall
  // divided by wall_radius and clipped to [0, 1] (1 = far or no wall).
  std::vector<double> wall_lo, wall_hi;
  double wall_radius = 0.0;
  // Momentum of free groups (an MPM scene without body forces conserves it exactly): bodies
  // closer than momentum_radius (two kernel supports: they share grid nodes) form one group; a
  // group whose nodes are all predicted and farther than momentum_wall_range from every wall
  // keeps its linear and angular momentum, so the model's acceleration there is projected onto
  // the momentum-conserving subspace (project_momentum). 0 = off.
  double momentum_radius = 0.0;
  double momentum_wall_range = 0.0;
  // The walls are slip or roller (they push only along their normal): a group near walls of
  // some axes still keeps its linear momentum along the others (false: such a group is left
  // alone; features.momentum "free").
  bool momentum_slip_walls = false;

  bool has_walls() const { return wall_radius > 0 && static_cast<int>(wall_lo.size()) == dim; }
  int input_size() const {
    return history * dim + num_node_types + (has_walls() ? 2 * dim : 0) +
           (kinematic_input ? dim : 0);
  }
  int mesh_dimension() const { return mesh_dim > 0 ? mesh_dim : dim; }
  int output_size() const { return dim + (stress ? 1 : 0); }
  bool has_contact() const { return contact_radius > 0; }
  bool has_momentum() const { return momentum_radius > 0; }
};
Json to_json(const LagrangianSpec& spec);
LagrangianSpec lagrangian_spec_from_json(const Json& json, const std::string& file);

// Contact candidates: pairs closer than `radius` in `points` [N, dim] that the mesh does not join
// and that belong to different bodies or mesh components (public data has no body ids), or to one
// body but lie ≥ 4 radii apart in mesh_pos (self-contact). Both directions, sorted like
// radius_pairs.
EdgeList contact_pairs(const RowMatrixXd& points, const TrajectoryMesh& mesh, double radius,
                       const CsrGraph& mesh_graph);

// Nodes whose next position the model predicts (others follow their prescribed path).
bool is_predicted_node(int32_t node_type, bool public_layout);

// One graph's state at frame t.
struct FrameState {
  const MeshGraphs* graphs = nullptr;
  const TrajectoryMesh* mesh = nullptr;
  torch::Tensor prev;  // [N, dim] float32 world positions at t-1 (m)
  torch::Tensor cur;   // [N, dim] float32 world positions at t (m)
  // [N, dim] positions at t+1: read only on prescribed nodes, for spec.kinematic_input (the
  // truth in training, the prescribed path in a rollout).
  torch::Tensor next;
  // Positions before t-1 for spec.history > 1: older[0] at t-2, older[1] at t-3, ... Missing
  // ones (a trajectory's first frames) are filled at constant velocity.
  std::vector<torch::Tensor> older;
};

// The momentum groups of one state (see LagrangianSpec::momentum_radius). A group with a
// kinematic node is left out. A group farther than momentum_wall_range from every wall keeps its
// linear and angular momentum; with spec.momentum_slip_walls a group near the walls of some axes
// (not all) keeps its linear momentum along the other axes (a slip wall pushes along its normal
// only; the torque of its push is not zero, so the angular momentum is not kept); otherwise a
// group near a wall is left out.
struct MomentumGroups {
  std::vector<int64_t> group;    // [N] group index or -1
  int64_t count = 0;             // groups
  std::vector<float> conserved;  // [count, dim + 1]: linear along each axis, then angular; 1 = kept
};
MomentumGroups momentum_groups(const LagrangianSpec& spec, const TrajectoryMesh& mesh,
                               const torch::Tensor& x);
// Lumped node masses of a mesh: each simplex's reference volume shared equally by its vertices.
std::vector<float> lumped_masses(const TrajectoryMesh& mesh);

// `accel` [N, dim] with, on every group of the batch, the mass-weighted mean (linear momentum,
// along the axes the group keeps) and the rigid angular acceleration about the group's centre of
// mass (angular momentum, 2-D and 3-D, where kept) removed; other nodes unchanged. The
// mass-weighted orthogonal projection onto accelerations that keep those momenta.
// Differentiable; identity when the batch has no group.
torch::Tensor project_momentum(const Batch& batch, const torch::Tensor& accel);
// project_momentum on a model output's motion channels (the first dim); further channels
// (stress) as they are. The Batch::project of a batch with momentum groups.
torch::Tensor project_motion(const Batch& batch, const torch::Tensor& output);
// The rigid part of `v` [N, dim] on each body of the batch (Batch::body; nodes weighted equally,
// positions Batch::cur): per body, the mean of v plus the rigid rotation about the body's centroid
// that fits v best (2-D and 3-D), i.e. the orthogonal projection onto rigid motions. Zero on
// nodes of no body. What a rollout's centre and rotation errors (body_motion_error.hpp) are made
// of, step by step. Differentiable.
torch::Tensor rigid_part(const Batch& batch, const torch::Tensor& v);

class LagrangianAdapter : public DomainAdapter {
 public:
  // `augment`: features.augment "symmetries", the data's scene symmetries (identity first), one
  // of which maps each noisy training sample; empty when off.
  explicit LagrangianAdapter(LagrangianSpec spec, std::vector<BoxSymmetry> augment = {})
      : spec_(std::move(spec)), augment_(std::move(augment)) {}
  const LagrangianSpec& spec() const { return spec_; }

  std::string kind() const override { return "lagrangian"; }
  ModelShape model_shape() const override;
  Json spec_json() const override { return to_json(spec_); }
  // Predicting t+1 from t-1 and t (and the history before). With a predictor and
  // config.features.pushforward = u > 0, sample (trajectory, t) starts from the truth at frames
  // t-1-u' and t-u' (u' = min(u, t-1)) and is rolled out by the predictor to frame t; the noise
  // is added to that state and the target is the truth's next frame, corrected by
  // (1 - noise_gamma) times noise plus drift (Batch::noise), or with pushforward_target
  // "acceleration" the frame's own noisy target, as if the state had not drifted. With augment,
  // each noisy sample (state, truth and mesh positions) is then mapped by one of its symmetries,
  // drawn from the sample's generator after its noise. With spec.stress the target gets the
  // next frame's stress as a last column.
  TrainBatch make_train_batch(const SampleRequest& request) const override;

  // `noise[g]` (optional, [N_g, dim]) is added to graph g's current positions on predicted nodes.
  // With spec.history > 1 it may be [N_g, history * dim]: the columns after the first dim are
  // draws like the first ones, for the older velocities' noise, a random walk back in time (as
  // GNS's): velocity t-k gets the current position's noise minus k of those draws, each divided
  // by sqrt(history).
  Batch make_batch(const std::vector<FrameState>& states,
                   const std::vector<torch::Tensor>& noise = {}) const;
  // Training noise `noise` ([N, dim] or [N, history * dim], as make_batch takes it) for `state`
  // with the rigid part of its first dim columns (x_t's noise) on each body scaled by
  // `rigid_scale`: per body of predicted nodes (mesh body_id), the uniform translation plus the
  // rigid rotation about the body's centroid (positions state.cur, nodes weighted equally) that
  // fits the noise best, the projection rigid_part makes. 0 leaves noise that only deforms the
  // bodies; 1 returns `noise` unchanged.
  torch::Tensor scale_rigid_noise(const FrameState& state, const torch::Tensor& noise,
                                  double rigid_scale) const;
  // Target acceleration (first order: velocity) for the batch from next positions [N, dim]
  // (concatenated like the batch). With training noise n on the current positions, the target next
  // position is next + (1 - noise_gamma) n (MeshGraphNets' convention): gamma 1 asks the model to
  // undo the noise in position, gamma 0 keeps the true velocity.
  torch::Tensor target(const Batch& batch, const torch::Tensor& next,
                       double noise_gamma = 1.0) const;
  // x_{t+1} = 2 x_t - x_{t-1} + a (first order: x_t + v) on predicted nodes, `prescribed`
  // [N, dim] elsewhere; `accel` may carry further output channels (stress), which are ignored.
  torch::Tensor integrate(const Batch& batch, const torch::Tensor& accel,
                          const torch::Tensor& prescribed) const;

 private:
  LagrangianSpec spec_;
  std::vector<BoxSymmetry> augment_;
};

}  // namespace bsms
