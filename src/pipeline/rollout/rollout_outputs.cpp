#include "pipeline/rollout/rollout_outputs.hpp"

#include <algorithm>
#include <cstdio>

#include "core/config.hpp"
#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/xdmf.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_stats.hpp"
#include "pipeline/train/trainer.hpp"

namespace bsms::rollout_outputs {

std::vector<float> to_floats(const torch::Tensor& t) {
  const auto c = t.to(torch::kFloat32).contiguous();
  return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}
namespace fs = std::filesystem;

fs::path out_dir(const RolloutRequest& request) {
  if (!request.out.empty()) return fs::path(request.out);
  std::string projected;
  for (const std::string& name : projection_names(request.projection))
    projected += (projected.empty() ? "_" : "+") + name;
  return run_rollout_dir(request.run, std::string(request.one_step ? "_one_step" : "") +
                                          (request.ensemble.empty() ? "" : "_ensemble") +
                                          (request.symmetrize ? "_symmetric" : "") + projected);
}

std::string prediction_file(const fs::path& out_dir, const std::string& split,
                            const Dataset& data) {
  const fs::path file = out_dir / (split + ".h5");
  std::error_code ec;
  if (fs::exists(file, ec) && fs::equivalent(file, data.location(), ec))
    throw InputError(file.string() +
                     ": is the dataset being rolled out; give --out a folder other than --data");
  return file.string();
}

void write_xdmf_files(const std::string& out_h5, const fs::path& out_dir,
                      const std::string& split) {
  const Dataset written(out_h5);
  for (int64_t t = 0; t < written.num_trajectories(); ++t) {
    char name[64];
    std::snprintf(name, sizeof name, "%s_%06lld.xdmf", split.c_str(), static_cast<long long>(t));
    write_trajectory_xdmf(written, t, (out_dir / name).string());
  }
}

void add_run_figures(RolloutMetrics& metrics, const RolloutTally& tally, int64_t count,
                     Seeding seeding, int threads, int levels,
                     const std::optional<TrainStats>& stats) {
  metrics.seeding = to_string(seeding);
  metrics.infer_ms_per_step = median(tally.infer_ms);
  metrics.peak_rss_mb_infer = peak_rss_mb();
  metrics.num_nodes_mean = count > 0 ? tally.nodes_total / static_cast<double>(count) : 0.0;
  metrics.threads = threads;
  metrics.cpu = cpu_model_name();
  metrics.diverged = tally.diverged;
  metrics.levels = levels;
  if (!stats) return;
  metrics.train_ms_per_step = stats->train_ms_per_step;
  metrics.peak_rss_mb_train = stats->peak_rss_mb_train;
  metrics.train_steps = stats->steps;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace bsms::rollout_outputs
