// bsms report RUN... [--out DIR]
#include <iostream>

#include "cli/command.hpp"
#include "pipeline/report.hpp"

namespace {

BSMS_COMMAND("report", "table and plots (speed vs error, RMSE over steps, loss) from runs",
             [](CLI::App& sub) {
               auto r = std::make_shared<bsms::ReportRequest>();
               sub.add_option("runs", r->runs, "run folders with rollout/metrics.json")->required();
               sub.add_option("--out", r->out, "report folder (report.md, plots/)")->required();
               sub.add_option("--title", r->title, "report title");
               sub.callback([r] { std::cout << bsms::write_report(*r) << '\n'; });
             });

}  // namespace
