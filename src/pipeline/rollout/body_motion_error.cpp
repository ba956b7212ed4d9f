#include "pipeline/rollout/body_motion_error.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace bsms {

BodyMotionError body_motion_error(const torch::Tensor& predicted, const torch::Tensor& truth,
                                  const std::vector<int32_t>& body_id) {
  if (predicted.dim() != 2 || predicted.sizes() != truth.sizes() || predicted.size(1) < 1 ||
      predicted.size(1) > 3)
    throw std::logic_error("body_motion_error: positions must be two [N, dim] tensors, dim 1-3");
  const int64_t n = predicted.size(0);
  const int dim = static_cast<int>(predicted.size(1));
  if (!body_id.empty() && static_cast<int64_t>(body_id.size()) != n)
    throw std::logic_error("body_motion_error: " + std::to_string(body_id.size()) +
                           " body ids for " + std::to_string(n) + " nodes");
  BodyMotionError out;
  if (n == 0) return out;
  const auto p = predicted.to(torch::kFloat64).contiguous();
  const auto q = truth.to(torch::kFloat64).contiguous();
  using Rows =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  const Rows P(p.data_ptr<double>(), n, dim), Q(q.data_ptr<double>(), n, dim);

  // Dense body index per node.
  std::unordered_map<int32_t, int> index;
  std::vector<int> body(n, 0);
  if (!body_id.empty())
    for (int64_t i = 0; i < n; ++i)
      body[i] = index.emplace(body_id[i], static_cast<int>(index.size())).first->second;
  const int bodies = std::max<int>(1, static_cast<int>(index.size()));

  // At most 3 × 3: fixed-capacity storage, no allocation per node.
  using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 3, 1>;
  using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>;
  std::vector<Vec> p_sum(bodies, Vec::Zero(dim)), q_sum(bodies, Vec::Zero(dim));
  std::vector<int64_t> count(bodies, 0);
  for (int64_t i = 0; i < n; ++i) {
    p_sum[body[i]] += P.row(i).transpose();
    q_sum[body[i]] += Q.row(i).transpose();
    ++count[body[i]];
  }
  std::vector<Mat> h(bodies, Mat::Zero(dim, dim));
  std::vector<double> about_centre(bodies, 0.0);  // Σ|p'_i - q'_i|²
  for (int64_t i = 0; i < n; ++i) {
    const int b = body[i];
    const double c = static_cast<double>(count[b]);
    const Vec pc = P.row(i).transpose() - p_sum[b] / c;
    const Vec qc = Q.row(i).transpose() - q_sum[b] / c;
    h[b] += pc * qc.transpose();
    about_centre[b] += (pc - qc).squaredNorm();
  }
  double centre = 0, rotation = 0, deformation = 0;
  for (int b = 0; b < bodies; ++b) {
    const double c = static_cast<double>(count[b]);
    if (count[b] == 0) continue;
    centre += c * ((p_sum[b] - q_sum[b]) / c).squaredNorm();
    // max over rotations of tr(R H) (Kabsch): the singular values with the last one signed by
    // det H, so that no reflection is counted as a rotation.
    const Vec s = Eigen::JacobiSVD<Mat>(h[b]).singularValues();
    double best = s.head(dim - 1).sum();
    const double det = h[b].determinant();
    best += (det < 0 ? -1.0 : 1.0) * s(dim - 1);
    const double turned = std::clamp(2.0 * (best - h[b].trace()), 0.0, about_centre[b]);
    rotation += turned;
    deformation += about_centre[b] - turned;
  }
  const double values = static_cast<double>(n) * dim;
  out.centre = centre / values;
  out.rotation = rotation / values;
  out.deformation = deformation / values;
  return out;
}

}  // namespace bsms
