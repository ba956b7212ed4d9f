#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "pipeline/experiments/heat_sticks.hpp"
#include "pipeline/report/number_format.hpp"

namespace bsms {
namespace {

std::string joined(const std::vector<int64_t>& values) {
  std::string out;
  for (size_t i = 0; i < values.size(); ++i) out += (i ? " / " : "") + std::to_string(values[i]);
  return out;
}

}  // namespace

std::string heat_sticks_markdown(const HeatSticksOptions& o, const Json& metrics,
                                 int64_t near_gap_nodes, int threads, bool plotted) {
  const double dx = 1.0 / static_cast<double>(o.nodes - 1);
  const Json& bs = metrics["models"]["bistride"];
  const Json& px = metrics["models"]["proximity"];
  std::ostringstream md;
  md << "## Spatial proximity failure case: steady heat on two sticks (thesis Fig. 4.6)\n\n"
     << "Steady 1-D heat conduction on sticks of length 1 with " << o.nodes
     << " nodes (dx = " << format_number(dx)
     << "): temperature T_d at one end, heat flux q at the other, "
     << "exact solution T(s) = T_d + q s (s = distance from the Dirichlet end). Inputs per node: "
     << "(is Dirichlet, is flux, value); output T. The same BSMS-GNN network (" << o.levels
     << " levels, latent " << o.latent << ", same initial weights and training data) is trained "
     << "for " << o.steps << " steps (batches of " << o.batch << " single sticks at a random "
     << "offset, both orientations, T_d and q uniform in [-1, 1], Adam " << format_number(o.lr)
     << " to " << format_number(o.lr_final)
     << ") with two coarsenings: **bi-stride** (CloseCenter seeding) and "
     << "**proximity** (MS-GNN-GRID style: grid cells of " << format_number(kProximityCellDx)
     << " dx doubling per level, edges between neighbouring cells, mean down / broadcast up). "
     << "Test: stick A on [0, 1] and stick B on [1 + " << format_number(o.gap) << " dx, 2 + "
     << format_number(o.gap) << " dx], no heat crosses the gap, for the 4 orientation combinations "
     << "(D = Dirichlet end, F = flux end, - = gap) x " << o.test_draws << " draws of T_d and q. "
     << "\"Alone\": each test stick evaluated on its own graph; \"near gap\": the "
     << near_gap_nodes << " nodes within " << format_number(kNearGapDx) << " dx of the gap. "
     << threads << " thread(s), total " << format_number(metrics["wall_s"].get<double>())
     << " s.\n\n"
     << "| coarsening | train RMSE | RMSE alone | RMSE two sticks | near gap alone | near gap two "
        "sticks |";
  for (const auto& c : kCombos) md << ' ' << c.name << " |";
  md << " max abs(two sticks - alone) | cross-gap edges per level | train s "
        "|\n|---|---|---|---|---|"
        "---|";
  for (size_t c = 0; c < kCombos.size(); ++c) md << "---|";
  md << "---|---|---|\n";
  for (const auto& spec : kModels) {
    const Json& r = metrics["models"][spec.key];
    md << "| " << spec.label << " | "
       << format_number(r["train_rmse_final"], 2, Notation::kScientific) << " | "
       << format_number(r["rmse_alone"], 2, Notation::kScientific) << " | "
       << format_number(r["rmse_pair"], 2, Notation::kScientific) << " | "
       << format_number(r["rmse_alone_near_gap"], 2, Notation::kScientific) << " | "
       << format_number(r["rmse_pair_near_gap"], 2, Notation::kScientific) << " |";
    for (const auto& c : kCombos)
      md << ' ' << format_number(r["rmse_pair_by_combo"][c.name], 2, Notation::kScientific) << " |";
    md << ' ' << format_number(r["max_abs_pair_minus_alone"], 2, Notation::kScientific) << " | "
       << joined(r["test_hierarchy"]["cross_gap_edges_per_level"].get<std::vector<int64_t>>())
       << " | " << format_number(r["train_wall_s"].get<double>()) << " |\n";
  }
  // The reading, from the figures above.
  auto sum_of = [](const Json& r, const char* key) {
    int64_t sum = 0;
    for (const auto& n : r["test_hierarchy"][key]) sum += n.get<int64_t>();
    return sum;
  };
  const bool bs_apart =
      sum_of(bs, "cross_gap_edges_per_level") == 0 && sum_of(bs, "mixed_nodes_per_level") == 0;
  const bool px_joined =
      sum_of(px, "cross_gap_edges_per_level") > 0 || sum_of(px, "mixed_nodes_per_level") > 0;
  const double ratio = px["rmse_pair_near_gap"].get<double>() /
                       std::max(bs["rmse_pair_near_gap"].get<double>(), 1e-12);
  const double bs_growth =
      bs["rmse_pair"].get<double>() / std::max(bs["rmse_alone"].get<double>(), 1e-12);
  md << "\n**Reading.** With bi-stride coarsening the two sticks "
     << (bs_apart ? "stay separate at every level" : "are joined at some level") << ", and the "
     << "two-stick prediction "
     << (bs["max_abs_pair_minus_alone"].get<double>() < 1e-4 ? "equals" : "differs from")
     << " the single-stick one (max difference "
     << format_number(bs["max_abs_pair_minus_alone"], 2, Notation::kScientific)
     << "; two-stick RMSE " << format_number(bs_growth, 2, Notation::kFixed)
     << "x the single-stick RMSE); proximity "
     << "coarsening " << (px_joined ? "joins" : "also keeps apart") << " the sticks (cross-gap "
     << "edges per level: "
     << joined(px["test_hierarchy"]["cross_gap_edges_per_level"].get<std::vector<int64_t>>())
     << "; nodes shared by both sticks: "
     << joined(px["test_hierarchy"]["mixed_nodes_per_level"].get<std::vector<int64_t>>())
     << ") and its RMSE near the gap is " << format_number(ratio, 2, Notation::kFixed)
     << "x the bi-stride model's ("
     << format_number(px["rmse_pair_near_gap"], 2, Notation::kScientific) << " vs "
     << format_number(bs["rmse_pair_near_gap"], 2, Notation::kScientific) << ", "
     << (ratio >= 2.0  ? "markedly worse"
         : ratio > 1.2 ? "somewhat worse"
                       : "no clear difference")
     << "; " << format_number(px["rmse_alone_near_gap"], 2, Notation::kScientific)
     << " for the same sticks evaluated alone).\n\n";
  if (plotted) {
    md << "![heat_sticks](plots/heat_sticks.png)\n\n";
  } else {
    md << "_The plot was left out: gnuplot is not installed._\n\n";
  }
  return md.str();
}

}  // namespace bsms
