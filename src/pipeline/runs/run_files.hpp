// Small files of a run or report folder, written atomically.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "pipeline/runs/train_config.hpp"
#include "pipeline/runs/train_stats.hpp"

namespace bsms {

// Files of a run folder (docs/design.md "Runs").
std::string run_config_path(const std::string& run);
std::string run_checkpoint_path(const std::string& run);
// RUN/checkpoints/best.h5: the checkpoint whose validation rollout scored best (train config
// valid_rollout_every), and RUN/valid_rollout.csv, the score of every one rolled out.
std::string run_best_checkpoint_path(const std::string& run);
std::string run_valid_rollout_log_path(const std::string& run);
// The checkpoint a rollout (or the Python module) loads from a run: `which` = "best" (an
// InputError when the run has none), "latest", or "" (best when the run has one, else latest).
struct ModelCheckpoint {
  std::string path;
  std::string name;  // "best" or "latest"
};
ModelCheckpoint run_model_checkpoint(const std::string& run, const std::string& which);
std::string run_log_path(const std::string& run);
std::string run_stats_path(const std::string& run);
std::string run_checkpoint_dir(const std::string& run);
// DIR/multilevel: the multilevel graph cache of a run or a dataset folder (graphs/graph_cache.hpp).
std::string multilevel_cache_dir(const std::string& dir);
// The cache folders a run looks in for its graphs on `data_dir`: the data's, then its own.
std::vector<std::string> multilevel_cache_dirs(const std::string& data_dir, const std::string& run);
// RUN/rollout...: the outputs of one rollout of a run (`suffix`: "", "_one_step",
// "_ensemble", ...), and its metrics file.
std::string run_rollout_dir(const std::string& run, const std::string& suffix);
std::string rollout_metrics_path(const std::string& rollout_dir);
// The LibTorch checkpoint older bsms wrote beside `path` (RUN/checkpoints/latest.pt for
// RUN/checkpoints/latest.h5; empty for other names), and the one line that refuses it.
std::string legacy_checkpoint_path(const std::string& path);
std::string legacy_checkpoint_message(const std::string& legacy_path);

void write_json_atomic(const std::string& path, const Json& value);
void write_text_atomic(const std::string& path, const std::string& text);

// A trained run's folder (`bsms train --out RUN`). RUN/config.json holds the validated training
// config, the level count the model was built with and the features resolved from the training
// data. This is the one reader of that file (rollout, train --resume and the experiments use it):
// strict, a missing folder, file or key is an InputError naming it.
struct RunFolder {
  std::string dir;
  std::string config_path;  // RUN/config.json
  TrainConfig config;
  int levels = 0;
  int world_size = 1;  // the ranks of the last session
  Json features_resolved;
  // RUN/train_stats.json, read and checked with the rest (none before a session has finished):
  // a damaged one is reported before any work, not after a rollout or a resumed training.
  std::optional<TrainStats> stats;

  static RunFolder open(const std::string& dir);
  std::string label() const;  // "<folder name> (<model type>)", for tables and plot keys
};

}  // namespace bsms
