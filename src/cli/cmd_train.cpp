// bsms train CONFIG.json [--set key=value] [--out RUN] [--resume] [--threads T]
#include <filesystem>

#include "cli/command.hpp"
#include "pipeline/trainer.hpp"

namespace {

struct TrainArgs {
  bsms::TrainRequest request;
};

BSMS_COMMAND(
    "train", "train BSMS-GNN or MeshGraphNets on a dataset (configs/train/*.json)",
    [](CLI::App& sub) {
      auto args = std::make_shared<TrainArgs>();
      auto& r = args->request;
      sub.add_option("config", r.config_path, "training config JSON")->required();
      bsms::cli::add_set_option(sub, r.overrides);
      sub.add_option("--out", r.out, "run folder (default runs/<config name>)");
      sub.add_flag("--resume", r.resume,
                   "continue the run in --out from its latest checkpoint, exactly");
      sub.add_option("--until", r.until,
                     "stop at this step with a checkpoint (continue later with --resume)")
          ->check(CLI::NonNegativeNumber);
      bsms::cli::add_threads_option(sub, r.threads);
      sub.footer(
          "Writes RUN/config.json (resolved), RUN/checkpoints/latest.pt (model, normalizers,\n"
          "optimizer, step; atomic), RUN/train_log.csv (step, wall_s, loss, valid_loss,\n"
          "valid_baseline = the loss of predicting zero, lr) and RUN/train_stats.json.\n"
          "Multilevel graphs are built on first use and cached in DATA/multilevel/ (or\n"
          "RUN/multilevel/ when the data folder is read-only).");
      sub.callback([args] {
        const auto& r = args->request;
        const std::string run =
            r.out.empty()
                ? (std::filesystem::path("runs") / std::filesystem::path(r.config_path).stem())
                      .string()
                : r.out;
        // A run folder this command created goes when it fails before its first checkpoint
        // (e.g. --resume of a folder that holds none); one with a checkpoint stays resumable.
        const bsms::cli::RemoveOnFailure cleanup(run, [run] {
          std::error_code ec;
          return std::filesystem::exists(std::filesystem::path(run) / "checkpoints" / "latest.pt",
                                         ec);
        });
        bsms::train(r);
      });
    });

}  // namespace
