#include "models/parameter_ema.hpp"

#include <gtest/gtest.h>
#include <torch/torch.h>

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "models/checkpoint.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

// Two layers and a buffer: the average covers the parameters only.
struct Small : torch::nn::Module {
  Small() {
    a = register_module("a", torch::nn::Linear(3, 4));
    b = register_module("b", torch::nn::Linear(4, 2));
    count = register_buffer("count", torch::zeros({2}, torch::kFloat64));
  }
  torch::Tensor forward(const torch::Tensor& x) { return b(torch::tanh(a(x))); }
  torch::nn::Linear a{nullptr}, b{nullptr};
  torch::Tensor count;
};

std::vector<torch::Tensor> parameter_values(const torch::nn::Module& m) {
  std::vector<torch::Tensor> out;
  for (const auto& p : m.parameters()) out.push_back(p.detach().clone());
  return out;
}

void set_parameters(torch::nn::Module& m, const std::vector<torch::Tensor>& values) {
  torch::NoGradGuard no_grad;
  auto params = m.parameters();
  for (size_t i = 0; i < params.size(); ++i) params[i].copy_(values[i]);
}

double max_difference(const std::vector<torch::Tensor>& a, const std::vector<torch::Tensor>& b) {
  double worst = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    worst = std::max(
        worst, (a[i].to(torch::kFloat64) - b[i].to(torch::kFloat64)).abs().max().item<double>());
  return worst;
}

std::vector<torch::Tensor> averages_of(const ParameterEma& ema) {
  std::vector<torch::Tensor> out;
  for (const auto& [name, value] : ema.averages()) out.push_back(value);
  return out;
}

TEST(ParameterEma, FollowsTheRecurrenceWithItsWarmUp) {
  torch::manual_seed(3);
  Small m;
  const double decay = 0.9;
  ParameterEma ema(m, decay);
  EXPECT_NEAR(ema.next_decay(), 0.1, 1e-15);  // (1 + 0) / (10 + 0)
  // Brute force in double: e_0 = p_0, e ← d_n e + (1 − d_n) p with d_n = min(decay, ...).
  std::vector<torch::Tensor> expected;
  for (const auto& p : parameter_values(m)) expected.push_back(p.to(torch::kFloat64));
  for (int n = 0; n < 200; ++n) {
    std::vector<torch::Tensor> next;
    for (const auto& p : parameter_values(m)) next.push_back(p + 0.05 * torch::randn_like(p));
    set_parameters(m, next);
    const double d = std::min(decay, (1.0 + n) / (10.0 + n));
    EXPECT_NEAR(ema.next_decay(), d, 1e-15) << n;
    ema.update();
    for (size_t i = 0; i < expected.size(); ++i)
      expected[i] = d * expected[i] + (1.0 - d) * next[i].to(torch::kFloat64);
  }
  EXPECT_EQ(ema.updates(), 200);
  EXPECT_NEAR(ema.next_decay(), decay, 1e-15);
  EXPECT_LT(max_difference(averages_of(ema), expected), 1e-5);
  // The average moved less than the weights: it is a mean of the random walk, not its end.
  EXPECT_GT(max_difference(averages_of(ema), parameter_values(m)), 0.01);
}

TEST(ParameterEma, CoversTheParametersOnlyAndRestarts) {
  Small m;
  ParameterEma ema(m, 0.99);
  std::vector<std::string> names;
  for (const auto& [name, value] : ema.averages()) names.push_back(name);
  EXPECT_EQ(names, (std::vector<std::string>{"a.weight", "a.bias", "b.weight", "b.bias"}));
  set_parameters(m, [&] {
    auto v = parameter_values(m);
    for (auto& t : v) t.fill_(2.0f);
    return v;
  }());
  ema.update();
  EXPECT_GT(max_difference(averages_of(ema), parameter_values(m)), 0.1);
  ema.restart();
  EXPECT_EQ(ema.updates(), 0);
  EXPECT_EQ(max_difference(averages_of(ema), parameter_values(m)), 0.0);
  EXPECT_THROW(ParameterEma(m, 1.0), std::invalid_argument);
  EXPECT_THROW(ParameterEma(m, 0.0), std::invalid_argument);
}

TEST(ParameterEma, ModulePredictsWithTheAverageInsideTheScopeOnly) {
  torch::manual_seed(5);
  Small m;
  ParameterEma ema(m, 0.9);
  for (int n = 0; n < 20; ++n) {
    auto v = parameter_values(m);
    for (auto& t : v) t.add_(0.1 * torch::randn_like(t));
    set_parameters(m, v);
    ema.update();
  }
  const auto weights = parameter_values(m);
  const auto average = [&] {
    std::vector<torch::Tensor> out;
    for (const auto& t : averages_of(ema)) out.push_back(t.clone());
    return out;
  }();
  ASSERT_GT(max_difference(weights, average), 0.01);
  const torch::Tensor x = torch::randn({5, 3});
  const torch::Tensor trained = m.forward(x).detach();
  torch::Tensor averaged;
  {
    const AverageInModule scope(&ema);
    EXPECT_EQ(max_difference(parameter_values(m), average), 0.0);
    EXPECT_EQ(max_difference(averages_of(ema), weights), 0.0);
    averaged = m.forward(x).detach();
  }
  // Back bit for bit, also after a scope left by an exception; the average itself unchanged.
  EXPECT_EQ(max_difference(parameter_values(m), weights), 0.0);
  EXPECT_EQ(max_difference(averages_of(ema), average), 0.0);
  EXPECT_FALSE(torch::allclose(trained, averaged));
  try {
    const AverageInModule scope(&ema);
    throw std::runtime_error("inside");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(max_difference(parameter_values(m), weights), 0.0);
  EXPECT_EQ(max_difference(averages_of(ema), average), 0.0);
  const AverageInModule none(nullptr);  // no average: nothing to do
  EXPECT_EQ(max_difference(parameter_values(m), weights), 0.0);
}

class CheckpointEma : public ::testing::Test {
 protected:
  // A few Adam steps on a regression, the average following: weights and average differ.
  void SetUp() override {
    torch::manual_seed(11);
    file_ = (testing::unique_temp_dir("ema") / "latest.h5").string();
    adam_ = std::make_unique<torch::optim::Adam>(m_.parameters(), torch::optim::AdamOptions(0.05));
    ema_ = std::make_unique<ParameterEma>(m_, 0.95);
    const torch::Tensor x = torch::randn({32, 3}), y = torch::randn({32, 2});
    for (int step = 0; step < 30; ++step) {
      adam_->zero_grad();
      (m_.forward(x) - y).square().mean().backward();
      adam_->step();
      ema_->update();
    }
    state_.step = 30;
    save_checkpoint_file(file_, m_, adam_.get(), &state_, ema_.get());
  }
  std::string error_of(const std::function<void(CheckpointContents&)>& damage) {
    CheckpointContents c = read_checkpoint_contents(file_, read_checkpoint_bytes(file_));
    damage(c);
    const std::string damaged = file_ + ".damaged.h5";
    write_checkpoint_contents(damaged, c);
    Small fresh;
    try {
      load_checkpoint_image(damaged, read_checkpoint_bytes(damaged), fresh, nullptr);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  Small m_;
  std::unique_ptr<torch::optim::Adam> adam_;
  std::unique_ptr<ParameterEma> ema_;
  TrainingState state_;
  std::string file_;
};

TEST_F(CheckpointEma, PredictionsLoadTheAverageTrainingLoadsTheWeights) {
  ASSERT_GT(max_difference(averages_of(*ema_), parameter_values(m_)), 1e-3);
  const std::string bytes = read_checkpoint_bytes(file_);
  const CheckpointContents c = read_checkpoint_contents(file_, bytes);
  EXPECT_EQ(c.ema.size(), 4u);
  EXPECT_EQ(c.ema_decay, 0.95);
  EXPECT_EQ(c.ema_updates, 30);

  Small predict;  // no optimizer: the average is the model; buffers as stored
  load_checkpoint_image(file_, bytes, predict, nullptr);
  EXPECT_EQ(max_difference(parameter_values(predict), averages_of(*ema_)), 0.0);

  Small resume;  // an optimizer: the training weights, and the average into its own object
  torch::optim::Adam adam(resume.parameters(), torch::optim::AdamOptions(0.05));
  ParameterEma ema(resume, 0.95);
  EXPECT_EQ(load_checkpoint_image(file_, bytes, resume, &adam, true, &ema).step, 30);
  EXPECT_EQ(max_difference(parameter_values(resume), parameter_values(m_)), 0.0);
  EXPECT_EQ(max_difference(averages_of(ema), averages_of(*ema_)), 0.0);
  EXPECT_EQ(ema.updates(), 30);

  // A training checkpoint without an average starts one from the loaded weights.
  const std::string plain = file_ + ".plain.h5";
  save_checkpoint_file(plain, m_, adam_.get(), &state_);
  ParameterEma again(resume, 0.95);
  again.update();
  load_checkpoint_image(plain, read_checkpoint_bytes(plain), resume, &adam, true, &again);
  EXPECT_EQ(again.updates(), 0);
  EXPECT_EQ(max_difference(averages_of(again), parameter_values(m_)), 0.0);
}

TEST_F(CheckpointEma, DamagedAveragesAreNamed) {
  EXPECT_EQ(error_of([](CheckpointContents&) {}), "");
  const std::string shape =
      error_of([](CheckpointContents& c) { c.ema[0].value = torch::zeros({7}, torch::kFloat32); });
  EXPECT_NE(shape.find("ema/" +
                       read_checkpoint_contents(file_, read_checkpoint_bytes(file_)).ema[0].name),
            std::string::npos)
      << shape;
  EXPECT_NE(shape.find("has shape [7]"), std::string::npos) << shape;
  const std::string partial = error_of([](CheckpointContents& c) { c.ema.pop_back(); });
  EXPECT_NE(partial.find("the average is partial"), std::string::npos) << partial;
  const std::string stranger = error_of([](CheckpointContents& c) {
    c.ema.push_back({"z.weight", torch::zeros({2})});
  });
  EXPECT_NE(stranger.find("ema/z.weight"), std::string::npos) << stranger;
  EXPECT_NE(stranger.find("names no entry"), std::string::npos) << stranger;
  const std::string buffer = error_of([](CheckpointContents& c) {
    c.ema.push_back({"count", torch::zeros({2}, torch::kFloat64)});
  });
  EXPECT_NE(buffer.find("not a parameter"), std::string::npos) << buffer;
  const std::string decay = error_of([](CheckpointContents& c) { c.ema_decay = 1.0; });
  EXPECT_NE(decay.find("decay"), std::string::npos) << decay;
  const std::string updates = error_of([](CheckpointContents& c) { c.ema_updates = -1; });
  EXPECT_NE(updates.find("updates -1"), std::string::npos) << updates;
  const std::string nan = error_of([](CheckpointContents& c) {
    c.ema[1].value = c.ema[1].value.clone();
    c.ema[1].value.view(-1)[0] = std::nanf("");
  });
  EXPECT_NE(nan.find("non-finite"), std::string::npos) << nan;
}

}  // namespace
}  // namespace bsms
