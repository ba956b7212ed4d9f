#include "pipeline/rollout/rollout_domain.hpp"

#include <algorithm>
#include <cmath>

namespace bsms {

void FieldCurves::add(size_t step, const FieldError& error) {
  auto& sum = sum_[error.name];
  auto& weight = weight_[error.name];
  if (sum.size() <= step) {
    sum.resize(step + 1, 0.0);
    weight.resize(step + 1, 0.0);
  }
  sum[step] += error.sum;
  weight[step] += error.weight;
  steps_ = std::max(steps_, step + 1);
}

std::optional<FieldRmse> FieldCurves::rmse_over(size_t steps) const {
  FieldRmse rmse;
  double total = 0;
  int in_total = 0;
  for (const ScoredField& field : fields_) {
    const auto sum = sum_.find(field.name);
    if (sum == sum_.end()) return std::nullopt;
    const std::vector<double>& weight = weight_.at(field.name);
    double s = 0, w = 0;
    for (size_t k = 0; k < std::min(steps, sum->second.size()); ++k) {
      s += sum->second[k];
      w += weight[k];
    }
    if (w == 0) return std::nullopt;
    rmse.fields[field.name] = std::sqrt(s / w);
    if (field.in_total) {
      total += s / w;
      ++in_total;
    }
  }
  if (in_total == 0) return std::nullopt;
  rmse.total = std::sqrt(total / in_total);
  return rmse;
}

std::vector<double> FieldCurves::per_step(const std::string& field) const {
  std::vector<double> curve;
  const auto sum = sum_.find(field);
  if (sum == sum_.end()) return curve;
  const std::vector<double>& weight = weight_.at(field);
  for (size_t k = 0; k < sum->second.size(); ++k)
    curve.push_back(std::sqrt(sum->second[k] / weight[k]));
  return curve;
}

}  // namespace bsms
