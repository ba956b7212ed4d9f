#include "pipeline/adapters/lagrangian_training.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <deque>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace bsms {

namespace {

std::string position_field(const Dataset& data) {
  if (data.has_field("world_pos")) return "world_pos";
  throw InputError(data.location() + ": a Lagrangian model needs the field world_pos");
}

}  // namespace

// Sample `ref` (frame t) with the state at frames t-1-before and t-before (the truth; before > 0
// for pushforward, which rolls it on to t) and the true next frame t+1; with `history` > 1 also
// the history - 1 frames before t-1-before that the trajectory has (FrameState::older).
LoadedSample load_sample(const Dataset& data, GraphStore& store, const SampleRef& ref,
                         int64_t before, int history) {
  const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
  const int64_t n = mesh.num_nodes();
  const int dim = data.dim();
  const int64_t first = ref.frame - 1 - before;
  const int64_t extra = std::min<int64_t>(history - 1, first);
  auto frames = data.read(ref.trajectory, position_field(data), first - extra, extra + before + 3);
  const auto all =
      torch::from_blob(frames.data(), {extra + before + 3, n, dim}, torch::kFloat32).clone();
  LoadedSample s;
  s.truth = all.narrow(0, extra, before + 3);
  s.graphs = store.get(mesh);
  s.state.graphs = s.graphs.get();
  s.state.mesh = &mesh;
  s.state.prev = s.truth[0];
  s.state.cur = s.truth[1];
  s.state.next = s.truth[2];
  for (int64_t k = extra - 1; k >= 0; --k) s.state.older.push_back(all[k]);
  s.next = s.truth[before + 2];
  return s;
}

namespace {

// Sample `ref` as the model reaches it: from the truth at frames t-1-u and t-u (u = min(unroll,
// t-1)), u steps of the predictor, with the truth on the nodes it does not predict.
LoadedSample pushed_forward_sample(const LagrangianAdapter& adapter, const Dataset& data,
                                   GraphStore& store, const SampleRef& ref, int unroll,
                                   const Predictor& predictor) {
  const int64_t u = std::min<int64_t>(unroll, ref.frame - 1);
  const int history = adapter.spec().history;
  LoadedSample s = load_sample(data, store, ref, u, history);
  const auto& x = s.truth;  // x[i] is frame t-1-u+i: x[u+1] is t
  for (int64_t i = 0; i < u; ++i) {
    const Batch b = adapter.make_batch({s.state});
    torch::Tensor predicted = adapter.integrate(b, predictor(b), x[i + 2]);
    if (!torch::isfinite(predicted).all().item<bool>())
      throw NumericalError("pushforward: the model's rollout of training trajectory " +
                           std::to_string(ref.trajectory) + " reached a non-finite position at " +
                           "frame " + std::to_string(ref.frame - u + i + 1) + " (sample frame " +
                           std::to_string(ref.frame) + ")");
    if (history > 1) {
      s.state.older.insert(s.state.older.begin(), s.state.prev);
      if (static_cast<int>(s.state.older.size()) > history - 1) s.state.older.pop_back();
    }
    s.state.prev = s.state.cur;
    s.state.cur = predicted;
    s.state.next = x[i + 3];
  }
  return s;
}

}  // namespace

TrainBatch LagrangianAdapter::make_train_batch(const SampleRequest& request) const {
  const TrainConfig& config = request.config;
  const Dataset& data = request.data;
  GraphStore& store = request.store;
  const std::vector<SampleRef>& refs = request.refs;
  std::vector<at::Generator>* generators = request.generators;
  const Predictor* predictor = request.predictor;
  TrainBatch b;
  const bool noisy = generators != nullptr;
  const int unroll = noisy && predictor ? config.features.pushforward : 0;
  // Columns of noise per coordinate: x_t's, and the older velocities' random walk (history_noise).
  const int64_t noise_width = config.features.history_noise == "walk" ? spec_.history : 1;
  std::vector<FrameState> states;
  std::vector<torch::Tensor> nexts, noise, drifts, truth_prevs, truth_curs;
  std::deque<TrajectoryMesh> mapped_meshes;  // augmented samples' meshes (stable addresses)
  std::vector<std::shared_ptr<const MeshGraphs>> owners;  // alive until the batch is made
  for (size_t k = 0; k < refs.size(); ++k) {
    LoadedSample s = unroll > 0
                         ? pushed_forward_sample(*this, data, store, refs[k], unroll, *predictor)
                         : load_sample(data, store, refs[k], 0, spec_.history);
    // x_t's noise (and the older velocities' walk), drawn before the augmentation's symmetry
    torch::Tensor raw;
    if (noisy)
      raw = torch::randn({s.state.cur.size(0), s.state.cur.size(1) * noise_width}, (*generators)[k],
                         torch::kFloat32) *
            config.features.noise_std;
    if (noisy && !augment_.empty()) {
      // One symmetry of the scene, uniform over the group (the identity included). The raw noise
      // is isotropic and independent per node, so it needs no map; its rigid part is taken on
      // the mapped state below.
      const auto pick = torch::randint(static_cast<int64_t>(augment_.size()), {1}, (*generators)[k],
                                       torch::kInt64)
                            .item<int64_t>();
      const BoxSymmetry& g = augment_[static_cast<size_t>(pick)];
      if (!g.is_identity()) {
        mapped_meshes.push_back(g.mesh(*s.state.mesh));
        s.state.mesh = &mapped_meshes.back();
        if (unroll > 0)  // the truth is read again only by pushforward's drift and target
          s.truth = g.points(s.truth.reshape({-1, s.truth.size(-1)})).view(s.truth.sizes());
        s.state.prev = g.points(s.state.prev);
        s.state.cur = g.points(s.state.cur);
        s.state.next = g.points(s.state.next);
        for (auto& older : s.state.older) older = g.points(older);
        s.next = g.points(s.next);
      }
    }
    if (noisy) noise.push_back(scale_rigid_noise(s.state, raw, config.features.noise_rigid_scale));
    owners.push_back(s.graphs);
    states.push_back(s.state);
    nexts.push_back(s.next);
    if (unroll > 0) {  // the truth at t-1 and t, and how far the rollout drifted from it
      const int64_t frames = s.truth.size(0);
      truth_prevs.push_back(s.truth[frames - 3]);
      truth_curs.push_back(s.truth[frames - 2]);
      drifts.push_back(s.state.cur - truth_curs.back());
    }
  }
  b.batch = make_batch(states, noise);
  if (!drifts.empty() && config.features.pushforward_target == "acceleration") {
    // The frame's true (noise-corrected) target, as if the state had not drifted: the target
    // formula applied to the truth plus the same noise.
    Batch truth = b.batch;
    truth.prev = torch::cat(truth_prevs, 0);
    truth.cur = torch::cat(truth_curs, 0) + b.batch.noise;
    b.target = target(truth, torch::cat(nexts, 0), config.features.noise_gamma);
  } else {
    if (!drifts.empty()) b.batch.noise = b.batch.noise + torch::cat(drifts, 0);
    b.target = target(b.batch, torch::cat(nexts, 0), noisy ? config.features.noise_gamma : 1.0);
  }
  if (spec_.stress) {
    // The next frame's stress, a per-node scalar: the same under the augmentation's symmetries.
    std::vector<torch::Tensor> stresses;
    for (const SampleRef& ref : refs) {
      const int64_t n = data.mesh(ref.trajectory).num_nodes();
      auto values = data.read(ref.trajectory, "stress", ref.frame + 1, 1);
      stresses.push_back(torch::from_blob(values.data(), {n, 1}, torch::kFloat32).clone());
    }
    b.target = torch::cat({b.target, torch::cat(stresses, 0)}, 1);
  }
  return b;
}

}  // namespace bsms
