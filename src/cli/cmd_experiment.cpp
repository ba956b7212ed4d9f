// bsms experiment zero-shot|seeding|long-rollout: hard-case experiments on trained runs, each a
// report section (OUT/<name>.md, OUT/plots/*.png) and OUT/metrics.json.
#include <iostream>

#include "cli/command.hpp"
#include "pipeline/hard_cases.hpp"

namespace {

// Options every rollout experiment shares.
std::shared_ptr<bsms::HardCaseRequest> add_common(CLI::App& sub) {
  auto r = std::make_shared<bsms::HardCaseRequest>();
  sub.add_option("runs", r->runs, "trained run folders (bsms train)")->required();
  sub.add_option("--out", r->out, "experiment folder")->required();
  sub.add_option("--split", r->split, "dataset split to roll out")->default_val("test");
  sub.add_option("--trajectories", r->max_trajectories, "at most K trajectories (0 = all)")
      ->check(CLI::NonNegativeNumber);
  bsms::cli::add_threads_option(sub, r->threads);
  return r;
}

BSMS_COMMAND(
    "experiment", "hard-case experiments: zero-shot, seeding, long-rollout", [](CLI::App& sub) {
      sub.require_subcommand(1);
      {
        CLI::App* z = sub.add_subcommand(
            "zero-shot", "roll runs out on meshes at least 4x larger than their training meshes");
        auto r = add_common(*z);
        auto data = std::make_shared<std::string>();
        z->add_option("--data", *data, "dataset folder with the larger meshes")->required();
        z->callback([r, data] {
          bsms::zero_shot_experiment(*r, *data);
          std::cout << r->out << "/zero_shot.md\n";
        });
      }
      {
        CLI::App* s = sub.add_subcommand(
            "seeding",
            "roll BSMS runs out with MinAve, CloseCenter and random seeding at test time");
        auto r = add_common(*s);
        s->callback([r] {
          bsms::seeding_experiment(*r);
          std::cout << r->out << "/seeding.md\n";
        });
      }
      {
        CLI::App* l = sub.add_subcommand(
            "long-rollout",
            "error growth over 10x the training horizon and stability on hard scenes");
        auto r = add_common(*l);
        auto data = std::make_shared<std::string>();
        auto hard = std::make_shared<std::string>();
        l->add_option("--data", *data,
                      "dataset folder with trajectories >= 10x the training length")
            ->required();
        l->add_option("--hard", *hard, "dataset folder with hard scenes (optional)");
        l->callback([r, data, hard] {
          bsms::long_rollout_experiment(*r, *data, *hard);
          std::cout << r->out << "/long_rollout.md\n";
        });
      }
    });

}  // namespace
