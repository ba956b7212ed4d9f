// bsms report RUN... --out DIR [--title T] [--rollout NAME] [--solver-frontier DIR]
#include <iostream>

#include "cli/command.hpp"
#include "pipeline/report/report.hpp"

namespace {

BSMS_COMMAND("report", "table and plots (speed vs error, RMSE over steps, loss) from runs",
             [](CLI::App& sub) {
               auto r = std::make_shared<bsms::ReportRequest>();
               sub.add_option("runs", r->runs, "run folders with rollout/metrics.json")->required();
               sub.add_option("--out", r->out, "report folder (report.md, plots/)")->required();
               sub.add_option("--title", r->title, "report title");
               sub.add_option("--rollout", r->rollout,
                              "rollout folder read in each run (default rollout; e.g. "
                              "rollout_symmetric, rollout_ensemble)");
               sub.add_option("--solver-frontier", r->solver_frontier,
                              "output folder of bsms experiment solver-frontier: the solver at "
                              "cheaper settings beside the models (plot, table, and whether a "
                              "setting beats each run at equal cost)");
               sub.callback([r] { std::cout << bsms::write_report(*r) << '\n'; });
             });

}  // namespace
