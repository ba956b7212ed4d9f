#include "pipeline/adapters/lagrangian.hpp"

#include <torch/torch.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/radius_search.hpp"
#include "preprocess/contact_enhancement.hpp"

namespace bsms {

namespace {

Json wall_json(double v) {
  return std::isnan(v) ? Json(nullptr) : Json(v);
}

}  // namespace

Json to_json(const LagrangianSpec& s) {
  Json j{{"dim", s.dim},
         {"num_node_types", s.num_node_types},
         {"position_scale", s.position_scale},
         {"contact_radius", s.contact_radius},
         {"strain_scale", s.strain_scale},
         {"public_layout", s.public_layout},
         {"multilevel", s.multilevel},
         {"mesh_dim", s.mesh_dimension()},
         {"output", s.first_order ? "velocity" : "acceleration"},
         {"stress", s.stress},
         {"kinematic_input", s.kinematic_input},
         {"velocity_input", s.velocity_input},
         {"history", s.history}};
  // Absent: no walls, no momentum conservation.
  if (s.has_walls()) {
    Json lo = Json::array(), hi = Json::array();
    for (int a = 0; a < s.dim; ++a) {
      lo.push_back(wall_json(s.wall_lo[a]));
      hi.push_back(wall_json(s.wall_hi[a]));
    }
    j["walls"] = {{"lo", lo}, {"hi", hi}, {"radius", s.wall_radius}};
  }
  if (s.has_momentum()) {
    j["momentum"] = {{"radius", s.momentum_radius},
                     {"wall_range", s.momentum_wall_range},
                     {"slip_walls", s.momentum_slip_walls}};
  }
  return j;
}

LagrangianSpec lagrangian_spec_from_json(const Json& json, const std::string& file) {
  LagrangianSpec s;
  JsonObjectReader r(json, {file, "features_resolved"});
  s.dim = r.get<int>("dim");
  s.num_node_types = r.get<int>("num_node_types");
  s.position_scale = r.get<double>("position_scale");
  s.contact_radius = r.get<double>("contact_radius");
  s.strain_scale = r.get<double>("strain_scale");
  require(s.strain_scale >= 0, r.context("strain_scale"), ">= 0 (0 = no strain channel)");
  s.public_layout = r.get<bool>("public_layout");
  s.multilevel = r.get<bool>("multilevel");
  s.mesh_dim = r.get<int>("mesh_dim");
  require(s.mesh_dim >= 1 && s.mesh_dim <= 3, r.context("mesh_dim"), "1, 2 or 3");
  const std::string output = r.get<std::string>("output");
  require(output == "acceleration" || output == "velocity", r.context("output"),
          "\"acceleration\" or \"velocity\"");
  s.first_order = output == "velocity";
  s.stress = r.get<bool>("stress");
  s.kinematic_input = r.get<bool>("kinematic_input");
  s.velocity_input = r.get<bool>("velocity_input");
  s.history = r.get<int>("history");
  require(s.history >= 1 && s.history <= 10, r.context("history"), "in 1..10");
  if (r.has("walls")) {
    JsonObjectReader w(r.raw("walls"), r.context("walls"));
    s.wall_radius = w.get<double>("radius");
    require(s.wall_radius > 0, w.context("radius"), "> 0");
    for (const char* side : {"lo", "hi"}) {
      const Json& values = w.raw(side);
      require(values.is_array() && static_cast<int>(values.size()) == s.dim, w.context(side),
              "one coordinate or null per axis");
      for (const auto& v : values)
        (side[0] == 'l' ? s.wall_lo : s.wall_hi)
            .push_back(v.is_number() ? v.get<double>() : std::nan(""));
    }
    w.finish();
  }
  if (r.has("momentum")) {
    JsonObjectReader m(r.raw("momentum"), r.context("momentum"));
    s.momentum_radius = m.get<double>("radius");
    s.momentum_wall_range = m.get<double>("wall_range");
    s.momentum_slip_walls = m.get<bool>("slip_walls");
    require(s.momentum_radius > 0, m.context("radius"), "> 0");
    require(s.momentum_wall_range >= 0, m.context("wall_range"), ">= 0");
    m.finish();
    require(s.has_walls(), r.context("momentum"), "walls beside it (momentum needs them)");
  }
  r.finish();
  require(s.dim >= 1 && s.dim <= 3, r.context("dim"), "1, 2 or 3");
  require(s.position_scale > 0, r.context("position_scale"), "> 0");
  return s;
}

std::vector<float> lumped_masses(const TrajectoryMesh& mesh) {
  const int dim = mesh.dim;
  const int64_t n = mesh.num_nodes();
  std::vector<float> mass(n, 0.0f);
  if (mesh.cell_size != dim + 1) {
    std::fill(mass.begin(), mass.end(), 1.0f);
    return mass;
  }
  for (int64_t c = 0; c < mesh.num_cells(); ++c) {
    const int32_t* v = &mesh.cells[c * mesh.cell_size];
    Eigen::Matrix3d jac = Eigen::Matrix3d::Identity();
    for (int k = 0; k < dim; ++k)
      for (int a = 0; a < dim; ++a)
        jac(a, k) = static_cast<double>(mesh.mesh_pos[v[k + 1] * dim + a]) -
                    static_cast<double>(mesh.mesh_pos[v[0] * dim + a]);
    double volume = std::abs(jac.determinant());
    for (int k = 2; k <= dim; ++k) volume /= k;
    for (int k = 0; k <= dim; ++k) mass[v[k]] += static_cast<float>(volume / (dim + 1));
  }
  return mass;
}

MomentumGroups momentum_groups(const LagrangianSpec& spec, const TrajectoryMesh& mesh,
                               const torch::Tensor& x) {
  const int dim = spec.dim;
  const int64_t n = mesh.num_nodes();
  const auto xc = x.to(torch::kFloat64).contiguous();
  const double* p = xc.data_ptr<double>();
  // Bodies: their nodes, bounding boxes, whether any node is kinematic, and the axes of the
  // walls they are near.
  std::map<int32_t, int> body_index;
  for (int64_t i = 0; i < n; ++i) body_index.emplace(mesh.body_id.empty() ? 0 : mesh.body_id[i], 0);
  int nb = 0;
  for (auto& [id, index] : body_index) index = nb++;
  std::vector<std::vector<int64_t>> nodes(nb);
  std::vector<char> bound(nb, 0);
  std::vector<uint32_t> walled(nb, 0);  // bit a: near a wall of axis a
  std::vector<double> lo(static_cast<size_t>(nb) * dim, 1e300), hi(lo.size(), -1e300);
  for (int64_t i = 0; i < n; ++i) {
    const int b = body_index[mesh.body_id.empty() ? 0 : mesh.body_id[i]];
    nodes[b].push_back(i);
    if (spec.public_layout || mesh.node_type[i] != static_cast<int32_t>(NodeType::kNormal))
      bound[b] = 1;
    for (int a = 0; a < dim; ++a) {
      const double v = p[i * dim + a];
      lo[b * dim + a] = std::min(lo[b * dim + a], v);
      hi[b * dim + a] = std::max(hi[b * dim + a], v);
      if (spec.has_walls() && (v - spec.wall_lo[a] < spec.momentum_wall_range ||
                               spec.wall_hi[a] - v < spec.momentum_wall_range))
        walled[b] |= 1u << a;  // NaN walls compare false: no wall on that side
    }
  }
  // Union of bodies closer than momentum_radius (bounding boxes first, then node pairs).
  std::vector<int> parent(nb);
  for (int b = 0; b < nb; ++b) parent[b] = b;
  auto root = [&](int b) {
    while (parent[b] != b) b = parent[b] = parent[parent[b]];
    return b;
  };
  const double r = spec.momentum_radius, r2 = r * r;
  for (int a = 0; a < nb; ++a) {
    for (int b = a + 1; b < nb; ++b) {
      bool apart = false;
      for (int k = 0; k < dim; ++k)
        apart = apart || lo[a * dim + k] - hi[b * dim + k] >= r ||
                lo[b * dim + k] - hi[a * dim + k] >= r;
      if (apart || root(a) == root(b)) continue;
      bool close = false;
      for (size_t i = 0; i < nodes[a].size() && !close; ++i) {
        for (size_t j = 0; j < nodes[b].size() && !close; ++j) {
          double d2 = 0;
          for (int k = 0; k < dim; ++k) {
            const double d = p[nodes[a][i] * dim + k] - p[nodes[b][j] * dim + k];
            d2 += d * d;
          }
          close = d2 < r2;
        }
      }
      if (close) parent[root(a)] = root(b);
    }
  }
  // A group keeps the linear momentum along the axes none of its bodies has a wall of (with slip
  // walls; otherwise only a group near no wall counts) and the angular one when near no wall.
  std::vector<char> group_bound(nb, 0);
  std::vector<uint32_t> group_walled(nb, 0);
  for (int b = 0; b < nb; ++b) {
    group_bound[root(b)] |= bound[b];
    group_walled[root(b)] |= walled[b];
  }
  const uint32_t all_axes = (1u << dim) - 1;
  MomentumGroups out;
  std::vector<int64_t> id_of_root(nb, -1);
  for (int b = 0; b < nb; ++b) {
    const uint32_t w = group_walled[b];
    const bool kept = !group_bound[b] && (w == 0 || (spec.momentum_slip_walls && w != all_axes));
    if (root(b) != b || !kept) continue;
    id_of_root[b] = out.count++;
    for (int a = 0; a < dim; ++a) out.conserved.push_back((w >> a) & 1u ? 0.0f : 1.0f);
    out.conserved.push_back(w == 0 ? 1.0f : 0.0f);
  }
  out.group.assign(n, -1);
  for (int b = 0; b < nb; ++b)
    for (int64_t i : nodes[b]) out.group[i] = id_of_root[root(b)];
  return out;
}

namespace {

// remove_group_motion_loops' state: the nodes' groups, weights and positions, the output being
// corrected, and per group what it keeps.
struct GroupMotion {
  int64_t n = 0, dim = 0, groups = 0;
  const int64_t* pg = nullptr;  // [n] group or -1
  const double* pw = nullptr;   // [n] weights
  const double* px = nullptr;   // [n, dim] positions
  double* po = nullptr;         // [n, dim] the vectors, corrected in place
  std::vector<double> kept;     // [groups, dim + 1], 1 = kept
  std::vector<double> centre;   // [groups, dim] weighted centres

  // Removes each group's weighted mean along the axes it keeps; sets `centre`.
  void remove_linear() {
    const size_t gd = static_cast<size_t>(groups * dim);
    std::vector<double> total(groups, 0.0), momentum(gd, 0.0);
    centre.assign(gd, 0.0);
    for (int64_t i = 0; i < n; ++i) {
      const int64_t g = pg[i];
      if (g < 0) continue;
      if (g >= groups)
        throw InputError("momentum projection: node " + std::to_string(i) + " is in group " +
                         std::to_string(g) + " of " + std::to_string(groups));
      total[g] += pw[i];
      for (int64_t a = 0; a < dim; ++a) {
        momentum[g * dim + a] += pw[i] * po[i * dim + a];
        centre[g * dim + a] += pw[i] * px[i * dim + a];
      }
    }
    for (int64_t g = 0; g < groups; ++g) {
      total[g] = std::max(total[g], 1e-30);
      for (int64_t a = 0; a < dim; ++a) {
        momentum[g * dim + a] = momentum[g * dim + a] / total[g] * kept[g * (dim + 1) + a];
        centre[g * dim + a] /= total[g];
      }
    }
    for (int64_t i = 0; i < n; ++i)
      if (pg[i] >= 0)
        for (int64_t a = 0; a < dim; ++a) po[i * dim + a] -= momentum[pg[i] * dim + a];
  }

  // Each node's offset from its group's centre ([n, 3]), and per group the torque ([groups, 3])
  // and the inertia tensor ([groups, 3, 3]; 2-D: its first entry).
  void moments(std::vector<double>& r, std::vector<double>& torque,
               std::vector<double>& inertia) const {
    r.assign(static_cast<size_t>(n * 3), 0.0);
    torque.assign(static_cast<size_t>(groups * 3), 0.0);
    inertia.assign(static_cast<size_t>(groups * 9), 0.0);
    for (int64_t i = 0; i < n; ++i) {
      const int64_t g = pg[i];
      if (g < 0) continue;
      double* ri = &r[i * 3];
      for (int64_t a = 0; a < dim; ++a) ri[a] = px[i * dim + a] - centre[g * dim + a];
      const double* oi = po + i * dim;
      const double m = pw[i];
      if (dim == 2) {
        torque[g * 3] += m * (ri[0] * oi[1] - ri[1] * oi[0]);
        inertia[g * 9] += m * (ri[0] * ri[0] + ri[1] * ri[1]);
      } else {
        torque[g * 3 + 0] += m * (ri[1] * oi[2] - ri[2] * oi[1]);
        torque[g * 3 + 1] += m * (ri[2] * oi[0] - ri[0] * oi[2]);
        torque[g * 3 + 2] += m * (ri[0] * oi[1] - ri[1] * oi[0]);
        const double rr = ri[0] * ri[0] + ri[1] * ri[1] + ri[2] * ri[2];
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            inertia[g * 9 + a * 3 + b] += m * ((a == b ? rr : 0.0) - ri[a] * ri[b]);
      }
    }
  }

  // alpha per group: 2-D torque / inertia; 3-D the pseudo-inverse of the inertia tensor (relative
  // cut-off 3 eps of the input's type, as torch::linalg::pinv) times the torque; 0 where the
  // group does not keep its spin.
  std::vector<double> spin_rates(const std::vector<double>& torque,
                                 const std::vector<double>& inertia, double eps) const {
    std::vector<double> alpha(groups * 3, 0.0);
    for (int64_t g = 0; g < groups; ++g) {
      const double spin = kept[g * (dim + 1) + dim];
      if (dim == 2) {
        alpha[g * 3] = torque[g * 3] / std::max(inertia[g * 9], 1e-30) * spin;
        continue;
      }
      const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> I(&inertia[g * 9]);
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(I, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Eigen::Vector3d sigma = svd.singularValues();
      Eigen::Vector3d inv = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k)
        if (sigma(k) > 3.0 * eps * sigma(0)) inv(k) = 1.0 / sigma(k);
      const Eigen::Vector3d t(torque[g * 3], torque[g * 3 + 1], torque[g * 3 + 2]);
      const Eigen::Vector3d a =
          svd.matrixV() * inv.asDiagonal() * svd.matrixU().transpose() * t * spin;
      for (int k = 0; k < 3; ++k) alpha[g * 3 + k] = a(k);
    }
    return alpha;
  }

  // Removes the rigid rotation alpha x r of each group.
  void remove_spin(const std::vector<double>& r, const std::vector<double>& alpha) {
    for (int64_t i = 0; i < n; ++i) {
      const int64_t g = pg[i];
      if (g < 0) continue;
      const double* ri = &r[i * 3];
      const double* al = &alpha[g * 3];
      double* oi = po + i * dim;
      if (dim == 2) {
        oi[0] += al[0] * ri[1];
        oi[1] -= al[0] * ri[0];
      } else {
        oi[0] -= al[1] * ri[2] - al[2] * ri[1];
        oi[1] -= al[2] * ri[0] - al[0] * ri[2];
        oi[2] -= al[0] * ri[1] - al[1] * ri[0];
      }
    }
  }
};

// `v` less, on each group of `group` (-1: none), the weighted mean along the axes the group keeps
// and, where it keeps the spin, the rigid rotation about its weighted centre of `position` that
// fits what is left: the weighted orthogonal projection onto motions without those parts.
// `conserved` [G, dim + 1], 1 = kept (undefined: all kept); `weight` [N].
// remove_group_motion without autograd, in loops over the nodes with double sums: the ~40 small
// tensor ops of the differentiable version cost a rollout step of a ~400-node graph ~0.2 ms.
torch::Tensor remove_group_motion_loops(const torch::Tensor& group_in, int64_t groups,
                                        const torch::Tensor& weight_in,
                                        const torch::Tensor& conserved_in,
                                        const torch::Tensor& position_in,
                                        const torch::Tensor& v_in) {
  const int64_t n = v_in.size(0), dim = v_in.size(1);
  if (group_in.numel() != n || weight_in.numel() != n || position_in.dim() != 2 ||
      position_in.size(0) != n || position_in.size(1) != dim)
    throw InputError("momentum projection: groups, weights and positions must cover the " +
                     std::to_string(n) + " nodes of the " + std::to_string(dim) + "-D vectors");
  const auto group = group_in.to(torch::kInt64).contiguous();
  const auto weight = weight_in.to(torch::kFloat64).contiguous();
  const auto x = position_in.to(torch::kFloat64).contiguous();
  auto out = v_in.to(torch::kFloat64).contiguous().clone();
  GroupMotion m;
  m.n = n;
  m.dim = dim;
  m.groups = groups;
  m.pg = group.data_ptr<int64_t>();
  m.pw = weight.data_ptr<double>();
  m.px = x.data_ptr<double>();
  m.po = out.data_ptr<double>();
  m.kept.assign(static_cast<size_t>(groups * (dim + 1)), 1.0);
  if (conserved_in.defined()) {
    const auto c = conserved_in.to(torch::kFloat64).contiguous();
    if (c.numel() != static_cast<int64_t>(m.kept.size()))
      throw InputError("momentum projection: conserved flags for " + std::to_string(c.numel()) +
                       " values, expected [" + std::to_string(groups) + ", " +
                       std::to_string(dim + 1) + "]");
    std::copy(c.data_ptr<double>(), c.data_ptr<double>() + m.kept.size(), m.kept.begin());
  }
  m.remove_linear();
  if (dim < 2) return out.to(v_in.scalar_type());
  // The angular part, about each group's weighted centre.
  std::vector<double> r, torque, inertia;
  m.moments(r, torque, inertia);
  const double eps = v_in.scalar_type() == torch::kFloat64
                         ? std::numeric_limits<double>::epsilon()
                         : static_cast<double>(std::numeric_limits<float>::epsilon());
  m.remove_spin(r, m.spin_rates(torque, inertia, eps));
  return out.to(v_in.scalar_type());
}

torch::Tensor remove_group_motion(const torch::Tensor& group, int64_t groups,
                                  const torch::Tensor& weight, const torch::Tensor& conserved,
                                  const torch::Tensor& position, const torch::Tensor& v) {
  if (!torch::GradMode::is_enabled() && v.dim() == 2 && v.size(1) <= 3)
    return remove_group_motion_loops(group, groups, weight, conserved, position, v);
  const int64_t dim = v.size(1);
  const auto inside = (group >= 0).to(v.dtype()).unsqueeze(1);  // [N, 1]
  const auto g = group.clamp_min(0);
  const auto m = weight.to(v.dtype()).unsqueeze(1) * inside;  // [N, 1], 0 outside
  auto sum = [&](const torch::Tensor& t) {                    // [N, k] -> [G, k], per group
    return torch::zeros({groups, t.size(1)}, t.options()).index_add(0, g, t);
  };
  // Which momenta each group keeps, [G, dim + 1] (all of them without `conserved`).
  const auto kept =
      conserved.defined() ? conserved.to(v.dtype()) : torch::ones({groups, dim + 1}, v.options());
  const auto total = sum(m).clamp_min(1e-30);  // [G, 1]
  const auto mean = sum(m * v) / total * kept.slice(1, 0, dim);
  auto out = v - mean.index_select(0, g) * inside;
  if (dim < 2) return out;
  // The angular part: only groups that keep it (kept.select(1, dim) is 1) lose it.
  const auto spin = kept.select(1, dim).unsqueeze(1);  // [G, 1]
  const auto x = position.to(v.dtype());
  const auto r = (x - (sum(m * x) / total).index_select(0, g)) * inside;  // [N, dim]
  if (dim == 2) {
    const auto rx = r.select(1, 0).unsqueeze(1), ry = r.select(1, 1).unsqueeze(1);
    const auto torque =
        sum(m * (rx * out.select(1, 1).unsqueeze(1) - ry * out.select(1, 0).unsqueeze(1)));
    const auto inertia = sum(m * r.square().sum(1, true)).clamp_min(1e-30);
    const auto alpha = (torque / inertia * spin).index_select(0, g);  // [N, 1]
    return out - alpha * torch::cat({-ry, rx}, 1);
  }
  // 3-D: inertia tensor sum m (|r|^2 I - r r^T), alpha = I^-1 torque, v -= alpha x r.
  const auto torque = sum(m * torch::cross(r, out, 1));                // [G, 3]
  const auto rr = (r.unsqueeze(2) * r.unsqueeze(1)).reshape({-1, 9});  // [N, 9]
  const auto eye = torch::eye(3, v.options()).reshape({1, 9});
  const auto inertia = sum(m * (r.square().sum(1, true) * eye - rr)).reshape({groups, 3, 3});
  // A degenerate group (one node, or nodes on a line) has a singular inertia tensor: the
  // pseudo-inverse leaves the rotation about that axis alone (its torque is ~0 there anyway).
  const auto alpha = torch::linalg::pinv(inertia).matmul(torque.unsqueeze(2)).squeeze(2) * spin;
  return out - torch::cross(alpha.index_select(0, g), r, 1);
}

// Each node's body (mesh body_id; 0 for all without body ids) where the node is predicted, -1
// elsewhere, [N] int64; `count`: one more than the largest id.
torch::Tensor predicted_bodies(const TrajectoryMesh& mesh, bool public_layout, int64_t* count) {
  const int64_t n = mesh.num_nodes();
  std::vector<int64_t> body(static_cast<size_t>(n), -1);
  *count = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (!is_predicted_node(mesh.node_type[i], public_layout)) continue;
    const int64_t id = mesh.body_id.empty() ? 0 : mesh.body_id[i];
    if (id < 0) continue;
    body[i] = id;
    *count = std::max(*count, id + 1);
  }
  return torch::from_blob(body.data(), {n}, torch::kInt64).clone();
}

}  // namespace

torch::Tensor project_momentum(const Batch& batch, const torch::Tensor& accel) {
  if (!batch.group.defined() || batch.num_groups == 0) return accel;
  return remove_group_motion(batch.group, batch.num_groups, batch.mass, batch.conserved, batch.cur,
                             accel);
}

torch::Tensor project_motion(const Batch& batch, const torch::Tensor& out) {
  if (batch.num_groups == 0) return out;
  const int64_t d = batch.cur.size(1);
  if (out.size(1) == d) return project_momentum(batch, out);
  return torch::cat(
      {project_momentum(batch, out.narrow(1, 0, d)), out.narrow(1, d, out.size(1) - d)}, 1);
}

torch::Tensor rigid_part(const Batch& batch, const torch::Tensor& v) {
  if (!batch.body.defined() || batch.num_bodies == 0) return torch::zeros_like(v);
  const auto ones = torch::ones({v.size(0)}, v.options());
  const auto inside = (batch.body >= 0).to(v.dtype()).unsqueeze(1);
  return (v - remove_group_motion(batch.body, batch.num_bodies, ones, {}, batch.cur, v)) * inside;
}

torch::Tensor LagrangianAdapter::scale_rigid_noise(const FrameState& state,
                                                   const torch::Tensor& noise,
                                                   double rigid_scale) const {
  if (rigid_scale == 1.0 || !noise.defined()) return noise;
  int64_t count = 0;
  const auto body = predicted_bodies(*state.mesh, spec_.public_layout, &count);
  if (count == 0) return noise;
  const auto first = noise.narrow(1, 0, spec_.dim);
  const auto ones = torch::ones({first.size(0)}, first.options());
  const auto inside = (body >= 0).to(first.dtype()).unsqueeze(1);
  const auto rigid =
      (first - remove_group_motion(body, count, ones, {}, state.cur, first)) * inside;
  auto out = noise.clone();
  out.narrow(1, 0, spec_.dim).sub_((1.0 - rigid_scale) * rigid);
  return out;
}

bool is_predicted_node(int32_t node_type, bool public_layout) {
  if (public_layout) return node_type == 0;
  return node_type == static_cast<int32_t>(NodeType::kNormal) ||
         node_type == static_cast<int32_t>(NodeType::kSlip);
}

namespace {

torch::Tensor edges_to_tensor(const EdgeList& edges, bool drop_loops) {
  std::vector<int64_t> flat;
  flat.reserve(edges.data.size());
  for (int64_t e = 0; e < edges.size(); ++e) {
    if (drop_loops && edges.sender(e) == edges.receiver(e)) continue;
    flat.push_back(edges.sender(e));
    flat.push_back(edges.receiver(e));
  }
  const int64_t count = static_cast<int64_t>(flat.size() / 2);
  return torch::from_blob(flat.data(), {count, 2}, torch::kInt64).clone();
}

}  // namespace

EdgeList contact_pairs(const RowMatrixXd& points, const TrajectoryMesh& mesh, double radius,
                       const CsrGraph& mesh_graph) {
  const int dim = mesh.dim;
  const double far2 = (4.0 * radius) * (4.0 * radius);
  // Connected components of the mesh: public data has no body ids, but its bodies (the plate
  // and its actuator) are separate components.
  std::vector<int64_t> component(mesh_graph.num_nodes, -1);
  std::vector<int64_t> stack;
  for (int64_t start = 0, next = 0; start < mesh_graph.num_nodes; ++start) {
    if (component[start] >= 0) continue;
    component[start] = next;
    stack.push_back(start);
    while (!stack.empty()) {
      const int64_t v = stack.back();
      stack.pop_back();
      for (const int64_t* u = mesh_graph.begin(v); u != mesh_graph.end(v); ++u)
        if (component[*u] < 0) {
          component[*u] = next;
          stack.push_back(*u);
        }
    }
    ++next;
  }
  // Inside the search, before the mesh-edge lookup: most pairs within the radius are neighbours
  // in one body, and this test rejects them first.
  const PairFilter keep = [&](int64_t i, int64_t j) {
    if (mesh.body_id.empty() || mesh.body_id[i] != mesh.body_id[j] || component[i] != component[j])
      return true;
    double d2 = 0;
    for (int a = 0; a < dim; ++a) {
      const double d = mesh.mesh_pos[i * dim + a] - mesh.mesh_pos[j * dim + a];
      d2 += d * d;
    }
    return d2 >= far2;
  };
  return radius_pairs(points, radius, &mesh_graph, keep);
}

namespace {

// The noise of one graph added to its current positions on the predicted nodes: returns what was
// added ([N, dim]) and sets `cur` (noisy) and `walk` ([N, (history - 1) * dim]: the older
// velocities' noise, a random walk back in time; undefined without it).
torch::Tensor add_noise(const LagrangianSpec& spec, const torch::Tensor& noise,
                        const torch::Tensor& mask, torch::Tensor& cur, torch::Tensor& walk) {
  torch::Tensor added = torch::zeros_like(cur);
  if (!noise.defined()) return added;
  const int64_t n = cur.size(0);
  const auto on = mask.unsqueeze(1).to(torch::kFloat32);
  added = noise.narrow(1, 0, spec.dim) * on;
  cur = cur + added;
  const int64_t older = noise.size(1) / spec.dim - 1;
  if (older > 0 && spec.history > 1) {
    const int64_t k = std::min<int64_t>(older, spec.history - 1);
    const auto steps = noise.narrow(1, spec.dim, k * spec.dim).reshape({n, k, spec.dim});
    walk = (added.unsqueeze(1) -
            steps.cumsum(1) * on.unsqueeze(2) / std::sqrt(static_cast<double>(spec.history)))
               .reshape({n, k * spec.dim});
  }
  return added;
}

// The velocity inputs: x_t - x_{t-1} from the (noisy) current positions and, with history, the
// velocities before from the positions without noise (a trajectory's missing first frames at
// constant velocity) plus their walk; zero on predicted nodes without the velocity input.
torch::Tensor velocity_inputs(const LagrangianSpec& spec, const FrameState& s,
                              const torch::Tensor& cur, const torch::Tensor& walk,
                              const torch::Tensor& mask) {
  auto velocity = cur - s.prev;
  if (spec.history > 1) {
    std::vector<torch::Tensor> velocities = {velocity};
    torch::Tensor newer = s.cur, at = s.prev;
    for (int k = 0; k + 1 < spec.history; ++k) {
      const torch::Tensor older =
          k < static_cast<int>(s.older.size()) ? s.older[k] : 2 * at - newer;
      velocities.push_back(at - older);
      newer = at;
      at = older;
    }
    velocity = torch::cat(velocities, 1);
    if (walk.defined()) velocity.narrow(1, spec.dim, walk.size(1)).add_(walk);
  }
  if (!spec.velocity_input)
    velocity = torch::where(mask.unsqueeze(1), torch::zeros_like(velocity), velocity);
  return velocity;
}

// A graph's node inputs: velocities, the one-hot node type, the prescribed nodes' next motion
// (kinematic input) and the clipped distances to the walls.
torch::Tensor node_inputs(const LagrangianSpec& spec, const FrameState& s, const torch::Tensor& cur,
                          const torch::Tensor& velocity, const torch::Tensor& mask) {
  const auto& mesh = *s.mesh;
  const int64_t n = mesh.num_nodes();
  auto types = torch::from_blob(const_cast<int32_t*>(mesh.node_type.data()), {n}, torch::kInt32)
                   .to(torch::kInt64);
  auto one_hot = torch::one_hot(types.clamp(0, spec.num_node_types - 1), spec.num_node_types)
                     .to(torch::kFloat32);
  if (spec.kinematic_input) {
    if (!s.next.defined())
      throw std::logic_error("LagrangianAdapter: kinematic input needs FrameState::next");
    const auto motion = torch::where(mask.unsqueeze(1), torch::zeros_like(s.cur), s.next - s.cur);
    one_hot = torch::cat({one_hot, motion}, 1);
  }
  if (!spec.has_walls()) return torch::cat({velocity, one_hot}, 1);
  std::vector<torch::Tensor> parts = {velocity, one_hot};
  const auto ones = torch::ones({n}, torch::kFloat32);
  for (int a = 0; a < spec.dim; ++a) {
    const auto x = cur.select(1, a);
    const double lo = spec.wall_lo[a], hi = spec.wall_hi[a];
    parts.push_back(std::isnan(lo) ? ones : ((x - lo) / spec.wall_radius).clamp(0.0, 1.0));
    parts.push_back(std::isnan(hi) ? ones : ((hi - x) / spec.wall_radius).clamp(0.0, 1.0));
  }
  for (size_t k = 2; k < parts.size(); ++k) parts[k] = parts[k].unsqueeze(1);
  return torch::cat(parts, 1);
}

// The graph's multilevel edges with, when the spec has contact, the contact edges found at `cur`
// carried to every level (A·Aᶜ·A); adds their level-0 count to `contact_edges`.
MultilevelTensors graph_with_contact(const LagrangianSpec& spec, const FrameState& s,
                                     const torch::Tensor& cur, int64_t& contact_edges) {
  if (!spec.has_contact()) return s.graphs->hierarchy;
  const int64_t n = s.mesh->num_nodes();
  const auto x = cur.to(torch::kFloat64).contiguous();
  RowMatrixXd points = Eigen::Map<const RowMatrixXd>(x.data_ptr<double>(), n, spec.dim);
  const MultilevelGraph& ml = s.graphs->multilevel;
  const EdgeList contact = contact_pairs(points, *s.mesh, spec.contact_radius, ml.levels[0].graph);
  contact_edges += contact.size();
  std::vector<std::vector<torch::Tensor>> extra;
  if (spec.multilevel && ml.num_levels() > 1) {
    const auto levels = enhance_contact_edges_all_levels(ml, contact);
    for (const auto& level : levels) extra.push_back({edges_to_tensor(level, true)});
  } else {
    extra.push_back({edges_to_tensor(contact, true)});
  }
  return s.graphs->hierarchy.with_edge_sets(extra);
}

// The pieces of a batch, one entry per graph, concatenated at the end.
struct BatchParts {
  std::vector<torch::Tensor> inputs, mesh_pos, world_pos, masks, curs, prevs, noises, groups,
      masses, conserved, bodies;
  std::vector<MultilevelTensors> graphs;

  void into(Batch& b) {
    b.inputs = torch::cat(inputs, 0);
    b.positions = {torch::cat(mesh_pos, 0), torch::cat(world_pos, 0)};
    b.mask = torch::cat(masks, 0);
    b.cur = torch::cat(curs, 0);
    b.prev = torch::cat(prevs, 0);
    if (!noises.empty()) b.noise = torch::cat(noises, 0);
    b.body = torch::cat(bodies, 0);
    if (!groups.empty()) {
      b.group = torch::cat(groups, 0);
      b.mass = torch::cat(masses, 0);
      b.conserved = torch::cat(conserved, 0);
    }
    if (graphs.size() == 1) {
      b.graph = std::move(graphs[0]);
    } else {
      std::vector<const MultilevelTensors*> pointers;
      for (const auto& g : graphs) pointers.push_back(&g);
      b.graph = merge_multilevel_tensors(pointers);
    }
  }
};

}  // namespace

Batch LagrangianAdapter::make_batch(const std::vector<FrameState>& states,
                                    const std::vector<torch::Tensor>& noise) const {
  Batch b;
  BatchParts parts;
  parts.graphs.reserve(states.size());
  const double inv_scale = 1.0 / spec_.position_scale;
  for (size_t g = 0; g < states.size(); ++g) {
    const FrameState& s = states[g];
    const auto& mesh = *s.mesh;
    const int64_t n = mesh.num_nodes();
    std::vector<uint8_t> predicted(n);
    for (int64_t i = 0; i < n; ++i)
      predicted[i] = is_predicted_node(mesh.node_type[i], spec_.public_layout);
    auto mask = torch::from_blob(predicted.data(), {n}, torch::kUInt8).to(torch::kBool);
    torch::Tensor cur = s.cur;
    torch::Tensor walk;
    if (!noise.empty())  // training: keep what was added, for the target's correction
      parts.noises.push_back(
          add_noise(spec_, g < noise.size() ? noise[g] : torch::Tensor(), mask, cur, walk));
    const auto velocity = velocity_inputs(spec_, s, cur, walk, mask);
    parts.inputs.push_back(node_inputs(spec_, s, cur, velocity, mask));
    parts.mesh_pos.push_back(torch::from_blob(const_cast<float*>(mesh.mesh_pos.data()),
                                              {n, spec_.mesh_dimension()}, torch::kFloat32) *
                             inv_scale);
    parts.world_pos.push_back(cur * inv_scale);
    parts.masks.push_back(mask);
    int64_t count = 0;
    const auto body = predicted_bodies(mesh, spec_.public_layout, &count);
    parts.bodies.push_back(torch::where(body >= 0, body + b.num_bodies, body));
    b.num_bodies += count;
    parts.curs.push_back(cur);
    parts.prevs.push_back(s.prev);
    if (spec_.has_momentum()) {
      MomentumGroups found = momentum_groups(spec_, mesh, cur);
      for (auto& v : found.group)
        if (v >= 0) v += b.num_groups;
      b.num_groups += found.count;
      parts.groups.push_back(torch::from_blob(found.group.data(), {n}, torch::kInt64).clone());
      parts.conserved.push_back(
          torch::from_blob(found.conserved.data(), {found.count, spec_.dim + 1}, torch::kFloat32)
              .clone());
      std::vector<float> mass = lumped_masses(mesh);
      parts.masses.push_back(torch::from_blob(mass.data(), {n}, torch::kFloat32).clone());
    }
    parts.graphs.push_back(graph_with_contact(spec_, s, cur, b.contact_edges));
  }
  parts.into(b);
  b.rigid_part = &bsms::rigid_part;
  if (b.num_groups > 0) b.project = &project_motion;
  return b;
}

ModelShape LagrangianAdapter::model_shape() const {
  ModelShape s;
  s.input_size = spec_.input_size();
  s.output_size = spec_.output_size();
  s.position_dims = {spec_.mesh_dimension(), spec_.dim};      // mesh X, world x
  s.edge_set_fields = {{0, 1}};                               // mesh edges: both offsets
  if (spec_.has_contact()) s.edge_set_fields.push_back({1});  // contact edges: world offsets
  if (spec_.strain_scale > 0) s.edge_set_stretch = {EdgeStretch{0, 1, 1.0 / spec_.strain_scale}};
  return s;
}

torch::Tensor LagrangianAdapter::target(const Batch& batch, const torch::Tensor& next,
                                        double noise_gamma) const {
  auto target_pos = next;
  if (noise_gamma != 1.0 && batch.noise.defined())
    target_pos = next + (1.0 - noise_gamma) * batch.noise;
  if (spec_.first_order) return target_pos - batch.cur;
  return target_pos - 2 * batch.cur + batch.prev;
}

torch::Tensor LagrangianAdapter::integrate(const Batch& batch, const torch::Tensor& accel,
                                           const torch::Tensor& prescribed) const {
  const auto motion = accel.size(1) > spec_.dim ? accel.narrow(1, 0, spec_.dim) : accel;
  auto predicted = spec_.first_order ? batch.cur + motion : 2 * batch.cur - batch.prev + motion;
  return torch::where(batch.mask.unsqueeze(1), predicted, prescribed);
}

}  // namespace bsms
