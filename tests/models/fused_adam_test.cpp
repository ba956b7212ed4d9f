// FusedAdam against LibTorch's Adam: the same trajectory of parameters and moments over many
// steps (small tensors, and one large enough for the parallel loop), the same state in a
// checkpoint (either reads the other's), and LibTorch's path where the fused loop does not apply.
#include "models/fused_adam.hpp"

#include <gtest/gtest.h>
#include <torch/serialize.h>
#include <torch/torch.h>

#include <sstream>
#include <vector>

namespace {

// Parameters of several shapes: a bias, a matrix, and one of 70,000 elements (> 2 grains).
std::vector<torch::Tensor> make_params(uint64_t seed) {
  torch::manual_seed(seed);
  std::vector<torch::Tensor> ps = {torch::randn({7}), torch::randn({33, 17}),
                                   torch::randn({70000})};
  for (auto& p : ps) p.requires_grad_(true);
  return ps;
}

std::vector<torch::Tensor> clone_params(const std::vector<torch::Tensor>& ps) {
  std::vector<torch::Tensor> out;
  for (const auto& p : ps) out.push_back(p.detach().clone().requires_grad_(true));
  return out;
}

// A loss whose gradients change sign and scale from step to step (so the moments matter).
void set_grads(std::vector<torch::Tensor>& ps, int step) {
  torch::manual_seed(1000 + step);
  for (auto& p : ps) {
    torch::NoGradGuard guard;
    auto g = torch::randn_like(p) * (1.0 + 0.5 * step) + 0.1 * p.detach();
    p.mutable_grad() = g;
  }
}

// Largest difference relative to the tensor's scale (elements near zero would make an
// element-wise ratio measure nothing but rounding).
double max_relative(const torch::Tensor& a, const torch::Tensor& b) {
  const double d = (a - b).abs().max().item<double>();
  return d / b.abs().max().item<double>();
}

TEST(FusedAdam, FollowsLibTorchAdamStepByStep) {
  auto a = make_params(3);
  auto b = clone_params(a);
  const auto options = torch::optim::AdamOptions(3e-3).betas({0.9, 0.999}).eps(1e-8);
  bsms::FusedAdam fused(a, options);
  torch::optim::Adam reference(b, options);
  for (int step = 0; step < 40; ++step) {
    set_grads(a, step);
    set_grads(b, step);
    // The learning rate changes as the trainer's schedule changes it.
    for (auto* opt : {static_cast<torch::optim::Optimizer*>(&fused),
                      static_cast<torch::optim::Optimizer*>(&reference)})
      static_cast<torch::optim::AdamOptions&>(opt->param_groups()[0].options())
          .lr(3e-3 * (1.0 - step / 50.0));
    fused.step();
    reference.step();
    ASSERT_TRUE(fused.last_step_fused());
  }
  for (size_t i = 0; i < a.size(); ++i) {
    // Moved well away from the start, and within float rounding of the reference.
    EXPECT_GT((a[i] - make_params(3)[i]).abs().max().item<double>(), 1e-2) << i;
    EXPECT_LT(max_relative(a[i], b[i]), 1e-5) << i;
    const auto key = c10::guts::to_string(a[i].unsafeGetTensorImpl());
    const auto ref_key = c10::guts::to_string(b[i].unsafeGetTensorImpl());
    const auto& s = static_cast<torch::optim::AdamParamState&>(*fused.state().at(key));
    const auto& r = static_cast<torch::optim::AdamParamState&>(*reference.state().at(ref_key));
    EXPECT_EQ(s.step(), 40);
    EXPECT_EQ(s.step(), r.step());
    EXPECT_LT(max_relative(s.exp_avg(), r.exp_avg()), 1e-5) << i;
    EXPECT_LT(max_relative(s.exp_avg_sq(), r.exp_avg_sq()), 1e-5) << i;
  }
}

TEST(FusedAdam, CheckpointsReadEitherWay) {
  auto a = make_params(5);
  auto b = clone_params(a);
  bsms::FusedAdam fused(a, torch::optim::AdamOptions(1e-2));
  for (int step = 0; step < 5; ++step) {
    set_grads(a, step);
    fused.step();
  }
  // Fused state into LibTorch's Adam, both continue: the same parameters after 5 more steps.
  {
    torch::NoGradGuard guard;
    for (size_t i = 0; i < a.size(); ++i) b[i].copy_(a[i]);
  }
  std::stringstream saved;
  {
    torch::serialize::OutputArchive archive;
    fused.save(archive);
    archive.save_to(saved);
  }
  torch::optim::Adam reference(b, torch::optim::AdamOptions(1e-2));
  {
    torch::serialize::InputArchive archive;
    archive.load_from(saved);
    reference.load(archive);
  }
  for (int step = 5; step < 10; ++step) {
    set_grads(a, step);
    set_grads(b, step);
    fused.step();
    reference.step();
  }
  for (size_t i = 0; i < a.size(); ++i) EXPECT_LT(max_relative(a[i], b[i]), 1e-5) << i;

  // And LibTorch's state into a FusedAdam.
  std::stringstream saved_reference;
  {
    torch::serialize::OutputArchive archive;
    reference.save(archive);
    archive.save_to(saved_reference);
  }
  auto c = clone_params(b);
  bsms::FusedAdam resumed(c, torch::optim::AdamOptions(1e-2));
  {
    torch::serialize::InputArchive archive;
    archive.load_from(saved_reference);
    resumed.load(archive);
  }
  set_grads(b, 10);
  set_grads(c, 10);
  reference.step();
  resumed.step();
  EXPECT_TRUE(resumed.last_step_fused());
  for (size_t i = 0; i < b.size(); ++i) EXPECT_LT(max_relative(c[i], b[i]), 1e-5) << i;
}

TEST(FusedAdam, UsesLibTorchAdamWhereTheLoopDoesNotApply) {
  // Weight decay, AMSGrad and a double parameter each take LibTorch's path, with its result.
  const std::vector<torch::optim::AdamOptions> variants = {
      torch::optim::AdamOptions(1e-2).weight_decay(1e-2),
      torch::optim::AdamOptions(1e-2).amsgrad(true)};
  for (const auto& options : variants) {
    auto a = make_params(9);
    auto b = clone_params(a);
    bsms::FusedAdam fused(a, options);
    torch::optim::Adam reference(b, options);
    for (int step = 0; step < 3; ++step) {
      set_grads(a, step);
      set_grads(b, step);
      fused.step();
      reference.step();
      EXPECT_FALSE(fused.last_step_fused());
    }
    for (size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(torch::equal(a[i], b[i])) << i;
  }
  auto d = torch::randn({5}, torch::kFloat64).requires_grad_(true);
  bsms::FusedAdam doubles({d}, torch::optim::AdamOptions(1e-2));
  d.mutable_grad() = torch::ones_like(d);
  const auto before = d.detach().clone();
  doubles.step();
  EXPECT_FALSE(doubles.last_step_fused());
  EXPECT_TRUE(torch::allclose(d.detach(), before - 1e-2, 0, 1e-9));
  // A parameter without a gradient is left alone and gets no state.
  auto p = torch::randn({4}).requires_grad_(true);
  bsms::FusedAdam idle({p}, torch::optim::AdamOptions(1e-2));
  const auto kept = p.detach().clone();
  idle.step();
  EXPECT_TRUE(torch::equal(p.detach(), kept));
  EXPECT_TRUE(idle.state().empty());
}

}  // namespace
