#include "pipeline/train/fit.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/error.hpp"
#include "core/runtime.hpp"

namespace bsms {

double FitResult::median_step_ms() const {
  if (step_ms.empty()) return 0.0;
  std::vector<double> sorted = step_ms;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  return sorted[sorted.size() / 2];
}

double fit_progress(const FitOptions& o, int64_t step, double wall_s) {
  double p = o.steps > 0 ? static_cast<double>(step) / static_cast<double>(o.steps) : 1.0;
  if (o.time_budget_s > 0) p = std::max(p, wall_s / o.time_budget_s);
  return std::min(p, 1.0);
}

FitResult fit(torch::optim::Adam& optimizer, const FitOptions& o, const FitHooks& hooks) {
  const bool by_time = o.time_budget_s > 0;
  // With a time budget the bar counts seconds of the budget, not steps the run may never reach.
  ProgressBar bar(by_time ? o.label + " (s)" : o.label,
                  by_time ? static_cast<int64_t>(std::ceil(o.time_budget_s)) : o.steps);
  Stopwatch clock;
  FitResult r;
  r.step = o.first_step;
  const int64_t stop = o.stop_step > 0 ? std::min(o.stop_step, o.steps) : o.steps;
  auto wall = [&] { return o.wall_before + clock.seconds(); };
  const bool synchronized = static_cast<bool>(hooks.synchronize);
  double agreed_wall = o.wall_before;  // synchronized: the last wall time all ranks agreed on
  auto schedule_wall = [&] { return synchronized ? agreed_wall : wall(); };
  while (r.step < stop) {
    // A budget spent before the session's first step (later steps settle it: `last` below).
    if (by_time && r.step == o.first_step && schedule_wall() >= o.time_budget_s) break;
    Stopwatch step_clock;
    const double lr = learning_rate(o.optimizer, r.step, fit_progress(o, r.step, schedule_wall()));
    for (auto& group : optimizer.param_groups())
      static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
    optimizer.zero_grad();
    auto loss = hooks.loss(r.step);
    loss.backward();
    r.last_loss = loss.item<double>();
    if (synchronized) {
      const FitHooks::Agreed agreed = hooks.synchronize(r.step, r.last_loss, wall());
      r.last_loss = agreed.loss;
      agreed_wall = agreed.wall_s;
    }
    optimizer.step();
    r.last_lr = lr;
    if (!std::isfinite(r.last_loss))
      throw NumericalError(o.label + ": step " + std::to_string(r.step) +
                           ": loss is not finite (lower optimizer.lr or check the data)");
    ++r.step;
    r.step_ms.push_back(step_clock.milliseconds());
    // Whether this step is the last is settled before after_step, with the wall time it is
    // told, so that it can checkpoint the last step of a time budget like any other.
    const double now = schedule_wall();
    const bool last = r.step >= stop || (by_time && now >= o.time_budget_s);
    std::string extra;
    if (hooks.after_step) extra = hooks.after_step(FitStep{r.step, now, r.last_loss, lr, last});
    if (!o.quiet) {
      std::ostringstream text;
      text << "step " << r.step << ", loss " << std::setprecision(3) << r.last_loss << extra << ", "
           << std::setprecision(3) << 1000.0 / r.step_ms.back() << " steps/s";
      bar.update(by_time ? static_cast<int64_t>(wall()) : r.step, text.str());
    }
    if (last) break;
  }
  r.wall_s = wall();
  if (!o.quiet) bar.finish();
  return r;
}

}  // namespace bsms
