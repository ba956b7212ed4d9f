#include "models/graph_tensors.hpp"

#include <algorithm>
#include <numeric>

#include "core/error.hpp"

namespace bsms {
namespace {

torch::Tensor to_tensor(const std::vector<int64_t>& values) {
  return torch::from_blob(const_cast<int64_t*>(values.data()),
                          {static_cast<int64_t>(values.size())}, torch::kInt64)
      .clone();
}

torch::Tensor to_tensor(const std::vector<float>& values) {
  return torch::from_blob(const_cast<float*>(values.data()), {static_cast<int64_t>(values.size())},
                          torch::kFloat32)
      .clone();
}

// Stable counting sort of edge ids by key: returns (offsets [N + 1], order [E]).
void group_by(const int64_t* key, int64_t num_edges, int64_t num_nodes,
              std::vector<int64_t>& offsets, std::vector<int64_t>& order) {
  offsets.assign(num_nodes + 1, 0);
  for (int64_t e = 0; e < num_edges; ++e) ++offsets[key[e] + 1];
  std::partial_sum(offsets.begin(), offsets.end(), offsets.begin());
  std::vector<int64_t> next(offsets.begin(), offsets.end() - 1);
  order.resize(num_edges);
  for (int64_t e = 0; e < num_edges; ++e) order[next[key[e]]++] = e;
}

EdgeIndex edge_index_from_vectors(std::vector<int64_t> senders, std::vector<int64_t> receivers,
                                  int64_t num_nodes) {
  const auto num_edges = static_cast<int64_t>(senders.size());
  EdgeIndex index;
  index.num_nodes = num_nodes;
  std::vector<int64_t> offsets, order;
  group_by(senders.data(), num_edges, num_nodes, offsets, order);
  index.sender_offsets = to_tensor(offsets);
  index.sender_order = to_tensor(order);
  group_by(receivers.data(), num_edges, num_nodes, offsets, order);
  index.receiver_offsets = to_tensor(offsets);
  index.receiver_order = to_tensor(order);
  index.senders = to_tensor(senders);
  index.receivers = to_tensor(receivers);
  return index;
}

std::vector<int64_t> to_vector(const torch::Tensor& t) {
  auto c = t.to(torch::kInt64).contiguous();
  return std::vector<int64_t>(c.data_ptr<int64_t>(), c.data_ptr<int64_t>() + c.numel());
}

// Concatenates int64 index tensors, adding offsets[g] to the entries of part g.
torch::Tensor cat_shifted(const std::vector<torch::Tensor>& parts,
                          const std::vector<int64_t>& shifts) {
  std::vector<torch::Tensor> shifted;
  shifted.reserve(parts.size());
  for (size_t g = 0; g < parts.size(); ++g) shifted.push_back(parts[g] + shifts[g]);
  return torch::cat(shifted);
}

// Concatenates CSR offset arrays of consecutive blocks: [n_g + 1] each, values shifted by nnz.
torch::Tensor cat_offsets(const std::vector<torch::Tensor>& offsets) {
  std::vector<torch::Tensor> parts;
  int64_t shift = 0;
  for (size_t g = 0; g < offsets.size(); ++g) {
    const auto& o = offsets[g];
    parts.push_back((g == 0 ? o : o.slice(0, 1)) + shift);
    shift += o[-1].item<int64_t>();
  }
  return torch::cat(parts);
}

EdgeIndex merge_edge_sets(const std::vector<const EdgeIndex*>& sets) {
  EdgeIndex out;
  std::vector<int64_t> node_shift, edge_shift;
  std::vector<torch::Tensor> s, r, so, ro, soff, roff;
  for (const auto* set : sets) {
    node_shift.push_back(out.num_nodes);
    edge_shift.push_back(static_cast<int64_t>(
        std::accumulate(s.begin(), s.end(), int64_t{0},
                        [](int64_t acc, const torch::Tensor& t) { return acc + t.size(0); })));
    out.num_nodes += set->num_nodes;
    s.push_back(set->senders);
    r.push_back(set->receivers);
    so.push_back(set->sender_order);
    ro.push_back(set->receiver_order);
    soff.push_back(set->sender_offsets);
    roff.push_back(set->receiver_offsets);
  }
  out.senders = cat_shifted(s, node_shift);
  out.receivers = cat_shifted(r, node_shift);
  out.sender_order = cat_shifted(so, edge_shift);
  out.receiver_order = cat_shifted(ro, edge_shift);
  out.sender_offsets = cat_offsets(soff);
  out.receiver_offsets = cat_offsets(roff);
  return out;
}

LevelTransition merge_transitions(const std::vector<const LevelTransition*>& parts) {
  LevelTransition out;
  std::vector<int64_t> fine_shift, coarse_shift;
  std::vector<torch::Tensor> doff, dcol, dval, uoff, ucol, uval;
  for (const auto* t : parts) {
    fine_shift.push_back(out.fine_nodes);
    coarse_shift.push_back(out.coarse_nodes);
    out.fine_nodes += t->fine_nodes;
    out.coarse_nodes += t->coarse_nodes;
    doff.push_back(t->down_offsets);
    dcol.push_back(t->down_columns);
    dval.push_back(t->down_values);
    uoff.push_back(t->up_offsets);
    ucol.push_back(t->up_columns);
    uval.push_back(t->up_values);
    out.up_is_down_transpose = out.up_is_down_transpose && t->up_is_down_transpose;
  }
  out.down_offsets = cat_offsets(doff);
  out.down_columns = cat_shifted(dcol, fine_shift);
  out.down_values = torch::cat(dval);
  out.up_offsets = cat_offsets(uoff);
  out.up_columns = cat_shifted(ucol, coarse_shift);
  out.up_values = torch::cat(uval);
  return out;
}

// `level`: index of the fine level `g`, for messages.
LevelTransition make_transition(const CsrGraph& g, const std::vector<int64_t>& pooled,
                                const std::vector<float>& down_weight, int level) {
  const int64_t nf = g.num_nodes;
  const int64_t nc = static_cast<int64_t>(pooled.size());
  if (static_cast<int64_t>(down_weight.size()) != g.num_edges()) {
    throw InputError("multilevel graph: level " + std::to_string(level + 1) + " has " +
                     std::to_string(down_weight.size()) + " down weights, expected one per " +
                     "level-" + std::to_string(level) + " edge (" + std::to_string(g.num_edges()) +
                     ")");
  }
  std::vector<int64_t> coarse_of(nf, -1);
  for (int64_t c = 0; c < nc; ++c) {
    const int64_t i = pooled[c];
    if (i < 0 || i >= nf) {
      throw InputError("multilevel graph: level " + std::to_string(level + 1) + " pooled index " +
                       std::to_string(i) + " outside [0, " + std::to_string(nf) + ")");
    }
    coarse_of[i] = c;
  }
  // Entries of D: fine edge i -> j with j pooled.
  std::vector<int64_t> rows, cols;
  std::vector<float> vals;
  for (int64_t i = 0; i < nf; ++i) {
    for (int64_t p = g.offsets[i]; p < g.offsets[i + 1]; ++p) {
      const int64_t c = coarse_of[g.targets[p]];
      if (c < 0) continue;
      rows.push_back(c);
      cols.push_back(i);
      vals.push_back(down_weight[p]);
    }
  }
  const auto nnz = static_cast<int64_t>(rows.size());
  LevelTransition t;
  t.fine_nodes = nf;
  t.coarse_nodes = nc;
  std::vector<int64_t> offsets, order;
  auto build = [&](const std::vector<int64_t>& key, const std::vector<int64_t>& other, int64_t n,
                   torch::Tensor& off_t, torch::Tensor& col_t, torch::Tensor& val_t) {
    group_by(key.data(), nnz, n, offsets, order);
    std::vector<int64_t> c(nnz);
    std::vector<float> v(nnz);
    for (int64_t q = 0; q < nnz; ++q) {
      c[q] = other[order[q]];
      v[q] = vals[order[q]];
    }
    off_t = to_tensor(offsets);
    col_t = to_tensor(c);
    val_t = to_tensor(v);
  };
  build(rows, cols, nc, t.down_offsets, t.down_columns, t.down_values);
  build(cols, rows, nf, t.up_offsets, t.up_columns, t.up_values);
  return t;
}

}  // namespace

EdgeIndex EdgeIndex::from_pairs(const torch::Tensor& edges, int64_t num_nodes) {
  if (edges.dim() != 2 || edges.size(1) != 2) {
    throw InputError("edge index: expected an [E, 2] tensor of (sender, receiver), got shape " +
                     std::string(c10::str(edges.sizes())));
  }
  EdgeList list;
  list.data = to_vector(edges);
  return from_edge_list(list, num_nodes);
}

EdgeIndex EdgeIndex::from_edge_list(const EdgeList& edges, int64_t num_nodes) {
  const int64_t num_edges = edges.size();
  std::vector<int64_t> senders(num_edges), receivers(num_edges);
  for (int64_t e = 0; e < num_edges; ++e) {
    senders[e] = edges.sender(e);
    receivers[e] = edges.receiver(e);
    if (senders[e] < 0 || senders[e] >= num_nodes || receivers[e] < 0 ||
        receivers[e] >= num_nodes) {
      throw InputError("edge index: edge " + std::to_string(e) + " (" + std::to_string(senders[e]) +
                       ", " + std::to_string(receivers[e]) + ") outside [0, " +
                       std::to_string(num_nodes) + ")");
    }
  }
  return edge_index_from_vectors(std::move(senders), std::move(receivers), num_nodes);
}

EdgeIndex EdgeIndex::from_csr(const CsrGraph& graph) {
  std::vector<int64_t> senders(graph.num_edges());
  for (int64_t i = 0; i < graph.num_nodes; ++i) {
    std::fill(senders.begin() + graph.offsets[i], senders.begin() + graph.offsets[i + 1], i);
  }
  return edge_index_from_vectors(std::move(senders), graph.targets, graph.num_nodes);
}

EdgeIndex EdgeIndex::empty(int64_t num_nodes) {
  return edge_index_from_vectors({}, {}, num_nodes);
}

LevelTransition LevelTransition::from_down_weights(const CsrGraph& fine,
                                                   const std::vector<int64_t>& pooled,
                                                   const std::vector<float>& down_weight,
                                                   int level) {
  return make_transition(fine, pooled, down_weight, level - 1);
}

int MultilevelTensors::num_graphs() const {
  return node_offsets.empty() ? 0 : static_cast<int>(node_offsets[0].size()) - 1;
}

int64_t MultilevelTensors::num_nodes(int level) const {
  return edge_sets.at(level).at(0).num_nodes;
}

MultilevelTensors MultilevelTensors::with_edge_sets(
    const std::vector<std::vector<EdgeIndex>>& extra) const {
  if (static_cast<int>(extra.size()) > num_levels()) {
    throw InputError("extra edge sets given for " + std::to_string(extra.size()) +
                     " levels, the graph has " + std::to_string(num_levels()));
  }
  size_t num_extra = 0;
  for (const auto& level : extra) num_extra = std::max(num_extra, level.size());
  MultilevelTensors out = *this;
  for (int k = 0; k < num_levels(); ++k) {
    const int64_t n = num_nodes(k);
    for (size_t s = 0; s < num_extra; ++s) {
      const bool given = k < static_cast<int>(extra.size()) && s < extra[k].size();
      if (given && extra[k][s].num_nodes != n) {
        throw InputError("extra edge set " + std::to_string(s) + " of level " + std::to_string(k) +
                         " is for " + std::to_string(extra[k][s].num_nodes) +
                         " nodes, the level has " + std::to_string(n));
      }
      out.edge_sets[k].push_back(given ? extra[k][s] : EdgeIndex::empty(n));
    }
  }
  return out;
}

MultilevelTensors MultilevelTensors::with_edge_sets(
    const std::vector<std::vector<torch::Tensor>>& extra) const {
  std::vector<std::vector<EdgeIndex>> sets(extra.size());
  for (size_t k = 0; k < extra.size() && static_cast<int>(k) < num_levels(); ++k) {
    for (const auto& edges : extra[k]) {
      sets[k].push_back(EdgeIndex::from_pairs(edges, num_nodes(static_cast<int>(k))));
    }
  }
  return with_edge_sets(sets);
}

MultilevelTensors MultilevelTensors::with_edge_sets(const std::vector<EdgeList>& per_level) const {
  std::vector<std::vector<EdgeIndex>> sets(per_level.size());
  for (size_t k = 0; k < per_level.size() && static_cast<int>(k) < num_levels(); ++k) {
    sets[k].push_back(EdgeIndex::from_edge_list(per_level[k], num_nodes(static_cast<int>(k))));
  }
  return with_edge_sets(sets);
}

MultilevelTensors merge_multilevel_tensors(const std::vector<const MultilevelTensors*>& graphs) {
  if (graphs.empty()) throw InputError("graph batch: no graphs to merge");
  if (graphs.size() == 1) return *graphs[0];
  const int levels = graphs[0]->num_levels();
  size_t num_sets = 0;
  for (const auto* g : graphs) {
    if (g->num_levels() != levels) {
      throw InputError("graph batch: graphs have " + std::to_string(levels) + " and " +
                       std::to_string(g->num_levels()) + " levels; a batch needs equal counts");
    }
    for (const auto& sets : g->edge_sets) num_sets = std::max(num_sets, sets.size());
  }
  MultilevelTensors out;
  out.edge_sets.resize(levels);
  out.node_offsets.resize(levels);
  for (int k = 0; k < levels; ++k) {
    std::vector<EdgeIndex> empties;
    empties.reserve(graphs.size());
    for (const auto* g : graphs) empties.push_back(EdgeIndex::empty(g->num_nodes(k)));
    for (size_t s = 0; s < num_sets; ++s) {
      std::vector<const EdgeIndex*> parts;
      for (size_t g = 0; g < graphs.size(); ++g) {
        const auto& sets = graphs[g]->edge_sets[k];
        parts.push_back(s < sets.size() ? &sets[s] : &empties[g]);
      }
      out.edge_sets[k].push_back(merge_edge_sets(parts));
    }
    out.node_offsets[k].push_back(0);
    for (const auto* g : graphs) {
      for (size_t j = 1; j < g->node_offsets[k].size(); ++j) {
        out.node_offsets[k].push_back(out.node_offsets[k].back() + g->node_offsets[k][j] -
                                      g->node_offsets[k][j - 1]);
      }
    }
    if (k == 0) {
      out.transitions.emplace_back();
    } else {
      std::vector<const LevelTransition*> parts;
      for (const auto* g : graphs) parts.push_back(&g->transitions[k]);
      out.transitions.push_back(merge_transitions(parts));
    }
  }
  return out;
}

}  // namespace bsms
