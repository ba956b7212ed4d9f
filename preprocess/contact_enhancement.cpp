#include "preprocess/contact_enhancement.hpp"

#include <algorithm>
#include <string>

#include "core/error.hpp"

namespace bsms {

namespace {

// Sorted unique pairs as one key each (nodes < 2^32 per level).
EdgeList edges_from_keys(std::vector<uint64_t>& keys) {
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  EdgeList out;
  out.data.resize(2 * keys.size());
  for (size_t e = 0; e < keys.size(); ++e) {
    out.data[2 * e] = static_cast<int64_t>(keys[e] >> 32);
    out.data[2 * e + 1] = static_cast<int64_t>(keys[e] & 0xFFFFFFFFull);
  }
  return out;
}

void check_level(const MultilevelGraph& graph, int level) {
  if (level < 0 || level + 1 >= graph.num_levels()) {
    throw InputError("contact enhancement: level " + std::to_string(level) +
                     " has no coarser level (levels: " + std::to_string(graph.num_levels()) + ")");
  }
  if (graph.levels[level].num_nodes() >= (int64_t{1} << 32)) {
    throw InputError("contact enhancement: more than 2^32 nodes at level " + std::to_string(level));
  }
}

void check_contact_range(const EdgeList& contact, int64_t n, int level) {
  for (int64_t e = 0; e < contact.size(); ++e) {
    const int64_t s = contact.sender(e), r = contact.receiver(e);
    if (s < 0 || s >= n || r < 0 || r >= n) {
      throw InputError("contact edge " + std::to_string(e) + " (" + std::to_string(s) + ", " +
                       std::to_string(r) + ") is out of range for level " + std::to_string(level) +
                       " with " + std::to_string(n) + " nodes");
    }
  }
}

// Contact edges grouped by sender: senders[k] sends to receivers[offsets[k] .. offsets[k+1]);
// sender_slot[i] is k for senders[k] == i, -1 for nodes that send none.
struct ContactBySender {
  std::vector<int64_t> senders, offsets, receivers;
  std::vector<int64_t> sender_slot;
};

ContactBySender group_by_sender(const EdgeList& contact, int64_t n) {
  std::vector<uint64_t> keys(contact.size());
  for (int64_t e = 0; e < contact.size(); ++e) {
    keys[e] = (static_cast<uint64_t>(contact.sender(e)) << 32) |
              static_cast<uint64_t>(contact.receiver(e));
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  ContactBySender g;
  std::vector<int64_t>& senders = g.senders;
  std::vector<int64_t>& offsets = g.offsets;
  std::vector<int64_t>& receivers = g.receivers;
  g.sender_slot.assign(n, -1);
  for (uint64_t key : keys) {
    const int64_t s = static_cast<int64_t>(key >> 32);
    if (senders.empty() || senders.back() != s) {
      g.sender_slot[s] = static_cast<int64_t>(senders.size());
      senders.push_back(s);
      offsets.push_back(static_cast<int64_t>(receivers.size()));
    }
    receivers.push_back(static_cast<int64_t>(key & 0xFFFFFFFFull));
  }
  offsets.push_back(static_cast<int64_t>(receivers.size()));
  return g;
}

// reach[k]: kept nodes (coarse indices, sorted) in the closed neighbourhoods of the receivers of
// sender k, i.e. the kept columns of row senders[k] of Aᶜ (A + I). `m`: kept nodes.
std::vector<std::vector<int64_t>> sender_reach(const CsrGraph& fine, const ContactBySender& g,
                                               const std::vector<int64_t>& coarse_index,
                                               int64_t m) {
  const std::vector<int64_t>& offsets = g.offsets;
  const std::vector<int64_t>& receivers = g.receivers;
  const int64_t num_senders = static_cast<int64_t>(g.senders.size());
  std::vector<std::vector<int64_t>> reach(num_senders);
#pragma omp parallel if (num_senders > 256)
  {
    std::vector<int64_t> mark(m, -1);
#pragma omp for schedule(dynamic, 16)
    for (int64_t k = 0; k < num_senders; ++k) {
      auto add = [&](int64_t v) {
        const int64_t c = coarse_index[v];
        if (c >= 0 && mark[c] != k) {
          mark[c] = k;
          reach[k].push_back(c);
        }
      };
      for (int64_t e = offsets[k]; e < offsets[k + 1]; ++e) {
        add(receivers[e]);
        for (const int64_t* w = fine.begin(receivers[e]); w != fine.end(receivers[e]); ++w) add(*w);
      }
      std::sort(reach[k].begin(), reach[k].end());
    }
  }
  return reach;
}

// Result rows: kept a (coarse index, ascending) with a sender in its closed neighbourhood.
std::vector<int64_t> result_rows(const CsrGraph& fine, const std::vector<int64_t>& senders,
                                 const std::vector<int64_t>& coarse_index, int64_t m) {
  std::vector<uint8_t> is_row(m, 0);
  for (int64_t s : senders) {
    if (coarse_index[s] >= 0) is_row[coarse_index[s]] = 1;
    for (const int64_t* a = fine.begin(s); a != fine.end(s); ++a) {
      if (coarse_index[*a] >= 0) is_row[coarse_index[*a]] = 1;
    }
  }
  std::vector<int64_t> rows;
  for (int64_t r = 0; r < m; ++r) {
    if (is_row[r]) rows.push_back(r);
  }
  return rows;
}

// Row a = union of reach[k] over the senders in a's closed neighbourhood (the kept rows of
// (A + I) Aᶜ (A + I)), sorted.
std::vector<std::vector<int64_t>> row_targets_of(const CsrGraph& fine,
                                                 const std::vector<int64_t>& pooled,
                                                 const std::vector<int64_t>& rows,
                                                 const ContactBySender& g,
                                                 const std::vector<std::vector<int64_t>>& reach) {
  const std::vector<int64_t>& sender_slot = g.sender_slot;
  const int64_t m = static_cast<int64_t>(pooled.size());
  const int64_t num_rows = static_cast<int64_t>(rows.size());
  std::vector<std::vector<int64_t>> row_targets(num_rows);
#pragma omp parallel if (num_rows > 256)
  {
    std::vector<int64_t> mark(m, -1);
#pragma omp for schedule(dynamic, 16)
    for (int64_t q = 0; q < num_rows; ++q) {
      const int64_t a = pooled[rows[q]];
      auto take = [&](int64_t i) {
        const int64_t k = sender_slot[i];
        if (k < 0) return;
        for (int64_t c : reach[k]) {
          if (mark[c] != q) {
            mark[c] = q;
            row_targets[q].push_back(c);
          }
        }
      };
      take(a);
      for (const int64_t* i = fine.begin(a); i != fine.end(a); ++i) take(*i);
      std::sort(row_targets[q].begin(), row_targets[q].end());
    }
  }
  return row_targets;
}

}  // namespace

EdgeList enhance_contact_edges(const MultilevelGraph& graph, int level, const EdgeList& contact) {
  check_level(graph, level);
  const CsrGraph& fine = graph.levels[level].graph;
  const std::vector<int64_t>& pooled = graph.levels[level + 1].pooled;
  const int64_t n = fine.num_nodes;
  const int64_t m = static_cast<int64_t>(pooled.size());
  check_contact_range(contact, n, level);
  std::vector<int64_t> coarse_index(n, -1);
  for (int64_t r = 0; r < m; ++r) coarse_index[pooled[r]] = r;

  const ContactBySender by_sender = group_by_sender(contact, n);
  const std::vector<std::vector<int64_t>> reach = sender_reach(fine, by_sender, coarse_index, m);
  const std::vector<int64_t> rows = result_rows(fine, by_sender.senders, coarse_index, m);
  const std::vector<std::vector<int64_t>> row_targets =
      row_targets_of(fine, pooled, rows, by_sender, reach);
  EdgeList out;
  size_t total = 0;
  for (const auto& targets : row_targets) total += targets.size();
  out.data.reserve(2 * total);
  const int64_t num_rows = static_cast<int64_t>(rows.size());
  for (int64_t q = 0; q < num_rows; ++q) {
    for (int64_t c : row_targets[q]) {
      out.data.push_back(rows[q]);
      out.data.push_back(c);
    }
  }
  return out;
}

std::vector<EdgeList> enhance_contact_edges_all_levels(const MultilevelGraph& graph,
                                                       const EdgeList& contact) {
  std::vector<EdgeList> out;
  if (graph.num_levels() == 0) return out;
  const int64_t n = graph.levels[0].num_nodes();
  std::vector<uint64_t> keys(contact.size());
  for (int64_t e = 0; e < contact.size(); ++e) {
    const int64_t s = contact.sender(e), r = contact.receiver(e);
    if (s < 0 || s >= n || r < 0 || r >= n || n >= (int64_t{1} << 32)) {
      throw InputError("contact edge " + std::to_string(e) + " (" + std::to_string(s) + ", " +
                       std::to_string(r) + ") is out of range for level 0 with " +
                       std::to_string(n) + " nodes");
    }
    keys[e] = (static_cast<uint64_t>(s) << 32) | static_cast<uint64_t>(r);
  }
  out.push_back(edges_from_keys(keys));
  for (int k = 0; k + 1 < graph.num_levels(); ++k) {
    out.push_back(enhance_contact_edges(graph, k, out.back()));
  }
  return out;
}

}  // namespace bsms
