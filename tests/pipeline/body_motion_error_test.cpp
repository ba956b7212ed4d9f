// The rollout's split of position error into each body's centre, rotation and deformation
// (pipeline/rollout/body_motion_error.hpp): rigid motions land in centre and rotation only, the
// parts add up to the position MSE, the deformation is the minimum over rotations (against a
// brute-force search), and a mirror image is not a rotation.
#include "pipeline/rollout/body_motion_error.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <random>
#include <set>

namespace bsms {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Random points of `bodies` bodies (ids 10, 11, ...; nodes interleaved), each around its own
// centre.
torch::Tensor random_bodies(int64_t n, int dim, int bodies, std::vector<int32_t>& ids,
                            std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  auto x = torch::zeros({n, dim}, torch::kFloat64);
  auto a = x.accessor<double, 2>();
  ids.assign(n, 0);
  for (int64_t i = 0; i < n; ++i) {
    ids[i] = 10 + static_cast<int32_t>(i % bodies);
    for (int d = 0; d < dim; ++d) a[i][d] = 3.0 * ids[i] * (d + 1) + 0.2 * normal(rng);
  }
  return x;
}

torch::Tensor rotation(int dim, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  if (dim == 2) {
    const double t = 2 * kPi * std::uniform_real_distribution<double>(0, 1)(rng);
    return torch::tensor({std::cos(t), -std::sin(t), std::sin(t), std::cos(t)}, torch::kFloat64)
        .view({2, 2});
  }
  // 3D: QR of a Gaussian matrix, signs fixed to a proper rotation.
  auto [q, r] = torch::linalg_qr(torch::randn({3, 3}, torch::kFloat64));
  q = q * r.diagonal().sign().unsqueeze(0);
  if (torch::det(q).item<double>() < 0) q.select(1, 0).neg_();
  return q;
}

// Each body of `x` rotated by `r` about its centroid and moved by its own offset.
torch::Tensor rigidly_moved(const torch::Tensor& x, const std::vector<int32_t>& ids,
                            const torch::Tensor& r, double offset_scale) {
  auto out = x.clone();
  const auto id = torch::tensor(std::vector<int64_t>(ids.begin(), ids.end()));
  for (int32_t b : std::set<int32_t>(ids.begin(), ids.end())) {
    const auto mask = id == b;
    const auto pts = x.index({mask});
    const auto c = pts.mean(0, true);
    const auto offset = torch::full({1, x.size(1)}, offset_scale * (b - 9), torch::kFloat64);
    out.index_put_({mask}, (pts - c).matmul(r.t()) + c + offset);
  }
  return out;
}

Eigen::MatrixXd to_eigen(const torch::Tensor& x) {
  const auto c = x.to(torch::kFloat64).contiguous();
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      c.data_ptr<double>(), c.size(0), c.size(1));
}

double mse(const torch::Tensor& a, const torch::Tensor& b) {
  return (a - b).pow(2).mean().item<double>();
}

TEST(BodyMotionError, RigidMotionsAreCentreAndRotationOnly) {
  std::mt19937 rng(3);
  torch::manual_seed(3);
  for (int dim : {2, 3}) {
    std::vector<int32_t> ids;
    const auto x = random_bodies(90, dim, 3, ids, rng);
    // Translation of each body: all centre.
    const auto moved = rigidly_moved(x, ids, torch::eye(dim, torch::kFloat64), 0.05);
    BodyMotionError e = body_motion_error(moved, x, ids);
    EXPECT_NEAR(e.centre, mse(moved, x), 1e-12);
    EXPECT_NEAR(e.rotation, 0.0, 1e-12);
    EXPECT_NEAR(e.deformation, 0.0, 1e-12);
    // Rotation about each centroid and translation: nothing is deformation.
    const auto r = rotation(dim, rng);
    const auto turned = rigidly_moved(x, ids, r, 0.05);
    e = body_motion_error(turned, x, ids);
    EXPECT_NEAR(e.centre, 0.0025 * (1 + 4 + 9) / 3.0, 1e-12) << dim;
    EXPECT_NEAR(e.rotation, mse(rigidly_moved(x, ids, r, 0.0), x), 1e-12) << dim;
    EXPECT_GT(e.rotation, 1e-5) << dim;
    EXPECT_NEAR(e.deformation, 0.0, 1e-12) << dim;
    EXPECT_NEAR(e.total(), mse(turned, x), 1e-12) << dim;
    // Seen as one body, the bodies' separate turns are no longer one rigid motion.
    EXPECT_GT(body_motion_error(turned, x, {}).deformation, 1e-4) << dim;
  }
}

TEST(BodyMotionError, PartsAddUpAndDeformationIsTheMinimumOverRotations) {
  std::mt19937 rng(5);
  torch::manual_seed(5);
  for (int trial = 0; trial < 40; ++trial) {
    const int dim = trial % 2 == 0 ? 2 : 3;
    std::vector<int32_t> ids;
    const auto truth = random_bodies(30 + trial, dim, 1 + trial % 3, ids, rng);
    const auto pred = rigidly_moved(truth, ids, rotation(dim, rng), 0.01) +
                      0.01 * torch::randn(truth.sizes(), torch::kFloat64);
    const BodyMotionError e = body_motion_error(pred, truth, ids);
    EXPECT_GE(e.centre, 0.0);
    EXPECT_GE(e.rotation, 0.0);
    EXPECT_GT(e.deformation, 0.0);
    EXPECT_NEAR(e.total(), mse(pred, truth), 1e-12 * mse(pred, truth) + 1e-15);
    // Brute force: per body, the smallest residual about the centroids over many rotations.
    double best_sum = 0.0;
    const auto id = torch::tensor(std::vector<int64_t>(ids.begin(), ids.end()));
    for (int b = 10; b < 10 + 1 + trial % 3; ++b) {
      const auto mask = id == b;
      const auto pt = pred.index({mask}) - pred.index({mask}).mean(0, true);
      const auto qt = truth.index({mask}) - truth.index({mask}).mean(0, true);
      const Eigen::MatrixXd p = to_eigen(pt), q = to_eigen(qt);
      double best = std::numeric_limits<double>::infinity();
      if (dim == 2) {
        for (int k = 0; k < 20000; ++k)
          best = std::min(
              best,
              ((p * Eigen::Rotation2Dd(2 * kPi * k / 20000.0).toRotationMatrix().transpose()) - q)
                  .squaredNorm());
      } else {
        std::normal_distribution<double> normal(0.0, 1.0);
        for (int k = 0; k < 20000; ++k) {
          Eigen::Quaterniond r(normal(rng), normal(rng), normal(rng), normal(rng));
          r.normalize();
          best = std::min(best, (p * r.toRotationMatrix().transpose() - q).squaredNorm());
        }
      }
      best_sum += best;
    }
    const double brute = best_sum / static_cast<double>(truth.numel());
    // Never beaten by a sampled rotation; in 2D the grid of 20,000 angles comes within 1e-4.
    EXPECT_LE(e.deformation, brute * (1 + 1e-12)) << trial;
    if (dim == 2) {
      EXPECT_GT(e.deformation, brute * (1 - 1e-4)) << trial;
    }
  }
}

TEST(BodyMotionError, AMirrorImageIsNotARotation) {
  // A triangle and its mirror image about its centroid's vertical line: the best rotation cannot
  // undo a reflection, so part of the error stays deformation.
  const auto truth = torch::tensor({0.0, 0.0, 1.0, 0.0, 0.2, 2.0}, torch::kFloat64).view({3, 2});
  auto mirrored = truth.clone();
  const double cx = truth.select(1, 0).mean().item<double>();
  mirrored.select(1, 0).copy_(2 * cx - truth.select(1, 0));
  const BodyMotionError e = body_motion_error(mirrored, truth, {});
  EXPECT_NEAR(e.centre, 0.0, 1e-15);
  EXPECT_GT(e.deformation, 0.01);
  EXPECT_NEAR(e.total(), mse(mirrored, truth), 1e-14);
  // Float positions, a single node and one dimension work as well.
  EXPECT_NEAR(
      body_motion_error(truth.to(torch::kFloat32) + 0.5f, truth.to(torch::kFloat32), {}).centre,
      0.25, 1e-7);
  const auto one = torch::tensor({1.0, 2.0}, torch::kFloat64).view({1, 2});
  EXPECT_NEAR(body_motion_error(one + 1.0, one, {7}).centre, 1.0, 1e-15);
  const auto line = torch::tensor({0.0, 1.0, 3.0}, torch::kFloat64).view({3, 1});
  const BodyMotionError e1 = body_motion_error(line * 2.0, line, {});
  EXPECT_NEAR(e1.rotation, 0.0, 1e-15);  // no rotation in 1D: stretch is deformation
  EXPECT_NEAR(e1.total(), mse(line * 2.0, line), 1e-14);
}

TEST(BodyMotionError, MismatchedInputsAreLogicErrors) {
  const auto x = torch::zeros({4, 2});
  EXPECT_THROW(body_motion_error(x, torch::zeros({4, 3}), {}), std::logic_error);
  EXPECT_THROW(body_motion_error(x, x, {1, 2}), std::logic_error);
  EXPECT_THROW(body_motion_error(torch::zeros({4, 4}), torch::zeros({4, 4}), {}), std::logic_error);
}

}  // namespace
}  // namespace bsms
