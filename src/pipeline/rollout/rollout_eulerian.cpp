// The Eulerian rollout (public CylinderFlow / Airfoil data), see rollout_eulerian.hpp.
#include "pipeline/rollout/rollout_eulerian.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/rollout/rollout_outputs.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/train/trainer.hpp"

namespace bsms {
namespace fs = std::filesystem;

RolloutMetrics rollout_eulerian(const RolloutRequest& request, const TrainConfig& config,
                                const EulerianSpec& spec, int levels,
                                const std::optional<TrainStats>& stats) {
  const std::string run = request.run;
  if (request.one_step)
    throw InputError(run +
                     ": --one-step (teacher forcing) is for Lagrangian runs; this one is "
                     "Eulerian (velocity)");
  const int threads = configure_threads(set_num_threads(request.threads));
  auto simulator = std::make_shared<LearnedSimulator>(model_shape(spec), config.model, levels);
  load_checkpoint(run_checkpoint_path(run), *simulator, nullptr);
  simulator->eval();

  const std::string data_dir = request.data.empty() ? config.data : request.data;
  const Dataset data = Dataset::open_split(data_dir, request.split);
  if (data.mesh(0).dim != spec.dim)
    throw InputError(data.location() + ": mesh dimension " + std::to_string(data.mesh(0).dim) +
                     " differs from the model's " + std::to_string(spec.dim));
  for (const FieldInfo& f : spec.state_fields())
    if (!data.has_field(f.name))
      throw InputError(data.location() + ": the model needs the field " + f.name);
  if (spec.pressure && !data.has_field("pressure"))
    throw InputError(data.location() + ": the model needs the field pressure");
  const int64_t count = request.max_trajectories > 0
                            ? std::min(request.max_trajectories, data.num_trajectories())
                            : data.num_trajectories();
  std::error_code ec;
  std::vector<std::string> cache_dirs = {(fs::path(data_dir) / "multilevel").string(),
                                         (fs::path(run) / "multilevel").string()};
  for (const auto& d : cache_dirs) fs::create_directories(d, ec);
  const Seeding seeding =
      request.seeding.empty() ? config.model.seeding : parse_seeding(request.seeding);
  GraphStore store(seeding, levels, cache_dirs);
  const EulerianAdapter adapter(spec);

  const fs::path out_dir = rollout_outputs::out_dir(request);
  const std::string out_h5 = rollout_outputs::prediction_file(out_dir, request.split, data);
  fs::create_directories(out_dir, ec);
  DatasetWriter writer(out_h5, data.scene(), spec.dim, data.frame_dt());

  // Per field: squared error sums per step (model, persistence) and node-value counts.
  std::vector<FieldInfo> outputs = spec.state_fields();
  if (spec.pressure) outputs.push_back({"pressure", 1});
  const size_t nf = outputs.size();
  std::vector<std::vector<double>> sq(nf), sq_hold(nf);
  std::vector<std::vector<double>> values(nf);
  rollout_outputs::RolloutTally tally;
  HorizonRmse horizons;  // the references' table: RMSE over the first h steps, per trajectory
  ProgressBar bar("rollout " + request.split, count);
  torch::InferenceMode inference;
  for (int64_t t = 0; t < count; ++t) {
    const TrajectoryMesh& mesh = data.mesh(t);
    const int64_t n = mesh.num_nodes();
    tally.nodes_total += static_cast<double>(n);
    int64_t frames = data.num_frames(t);
    if (request.max_steps > 0) frames = std::min(frames, request.max_steps + 1);
    if (frames < 2)
      throw InputError(data.location() + ": trajectory " + std::to_string(t) +
                       " has fewer than 2 frames");
    const auto truth = read_eulerian_state(data, spec, t, 0, frames);  // [T, N, S]
    const auto truth_p = read_eulerian_pressure(data, spec, t, 0, frames);
    const auto graphs_owner = store.get(mesh);
    const MeshGraphs& graphs = *graphs_owner;
    std::vector<torch::Tensor> pred = {truth[0]}, pred_p;
    if (spec.pressure) pred_p.push_back(truth_p[0]);
    torch::Tensor held;  // persistence: the first frame on predicted nodes, the truth elsewhere
    std::map<std::string, std::vector<double>> step_mse;  // this trajectory's, for `horizons`
    for (int64_t f = 0; f + 1 < frames; ++f) {
      Stopwatch clock;
      const Batch batch = adapter.make_batch({EulerianFrame{&graphs, &mesh, pred[f]}});
      const auto output = simulator->predict(batch);
      auto [state, pressure] = adapter.integrate(batch, output, truth[f + 1],
                                                 spec.pressure ? truth_p[f + 1] : torch::Tensor());
      tally.infer_ms.push_back(clock.milliseconds());
      if (!torch::isfinite(state).all().item<bool>() ||
          (pressure.defined() && !torch::isfinite(pressure).all().item<bool>())) {
        tally.diverged.push_back({t, f + 1});
        break;
      }
      pred.push_back(state);
      if (spec.pressure) pred_p.push_back(pressure);
      held = torch::where(batch.mask.unsqueeze(1), truth[0], truth[f + 1]);
      const auto err = state - truth[f + 1], err_hold = held - truth[f + 1];
      int64_t c0 = 0;
      for (size_t k = 0; k < nf; ++k) {
        if (sq[k].size() <= static_cast<size_t>(f)) {
          sq[k].resize(f + 1, 0.0);
          sq_hold[k].resize(f + 1, 0.0);
          values[k].resize(f + 1, 0.0);
        }
        const int64_t w = outputs[k].width;
        const double before = sq[k][f];
        if (outputs[k].name == "pressure") {
          sq[k][f] += (pressure - truth_p[f + 1]).square().sum().item<double>();
          sq_hold[k][f] +=
              (torch::where(batch.mask.unsqueeze(1), truth_p[0], truth_p[f + 1]) - truth_p[f + 1])
                  .square()
                  .sum()
                  .item<double>();
        } else {
          sq[k][f] += err.slice(1, c0, c0 + w).square().sum().item<double>();
          sq_hold[k][f] += err_hold.slice(1, c0, c0 + w).square().sum().item<double>();
          c0 += w;
        }
        values[k][f] += static_cast<double>(n);
        step_mse[outputs[k].name].push_back((sq[k][f] - before) / static_cast<double>(n * w));
      }
    }
    horizons.add(step_mse);
    Trajectory out;
    out.mesh = mesh;
    out.seed = data.seed(t);
    out.parameters = data.parameters(t);
    out.num_frames = static_cast<int64_t>(pred.size());
    auto put = [&](const std::string& name, const torch::Tensor& v) {
      out.fields[name] = rollout_outputs::to_floats(v);
    };
    const auto stacked = torch::stack(pred);
    const auto target = truth.slice(0, 0, out.num_frames);
    int64_t c0 = 0;
    for (const FieldInfo& field : spec.state_fields()) {
      put(field.name, stacked.slice(2, c0, c0 + field.width));
      put("target_" + field.name, target.slice(2, c0, c0 + field.width));
      c0 += field.width;
    }
    if (spec.pressure) {
      put("pressure", torch::stack(pred_p));
      put("target_pressure", truth_p.slice(0, 0, out.num_frames));
    }
    writer.add(out);
    if (!request.quiet) bar.update(t + 1);
  }
  writer.commit();
  if (!request.quiet) bar.finish();
  rollout_outputs::write_xdmf_files(out_h5, out_dir, request.split);

  // RMSE per field over the first `steps` predicted steps; "total" is the RMS of the fields'
  // RMSEs (fields have different units: compare totals only between models on one dataset).
  auto rmse_over = [&](const std::vector<std::vector<double>>& sums,
                       size_t steps) -> std::optional<FieldRmse> {
    FieldRmse rmse;
    double total = 0;
    for (size_t k = 0; k < nf; ++k) {
      double s = 0, v = 0;
      for (size_t f = 0; f < std::min(steps, sums[k].size()); ++f) {
        s += sums[k][f];
        v += values[k][f] * static_cast<double>(outputs[k].width);
      }
      if (v == 0) return std::nullopt;
      rmse.fields[outputs[k].name] = std::sqrt(s / v);
      total += s / v;
    }
    rmse.total = std::sqrt(total / static_cast<double>(nf));
    return rmse;
  };
  const size_t all = sq.empty() ? 0 : sq[0].size();
  RolloutMetrics metrics;
  metrics.model = config.model.type;
  metrics.eulerian = true;
  metrics.split = request.split;
  metrics.data = data.location();
  metrics.num_trajectories = count;
  metrics.rmse_1 = rmse_over(sq, 1);
  metrics.rmse_50 = rmse_over(sq, 50);
  metrics.rmse_all = rmse_over(sq, all);
  metrics.rmse_trajectory_mean = horizons.result();
  // What no model achieves: the first frame held on the predicted nodes.
  metrics.rmse_1_persistence = rmse_over(sq_hold, 1);
  metrics.rmse_all_persistence = rmse_over(sq_hold, all);
  for (size_t k = 0; k < nf; ++k) {
    std::vector<double>& curve = metrics.rmse_per_step[outputs[k].name];
    for (size_t f = 0; f < sq[k].size(); ++f)
      curve.push_back(std::sqrt(sq[k][f] / (values[k][f] * static_cast<double>(outputs[k].width))));
  }
  rollout_outputs::add_run_figures(metrics, tally, count, seeding, threads, levels, stats);
  write_json_atomic((out_dir / "metrics.json").string(), to_json(metrics));
  if (!request.quiet) {
    std::cerr << "bsms rollout: " << count << " trajectories, RMSE-all";
    if (metrics.rmse_all)
      for (const auto& f : outputs)
        std::cerr << " " << f.name << " " << metrics.rmse_all->at(f.name) << " (held "
                  << RolloutMetrics::rmse(metrics.rmse_all_persistence, f.name) << ")";
    std::cerr << ", " << metrics.infer_ms_per_step << " ms/step -> "
              << (out_dir / "metrics.json").string() << "\n";
  }
  return metrics;
}

}  // namespace bsms
