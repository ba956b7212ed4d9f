// The shared optimisation loop (pipeline/fit): schedule, stops, resume and the finite-loss check.
#include "pipeline/train/fit.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <string>

#include "core/error.hpp"

namespace bsms {
namespace {

// Least squares of a 1-parameter model w * x on y = 3 x: fit() must drive w to 3.
struct Line {
  torch::Tensor w = torch::zeros({1}, torch::requires_grad());
  torch::Tensor loss() const {
    const auto x = torch::linspace(-1, 1, 16);
    return (w * x - 3 * x).square().mean();
  }
};

FitOptions quiet(int64_t steps) {
  FitOptions o;
  o.optimizer.lr = 0.1;
  o.optimizer.lr_final = 0.01;
  o.steps = steps;
  o.quiet = true;
  return o;
}

TEST(Fit, ConvergesFollowsTheScheduleAndReportsEveryStep) {
  Line line;
  torch::optim::Adam adam({line.w}, torch::optim::AdamOptions(0.1));
  std::vector<FitStep> seen;
  std::vector<int64_t> indices;
  FitHooks hooks;
  hooks.loss = [&](int64_t index) {
    indices.push_back(index);
    return line.loss();
  };
  hooks.after_step = [&](const FitStep& s) {
    seen.push_back(s);
    return std::string();
  };
  const FitOptions o = quiet(400);
  const FitResult r = fit(adam, o, hooks);
  EXPECT_EQ(r.step, 400);
  ASSERT_EQ(seen.size(), 400u);
  EXPECT_EQ(indices.front(), 0);
  EXPECT_EQ(indices.back(), 399);
  EXPECT_EQ(seen.back().step, 400);
  EXPECT_NEAR(line.w.item<double>(), 3.0, 1e-2);
  EXPECT_LT(r.last_loss, 1e-4);
  // The schedule: lr at step s is learning_rate(optimizer, s, s / steps).
  for (int64_t s : {0, 100, 399})
    EXPECT_DOUBLE_EQ(seen[s].lr, learning_rate(o.optimizer, s, static_cast<double>(s) / 400.0));
  EXPECT_EQ(r.step_ms.size(), 400u);
  EXPECT_GE(r.median_step_ms(), 0.0);
}

TEST(Fit, ResumesStopsEarlyAndHonoursTheTimeBudget) {
  Line line;
  torch::optim::Adam adam({line.w}, torch::optim::AdamOptions(0.1));
  FitHooks hooks;
  int64_t first = -1;
  hooks.loss = [&](int64_t index) {
    if (first < 0) first = index;
    return line.loss();
  };
  FitOptions o = quiet(100);
  o.first_step = 40;
  o.stop_step = 60;
  const FitResult r = fit(adam, o, hooks);
  EXPECT_EQ(first, 40);
  EXPECT_EQ(r.step, 60);
  EXPECT_EQ(r.step_ms.size(), 20u);
  // A budget already spent runs no step; the progress then counts time.
  o.first_step = 0;
  o.stop_step = 0;
  o.time_budget_s = 10.0;
  o.wall_before = 10.0;
  EXPECT_EQ(fit(adam, o, hooks).step, 0);
  EXPECT_DOUBLE_EQ(fit_progress(o, 10, 5.0), 0.5);   // time share beats 10 / 100 steps
  EXPECT_DOUBLE_EQ(fit_progress(o, 80, 5.0), 0.8);   // step share beats time
  EXPECT_DOUBLE_EQ(fit_progress(o, 80, 50.0), 1.0);  // capped
}

TEST(Fit, NonFiniteLossNamesTheStep) {
  Line line;
  torch::optim::Adam adam({line.w}, torch::optim::AdamOptions(0.1));
  FitHooks hooks;
  hooks.loss = [&](int64_t index) { return index == 7 ? line.loss() * std::nan("") : line.loss(); };
  FitOptions o = quiet(20);
  o.label = "train probe";
  try {
    fit(adam, o, hooks);
    FAIL() << "no error";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("train probe: step 7"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bsms
