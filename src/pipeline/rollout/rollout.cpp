// The rollout loop, one for every domain (rollout_domain.hpp).
#include "pipeline/rollout/rollout.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/rollout/rollout_domain.hpp"
#include "pipeline/rollout/rollout_outputs.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// Predicts trajectory t of the domain's data from its first frames, scoring each step; returns
// the predicted frames (the given true ones first) and adds the trajectory's step errors to
// `curves` and `horizons`.
std::vector<torch::Tensor> roll_trajectory(RolloutDomain& domain, int64_t t,
                                           const torch::Tensor& truth, FieldCurves& curves,
                                           HorizonRmse& horizons,
                                           rollout_outputs::RolloutTally& tally) {
  const int64_t given = domain.layout().given_frames;
  std::vector<torch::Tensor> pred;
  for (int64_t k = 0; k < given; ++k) pred.push_back(truth[k]);
  std::map<std::string, std::vector<double>> step_mse;  // this trajectory's, for `horizons`
  int64_t steps = 0;
  for (int64_t f = given - 1; f + 1 < truth.size(0); ++f) {
    Stopwatch clock;
    const torch::Tensor next = domain.step(f);
    tally.infer_ms.push_back(clock.milliseconds());
    if (!torch::isfinite(next).all().item<bool>()) {
      tally.diverged.push_back({t, f + 1});
      break;
    }
    pred.push_back(next);
    for (const FieldError& e : domain.accept(f)) {
      curves.add(static_cast<size_t>(f + 1 - given), e);
      step_mse[e.name].push_back(e.sum / e.weight);
    }
    ++steps;
  }
  horizons.add(step_mse);
  domain.end_trajectory(steps);
  return pred;
}

// The predicted and true frames of trajectory t, each frame column a field.
Trajectory written_trajectory(const Dataset& data, const RolloutLayout& layout, int64_t t,
                              const std::vector<torch::Tensor>& pred, const torch::Tensor& truth) {
  Trajectory out;
  out.mesh = data.mesh(t);
  out.seed = data.seed(t);
  out.parameters = data.parameters(t);
  out.num_frames = static_cast<int64_t>(pred.size());
  const auto stacked = torch::stack(pred);
  const auto target = truth.slice(0, 0, out.num_frames);
  int64_t c0 = 0;
  for (const FieldInfo& field : layout.frame) {
    out.fields[field.name] = rollout_outputs::to_floats(stacked.slice(2, c0, c0 + field.width));
    out.fields["target_" + field.name] =
        rollout_outputs::to_floats(target.slice(2, c0, c0 + field.width));
    c0 += field.width;
  }
  return out;
}

}  // namespace

RolloutMetrics rollout(const RolloutRequest& request) {
  const RunFolder folder = RunFolder::open(request.run);
  const Json& features = folder.features_resolved;
  const bool eulerian = features.is_object() && features.value("kind", std::string()) == "eulerian";
  std::unique_ptr<RolloutDomain> domain =
      eulerian ? eulerian_rollout(request, folder) : lagrangian_rollout(request, folder);
  const Dataset& data = domain->data();
  const RolloutLayout& layout = domain->layout();
  const int64_t count = request.max_trajectories > 0
                            ? std::min(request.max_trajectories, data.num_trajectories())
                            : data.num_trajectories();

  const fs::path out_dir = rollout_outputs::out_dir(request);
  const std::string out_h5 = rollout_outputs::prediction_file(out_dir, request.split, data);
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  DatasetWriter writer(out_h5, data.scene(), layout.dim, data.frame_dt());

  FieldCurves curves(layout.scored);
  HorizonRmse horizons;  // the references' table: RMSE over the first h steps, per trajectory
  rollout_outputs::RolloutTally tally;
  std::vector<double> solver_ms_per_frame;
  ProgressBar bar("rollout " + request.split, count);
  torch::InferenceMode inference;
  for (int64_t t = 0; t < count; ++t) {
    tally.nodes_total += static_cast<double>(data.mesh(t).num_nodes());
    int64_t frames = data.num_frames(t);
    if (request.max_steps > 0) frames = std::min(frames, request.max_steps + layout.given_frames);
    if (frames < layout.given_frames + 1)
      throw InputError(data.location() + ": trajectory " + std::to_string(t) + " has fewer than " +
                       std::to_string(layout.given_frames + 1) + " frames");
    const torch::Tensor truth = domain->start(t, frames);
    const auto pred = roll_trajectory(*domain, t, truth, curves, horizons, tally);
    const double solver_s = data.solver_wall_s(t);
    if (solver_s >= 0)
      solver_ms_per_frame.push_back(1000.0 * solver_s /
                                    static_cast<double>(data.num_frames(t) - 1));
    writer.add(written_trajectory(data, layout, t, pred, truth));
    if (!request.quiet) bar.update(t + 1);
  }
  writer.commit();
  if (!request.quiet) bar.finish();
  rollout_outputs::write_xdmf_files(out_h5, out_dir, request.split);

  RolloutMetrics metrics;
  metrics.split = request.split;
  metrics.data = data.location();
  metrics.num_trajectories = count;
  metrics.checkpoint = domain->checkpoint;
  metrics.checkpoint_step = domain->checkpoint_step;
  metrics.rmse_1 = curves.rmse_over(1);
  metrics.rmse_50 = curves.rmse_over(50);
  metrics.rmse_all = curves.rmse_over(curves.steps());
  metrics.rmse_trajectory_mean = horizons.result();
  for (const ScoredField& field : layout.scored)
    if (field.per_step) metrics.rmse_per_step[field.name] = curves.per_step(field.name);
  const std::string summary = domain->finish(metrics);
  rollout_outputs::add_run_figures(metrics, tally, count, domain->seeding, domain->threads,
                                   domain->levels, folder.stats);
  if (!solver_ms_per_frame.empty()) {
    metrics.solver_ms_per_frame = rollout_outputs::median(solver_ms_per_frame);
    if (metrics.infer_ms_per_step > 0)
      metrics.speedup_vs_solver = *metrics.solver_ms_per_frame / metrics.infer_ms_per_step;
  }
  write_json_atomic((out_dir / "metrics.json").string(), to_json(metrics));
  if (!request.quiet)
    std::cerr << "bsms rollout: " << metrics.checkpoint << " checkpoint (step "
              << metrics.checkpoint_step.value_or(0) << "), " << count << " trajectories, "
              << summary << ", " << metrics.infer_ms_per_step << " ms/step -> "
              << (out_dir / "metrics.json").string() << "\n";
  return metrics;
}

}  // namespace bsms
