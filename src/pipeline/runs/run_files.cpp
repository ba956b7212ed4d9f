#include "pipeline/runs/run_files.hpp"

#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {
namespace fs = std::filesystem;

std::string run_config_path(const std::string& run) {
  return (fs::path(run) / "config.json").string();
}
std::string run_checkpoint_dir(const std::string& run) {
  return (fs::path(run) / "checkpoints").string();
}
std::string run_checkpoint_path(const std::string& run) {
  return (fs::path(run_checkpoint_dir(run)) / "latest.h5").string();
}
std::string run_best_checkpoint_path(const std::string& run) {
  return (fs::path(run_checkpoint_dir(run)) / "best.h5").string();
}
std::string run_valid_rollout_log_path(const std::string& run) {
  return (fs::path(run) / "valid_rollout.csv").string();
}
ModelCheckpoint run_model_checkpoint(const std::string& run, const std::string& which) {
  const std::string best = run_best_checkpoint_path(run);
  if (which == "best" && !fs::exists(best))
    throw InputError(best +
                     ": no best checkpoint (the run was trained without valid_rollout_every); "
                     "use the latest one");
  if (!which.empty() && which != "best" && which != "latest")
    throw InputError("checkpoint " + which + ": expected \"best\" or \"latest\"");
  if (which == "best" || (which.empty() && fs::exists(best))) return {best, "best"};
  return {run_checkpoint_path(run), "latest"};
}
std::string multilevel_cache_dir(const std::string& dir) {
  return (fs::path(dir) / "multilevel").string();
}
std::vector<std::string> multilevel_cache_dirs(const std::string& data_dir,
                                               const std::string& run) {
  return {multilevel_cache_dir(data_dir), multilevel_cache_dir(run)};
}
std::string run_rollout_dir(const std::string& run, const std::string& suffix) {
  return (fs::path(run) / ("rollout" + suffix)).string();
}
std::string rollout_metrics_path(const std::string& rollout_dir) {
  return (fs::path(rollout_dir) / "metrics.json").string();
}
std::string run_log_path(const std::string& run) {
  return (fs::path(run) / "train_log.csv").string();
}
std::string run_stats_path(const std::string& run) {
  return (fs::path(run) / "train_stats.json").string();
}

std::string legacy_checkpoint_path(const std::string& path) {
  const std::filesystem::path p(path);
  if (p.filename() != "latest.h5") return "";
  return (p.parent_path() / "latest.pt").string();
}

std::string legacy_checkpoint_message(const std::string& legacy) {
  const std::filesystem::path run = std::filesystem::path(legacy).parent_path().parent_path();
  return legacy +
         ": a LibTorch archive (older bsms), which bsms no longer loads because loading one runs "
         "code from the file; if you trust it, convert it once: bsms convert-checkpoint " +
         (run.empty() ? std::string(".") : run.string()) + " --trust-torch-archive";
}

void write_json_atomic(const std::string& path, const Json& value) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << value.dump(2) << '\n';
    if (!f) throw IoError(path + ": cannot write");
  }
  out.commit();
}

void write_text_atomic(const std::string& path, const std::string& text) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << text;
    if (!f) throw IoError(path + ": cannot write");
  }
  out.commit();
}

RunFolder RunFolder::open(const std::string& dir) {
  RunFolder run;
  run.dir = dir;
  run.config_path = run_config_path(dir);
  if (!std::filesystem::exists(run.config_path))
    throw InputError(dir + ": not a run folder (no config.json; train first with bsms train)");
  const Json saved = load_json_file(run.config_path, "run config");
  for (const char* key : {"config", "features_resolved", "levels"})
    if (!saved.contains(key))
      throw InputError(run.config_path + ": key " + key + " is missing (written by bsms train)");
  // As model.levels allows (train_config.cpp).
  if (!saved["levels"].is_number_integer() || saved["levels"].get<int64_t>() < 1 ||
      saved["levels"].get<int64_t>() > 64)
    throw InputError(run.config_path + ": levels = " + describe_json(saved["levels"]) +
                     ", expected an integer in [1, 64]");
  if (saved.contains("world_size")) {
    const Json& world = saved["world_size"];
    if (!world.is_number_integer() || world.get<int64_t>() < 1 || world.get<int64_t>() > 1 << 20)
      throw InputError(run.config_path + ": world_size = " + describe_json(world) +
                       ", expected an integer in [1, 1048576]");
    run.world_size = world.get<int>();
  }
  run.config = parse_train_config(saved["config"], run.config_path);
  run.levels = saved["levels"].get<int>();
  run.features_resolved = saved["features_resolved"];
  const std::string stats = run_stats_path(dir);
  if (std::filesystem::exists(stats)) run.stats = read_train_stats(stats);
  return run;
}

std::string RunFolder::label() const {
  return std::filesystem::path(dir).filename().string() + " (" + config.model.type + ")";
}

}  // namespace bsms
