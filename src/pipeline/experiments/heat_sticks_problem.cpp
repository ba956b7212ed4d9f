#include "pipeline/experiments/heat_sticks_problem.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/graph.hpp"
#include "pipeline/graphs/multilevel_tensors.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "preprocess/proximity_pooling.hpp"

namespace bsms {

int max_stick_levels(int64_t nodes) {
  const Sticks stick = make_sticks({0.0}, nodes);
  BuildOptions options;
  options.seeding = Seeding::kCloseCenter;
  options.num_levels = 2;
  while ((int64_t{1} << (options.num_levels - 1)) < nodes) ++options.num_levels;
  const RowMatrixXd positions = Eigen::Map<const RowMatrixXd>(stick.x.data(), nodes, 1);
  std::vector<int64_t> pairs;
  for (int64_t i = 0; i + 1 < nodes; ++i) pairs.insert(pairs.end(), {i, i + 1});
  const MultilevelGraph graph =
      build_multilevel_graph(graph_from_pairs(nodes, pairs), positions, options);
  int levels = 0;
  while (levels < graph.num_levels() && graph.levels[levels].num_nodes() >= 2) ++levels;
  return levels;
}

Sticks make_sticks(const std::vector<double>& starts, int64_t nodes) {
  if (nodes < 2)
    throw InputError("sticks: need at least 2 nodes per stick, got " + std::to_string(nodes));
  Sticks s;
  s.nodes = nodes;
  const double dx = s.dx();
  std::vector<int64_t> edges;
  for (size_t k = 0; k < starts.size(); ++k) {
    const int64_t first = static_cast<int64_t>(k) * nodes;
    for (int64_t i = 0; i < nodes; ++i) {
      s.x.push_back(starts[k] + dx * static_cast<double>(i));
      s.stick.push_back(static_cast<int64_t>(k));
      if (i + 1 < nodes) {
        edges.insert(edges.end(), {first + i, first + i + 1, first + i + 1, first + i});
      }
    }
  }
  const auto n = static_cast<int64_t>(s.x.size());
  s.positions = torch::tensor(s.x, torch::kFloat64).reshape({n, 1}).to(torch::kFloat32);
  s.edges = torch::tensor(edges, torch::kInt64).reshape({-1, 2});
  return s;
}

torch::Tensor stick_inputs(const Sticks& sticks, const std::vector<StickBc>& bcs) {
  if (static_cast<int64_t>(bcs.size()) != sticks.num_sticks()) {
    throw InputError("sticks: " + std::to_string(bcs.size()) + " boundary conditions for " +
                     std::to_string(sticks.num_sticks()) + " sticks");
  }
  auto inputs = torch::zeros({static_cast<int64_t>(sticks.x.size()), 3});
  auto a = inputs.accessor<float, 2>();
  for (size_t k = 0; k < bcs.size(); ++k) {
    const int64_t first = static_cast<int64_t>(k) * sticks.nodes, last = first + sticks.nodes - 1;
    const int64_t d = bcs[k].dirichlet_left ? first : last;
    const int64_t f = bcs[k].dirichlet_left ? last : first;
    a[d][0] = 1.0f;
    a[d][2] = static_cast<float>(bcs[k].t_dirichlet);
    a[f][1] = 1.0f;
    a[f][2] = static_cast<float>(bcs[k].flux);
  }
  return inputs;
}

torch::Tensor stick_solution(const Sticks& sticks, const std::vector<StickBc>& bcs) {
  if (static_cast<int64_t>(bcs.size()) != sticks.num_sticks()) {
    throw InputError("sticks: " + std::to_string(bcs.size()) + " boundary conditions for " +
                     std::to_string(sticks.num_sticks()) + " sticks");
  }
  auto t = torch::zeros({static_cast<int64_t>(sticks.x.size()), 1});
  auto a = t.accessor<float, 2>();
  for (size_t k = 0; k < bcs.size(); ++k) {
    const int64_t first = static_cast<int64_t>(k) * sticks.nodes;
    for (int64_t i = 0; i < sticks.nodes; ++i) {
      const double s =
          sticks.dx() * static_cast<double>(bcs[k].dirichlet_left ? i : sticks.nodes - 1 - i);
      a[first + i][0] = static_cast<float>(bcs[k].t_dirichlet + bcs[k].flux * s);
    }
  }
  return t;
}

MultilevelTensors bistride_multilevel(const Sticks& sticks, int levels) {
  const auto n = static_cast<int64_t>(sticks.x.size());
  const auto e = sticks.edges.contiguous();
  std::vector<int64_t> pairs(e.data_ptr<int64_t>(), e.data_ptr<int64_t>() + e.numel());
  BuildOptions options;
  options.seeding = Seeding::kCloseCenter;
  options.num_levels = levels;
  const RowMatrixXd positions = Eigen::Map<const RowMatrixXd>(sticks.x.data(), n, 1);
  return make_multilevel_tensors(
      build_multilevel_graph(graph_from_pairs(n, pairs), positions, options));
}

MultilevelTensors proximity_multilevel(const Sticks& sticks, int levels) {
  // The grid bins the positions the model sees (float32), not the double ones.
  const auto p = sticks.positions.to(torch::kFloat64).contiguous();
  const RowMatrixXd positions =
      Eigen::Map<const RowMatrixXd>(p.data_ptr<double>(), p.size(0), p.size(1));
  const auto e = sticks.edges.contiguous();
  EdgeList edges;
  edges.data.assign(e.data_ptr<int64_t>(), e.data_ptr<int64_t>() + e.numel());
  return make_multilevel_tensors(
      build_proximity_multilevel_graph(positions, edges, levels, kProximityCellDx * sticks.dx()));
}

StickMixing stick_mixing(const MultilevelTensors& graph, const std::vector<int64_t>& stick) {
  if (graph.num_levels() == 0 || static_cast<int64_t>(stick.size()) != graph.num_nodes(0)) {
    throw InputError("stick mixing: " + std::to_string(stick.size()) +
                     " stick labels for a graph of " +
                     std::to_string(graph.num_levels() ? graph.num_nodes(0) : 0) + " nodes");
  }
  constexpr int64_t kNone = std::numeric_limits<int64_t>::max();
  std::vector<int64_t> lo = stick, hi = stick;
  StickMixing out;
  for (int k = 0; k < graph.num_levels(); ++k) {
    if (k > 0) {
      // Coarse node c aggregates the fine nodes of row c of D.
      const auto& t = graph.transitions[k];
      const auto off = t.down_offsets.contiguous(), col = t.down_columns.contiguous();
      const int64_t* po = off.data_ptr<int64_t>();
      const int64_t* pc = col.data_ptr<int64_t>();
      std::vector<int64_t> clo(t.coarse_nodes, kNone), chi(t.coarse_nodes, -kNone);
      for (int64_t c = 0; c < t.coarse_nodes; ++c) {
        for (int64_t q = po[c]; q < po[c + 1]; ++q) {
          clo[c] = std::min(clo[c], lo[pc[q]]);
          chi[c] = std::max(chi[c], hi[pc[q]]);
        }
      }
      lo = std::move(clo);
      hi = std::move(chi);
    }
    int64_t mixed = 0, crossing = 0;
    for (size_t i = 0; i < lo.size(); ++i) mixed += lo[i] < hi[i] ? 1 : 0;
    const auto& edges = graph.edge_sets[k][0];
    const auto s = edges.senders.contiguous(), r = edges.receivers.contiguous();
    const int64_t* ps = s.data_ptr<int64_t>();
    const int64_t* pr = r.data_ptr<int64_t>();
    for (int64_t e = 0; e < edges.num_edges(); ++e) {
      crossing += std::min(lo[ps[e]], lo[pr[e]]) < std::max(hi[ps[e]], hi[pr[e]]) ? 1 : 0;
    }
    out.mixed_nodes.push_back(mixed);
    out.cross_stick_edges.push_back(crossing);
  }
  return out;
}

GraphModelOptions heat_model_options(int levels, int64_t latent) {
  GraphModelOptions o;
  o.input_size = 3;
  o.output_size = 1;
  o.latent = latent;
  o.position_dims = {1};
  o.num_levels = levels;
  return o;
}

}  // namespace bsms
