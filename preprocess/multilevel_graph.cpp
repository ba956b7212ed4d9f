#include "preprocess/multilevel_graph.hpp"

#include <algorithm>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "preprocess/bi_stride_pooling.hpp"
#include "preprocess/edge_thinning.hpp"
#include "preprocess/seeding.hpp"

namespace bsms {

std::string to_string(Seeding seeding) {
  switch (seeding) {
    case Seeding::kCloseCenter:
      return "closecenter";
    case Seeding::kMinAve:
      return "minave";
    case Seeding::kRandom:
      return "random";
  }
  return "unknown";
}

Seeding parse_seeding(const std::string& name) {
  if (name == "closecenter") return Seeding::kCloseCenter;
  if (name == "minave") return Seeding::kMinAve;
  if (name == "random") return Seeding::kRandom;
  throw InputError("unknown seeding '" + name + "' (expected minave, closecenter or random)");
}

std::vector<std::string> seeding_names() {
  std::vector<std::string> names;
  for (const Seeding s : kAllSeedings) names.push_back(to_string(s));
  return names;
}

std::string to_string(Thinning thinning) {
  switch (thinning) {
    case Thinning::kAuto:
      return "auto";
    case Thinning::kOn:
      return "on";
    case Thinning::kOff:
      return "off";
  }
  return "unknown";
}

Thinning parse_thinning(const std::string& name) {
  if (name == "auto") return Thinning::kAuto;
  if (name == "on") return Thinning::kOn;
  if (name == "off") return Thinning::kOff;
  throw InputError("unknown thinning '" + name + "' (expected auto, on or off)");
}

double mean_degree(const CsrGraph& graph) {
  return graph.num_nodes > 0
             ? static_cast<double>(graph.num_edges()) / static_cast<double>(graph.num_nodes)
             : 0.0;
}

namespace {

RowMatrixXd select_rows(const RowMatrixXd& positions, const std::vector<int64_t>& rows) {
  RowMatrixXd out(static_cast<Eigen::Index>(rows.size()), positions.cols());
  for (size_t r = 0; r < rows.size(); ++r) out.row(r) = positions.row(rows[r]);
  return out;
}

}  // namespace

bool auto_accepts_level(const CsrGraph& candidate, int64_t previous_nodes, int64_t level0_edges,
                        int64_t coarse_edges, bool thinned) {
  const double edges = static_cast<double>(candidate.num_edges());
  const bool too_costly =
      thinned ? static_cast<double>(coarse_edges) + edges >
                    kAutoMaxEdgesFactor * static_cast<double>(level0_edges)
              : edges > kAutoMaxLevelEdgesFactor * static_cast<double>(level0_edges);
  if (candidate.num_nodes >= previous_nodes || too_costly) return false;
  const Components components = connected_components(candidate);
  std::vector<int64_t> size(components.count, 0);
  for (int64_t label : components.label) ++size[label];
  int64_t largest = 0;
  double pairs = 0.0;
  for (int64_t n : size) {
    largest = std::max(largest, n);
    pairs += static_cast<double>(n) * static_cast<double>(n - 1);
  }
  return largest >= kAutoMinClusterNodes &&
         static_cast<double>(candidate.num_edges()) <= kAutoMaxDensity * pairs;
}

GraphLevel coarsen_level(const GraphLevel& fine, Seeding seeding, uint64_t rng_seed, bool thin,
                         int64_t* clusters_out) {
  const ClusterNodes clusters = group_clusters(connected_components(fine.graph));
  if (clusters_out != nullptr) *clusters_out = clusters.count;
  std::vector<int64_t> seeds;
  switch (seeding) {
    case Seeding::kCloseCenter:
      if (fine.positions.rows() != fine.num_nodes()) {
        throw InputError("CloseCenter seeding needs positions for all " +
                         std::to_string(fine.num_nodes()) + " nodes, got " +
                         std::to_string(fine.positions.rows()));
      }
      seeds = close_center_seeds(clusters, fine.positions);
      break;
    case Seeding::kMinAve:
      seeds = min_ave_seeds(fine.graph, clusters);
      break;
    case Seeding::kRandom:
      seeds = random_seeds(clusters, rng_seed);
      break;
  }
  GraphLevel coarse;
  coarse.pooled = bi_stride_pool(fine.graph, clusters, seeds);
  coarse.graph = enhance_adjacency(fine.graph, coarse.pooled);
  if (fine.positions.rows() == fine.num_nodes()) {
    coarse.positions = select_rows(fine.positions, coarse.pooled);
  }
  if (thin) {
    if (coarse.positions.rows() != coarse.num_nodes()) {
      throw InputError("thinning coarse levels needs the positions of all " +
                       std::to_string(fine.num_nodes()) + " nodes");
    }
    coarse.graph = thin_adjacency(coarse.graph, coarse.positions);
  }
  std::vector<double> weight = fine.node_weight;
  if (weight.empty()) weight.assign(fine.num_nodes(), 1.0);
  TransitionWeights transition = transition_weights(fine.graph, weight, coarse.pooled);
  coarse.down_weight = std::move(transition.down_weight);
  coarse.node_weight = std::move(transition.node_weight);
  return coarse;
}

MultilevelGraph build_multilevel_graph(CsrGraph graph, const RowMatrixXd& positions,
                                       const BuildOptions& options,
                                       std::vector<LevelReport>* report) {
  if (options.num_levels < 0) {
    throw InputError("number of levels must be >= 1 or auto, got " +
                     std::to_string(options.num_levels));
  }
  const bool automatic = options.num_levels == 0;
  const int target = automatic ? kAutoMaxLevels : options.num_levels;
  MultilevelGraph out;
  out.seeding = options.seeding;
  // Thinning needs positions; auto thins only automatic hierarchies.
  const bool have_positions = positions.rows() == graph.num_nodes && positions.cols() >= 1;
  if (options.thinning == Thinning::kOn && !have_positions) {
    throw InputError("thinning coarse levels needs node positions");
  }
  out.thinned = options.thinning == Thinning::kOn ||
                (options.thinning == Thinning::kAuto && automatic && have_positions);
  const int64_t level0_edges = graph.num_edges();
  int64_t coarse_edges = 0;
  if (report != nullptr) {
    report->clear();
    report->push_back({0, graph.num_nodes, graph.num_edges(), connected_components(graph).count,
                       mean_degree(graph), 0.0});
  }
  GraphLevel level0;
  level0.graph = std::move(graph);
  level0.positions = positions;
  level0.node_weight.assign(level0.graph.num_nodes, 1.0);
  out.levels.push_back(std::move(level0));
  for (int k = 1; k < target; ++k) {
    Stopwatch clock;
    int64_t clusters = 0;
    // Mix the level into the random seed so levels draw independently.
    GraphLevel next =
        coarsen_level(out.levels.back(), options.seeding,
                      options.rng_seed + 0x9E3779B97F4A7C15ull * static_cast<uint64_t>(k),
                      out.thinned, &clusters);
    if (automatic && !auto_accepts_level(next.graph, out.levels.back().num_nodes(), level0_edges,
                                         coarse_edges, out.thinned)) {
      break;
    }
    coarse_edges += next.graph.num_edges();
    if (report != nullptr) {
      report->push_back({k, next.num_nodes(), next.graph.num_edges(), clusters,
                         mean_degree(next.graph), clock.milliseconds()});
    }
    out.levels.push_back(std::move(next));
  }
  return out;
}

MultilevelGraph build_multilevel_graph(const Mesh& mesh, const BuildOptions& options,
                                       std::vector<LevelReport>* report) {
  Stopwatch clock;
  CsrGraph graph = mesh_graph(mesh);
  const double graph_ms = clock.milliseconds();
  MultilevelGraph out = build_multilevel_graph(std::move(graph), mesh.points, options, report);
  if (report != nullptr && !report->empty()) report->front().milliseconds = graph_ms;
  return out;
}

}  // namespace bsms
