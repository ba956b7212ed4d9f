#include "preprocess/multilevel_file.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {

namespace {

std::string level_group(int k) {
  return "/level_" + std::to_string(k);
}

// Level-0 nodes without edges (mesh nodes no cell uses) accepted beyond those the edges join.
constexpr int64_t kMaxIsolatedNodes = int64_t{1} << 20;

}  // namespace

void write_multilevel_graph(const MultilevelGraph& graph, const std::string& path) {
  AtomicOutput output(path);
  {
    H5File file(output.temp_path(), H5File::Mode::kTruncate);
    file.set_attr("/", "format", std::string(kMultilevelFormat));
    file.set_attr("/", "version", kMultilevelVersion);
    file.set_attr("/", "seeding", to_string(graph.seeding));
    file.set_attr("/", "num_levels", static_cast<int64_t>(graph.num_levels()));
    // Readers take an absent attribute as exact A² (the format's default).
    file.set_attr("/", "coarse_edges", std::string(graph.thinned ? "thinned" : "exact"));
    for (int k = 0; k < graph.num_levels(); ++k) {
      const GraphLevel& level = graph.levels[k];
      const std::string group = level_group(k);
      file.create_group(group);
      file.set_attr(group, "num_nodes", level.num_nodes());
      const EdgeList edges = level.graph.edges();
      file.write(group + "/edges", edges.data, {static_cast<hsize_t>(edges.size()), 2});
      if (k >= 1) {
        file.write(group + "/pooled", level.pooled, {static_cast<hsize_t>(level.pooled.size())});
        file.write(group + "/down_weight", level.down_weight,
                   {static_cast<hsize_t>(level.down_weight.size())});
      }
    }
    file.close();
  }
  output.commit();
}

namespace {

// CSR graph from an [E, 2] edge array, checking the file conventions.
CsrGraph graph_from_edge_dataset(const std::vector<int64_t>& data, int64_t num_nodes,
                                 const std::string& where) {
  const int64_t num_edges = static_cast<int64_t>(data.size() / 2);
  CsrGraph g;
  g.num_nodes = num_nodes;
  g.offsets.assign(num_nodes + 1, 0);
  g.targets.resize(num_edges);
  for (int64_t e = 0; e < num_edges; ++e) {
    const int64_t s = data[2 * e], r = data[2 * e + 1];
    if (s < 0 || s >= num_nodes || r < 0 || r >= num_nodes) {
      throw InputError(where + ": edge " + std::to_string(e) + " (" + std::to_string(s) + ", " +
                       std::to_string(r) + ") is out of range for " + std::to_string(num_nodes) +
                       " nodes");
    }
    if (s == r) throw InputError(where + ": self loop at edge " + std::to_string(e));
    if (e > 0 && (s < data[2 * e - 2] || (s == data[2 * e - 2] && r <= data[2 * e - 1]))) {
      throw InputError(where + ": edges not sorted and unique at edge " + std::to_string(e));
    }
    ++g.offsets[s + 1];
    g.targets[e] = r;
  }
  for (int64_t i = 0; i < num_nodes; ++i) g.offsets[i + 1] += g.offsets[i];
  for (int64_t i = 0; i < num_nodes; ++i) {
    for (const int64_t* j = g.begin(i); j != g.end(i); ++j) {
      if (!std::binary_search(g.begin(*j), g.end(*j), i)) {
        throw InputError(where + ": edge (" + std::to_string(i) + ", " + std::to_string(*j) +
                         ") has no reverse edge (graphs must be symmetric)");
      }
    }
  }
  return g;
}

}  // namespace

MultilevelGraph read_multilevel_graph(const std::string& path) {
  H5File file(path, H5File::Mode::kRead);
  if (!file.has_attr("/", "format") || file.attr_string("/", "format") != kMultilevelFormat) {
    throw InputError(path + ": not a multilevel graph file (attribute format != \"" +
                     std::string(kMultilevelFormat) + "\")");
  }
  const int64_t version = file.attr_int("/", "version");
  if (version != kMultilevelVersion) {
    throw InputError(path + ": unsupported multilevel graph version " + std::to_string(version) +
                     " (this build reads version " + std::to_string(kMultilevelVersion) + ")");
  }
  MultilevelGraph out;
  try {
    out.seeding = parse_seeding(file.attr_string("/", "seeding"));
  } catch (const InputError& e) {
    throw InputError(path + ": attribute seeding: " + e.what());
  }
  if (file.has_attr("/", "coarse_edges")) {
    const std::string coarse = file.attr_string("/", "coarse_edges");
    if (coarse != "exact" && coarse != "thinned") {
      throw InputError(path + ": attribute coarse_edges = \"" + coarse +
                       "\", expected \"exact\" or \"thinned\"");
    }
    out.thinned = coarse == "thinned";
  }
  const int64_t num_levels = file.attr_int("/", "num_levels");
  if (num_levels < 1) {
    throw InputError(path + ": attribute num_levels = " + std::to_string(num_levels) +
                     ", expected >= 1");
  }
  for (int k = 0; k < num_levels; ++k) {
    const std::string group = level_group(k);
    const int64_t num_nodes = file.attr_int(group, "num_nodes");
    if (num_nodes < 0) {
      throw InputError(path + ": " + group + "@num_nodes = " + std::to_string(num_nodes));
    }
    GraphLevel level;
    const std::vector<int64_t> edges = file.read<int64_t>(group + "/edges", nullptr, {0, 2});
    // num_nodes sizes the CSR arrays: check it against data before allocating. Level k >= 1:
    // pooled holds one ascending entry per node (so num_nodes <= the finer level's); level 0:
    // every node with an edge has an out-edge, and nodes without one (no cell uses them) are few.
    if (k == 0 && num_nodes > static_cast<int64_t>(edges.size() / 2) + kMaxIsolatedNodes) {
      throw InputError(path + ": " + group + "@num_nodes = " + std::to_string(num_nodes) +
                       " is more than its " + std::to_string(edges.size() / 2) + " edges join (+ " +
                       std::to_string(kMaxIsolatedNodes) + " nodes without edges)");
    }
    if (k >= 1) {
      const GraphLevel& fine = out.levels.back();
      level.pooled =
          file.read<int64_t>(group + "/pooled", nullptr, {static_cast<hsize_t>(num_nodes)});
      // (A 0 in the expected shape accepts any length: check the count itself.)
      if (static_cast<int64_t>(level.pooled.size()) != num_nodes)
        throw InputError(path + ": " + group + "/pooled has " +
                         std::to_string(level.pooled.size()) +
                         " entries, expected num_nodes = " + std::to_string(num_nodes));
      for (size_t r = 0; r < level.pooled.size(); ++r) {
        const int64_t v = level.pooled[r];
        if (v < 0 || v >= fine.num_nodes() || (r > 0 && v <= level.pooled[r - 1])) {
          throw InputError(path + ": " + group + "/pooled: entry " + std::to_string(r) + " = " +
                           std::to_string(v) + " is out of range or not ascending");
        }
      }
    }
    level.graph = graph_from_edge_dataset(edges, num_nodes, path + ": " + group + "/edges");
    if (k >= 1) {
      const GraphLevel& fine = out.levels.back();
      level.down_weight = file.read<float>(group + "/down_weight", nullptr,
                                           {static_cast<hsize_t>(fine.graph.num_edges())});
      if (static_cast<int64_t>(level.down_weight.size()) != fine.graph.num_edges())
        throw InputError(path + ": " + group + "/down_weight has " +
                         std::to_string(level.down_weight.size()) +
                         " entries, expected one per edge of level " + std::to_string(k - 1) +
                         " (" + std::to_string(fine.graph.num_edges()) + ")");
      for (size_t e = 0; e < level.down_weight.size(); ++e) {
        // Each weight is a share of a coarse node's incoming spread (bi_stride_pooling.cpp): in
        // 0..1, with room for float rounding.
        if (!(level.down_weight[e] >= 0.0f && level.down_weight[e] <= 1.001f)) {
          throw InputError(path + ": " + group + "/down_weight: entry " + std::to_string(e) +
                           " is " + std::to_string(level.down_weight[e]) +
                           ", expected a share in 0..1");
        }
      }
    }
    out.levels.push_back(std::move(level));
  }
  return out;
}

}  // namespace bsms
