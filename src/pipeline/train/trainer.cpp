#include "pipeline/train/trainer.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <signal.h>
#include <torch/torch.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <memory>
#include <optional>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/one_line.hpp"
#include "core/runtime.hpp"
#include "models/fused_adam.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_log.hpp"
#include "pipeline/runs/train_stats.hpp"
#include "pipeline/train/fit.hpp"
#include "pipeline/train/prefetch.hpp"
#include "pipeline/train/training_data.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// Drops log rows after `step` (resume) and returns the file for appending. A session killed
// mid-write may have left rows past its checkpoint and a torn last line (no newline): only whole,
// newline-terminated rows up to the checkpoint's step are kept, so the log holds each step once.
std::ofstream open_log(const std::string& path, int64_t keep_until_step, bool fresh) {
  std::vector<std::string> kept;
  if (!fresh && fs::exists(path)) {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    int64_t last = 0;
    while (std::getline(in, line)) {
      if (in.eof()) break;  // no newline after it: torn by a kill
      const auto row = parse_train_log_row(line);
      // The header, a torn row or one past the checkpoint.
      if (!row || row->step <= last || row->step > keep_until_step) continue;
      kept.push_back(line);
      last = row->step;
    }
  }
  {
    AtomicOutput out(path);
    std::ofstream f(out.temp_path());
    f << kTrainLogHeader << '\n';
    for (const auto& l : kept) f << l << '\n';
    f.close();
    out.commit();
  }
  return std::ofstream(path, std::ios::app);
}

// Removes the temporary files (NAME.tmp.PID.N, see AtomicOutput) that sessions killed while
// writing left in `dir`; those of a live process are kept.
void remove_stale_temporaries(const fs::path& dir) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const size_t tmp = name.rfind(".tmp.");
    if (tmp == std::string::npos || !it->is_regular_file(ec)) continue;
    const std::string rest = name.substr(tmp + 5);  // PID.N
    const size_t dot = rest.find('.');
    const std::string pid = rest.substr(0, dot);
    if (dot == std::string::npos || pid.empty() || pid.size() > 9 ||
        !std::all_of(rest.begin(), rest.end(),
                     [](char c) { return c == '.' || (c >= '0' && c <= '9'); }))
      continue;
    const pid_t owner = static_cast<pid_t>(std::stol(pid));
    if (owner == ::getpid() || ::kill(owner, 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

TrainConfig load_train_config(const TrainRequest& request) {
  Json raw = load_json_file(request.config_path);
  for (const auto& set : request.overrides) apply_override(raw, set, "--set " + set);
  return parse_train_config(raw, request.config_path);
}

// Threads of this process: --threads, or with 0 the hardware's shared among the local ranks.
int requested_threads(const TrainRequest& request) {
  if (request.threads > 0 || !request.distributed.enabled()) return request.threads;
  const char* local = std::getenv("LOCAL_WORLD_SIZE");
  const int ranks = local ? std::max(1, std::atoi(local)) : 1;
  return std::max(1, hardware_threads() / ranks);
}

// What rank 0 tells the others once it has checked the run folder: "ok" and, on --resume, the
// checkpoint's bytes; or the exit code of its error (the others exit with it, silently).
std::string encode_verdict(int code, const std::string& payload) {
  return std::to_string(code) + "\n" + payload;
}

}  // namespace

void check_train_request(const TrainRequest& request) {
  const TrainConfig config = load_train_config(request);
  const Dataset train_data = Dataset::open_split(config.data, "train");
  if (Dataset::has_split(config.data, "valid")) Dataset::open_split(config.data, "valid");
}

namespace {

// The order in which training asks for batches: the normaliser's (indices -2, -3, ...; a fresh
// run only), then the optimizer steps from `first_step` on. Positions count them from 0 (what
// the prefetcher follows).
struct BatchOrder {
  int64_t first_step = 0;
  int64_t normalizer_batches = 0;
  int64_t index_at(int64_t position) const {
    return position < normalizer_batches ? -2 - position
                                         : first_step + (position - normalizer_batches);
  }
  int64_t position_of(int64_t index) const {
    return index <= -2 ? -2 - index : normalizer_batches + (index - first_step);
  }
};

}  // namespace

TrainResult train(const TrainRequest& request) {
  const auto started = std::chrono::steady_clock::now();
  TrainConfig config = load_train_config(request);
  const int threads = configure_threads(set_num_threads(requested_threads(request)));
  torch::manual_seed(config.seed);
  const DistributedSettings& dist = request.distributed;
  if (dist.enabled() && static_cast<int64_t>(dist.world) * config.optimizer.batch_size > 4096)
    throw InputError("WORLD_SIZE=" + std::to_string(dist.world) +
                     " x optimizer.batch_size=" + std::to_string(config.optimizer.batch_size) +
                     ": at most 4096 samples per step in all");

  TrainResult result;
  result.run_dir = request.out.empty()
                       ? (fs::path("runs") / fs::path(request.config_path).stem()).string()
                       : request.out;
  const std::string run = result.run_dir;
  // First thing: sessions killed while writing may have left temporary files (those of live
  // processes, e.g. other ranks, are kept).
  for (const fs::path& dir : {fs::path(run), fs::path(run) / "checkpoints",
                              fs::path(run) / "multilevel", fs::path(config.data) / "multilevel"})
    remove_stale_temporaries(dir);
  const Dataset train_data = Dataset::open_split(config.data, "train");
  // A missing valid split validates on training data and says so; a broken one is an error.
  const bool has_valid = Dataset::has_split(config.data, "valid");
  const Dataset valid_data = Dataset::open_split(config.data, has_valid ? "valid" : "train");
  const ResolvedModel resolved = resolve_model(config, train_data);

  // Data parallelism: every rank has checked its config and data; now they meet.
  std::unique_ptr<Communicator> comm;
  if (dist.enabled()) comm = std::make_unique<Communicator>(dist);
  const int rank = comm ? comm->rank() : 0;
  const int world = comm ? comm->world() : 1;
  const bool writer = rank == 0;  // rank 0 alone writes the run folder
  const bool quiet = request.quiet || !writer;
  if (!has_valid && writer)
    std::cerr << "bsms train: warning: " << one_line(config.data, 300)
              << " has no valid split; valid_loss is measured on training frames\n";

  const std::string checkpoint = run_checkpoint_path(run);
  const Json run_json = {{"config", to_json(config)},
                         {"features_resolved", resolved.spec_json()},
                         {"levels", resolved.levels},
                         {"world_size", world},
                         {"config_file", request.config_path}};
  // Rank 0 checks and prepares the run folder; with --resume it reads the checkpoint, which the
  // other ranks (perhaps on machines without the folder) receive from it.
  std::string checkpoint_bytes;
  std::optional<TrainStats> stats_before;  // RUN/train_stats.json on --resume, when there is one
  if (writer) {
    try {
      std::error_code ec;
      fs::create_directories(fs::path(run) / "checkpoints", ec);
      if (ec) throw InputError(run + ": cannot create the run folder (" + ec.message() + ")");
      const std::string legacy = legacy_checkpoint_path(checkpoint);
      if (!request.resume && (fs::exists(checkpoint) || fs::exists(legacy)))
        throw InputError(run +
                         ": run folder already holds a checkpoint; pass --resume to continue it "
                         "or --out for a new run");
      if (request.resume && !fs::exists(checkpoint) && fs::exists(legacy))
        throw InputError(legacy_checkpoint_message(legacy));
      if (request.resume && !fs::exists(checkpoint))
        throw InputError(checkpoint +
                         ": nothing to resume (no checkpoint in this run folder; a session "
                         "stopped before its first checkpoint is started again without --resume)");
      if (request.resume) {
        // Every file the resume reads besides the checkpoint is read and checked here, before
        // anything is trained or written: config.json and train_stats.json (RunFolder), the log.
        // The saved config read back and written again: keys added since it was written
        // (e.g. model.mp_per_level) take their defaults instead of counting as a change.
        const RunFolder before_run = RunFolder::open(run);
        stats_before = before_run.stats;
        if (fs::exists(run_log_path(run))) (void)read_train_log(run_log_path(run));
        Json a = to_json(before_run.config), b = run_json["config"];
        for (auto* j : {&a, &b}) {
          j->erase("steps");
          j->erase("time_budget_s");
          j->erase("graph_cache_mb");
        }
        if (a != b || before_run.levels != resolved.levels)
          throw InputError(run_config_path(run) +
                           ": the run was trained with another configuration; "
                           "only steps, time_budget_s and graph_cache_mb may change on --resume");
        const int before = before_run.world_size;
        if (before != world)
          std::cerr << "bsms train: warning: " << one_line(run, 300) << " was trained with "
                    << before << " rank(s) of batch size " << config.optimizer.batch_size
                    << "; continuing with " << world
                    << ": the sample sequence changed (training goes on correctly, with "
                    << world * config.optimizer.batch_size << " samples per step instead of "
                    << before * config.optimizer.batch_size << ")\n";
        // Read once here: every rank (this one too) loads these bytes as an HDF5 file image.
        if (comm) checkpoint_bytes = read_checkpoint_bytes(checkpoint);
      }
      write_json_atomic(run_config_path(run), run_json);
    } catch (const InputError& e) {
      if (comm) comm->share("start", encode_verdict(2, e.what()));
      throw;
    } catch (const IoError& e) {
      if (comm) comm->share("start", encode_verdict(4, e.what()));
      throw;
    }
    if (comm) comm->share("start", encode_verdict(0, checkpoint_bytes));
  } else {
    const std::string verdict = comm->share("start", {});
    const size_t newline = verdict.find('\n');
    const int code = std::atoi(verdict.substr(0, newline).c_str());
    if (code != 0) throw SilentExit(code);  // rank 0 reported it
    checkpoint_bytes = verdict.substr(newline + 1);
  }

  std::vector<std::string> cache_dirs = {(fs::path(config.data) / "multilevel").string(),
                                         (fs::path(run) / "multilevel").string()};
  for (const auto& d : cache_dirs) {
    std::error_code ec;
    fs::create_directories(d, ec);
  }
  GraphStore store(config.model.seeding, resolved.levels, cache_dirs, 0, false,
                   config.graph_cache_mb * (int64_t{1} << 20));
  auto simulator =
      std::make_shared<LearnedSimulator>(resolved.shape(), config.model, resolved.levels);
  FusedAdam optimizer(simulator->parameters(), torch::optim::AdamOptions(config.optimizer.lr));

  int64_t step = 0;
  double wall_before = 0.0;
  CheckpointInfo resumed;  // the losses at the checkpoint: reported if no step is trained
  if (request.resume) {
    resumed = comm ? load_checkpoint_bytes(checkpoint_bytes, checkpoint, *simulator, &optimizer)
                   : load_checkpoint(checkpoint, *simulator, &optimizer);
    step = resumed.step;
    wall_before = resumed.wall_s;
  }
  std::ofstream log;
  if (writer) log = open_log(run_log_path(run), step, !request.resume);

  // Fixed validation samples: the same every time, no noise.
  std::vector<SampleRef> valid_refs;
  for (int i = 0; i < config.valid_samples; ++i)
    valid_refs.push_back(draw_sample(valid_data, config.seed ^ 0x5bd1e995ull, -1, i));

  // Validation loss and, beside it, the loss of predicting zero acceleration (same units).
  struct Validation {
    double loss = std::nan(""), baseline = std::nan("");
  };
  // One log row; a checkpoint's row is flushed before the checkpoint is written, so that every
  // step up to a checkpoint is in the log whenever a session is killed.
  auto log_row = [&](int64_t at, double wall_s, double loss, const Validation* v, double lr) {
    TrainLogRow row;
    row.step = at;
    row.wall_s = wall_s;
    row.loss = loss;
    if (v) {
      row.valid_loss = v->loss;
      row.valid_baseline = v->baseline;
    }
    row.lr = lr;
    log << format_train_log_row(row) << '\n';
    if (v) log.flush();
    if (!log) throw IoError(run_log_path(run) + ": cannot write");
  };
  auto validate = [&]() {
    torch::NoGradGuard no_grad;
    simulator->eval();
    double total = 0, zero = 0;
    for (const auto& ref : valid_refs) {
      const TrainBatch b = make_train_batch(resolved, config, valid_data, store, {ref}, nullptr);
      total += simulator->loss(b.batch, b.target).item<double>();
      zero += simulator->zero_prediction_loss(b.batch, b.target).item<double>();
    }
    simulator->train();
    const double n = static_cast<double>(valid_refs.size());
    return Validation{total / n, zero / n};
  };
  // One training batch: deterministic in (seed, step), noise included; this rank's slots.
  const int per_rank = config.optimizer.batch_size;
  double batch_weight = 0.0;  // predicted nodes of the last batch: the weight of its loss
  // Pushforward: the model's own rollout (no gradient, inference mode) feeds the samples of steps
  // from features.pushforward_from on (steps count from 1 as in the log; `index` from 0; never
  // the normaliser batches, whose indices are < 0).
  const Predictor rollout_step = [&](const Batch& b) {
    torch::NoGradGuard no_grad;
    simulator->eval();
    torch::Tensor out = simulator->predict(b);
    simulator->train();
    return out;
  };
  const BatchOrder order{step, request.resume ? 0 : config.normalizer_steps};
  Prefetcher prefetcher(
      train_data, store,
      [&, order](int64_t position) {
        std::vector<int64_t> trajectories;
        for (int k = 0; k < per_rank; ++k)
          trajectories.push_back(
              draw_sample(train_data, config.seed, order.index_at(position), rank * per_rank + k)
                  .trajectory);
        return trajectories;
      },
      std::clamp<int64_t>(256 / std::max(per_rank, 1), 1, 8));  // batches ahead, <= 256 samples
  auto training_batch = [&](int64_t index) {
    prefetcher.reached(order.position_of(index));
    std::vector<SampleRef> refs;
    std::vector<at::Generator> generators;
    for (int k = 0; k < per_rank; ++k) {
      const int slot = rank * per_rank + k;
      refs.push_back(draw_sample(train_data, config.seed, index, slot));
      generators.push_back(at::detail::createCPUGenerator(noise_seed(config.seed, index, slot)));
    }
    const bool push =
        config.features.pushforward > 0 && index + 1 >= config.features.pushforward_from;
    TrainBatch b = make_train_batch(resolved, config, train_data, store, refs, &generators,
                                    push ? &rollout_step : nullptr);
    batch_weight = b.batch.mask.sum().item<double>();
    return b;
  };
  // Normaliser statistics are settled before the optimiser moves (batches -1, -2, ... are
  // drawn apart from the training steps'), summed over the ranks. A resumed run has them in its
  // checkpoint; a fresh one starts every rank from rank 0's parameters.
  if (!request.resume) {
    const bool all_nodes =
        config.features.output_statistics == "all" ||
        (config.features.output_statistics == "auto" && train_data.is_public_layout());
    for (int64_t i = 0; i < config.normalizer_steps; ++i) {
      const TrainBatch b = training_batch(-2 - i);
      simulator->accumulate_statistics(b.batch, b.target, all_nodes);
    }
    if (comm) {
      comm->broadcast(simulator->parameters(), 0, "broadcast of the initial parameters");
      comm->all_reduce_sum(simulator->normalizer_sums(), 0,
                           "all-reduce of the normalizer statistics");
    }
  }

  if (!quiet)
    std::cerr << "bsms train: " << config.model.type << (resolved.eulerian ? " (Eulerian)" : "")
              << ", " << resolved.levels << " level(s), " << simulator->num_parameters()
              << " parameters, " << train_data.num_trajectories()
              << " training trajectories, contact "
              << (resolved.spec.has_contact()
                      ? "radius " + std::to_string(resolved.spec.contact_radius)
                      : std::string("off"))
              << ", momentum "
              << (resolved.spec.has_momentum()
                      ? std::string(resolved.spec.momentum_slip_walls
                                        ? "conserved on free bodies and along slip walls"
                                        : "conserved on free bodies") +
                            " (data residual " +
                            std::to_string(100.0 * resolved.momentum_residual) + " %)"
                      : "not conserved" + (resolved.momentum_note.empty()
                                               ? std::string()
                                               : " (" + resolved.momentum_note + ")"))
              << ", " << threads << " thread(s)"
              << (comm ? " x " + std::to_string(world) + " ranks (" +
                             std::to_string(world * per_rank) + " samples per step)"
                       : std::string())
              << " -> " << run << "\n";

  FitOptions fit_options;
  fit_options.optimizer = config.optimizer;
  fit_options.steps = config.steps;
  fit_options.time_budget_s = config.time_budget_s;
  fit_options.first_step = step;
  fit_options.wall_before = wall_before;
  fit_options.stop_step = request.until;
  fit_options.quiet = quiet;
  Validation last_valid{resumed.valid_loss, resumed.valid_baseline};
  FitHooks hooks;
  std::optional<double> seconds_to_first_step;
  hooks.loss = [&](int64_t index) {
    if (!seconds_to_first_step)
      seconds_to_first_step =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    const TrainBatch b = training_batch(index);
    return simulator->loss(b.batch, b.target, config.features.rigid_loss_weight);
  };
  if (comm) {
    // The loss is a mean over predicted nodes: weighting each rank's gradient by its node count
    // gives the gradient of the mean over all ranks' nodes, as one rank with all samples would.
    // One bucketed all-reduce carries the gradients, the weights, the losses and rank 0's clock.
    const auto parameters = simulator->parameters();
    hooks.synchronize = [&, parameters](int64_t index, double loss, double wall_s) {
      std::vector<torch::Tensor> tensors;
      auto scalars = torch::tensor({batch_weight, batch_weight * loss, writer ? wall_s : 0.0},
                                   torch::kFloat64);
      tensors.push_back(scalars);
      for (const auto& p : parameters) {
        auto& g = p.mutable_grad();
        if (!g.defined()) g = torch::zeros_like(p);
        g.mul_(batch_weight);
        tensors.push_back(g);
      }
      comm->all_reduce_sum(tensors, index, "all-reduce of the gradients");
      const double total = scalars[0].item<double>();
      if (!(total > 0))
        throw InputError("step " + std::to_string(index) +
                         ": no rank's batch has a predicted node (check the data's node types)");
      for (size_t i = 1; i < tensors.size(); ++i) tensors[i].div_(total);
      return FitHooks::Agreed{scalars[1].item<double>() / total, scalars[2].item<double>()};
    };
  }
  // Validation and an atomic checkpoint every valid_every steps and at the last step; one log
  // row per step (validation columns empty between checks). Rank 0 only.
  hooks.after_step = [&](const FitStep& s) {
    if (!writer) return std::string();
    const bool checkpoint_now = s.step % config.valid_every == 0 || s.last;
    if (checkpoint_now) {
      last_valid = validate();
      log_row(s.step, s.wall_s, s.loss, &last_valid, s.lr);
      save_checkpoint(checkpoint, *simulator, optimizer,
                      {s.step, s.wall_s, s.loss, last_valid.loss, last_valid.baseline});
    } else {
      log_row(s.step, s.wall_s, s.loss, nullptr, s.lr);
    }
    std::ostringstream extra;
    if (std::isfinite(last_valid.loss))
      extra << ", valid " << std::setprecision(3) << last_valid.loss << " (zero "
            << last_valid.baseline << ")";
    return extra.str();
  };
  simulator->train();
  const int64_t collective_calls_before = comm ? comm->collective_calls : 0;
  const double collective_ms_before = comm ? comm->collective_ms : 0.0;
  const FitResult fitted = fit(optimizer, fit_options, hooks);
  step = fitted.step;
  // The last step of the session was checkpointed (a time budget's too: FitStep::last); without
  // a step the losses are the checkpoint's.
  const double last_loss = step > fit_options.first_step ? fitted.last_loss : resumed.loss;
  result.steps = step;
  result.final_loss = last_loss;
  result.final_valid_loss = last_valid.loss;
  result.train_ms_per_step = fitted.median_step_ms();
  if (!writer) return result;
  log.close();

  const double session_steps = static_cast<double>(fitted.step_ms.size());
  TrainStats stats;
  stats.steps = step;
  stats.train_ms_per_step = result.train_ms_per_step;
  stats.peak_rss_mb_train = peak_rss_mb();
  stats.threads = threads;
  stats.world_size = world;
  stats.samples_per_step = world * per_rank;
  stats.wall_s = fitted.wall_s;
  stats.final_loss = last_loss;
  stats.final_valid_loss = last_valid.loss;
  stats.final_valid_baseline = last_valid.baseline;
  stats.num_parameters = simulator->num_parameters();
  stats.valid_split = has_valid ? "valid" : "train";
  stats.blas = blas_config();
  stats.allocator = allocator_name();
  stats.seconds_to_first_step = seconds_to_first_step;
  const GraphStore::Stats graphs = store.stats();
  stats.graphs_made = graphs.builds;
  stats.graphs_evicted = graphs.evictions;
  stats.graph_cache_peak_mb = static_cast<double>(graphs.peak_bytes) / (1 << 20);
  if (comm && session_steps > 0) {
    stats.allreduce_ms_per_step = (comm->collective_ms - collective_ms_before) / session_steps;
    stats.allreduce_calls_per_step =
        static_cast<double>(comm->collective_calls - collective_calls_before) / session_steps;
  }
  if (stats_before) {
    // Keep the median of the first session when this one ran no step.
    const TrainStats& before = *stats_before;
    if (fitted.step_ms.empty()) stats.train_ms_per_step = before.train_ms_per_step;
    stats.peak_rss_mb_train = std::max(before.peak_rss_mb_train, stats.peak_rss_mb_train);
  }
  write_json_atomic(run_stats_path(run), to_json(stats));
  if (!request.quiet)
    std::cerr << "bsms train: " << step << " steps, loss " << last_loss << ", valid loss "
              << last_valid.loss << " (zero prediction " << last_valid.baseline << "), "
              << stats.train_ms_per_step << " ms/step (median), peak RSS " << peak_rss_mb()
              << " MB; graphs: " << graphs.builds << " made, " << graphs.evictions
              << " evicted, peak " << std::fixed << std::setprecision(1)
              << *stats.graph_cache_peak_mb << " MB\n";
  return result;
}

}  // namespace bsms
