#include "pipeline/adapters/scene_symmetry.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>

#include "data/mpm/background.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms {
namespace {

// Column k of the result is sign[k] * v[:, source[k]].
torch::Tensor signed_columns(const torch::Tensor& v, const std::vector<int>& source,
                             const std::vector<int>& sign) {
  std::vector<int64_t> idx(source.begin(), source.end());
  std::vector<float> s(sign.begin(), sign.end());
  const auto index = torch::tensor(idx, torch::kInt64);
  const auto factor = torch::tensor(s, torch::kFloat32).to(v.scalar_type());
  return v.index_select(1, index) * factor;
}

}  // namespace

bool BoxSymmetry::is_identity() const {
  for (int i = 0; i < dim(); ++i)
    if (source[i] != i || sign[i] != 1) return false;
  return true;
}

torch::Tensor BoxSymmetry::points(const torch::Tensor& x) const {
  std::vector<double> offset(dim());
  for (int i = 0; i < dim(); ++i) offset[i] = centre[i] - sign[i] * centre[source[i]];
  return signed_columns(x, source, sign) +
         torch::tensor(offset, torch::kFloat64).to(x.scalar_type());
}

torch::Tensor BoxSymmetry::vectors(const torch::Tensor& v) const {
  return signed_columns(v, source, sign);
}

torch::Tensor BoxSymmetry::vectors_back(const torch::Tensor& v) const {
  // The inverse of a signed permutation: axis source[i] of the original is sign[i] * axis i.
  std::vector<int> back(dim()), back_sign(dim());
  for (int i = 0; i < dim(); ++i) {
    back[source[i]] = i;
    back_sign[source[i]] = sign[i];
  }
  return signed_columns(v, back, back_sign);
}

TrajectoryMesh BoxSymmetry::mesh(const TrajectoryMesh& m) const {
  TrajectoryMesh out = m;
  const auto mapped = points(torch::from_blob(const_cast<float*>(m.mesh_pos.data()),
                                              {m.num_nodes(), dim()}, torch::kFloat32))
                          .contiguous();
  std::copy(mapped.data_ptr<float>(), mapped.data_ptr<float>() + mapped.numel(),
            out.mesh_pos.begin());
  return out;
}

std::vector<BoxSymmetry> scene_symmetries(const std::optional<mpm::Scene>& scene, int dim,
                                          std::string* why) {
  BoxSymmetry identity;
  identity.source.resize(dim);
  std::iota(identity.source.begin(), identity.source.end(), 0);
  identity.sign.assign(dim, 1);
  identity.centre.assign(dim, 0.0);
  std::vector<BoxSymmetry> out = {identity};
  auto none = [&](const std::string& reason) {
    if (why) *why = reason;
    return out;
  };
  if (!scene || scene->background.type != "box") return none("the scene has no \"box\" background");
  const mpm::BackgroundSpec& box = scene->background;
  if (box.rotation_deg != 0.0) return none("the scene's box is rotated");
  if (scene->dim != dim)
    return none("the scene's box has no min and max of " + std::to_string(dim) + " numbers");
  std::vector<double> extent(dim);
  for (int a = 0; a < dim; ++a) {
    identity.centre[a] = 0.5 * (box.min[a] + box.max[a]);
    extent[a] = box.max[a] - box.min[a];
  }
  out = {identity};
  // Boundary type of each side (axis, 0 = low, 1 = high); none = no boundary there.
  std::map<std::string, std::pair<int, int>> side_of;
  for (int a = 0; a < dim; ++a)
    for (int s = 0; s < 2; ++s) side_of[mpm::box_side_name(a, s != 0)] = {a, s};
  std::vector<std::vector<std::optional<mpm::BoundaryType>>> type(
      dim, std::vector<std::optional<mpm::BoundaryType>>(2));
  for (const auto& b : scene->boundaries) {
    if (side_of.count(b.group) == 0)  // a half-space has no group
      return none("the scene has a boundary that is not a side of its box");
    const auto [a, s] = side_of[b.group];
    if (type[a][s] && *type[a][s] != b.type)
      return none("the scene has two boundary types on one side");
    type[a][s] = b.type;
  }
  const std::vector<double>& gravity = scene->gravity;  // [dim], zero unless the scene sets it
  std::vector<int> perm(dim);
  std::iota(perm.begin(), perm.end(), 0);
  do {
    for (int mask = 0; mask < (1 << dim); ++mask) {
      BoxSymmetry g = identity;
      g.source = perm;
      for (int i = 0; i < dim; ++i) g.sign[i] = (mask >> i) & 1 ? -1 : 1;
      if (g.is_identity()) continue;
      bool ok = true;
      for (int i = 0; i < dim && ok; ++i) {
        const int j = perm[i];
        const double scale = std::max(std::abs(extent[i]), std::abs(extent[j]));
        ok = std::abs(extent[i] - extent[j]) <= 1e-9 * scale &&
             std::abs(g.sign[i] * gravity[j] - gravity[i]) <=
                 1e-12 * (std::abs(gravity[i]) + std::abs(gravity[j]) + 1.0) &&
             // The low side of axis j lands on the low side of axis i (sign +1) or its high side.
             type[j][0] == type[i][g.sign[i] > 0 ? 0 : 1] &&
             type[j][1] == type[i][g.sign[i] > 0 ? 1 : 0];
      }
      if (ok) out.push_back(g);
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  if (out.size() == 1) return none("no reflection or axis swap maps the scene onto itself");
  return out;
}

}  // namespace bsms
