#include "pipeline/experiments/heat_sticks.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

#include "core/error.hpp"
#include "core/graph.hpp"
#include "core/runtime.hpp"
#include "models/fused_adam.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/report/plotting.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_config.hpp"
#include "pipeline/train/fit.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

constexpr int64_t kMaxNodes = 100000;
constexpr int64_t kMaxLatent = 4096;
// The gap in units of dx: far beyond a stick's length (kMaxNodes dx) it tests nothing more, and
// the test sticks' coordinates must stay in the proximity grid's range (checked only after
// training otherwise).
constexpr double kMaxGapDx = 1e6;
// Losses averaged for the reported final training loss.
constexpr int64_t kFinalLossSteps = 100;

MultilevelTensors build_hierarchy(HierarchyKind kind, const Sticks& sticks, int levels) {
  return kind == HierarchyKind::kBiStride ? bistride_multilevel(sticks, levels)
                                          : proximity_multilevel(sticks, levels);
}

std::vector<float> to_floats(const torch::Tensor& t) {
  auto c = t.to(torch::kFloat32).contiguous();
  return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}

// Root mean square of the errors added.
struct RmsAccumulator {
  double sum = 0.0;
  int64_t count = 0;
  void add(double error) {
    sum += error * error;
    ++count;
  }
  double value() const { return count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0; }
};

struct TrainResult {
  std::shared_ptr<BsmsGnn> model;
  std::vector<double> losses;
  double wall_s = 0.0;
};

// Single sticks at a random offset in [0, 1) (so the proximity model sees every alignment of a
// stick with its grids; the bi-stride hierarchy does not depend on it), both orientations in every
// batch, T_d and q uniform in [-1, 1]. The same seed gives both models the same initial weights
// and the same training data.
TrainResult train_model(const HeatSticksOptions& o, const ModelSpec& spec) {
  TrainResult r;
  torch::manual_seed(o.seed);
  r.model = std::make_shared<BsmsGnn>(heat_model_options(o.levels, o.latent));
  r.model->train();
  FusedAdam optimizer(r.model->parameters(), torch::optim::AdamOptions(o.lr));
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> value(-1.0, 1.0), offset(0.0, 1.0);
  FitOptions fit_options;  // the trainer's loop and schedule (no warm-up here)
  fit_options.optimizer.lr = o.lr;
  fit_options.optimizer.lr_final = o.lr_final;
  fit_options.steps = o.steps;
  fit_options.label = std::string("train ") + spec.label;
  FitHooks hooks;
  hooks.loss = [&](int64_t) {
    std::vector<MultilevelTensors> graphs;
    std::vector<torch::Tensor> inputs, positions, truth;
    for (int64_t b = 0; b < o.batch; ++b) {
      const Sticks stick = make_sticks({offset(rng)}, o.nodes);
      StickBc bc;
      bc.dirichlet_left = b % 2 == 0;
      bc.t_dirichlet = value(rng);
      bc.flux = value(rng);
      graphs.push_back(build_hierarchy(spec.kind, stick, o.levels));
      inputs.push_back(stick_inputs(stick, {bc}));
      positions.push_back(stick.positions);
      truth.push_back(stick_solution(stick, {bc}));
    }
    std::vector<const MultilevelTensors*> parts;
    for (const auto& g : graphs) parts.push_back(&g);
    const MultilevelTensors batch = merge_multilevel_tensors(parts);
    auto pred = r.model->forward(torch::cat(inputs), {torch::cat(positions)}, batch);
    return torch::mse_loss(pred, torch::cat(truth));
  };
  hooks.after_step = [&](const FitStep& s) {
    r.losses.push_back(s.loss);
    return std::string();
  };
  r.wall_s = fit(optimizer, fit_options, hooks).wall_s;
  r.model->eval();
  return r;
}

torch::Tensor predict(BsmsGnn& model, HierarchyKind kind, const Sticks& sticks,
                      const std::vector<StickBc>& bcs, int levels) {
  torch::NoGradGuard no_grad;
  const MultilevelTensors graph = build_hierarchy(kind, sticks, levels);
  return model.forward(stick_inputs(sticks, bcs), {sticks.positions}, graph);
}

// One test case: the two sticks together, and each stick alone, for both models.
struct TestCase {
  int combo = 0, draw = 0;
  std::array<StickBc, 2> bcs;
  std::vector<float> truth;                 // [2 * nodes]
  std::array<std::vector<float>, 2> pair;   // per model, [2 * nodes], two-stick graph
  std::array<std::vector<float>, 2> alone;  // per model, [2 * nodes], each stick on its own
};

// The test: two sticks head to tail, A on [0, 1] and B on [1 + gap, 2 + gap], and each alone.
struct TestSticks {
  double dx = 0.0, gap = 0.0, b_start = 0.0, gap_mid = 0.0;
  Sticks pair;
  std::array<Sticks, 2> alone;
  std::vector<char> near_gap;  // [2 * nodes] 1 for nodes within kNearGapDx of the gap
};

TestSticks make_test_sticks(const HeatSticksOptions& o) {
  TestSticks t;
  t.dx = 1.0 / static_cast<double>(o.nodes - 1);
  t.gap = o.gap * t.dx;
  t.b_start = 1.0 + t.gap;
  t.gap_mid = 1.0 + 0.5 * t.gap;
  t.pair = make_sticks({0.0, t.b_start}, o.nodes);
  t.alone = {make_sticks({0.0}, o.nodes), make_sticks({t.b_start}, o.nodes)};
  t.near_gap.resize(t.pair.x.size());
  for (size_t i = 0; i < t.pair.x.size(); ++i) {
    const double distance = t.pair.stick[i] == 0 ? 1.0 - t.pair.x[i] : t.pair.x[i] - t.b_start;
    t.near_gap[i] = distance <= kNearGapDx * t.dx + 1e-9 ? 1 : 0;
  }
  return t;
}

// Every combination with o.test_draws boundary-condition draws, predicted by both models.
std::vector<TestCase> run_test_cases(const HeatSticksOptions& o, const TestSticks& sticks,
                                     const std::array<TrainResult, 2>& trained) {
  std::mt19937_64 test_rng(o.seed ^ 0x9E3779B97F4A7C15ull);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<TestCase> cases;
  for (int c = 0; c < static_cast<int>(kCombos.size()); ++c) {
    for (int d = 0; d < o.test_draws; ++d) {
      TestCase t;
      t.combo = c;
      t.draw = d;
      t.bcs[0].dirichlet_left = kCombos[c].a_dirichlet_left;
      t.bcs[1].dirichlet_left = kCombos[c].b_dirichlet_left;
      for (auto& bc : t.bcs) {
        bc.t_dirichlet = value(test_rng);
        bc.flux = value(test_rng);
      }
      const std::vector<StickBc> bcs(t.bcs.begin(), t.bcs.end());
      t.truth = to_floats(stick_solution(sticks.pair, bcs));
      for (size_t m = 0; m < kModels.size(); ++m) {
        BsmsGnn& model = *trained[m].model;
        t.pair[m] = to_floats(predict(model, kModels[m].kind, sticks.pair, bcs, o.levels));
        for (size_t s = 0; s < 2; ++s) {
          auto p =
              to_floats(predict(model, kModels[m].kind, sticks.alone[s], {t.bcs[s]}, o.levels));
          t.alone[m].insert(t.alone[m].end(), p.begin(), p.end());
        }
      }
      cases.push_back(std::move(t));
    }
  }
  return cases;
}

Json setup_metrics(const HeatSticksOptions& o, const TestSticks& sticks) {
  return {{"nodes_per_stick", o.nodes},
          {"dx", sticks.dx},
          {"levels", o.levels},
          {"gap_dx", o.gap},
          {"gap", sticks.gap},
          {"stick_a", {0.0, 1.0}},
          {"stick_b", {sticks.b_start, sticks.b_start + 1.0}},
          {"near_gap_dx", kNearGapDx},
          {"proximity_cell_size", kProximityCellDx * sticks.dx},
          {"seeding", "closecenter"},
          {"latent", o.latent},
          {"batch", o.batch},
          {"steps", o.steps},
          {"lr", o.lr},
          {"lr_final", o.lr_final},
          {"train_offset_range", {0.0, 1.0}},
          {"test_draws_per_combo", o.test_draws},
          {"seed", o.seed}};
}

// Mean of the last kFinalLossSteps training losses.
double final_loss(const std::vector<double>& losses) {
  const int64_t tail = std::min<int64_t>(kFinalLossSteps, static_cast<int64_t>(losses.size()));
  double loss = 0.0;
  for (int64_t s = static_cast<int64_t>(losses.size()) - tail;
       s < static_cast<int64_t>(losses.size()); ++s) {
    loss += losses[s] / static_cast<double>(tail);
  }
  return loss;
}

// Node and edge counts and how much the hierarchy of the two test sticks mixes them.
Json hierarchy_metrics(const MultilevelTensors& g, const std::vector<int64_t>& stick) {
  const StickMixing mixing = stick_mixing(g, stick);
  std::vector<int64_t> nodes_per_level, edges_per_level;
  for (int k = 0; k < g.num_levels(); ++k) {
    nodes_per_level.push_back(g.num_nodes(k));
    edges_per_level.push_back(g.edge_sets[k][0].num_edges());
  }
  return {{"nodes_per_level", nodes_per_level},
          {"edges_per_level", edges_per_level},
          {"cross_gap_edges_per_level", mixing.cross_stick_edges},
          {"mixed_nodes_per_level", mixing.mixed_nodes}};
}

// Model m's training figures and test errors; `test_graph` is its hierarchy of the two sticks.
Json model_metrics(size_t m, const TrainResult& trained, const std::vector<TestCase>& cases,
                   const TestSticks& sticks, const MultilevelTensors& test_graph) {
  RmsAccumulator all, near, all_alone, near_alone;
  std::array<RmsAccumulator, 4> by_combo;
  double max_diff = 0.0;
  for (const auto& t : cases) {
    for (size_t i = 0; i < t.truth.size(); ++i) {
      const double e = t.pair[m][i] - t.truth[i], ea = t.alone[m][i] - t.truth[i];
      all.add(e);
      all_alone.add(ea);
      by_combo[t.combo].add(e);
      if (sticks.near_gap[i]) {
        near.add(e);
        near_alone.add(ea);
      }
      max_diff = std::max(max_diff, std::abs(static_cast<double>(t.pair[m][i] - t.alone[m][i])));
    }
  }
  const auto& losses = trained.losses;
  const double loss = final_loss(losses);
  Json combos = Json::object();
  for (size_t c = 0; c < kCombos.size(); ++c) combos[kCombos[c].name] = by_combo[c].value();
  return {{"label", kModels[m].label},
          {"train_loss_final", loss},
          {"train_rmse_final", std::sqrt(loss)},
          {"train_steps", static_cast<int64_t>(losses.size())},
          {"train_wall_s", trained.wall_s},
          {"train_ms_per_step", 1e3 * trained.wall_s / static_cast<double>(losses.size())},
          {"rmse_alone", all_alone.value()},
          {"rmse_pair", all.value()},
          {"rmse_alone_near_gap", near_alone.value()},
          {"rmse_pair_near_gap", near.value()},
          {"rmse_pair_by_combo", combos},
          {"max_abs_pair_minus_alone", max_diff},
          {"test_hierarchy", hierarchy_metrics(test_graph, sticks.pair.stick)}};
}

// profiles.csv: every test case, both models, on the two-stick graph and each stick alone.
void write_profiles(const HeatSticksOptions& o, const fs::path& out, const Sticks& pair,
                    const std::vector<TestCase>& cases) {
  std::ostringstream csv;
  csv << "case,combo,draw,stick,node,x,truth,bistride,proximity,bistride_alone,proximity_alone\n";
  csv << std::setprecision(7);
  for (size_t k = 0; k < cases.size(); ++k) {
    const auto& t = cases[k];
    for (size_t i = 0; i < t.truth.size(); ++i) {
      csv << k << ',' << kCombos[t.combo].name << ',' << t.draw << ',' << pair.stick[i] << ','
          << static_cast<int64_t>(i) % o.nodes << ',' << pair.x[i] << ',' << t.truth[i] << ','
          << t.pair[0][i] << ',' << t.pair[1][i] << ',' << t.alone[0][i] << ',' << t.alone[1][i]
          << '\n';
    }
  }
  write_text_atomic((out / "profiles.csv").string(), csv.str());
}

// train_log.csv: both models' training losses.
void write_train_log(const HeatSticksOptions& o, const fs::path& out,
                     const std::array<TrainResult, 2>& trained) {
  std::ostringstream log;
  log << "step,bistride_loss,proximity_loss\n" << std::setprecision(6);
  for (int64_t s = 0; s < o.steps; ++s) {
    log << s + 1 << ',' << trained[0].losses[s] << ',' << trained[1].losses[s] << '\n';
  }
  write_text_atomic((out / "train_log.csv").string(), log.str());
}

// The plot's data: the four combinations, first draw, one file each.
void write_plot_data(const HeatSticksOptions& o, const fs::path& plots, const Sticks& pair,
                     const std::vector<TestCase>& cases) {
  for (const auto& t : cases) {
    if (t.draw != 0) continue;
    std::ostringstream dat;
    dat << "# x truth bistride proximity (two-stick graph)\n" << std::setprecision(7);
    for (size_t i = 0; i < t.truth.size(); ++i) {
      if (i == static_cast<size_t>(o.nodes)) dat << '\n';  // break the line at the gap
      dat << pair.x[i] << ' ' << t.truth[i] << ' ' << t.pair[0][i] << ' ' << t.pair[1][i] << '\n';
    }
    write_text_atomic(
        (plots / ("heat_sticks_" + std::string(kCombos[t.combo].name) + ".dat")).string(),
        dat.str());
  }
}

std::string plot_script(const HeatSticksOptions& o, const fs::path& plots,
                        const std::vector<TestCase>& cases, double gap_mid) {
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / "heat_sticks.png").string(), 1400, 1000)
    << "set multiplot layout 2,2 title "
    << "'Steady 1-D heat on two sticks with a gap of " << format_number(o.gap)
    << " dx (first test draw): exact solution, BSMS-GNN with bi-stride and with proximity "
       "coarsening'\n"
    << "set grid\nset xlabel 'x'\nset ylabel 'temperature T'\nset key top left box opaque\n"
    << "set xrange [-0.05:" << 2.05 + 2.0 * (gap_mid - 1.0) << "]\n"
    << "set arrow 1 from " << gap_mid << ", graph 0 to " << gap_mid
    << ", graph 1 nohead dt 2 lw 2 lc rgb '#555555'\n"
    << "set label 1 'gap' at " << gap_mid << ", graph 0.04 offset 0.5,0 tc rgb '#555555'\n";
  for (const auto& c : cases) {
    if (c.draw != 0) continue;
    const std::string data = gnuplot_quoted(
        (plots / ("heat_sticks_" + std::string(kCombos[c.combo].name) + ".dat")).string());
    g << "set title '" << kCombos[c.combo].name << "   (D = Dirichlet end, F = flux end, "
      << "- = gap)'\nplot " << data << " using 1:2 with lines lw 2 lc rgb '#222222' title "
      << "'exact', " << data << " using 1:3 with points pt 6 ps 1.3 lc rgb '#1f77b4' title "
      << "'bi-stride', " << data << " using 1:4 with points pt 2 ps 1.3 lc rgb '#d62728' title "
      << "'proximity'\n";
  }
  g << "unset multiplot\n";
  return g.str();
}

}  // namespace

void validate(const HeatSticksOptions& o) {
  if (o.out.empty()) throw InputError("--out: give an output folder");
  if (o.steps < 1) throw InputError("--steps must be >= 1, got " + std::to_string(o.steps));
  if (o.nodes < 5 || o.nodes > kMaxNodes) {
    throw InputError("--nodes (nodes per stick) must be in [5, " + std::to_string(kMaxNodes) +
                     "], got " + std::to_string(o.nodes));
  }
  if (o.levels < 2) {
    throw InputError(
        "--levels must be >= 2 (the input graph and at least one coarser level), got " +
        std::to_string(o.levels));
  }
  const int most = max_stick_levels(o.nodes);
  if (o.levels > most) {
    throw InputError("--levels " + std::to_string(o.levels) + " is too many for --nodes " +
                     std::to_string(o.nodes) + ": at most " + std::to_string(most) +
                     " levels keep 2 or more nodes on the coarsest bi-stride level");
  }
  if (!(o.gap > 0.0) || !(o.gap <= kMaxGapDx)) {
    throw InputError("--gap (in units of dx) must be a number in (0, " + format_number(kMaxGapDx) +
                     "], got " + format_number(o.gap));
  }
  if (o.latent < 1 || o.latent > kMaxLatent) {
    throw InputError("--latent must be in [1, " + std::to_string(kMaxLatent) + "], got " +
                     std::to_string(o.latent));
  }
  if (o.batch < 1) throw InputError("--batch must be >= 1, got " + std::to_string(o.batch));
  if (o.test_draws < 1) {
    throw InputError("--draws must be >= 1, got " + std::to_string(o.test_draws));
  }
  if (!(o.lr > 0.0) || !(o.lr_final > 0.0) || !std::isfinite(o.lr) || !std::isfinite(o.lr_final)) {
    throw InputError("learning rates must be positive, got " + format_number(o.lr) + " and " +
                     format_number(o.lr_final));
  }
}

Json run_heat_sticks(const HeatSticksOptions& o) {
  validate(o);
  const int threads = configure_threads(set_num_threads(o.threads));
  const fs::path out = o.out, plots = out / "plots";
  std::error_code ec;
  fs::create_directories(plots, ec);
  if (ec) throw InputError(o.out + ": cannot create the output folder (" + ec.message() + ")");
  Stopwatch total;

  std::array<TrainResult, 2> trained;
  for (size_t m = 0; m < kModels.size(); ++m) trained[m] = train_model(o, kModels[m]);
  const TestSticks sticks = make_test_sticks(o);
  const std::vector<TestCase> cases = run_test_cases(o, sticks, trained);

  Json metrics;
  metrics["experiment"] = "heat-sticks";
  metrics["reference"] = "thesis Figure 4.6 (failure cases for spatial proximity)";
  metrics["setup"] = setup_metrics(o, sticks);
  const std::array<MultilevelTensors, 2> test_graphs{bistride_multilevel(sticks.pair, o.levels),
                                                     proximity_multilevel(sticks.pair, o.levels)};
  for (size_t m = 0; m < kModels.size(); ++m) {
    metrics["models"][kModels[m].key] = model_metrics(m, trained[m], cases, sticks, test_graphs[m]);
  }
  metrics["threads"] = threads;

  write_profiles(o, out, sticks.pair, cases);
  write_train_log(o, out, trained);
  write_plot_data(o, plots, sticks.pair, cases);
  const bool plotted =
      draw_plot((plots / "heat_sticks.gp").string(), plot_script(o, plots, cases, sticks.gap_mid));
  metrics["plot"] = plotted ? Json("plots/heat_sticks.png") : Json(nullptr);
  metrics["wall_s"] = total.seconds();

  const int64_t near_gap_nodes = std::count(sticks.near_gap.begin(), sticks.near_gap.end(), 1);
  write_text_atomic((out / "heat_sticks.md").string(),
                    heat_sticks_markdown(o, metrics, near_gap_nodes, threads, plotted));
  write_json_atomic((out / "metrics.json").string(), metrics);
  return metrics;
}

}  // namespace bsms
