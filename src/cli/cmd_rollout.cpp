// bsms rollout RUN [--split test] [--data DIR] [--seeding S] [--out DIR]
// [--max-trajectories K] [--max-steps S] [--one-step] [--ensemble RUN2,...] [--symmetrize]
// [--project LIST] [--checkpoint best|latest] [--threads T]
#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/physical_projection.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/rollout/rollout_outputs.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace {

BSMS_COMMAND("rollout", bsms::cli::handed_command_help("rollout"), [](CLI::App& sub) {
  auto r = std::make_shared<bsms::RolloutRequest>();
  sub.add_option("run", r->run, "run folder written by bsms train")->required();
  sub.add_option("--split", r->split, "dataset split")->default_val("test");
  sub.add_option("--data", r->data,
                 "dataset folder (default: the run's training data; use another for "
                 "zero-shot tests)");
  sub.add_option("--seeding", r->seeding,
                 "seeding of the multilevel graphs at test time (default: the training "
                 "seeding)")
      ->check(CLI::IsMember(bsms::seeding_names()));
  sub.add_option("--out", r->out, "output folder (default RUN/rollout)");
  sub.add_option("--max-trajectories", r->max_trajectories, "roll out at most K (0 = all)")
      ->check(CLI::NonNegativeNumber);
  sub.add_option("--max-steps", r->max_steps, "at most S predicted steps each (0 = all)")
      ->check(CLI::NonNegativeNumber);
  sub.add_flag("--one-step", r->one_step,
               "teacher forcing: every step from the true frames (one-step errors along "
               "each trajectory; default output RUN/rollout_one_step; Lagrangian runs)");
  sub.add_option("--ensemble", r->ensemble,
                 "further Lagrangian runs: average their predicted accelerations with RUN's "
                 "at every step (default output RUN/rollout_ensemble)")
      ->delimiter(',');
  sub.add_flag("--symmetrize", r->symmetrize,
               "average each prediction over the symmetries of the data's box scene "
               "(reflections, equal-side axis swaps; default output "
               "RUN/rollout_symmetric)");
  bsms::cli::add_projection_option(sub, r->projection);
  sub.add_option("--checkpoint", r->checkpoint,
                 "the run's checkpoint: best (selected by validation rollouts, train config "
                 "valid_rollout_every) or latest (default: best when the run has one)")
      ->check(CLI::IsMember({"best", "latest"}));
  bsms::cli::add_threads_option(sub, r->threads);
  sub.footer(
      "Writes RUN/rollout/<split>.h5 (predicted world_pos and target_world_pos, dataset\n"
      "format), one XDMF per trajectory for ParaView, and RUN/rollout/metrics.json:\n"
      "RMSE over the first 1, 50 and all steps per field, inference ms per step, the\n"
      "solver's ms per frame and the speed-up, training ms per step, peak memory.");
  sub.callback([r] {
    // A rollout refused midway (a damaged trajectory) leaves no output folder it created.
    const bsms::cli::RemoveOnFailure cleanup(bsms::rollout_outputs::out_dir(*r).string());
    bsms::rollout(*r);
  });
});

}  // namespace
