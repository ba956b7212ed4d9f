// bsms train CONFIG.json [--set key=value] [--out RUN] [--resume] [--threads T] [--nproc N]
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/error.hpp"
#include "core/runtime.hpp"
#include "pipeline/distributed/distributed.hpp"
#include "pipeline/distributed/launcher.hpp"
#include "pipeline/train/trainer.hpp"

namespace {

struct TrainArgs {
  bsms::TrainRequest request;
  int nproc = 1;
  double timeout_s = 300.0;
};

BSMS_COMMAND("train", bsms::cli::handed_command_help("train"), [](CLI::App& sub) {
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
  sub.add_option("--nproc", args->nproc,
                 "data-parallel ranks to start on this machine (c10d/Gloo); --threads and "
                 "optimizer.batch_size apply per rank")
      ->check(CLI::Range(1, 1024))
      ->default_val(1);
  sub.add_option("--timeout", args->timeout_s,
                 "seconds a rank waits for the others (rendezvous, all-reduce) before the "
                 "run stops, naming the rank and the step")
      ->check(CLI::Range(1.0, 86400.0))
      ->default_val(300.0);
  sub.footer(
      "Writes RUN/config.json (resolved), RUN/checkpoints/latest.h5 (model, normalizers,\n"
      "optimizer, step; HDF5, atomic), RUN/train_log.csv (step, wall_s, loss, valid_loss,\n"
      "valid_zero_prediction = the loss of predicting zero, lr) and RUN/train_stats.json.\n"
      "Multilevel graphs are built on first use and cached in DATA/multilevel/ (or\n"
      "RUN/multilevel/ when the data folder is read-only).\n"
      "Data parallel: --nproc N starts N ranks here; across machines run one command per\n"
      "machine with MASTER_ADDR, MASTER_PORT, WORLD_SIZE and NODE_RANK set (or start each\n"
      "rank yourself with torchrun's RANK, LOCAL_RANK, WORLD_SIZE). Rank 0 writes RUN.");
  sub.callback([args] {
    auto r = args->request;
    const std::string run =
        r.out.empty()
            ? (std::filesystem::path("runs") / std::filesystem::path(r.config_path).stem()).string()
            : r.out;
    // A run folder this command created goes when it fails before its first checkpoint
    // (e.g. --resume of a folder that holds none); one with a checkpoint stays resumable.
    // (An older run's LibTorch checkpoint, latest.pt, counts: it is never removed.)
    auto keep = [run] {
      std::error_code ec;
      const auto dir = std::filesystem::path(run) / "checkpoints";
      return std::filesystem::exists(dir / "latest.h5", ec) ||
             std::filesystem::exists(dir / "latest.pt", ec);
    };
    const bool launched = std::getenv("BSMS_LAUNCHED") != nullptr;
    if (args->nproc > 1 && !launched) {
      // The launcher: bad input is reported here, once, before any rank starts.
      bsms::check_train_request(r);
      const int cores = bsms::hardware_threads();
      if (r.threads > 0 && static_cast<int64_t>(r.threads) * args->nproc > cores)
        std::cerr << "bsms train: warning: " << args->nproc << " ranks x " << r.threads
                  << " threads on " << cores
                  << " hardware threads: oversubscribed (measured on 2 cores with 2 x 2: "
                     "3-20x slower per step than 2 x 1); use --threads "
                  << std::max(1, cores / args->nproc) << " or fewer ranks\n";
      const bsms::cli::RemoveOnFailure cleanup(run, keep);
      const int code = bsms::launch_local_ranks(bsms::cli::program_arguments(), args->nproc,
                                                args->timeout_s + 5.0);
      if (code != 0) throw bsms::SilentExit(code);
      return;
    }
    r.distributed = bsms::distributed_from_environment(args->timeout_s);
    // Only rank 0 owns the run folder (the others may share its file system).
    std::optional<bsms::cli::RemoveOnFailure> cleanup;
    if (r.distributed.rank == 0) cleanup.emplace(run, keep);
    bsms::train(r);
  });
});

}  // namespace
