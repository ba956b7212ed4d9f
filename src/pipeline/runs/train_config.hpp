// Training configuration (configs/train/*.json): one typed struct per concern, read strictly.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace bsms {

struct ModelConfig {
  std::string type = "bsms";  // "bsms" | "mgn"
  int64_t latent = 128;
  int levels = 0;  // BSMS: total levels incl. the mesh; 0 = auto (from the mesh)
  Seeding seeding = Seeding::kMinAve;  // seeding of the multilevel graphs
  int message_passing_steps = 15;      // MeshGraphNets
  int mp_per_level = 1;                // BSMS: message-passing blocks per level (down, bottom, up)
  // BSMS: blocks per level, one per level from the mesh down (config: mp_per_level as a list);
  // empty = mp_per_level on every level.
  std::vector<int> mp_per_level_list;
  // Matrix products of the model's layers: "float32" or "bf16" (models/graph_ops.hpp,
  // MatmulPrecision: bfloat16 operands, float32 everything else).
  std::string precision = "float32";
  // "on": edge features standardised per channel by normalizers settled with the node
  // normalizer's (models/networks.hpp GraphModelOptions::edge_normalizer); "off": raw features.
  std::string edge_normalizer = "off";
};

struct FeatureConfig {
  // Contact edges: radius search on world positions between nodes the mesh does not join.
  // < 0: auto (on when a training trajectory has several bodies, radius = 1.5 × mean mesh edge
  // length); 0: off; > 0: this radius (m).
  double contact_radius = -1.0;
  double noise_std = 3e-4;  // Gaussian noise on input positions (m)
  // Share of the noise the target position keeps undoing (MeshGraphNets' noise_gamma): the
  // target next position is next + (1 - gamma) * noise. 1: correct the position; 0: keep the
  // true velocity.
  double noise_gamma = 1.0;
  // Strain channel on mesh edges (|x_ij| / |X_ij| - 1 over the training data's RMS strain):
  // "auto" = on, "off".
  std::string strain = "auto";
  int num_node_types = 0;  // one-hot width; 0 = auto (max node_type in training data + 1)
  // Distance-to-wall inputs (GNS style): "auto" = on when the dataset's scene is a box
  // background with named wall boundaries; "off".
  std::string walls = "auto";
  // Momentum of free bodies: "auto" = on when the scene allows it (LagrangianSpec,
  // resolve_momentum) and the training data confirms it (free groups' true accelerations conserve
  // momentum to 5 %: FLIP keeps angular momentum only to ~1 %), including, with slip or roller
  // walls, a group's linear momentum along a wall near it; "free" = the same for groups near no
  // wall only; "off".
  std::string momentum = "auto";
  // Lagrangian output: "acceleration" (x_{t+1} - 2 x_t + x_{t-1}, second-order integration),
  // "velocity" (x_{t+1} - x_t, first-order, as MeshGraphNets' DeformingPlate), or "auto"
  // (acceleration).
  std::string output = "auto";
  // Next-step motion of the nodes that follow a prescribed path (actuators, handles) as a node
  // input, as MeshGraphNets does for DeformingPlate: "auto" = on for public MeshGraphNets data,
  // off for bsms data; "on"; "off".
  std::string kinematic_input = "auto";
  // Lagrangian data with a per-node `stress` field (MeshGraphNets' DeformingPlate): "auto" =
  // the next frame's stress is a second output, predicted beside the motion with one output
  // normalizer over both (as MeshGraphNets' plate model); "off" = motion only.
  std::string stress = "auto";
  // Rows of the output normalizer's statistics: "predicted" = the nodes the loss covers,
  // "all" = every node, as MeshGraphNets' reference (its statistics include boundary nodes,
  // whose targets are zero or prescribed), "auto" = "all" on public MeshGraphNets data,
  // "predicted" on bsms data.
  std::string output_statistics = "auto";
  // The velocity x_t - x_{t-1} as an input on solved nodes: "auto" = off for first-order output
  // (quasi-static data, MeshGraphNets' DeformingPlate), on otherwise; "on"; "off".
  std::string velocity_input = "auto";
  // Eulerian data: Gaussian noise on the density input (the velocity input gets noise_std).
  double density_noise_std = 0.0;
  // Training against rollout drift (Lagrangian data; "pushforward", Brandstetter et al. 2022):
  // each training sample at frame t starts `pushforward` frames earlier from the truth and is
  // rolled out by the model itself (no gradient) up to t, so the input is the model's own drifted
  // state; the target is the truth, corrected for the drift as for noise (noise_gamma). 0: off.
  int pushforward = 0;
  // The first training step (counted from 1, as in train_log.csv) that pushes forward; the
  // earlier ones train on the truth plus noise while the model's own rollouts are still far off.
  int64_t pushforward_from = 1000;
  // The target of a pushed-forward sample: "position" (back to the true trajectory: the drift is
  // corrected like noise, with noise_gamma) or "acceleration" (the frame's true target, as if the
  // state had not drifted: a rigid drift the state cannot reveal is not asked to be undone).
  std::string pushforward_target = "position";
  // Velocities the model sees (Lagrangian data, acceleration output): 1 = x_t - x_{t-1} only;
  // k > 1 adds the k - 1 before it (x_{t-1} - x_{t-2}, ...; Sanchez-Gonzalez et al.'s GNS uses
  // 5). Frames before a trajectory's first are filled at constant velocity.
  int history = 1;
  // Training noise on those older velocities: "off" (the true ones; only x_t is noisy) or "walk"
  // (GNS's random walk back from x_t's noise, steps of noise_std / sqrt(history)).
  std::string history_noise = "off";
  // Extra weight of the rigid part of the training error (Lagrangian data): per body, the part of
  // the normalised acceleration error that a uniform acceleration plus a rigid spin explains
  // (rigid_part in lagrangian.hpp) counts 1 + w times, the deformation part once. A rollout's
  // error is mostly where bodies go and how they turn, a small share of the per-node loss beside
  // the particles' own jitter. 0: off. The validation loss stays the plain one.
  double rigid_loss_weight = 0.0;
  // Share of the training noise's rigid part kept (Lagrangian data): per body, the uniform
  // translation plus rigid rotation that fits x_t's noise best (2e-3 m on ~100 nodes: ~2e-4 m)
  // is multiplied by this. The model cannot tell that part from a true velocity, so its
  // correction in the target is noise no training removes; 0 leaves noise that only deforms the
  // bodies. 1: the plain Gaussian noise.
  double noise_rigid_scale = 1.0;
  // Training data augmentation (Lagrangian data): "symmetries" maps each noisy training sample
  // (its frames and mesh positions, hence its target) by one symmetry of the data's box scene
  // drawn uniformly (the group `bsms rollout --symmetrize` averages over: reflections and, where
  // sides are equal, axis swaps that keep every side's boundary type and the gravity), so that the
  // model learns from every mirror image of each state; validation stays on the data as stored.
  // "off": the data as stored.
  std::string augment = "off";
};

struct OptimizerConfig {
  double lr = 1e-4;          // peak learning rate, reached after the warm-up
  double lr_final = 1e-6;    // exponential decay from lr to lr_final over the run's progress
  int64_t warmup_steps = 0;  // linear warm-up from lr / 100 over this many steps
  int batch_size = 2;        // graphs per step (block-diagonal merge)
  // > 0: keep an exponential moving average of the parameters with this decay
  // (models/parameter_ema.hpp); checkpoints carry it and predictions use it. 0: none.
  double ema_decay = 0.0;
};

struct TrainConfig {
  std::string data;            // dataset folder (train.h5/valid.h5 or public {split}/ folders)
  int64_t steps = 1000;        // training steps
  double time_budget_s = 0.0;  // > 0: also stop after this many wall seconds of training
  int64_t valid_every = 200;   // validation loss and checkpoint every this many steps
  int valid_samples = 64;      // (trajectory, frame) samples in each validation
  // Checkpoint selection by rollout: every this many steps (a multiple of valid_every; 0 = off)
  // and at the last step, the checkpoint just written is rolled out over the first
  // valid_rollout_trajectories trajectories of the valid split (RUN/valid_rollout.csv) and kept
  // as RUN/checkpoints/best.h5 when its RMSE-all is the lowest so far. One-step losses can keep
  // falling while rollouts get worse; this is what the rollout a user runs is scored on.
  int64_t valid_rollout_every = 0;
  int valid_rollout_trajectories = 8;
  // Batches whose statistics settle the normalizers before the first optimizer step.
  int64_t normalizer_steps = 1000;
  uint64_t seed = 0;
  // Memory cap of the meshes' graph hierarchies kept between steps (least recently used ones go
  // beyond it); 0: no cap. Matters for splits with many distinct meshes (MeshGraphNets' public
  // sets: one mesh per trajectory).
  int64_t graph_cache_mb = 4096;
  ModelConfig model;
  FeatureConfig features;
  OptimizerConfig optimizer;
};

// Learning rate at `step` when the run is `progress` (0..1) done: linear warm-up over
// warmup_steps, then exponential decay from lr to lr_final as progress goes from 0 to 1.
double learning_rate(const OptimizerConfig& optimizer, int64_t step, double progress);

// Reads and validates `json` (from `file`); InputError names the file and the key.
TrainConfig parse_train_config(const Json& json, const std::string& file);
Json to_json(const TrainConfig& config);

}  // namespace bsms
