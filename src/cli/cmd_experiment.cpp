// bsms experiment heat-sticks|zero-shot|seeding|long-rollout|predictability|solver-frontier: the
// hard-case experiments, the solver's predictability and its speed-error frontier, each a report
// section (OUT/<name>.md, OUT/plots/*.png) and OUT/metrics.json.
#include <iostream>
#include <memory>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/physical_projection.hpp"
#include "pipeline/experiments/hard_cases.hpp"
#include "pipeline/experiments/heat_sticks.hpp"
#include "pipeline/experiments/predictability.hpp"
#include "pipeline/experiments/solver_frontier.hpp"
#include "pipeline/report/number_format.hpp"

namespace {

void print_heat_sticks_summary(const bsms::Json& m, const std::string& out) {
  std::cout << "heat-sticks (" << m["threads"].get<int>() << " thread(s), "
            << m["wall_s"].get<double>() << " s):\n";
  for (const char* key : {"bistride", "proximity"}) {
    const auto& r = m["models"][key];
    std::cout << "  " << r["label"].get<std::string>() << ": train RMSE "
              << r["train_rmse_final"].get<double>() << ", test RMSE alone "
              << r["rmse_alone"].get<double>() << ", two sticks " << r["rmse_pair"].get<double>()
              << ", near the gap " << r["rmse_pair_near_gap"].get<double>()
              << "; cross-gap edges per level "
              << r["test_hierarchy"]["cross_gap_edges_per_level"].dump() << "\n";
  }
  std::cout << "  -> " << out << "/heat_sticks.md\n";
}

void print_predictability_summary(const bsms::Json& m, const std::string& out) {
  std::cout << "predictability (" << m["trajectories"].get<int64_t>() << " trajectories, "
            << m["wall_s"].get<double>() << " s): RMSE-all / "
            << "constant velocity";
  for (const auto& row : m["points"])
    std::cout << "\n  "
              << (row["scale"].get<double>() > 0
                      ? bsms::format_number(row["scale"].get<double>()) + "x "
                      : std::string())
              << row["mode"].get<std::string>() << ": "
              << row["rmse_all_over_constant_velocity"].dump();
  std::cout << "\n  -> " << out << "/predictability.md\n";
}

void print_solver_frontier_summary(const bsms::SolverFrontier& m, const std::string& out) {
  std::cout << "solver-frontier (" << m.trajectories << " trajectories, " << m.threads
            << " solves at once, " << m.wall_s << " s): ms/frame, RMSE-all / constant velocity";
  const auto line = [](const bsms::FrontierSetting& s) {
    std::cout << "\n  " << s.name << ": " << bsms::format_number(s.ms_per_frame) << ", "
              << bsms::format_number(s.rmse_all_over_constant_velocity)
              << (s.unstable > 0 ? ", " + std::to_string(s.unstable) + " unstable" : "");
  };
  line(m.ground_truth);
  for (const auto& s : m.settings) line(s);
  std::cout << "\n  -> " << out << "/solver_frontier.md\n";
}

// Options every rollout experiment shares.
std::shared_ptr<bsms::HardCaseRequest> add_common(CLI::App& sub) {
  auto r = std::make_shared<bsms::HardCaseRequest>();
  sub.add_option("runs", r->runs, "trained run folders (bsms train)")->required();
  sub.add_option("--out", r->out, "experiment folder")->required();
  sub.add_option("--split", r->split, "dataset split to roll out")->default_val("test");
  sub.add_option("--max-trajectories", r->max_trajectories, "at most K trajectories (0 = all)")
      ->check(CLI::NonNegativeNumber);
  bsms::cli::add_threads_option(sub, r->threads);
  return r;
}

void add_heat_sticks(CLI::App& experiment) {
  auto o = std::make_shared<bsms::HeatSticksOptions>();
  CLI::App* heat = experiment.add_subcommand(
      "heat-sticks",
      "spatial-proximity failure case: BSMS-GNN with bi-stride vs proximity (grid) "
      "coarsening on 1-D steady heat, trained on single sticks, tested on two sticks "
      "across a gap");
  heat->add_option("--out", o->out, "output folder (metrics.json, heat_sticks.md, plots/)")
      ->required();
  heat->add_option("--steps", o->steps, "training steps per model")
      ->check(CLI::Range(int64_t{1}, int64_t{1000000000}))
      ->capture_default_str();
  heat->add_option("--nodes", o->nodes, "nodes per stick (>= 5)")->capture_default_str();
  heat->add_option("--levels", o->levels, "levels of both hierarchies, input graph included")
      ->capture_default_str();
  heat->add_option("--gap", o->gap, "gap between the two test sticks, in units of dx (> 0)")
      ->capture_default_str();
  heat->add_option("--latent", o->latent, "MLP width")->capture_default_str();
  heat->add_option("--batch", o->batch, "sticks per training step")
      ->check(CLI::Range(int64_t{1}, int64_t{1000000}))
      ->capture_default_str();
  heat->add_option("--draws", o->test_draws,
                   "boundary-condition draws per test orientation combination")
      ->check(CLI::Range(int64_t{1}, int64_t{1000000}))
      ->capture_default_str();
  heat->add_option("--seed", o->seed, "seed of weights, training and test draws")
      ->capture_default_str();
  bsms::cli::add_threads_option(*heat, o->threads);
  heat->footer(
      "Writes DIR/metrics.json (RMSEs per model, cross-gap edges per level), "
      "DIR/profiles.csv,\n"
      "DIR/train_log.csv, DIR/heat_sticks.md and DIR/plots/heat_sticks.png.");
  heat->callback([o] {
    const bsms::cli::RemoveOnFailure cleanup(o->out);
    const auto metrics = bsms::run_heat_sticks(*o);
    print_heat_sticks_summary(metrics, o->out);
  });
}

void add_zero_shot(CLI::App& experiment) {
  CLI::App* z = experiment.add_subcommand(
      "zero-shot", "roll runs out on meshes at least 4x larger than their training meshes");
  auto r = add_common(*z);
  auto data = std::make_shared<std::string>();
  z->add_option("--data", *data, "dataset folder with the larger meshes")->required();
  z->callback([r, data] {
    const bsms::cli::RemoveOnFailure cleanup(r->out);
    bsms::zero_shot_experiment(*r, *data);
    std::cout << r->out << "/zero_shot.md\n";
  });
}

void add_seeding(CLI::App& experiment) {
  CLI::App* s = experiment.add_subcommand(
      "seeding", "roll BSMS runs out with MinAve, CloseCenter and random seeding at test time");
  auto r = add_common(*s);
  auto data = std::make_shared<std::string>();
  s->add_option("--data", *data, "dataset folder to roll out (default: each run's own)");
  s->callback([r, data] {
    const bsms::cli::RemoveOnFailure cleanup(r->out);
    bsms::seeding_experiment(*r, *data);
    std::cout << r->out << "/seeding.md\n";
  });
}

void add_long_rollout(CLI::App& experiment) {
  CLI::App* l = experiment.add_subcommand(
      "long-rollout", "error growth over 10x the training horizon and stability on hard scenes");
  auto r = add_common(*l);
  auto data = std::make_shared<std::string>();
  auto hard = std::make_shared<std::string>();
  l->add_option("--data", *data, "dataset folder with trajectories >= 10x the training length")
      ->required();
  l->add_option("--hard-scenes", *hard, "dataset folder with hard scenes (optional)");
  bsms::cli::add_projection_option(*l, r->projection);
  l->callback([r, data, hard] {
    const bsms::cli::RemoveOnFailure cleanup(r->out);
    bsms::long_rollout_experiment(*r, *data, *hard);
    std::cout << r->out << "/long_rollout.md\n";
  });
}

void add_predictability(CLI::App& experiment) {
  auto o = std::make_shared<bsms::PredictabilityOptions>();
  CLI::App* p = experiment.add_subcommand(
      "predictability",
      "re-solve a generated dataset with random one-step body errors (kicks): the rollout "
      "error that a model with that one-step error and perfect physics otherwise reaches");
  p->add_option("--data", o->data, "dataset folder written by bsms generate")->required();
  p->add_option("--out", o->out, "output folder (metrics.json, predictability.md, plots/)")
      ->required();
  p->add_option("--split", o->split, "dataset split")->capture_default_str();
  p->add_option("--max-trajectories", o->max_trajectories, "at most K trajectories (0 = all)")
      ->check(CLI::NonNegativeNumber);
  p->add_option("--run", o->run,
                "trained run: base error from RUN/rollout_one_step/metrics.json (bsms "
                "rollout --one-step), its RUN/rollout curve drawn beside");
  p->add_option("--centre", o->centre,
                "base error of each body's centre per frame, m (RMS per component)")
      ->check(CLI::PositiveNumber);
  p->add_option("--rotation", o->rotation,
                "base error from each body's spin per frame, m (RMS per component)")
      ->check(CLI::NonNegativeNumber);
  p->add_option("--scales", o->scales, "multiples of the base error, ascending")
      ->delimiter(',')
      ->capture_default_str();
  p->add_option("--correlation", o->correlation,
                "correlation of the persistent rows' kicks between frames, in [0, 1) "
                "(default: as long as the run's one-step errors persist; 0: no such rows)")
      ->check(CLI::Range(0.0, 0.999));
  p->add_option("--draws", o->draws, "kick sequences per trajectory and scale")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  p->add_option("--target", o->target, "RMSE-all / constant velocity asked for")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  p->add_option("--seed", o->seed, "seed of the kicks")->capture_default_str();
  p->add_option("--solver-set", o->solver_set,
                "scene.KEY=VALUE: re-solve with the family's scene changed (repeatable), "
                "scored against the stored frames, e.g. "
                "scene.background.element_size=0.041");
  bsms::cli::add_threads_option(*p, o->threads);
  p->footer(
      "Example: bsms experiment predictability --data runs/long/data --run runs/slip/long "
      "--out runs/predictability");
  p->callback([o] {
    const bsms::cli::RemoveOnFailure cleanup(o->out);
    print_predictability_summary(bsms::predictability_experiment(*o), o->out);
  });
}

void add_solver_frontier(CLI::App& experiment) {
  auto o = std::make_shared<bsms::SolverFrontierOptions>();
  CLI::App* f = experiment.add_subcommand(
      "solver-frontier",
      "re-solve a generated dataset at cheaper solver settings (coarser background, larger "
      "CFL, coarser particles), scored against the stored frames like a rollout and timed: "
      "the solver's own speed-error frontier");
  f->add_option("--data", o->data, "dataset folder written by bsms generate")->required();
  f->add_option("--out", o->out, "output folder (metrics.json, solver_frontier.md)")->required();
  f->add_option("--split", o->split, "dataset split")->capture_default_str();
  f->add_option("--max-trajectories", o->max_trajectories, "at most K trajectories (0 = all)")
      ->check(CLI::NonNegativeNumber);
  f->add_option("--setting", o->settings,
                "NAME=scene.KEY=VALUE[,scene.KEY=VALUE...] (or sample.KEY=VALUE): a named "
                "solver setting, or the NAME of a default one (repeatable; default: "
                "background_x1.5, background_x2, cfl_x2, cfl_x3, spacing_x1.5 and another_mesh: "
                "the same resolution on another background mesh, the data's floor for a model)");
  f->add_flag("--quiet", o->quiet, "no progress bar");
  bsms::cli::add_threads_option(*f, o->threads);
  f->footer(
      "Solves run single-threaded, --threads at once. Example: bsms experiment "
      "solver-frontier --data runs/fr/data --out runs/fr/frontier --threads 2\n"
      "Then: bsms report RUN... --out DIR --solver-frontier runs/fr/frontier");
  f->callback([o] {
    const bsms::cli::RemoveOnFailure cleanup(o->out);
    print_solver_frontier_summary(bsms::solver_frontier_experiment(*o), o->out);
  });
}

// Each subcommand in its own function; --help lists them in this order.
BSMS_COMMAND("experiment", bsms::cli::handed_command_help("experiment"), [](CLI::App& sub) {
  sub.require_subcommand(1);
  add_heat_sticks(sub);
  add_zero_shot(sub);
  add_seeding(sub);
  add_long_rollout(sub);
  add_predictability(sub);
  add_solver_frontier(sub);
});

}  // namespace
