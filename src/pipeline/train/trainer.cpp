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
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/one_line.hpp"
#include "core/runtime.hpp"
#include "models/fused_adam.hpp"
#include "models/graph_ops.hpp"
#include "models/parameter_ema.hpp"
#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_log.hpp"
#include "pipeline/runs/train_stats.hpp"
#include "pipeline/train/fit.hpp"
#include "pipeline/train/prefetch.hpp"
#include "pipeline/train/training_data.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// Rewrites the CSV file `path` atomically as `header` and the `kept` rows, and returns it for
// appending.
std::ofstream rewrite_for_appending(const std::string& path, const char* header,
                                    const std::vector<std::string>& kept) {
  {
    AtomicOutput out(path);
    std::ofstream f(out.temp_path());
    f << header << '\n';
    for (const auto& l : kept) f << l << '\n';
    f.close();
    out.commit();
  }
  return std::ofstream(path, std::ios::app);
}

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
  return rewrite_for_appending(path, kTrainLogHeader, kept);
}

// RUN/valid_rollout.csv: one row per checkpoint scored by a validation rollout.
constexpr const char* kValidRolloutHeader =
    "step,wall_s,trajectories,rmse_all,constant_velocity,ratio,best";

struct RolloutScore {
  int64_t step = 0;
  double rmse = 0.0;
};

// Keeps the whole rows of RUN/valid_rollout.csv up to `keep_until_step` (resume; none when
// `fresh`), rewrites it and returns it for appending; `best` gets the lowest RMSE among them.
std::ofstream open_valid_rollout_log(const std::string& path, int64_t keep_until_step, bool fresh,
                                     std::optional<RolloutScore>& best) {
  std::vector<std::string> kept;
  best.reset();
  if (!fresh && fs::exists(path)) {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    while (std::getline(in, line)) {
      if (in.eof()) break;  // no newline after it: torn by a kill
      const char* text = line.c_str();
      char* end = nullptr;
      const long long step = std::strtoll(text, &end, 10);
      if (end == text || *end != ',' || step < 1 || step > keep_until_step) continue;
      // rmse_all is the fourth column.
      const char* field = end;
      for (int k = 0; k < 2 && field; ++k) field = std::strchr(field + 1, ',');
      if (!field) continue;
      const double rmse = std::strtod(field + 1, &end);
      if (end == field + 1 || *end != ',') continue;
      kept.push_back(line);
      if (!best || rmse < best->rmse) best = RolloutScore{step, rmse};
    }
  }
  return rewrite_for_appending(path, kValidRolloutHeader, kept);
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

namespace {

// Validation loss and, beside it, the loss of predicting zero (same units).
struct Validation {
  double loss = std::nan(""), zero_prediction = std::nan("");
};

// One `bsms train` session on one rank: set up in the constructor (config, data, features, the
// run folder, the model), then run().
class TrainSession {
 public:
  explicit TrainSession(const TrainRequest& request);
  TrainResult run();

 private:
  // Rank 0 checks and prepares the run folder (with --resume it reads the checkpoint, which the
  // other ranks, perhaps on machines without the folder, receive from it); the others wait for
  // its verdict.
  void prepare_run_folder(const Json& run_json);
  void check_resume(const Json& run_json);
  void build_model();
  // One log row; a checkpoint's row is flushed before the checkpoint is written, so that every
  // step up to a checkpoint is in the log whenever a session is killed.
  void log_row(int64_t at, double wall_s, double loss, const Validation* v, double lr);
  Validation validate();
  // Rolls the checkpoint just written out over the first valid trajectories, logs its score and
  // keeps it as the best checkpoint when it beats every earlier one; returns the progress text.
  std::string score_by_rollout(const FitStep& s);
  // One training batch: deterministic in (seed, step), noise included; this rank's slots.
  TrainBatch training_batch(int64_t index);
  // Normaliser statistics are settled before the optimiser moves (batches -1, -2, ... are
  // drawn apart from the training steps'), summed over the ranks. A resumed run has them in its
  // checkpoint; a fresh one starts every rank from rank 0's parameters.
  void settle_normalizers();
  void print_start() const;
  FitHooks fit_hooks();
  void write_stats(const FitResult& fitted, double last_loss, int64_t collective_calls_before,
                   double collective_ms_before);

  const TrainRequest& request_;
  const std::chrono::steady_clock::time_point started_;
  TrainConfig config_;
  int threads_ = 1;
  std::string run_;
  std::optional<Dataset> train_data_, valid_data_;
  bool has_valid_ = false;
  ResolvedModel resolved_;
  std::unique_ptr<Communicator> comm_;
  int rank_ = 0, world_ = 1, per_rank_ = 1;
  bool writer_ = true;  // rank 0 alone writes the run folder
  bool quiet_ = false;
  std::string checkpoint_;
  std::string checkpoint_bytes_;            // rank 0's checkpoint, for the other ranks
  std::optional<TrainStats> stats_before_;  // RUN/train_stats.json on --resume, when there is one
  std::unique_ptr<GraphStore> store_;
  std::shared_ptr<LearnedSimulator> simulator_;
  std::unique_ptr<FusedAdam> optimizer_;
  std::unique_ptr<ParameterEma> ema_;  // ema_decay > 0, rank 0: what checkpoints predict with
  int64_t step_ = 0;
  double wall_before_ = 0.0;
  CheckpointInfo resumed_;  // the losses at the checkpoint: reported if no step is trained
  std::ofstream log_;
  std::vector<SampleRef> valid_refs_;  // fixed validation samples: the same every time, no noise
  Validation last_valid_;
  std::ofstream rollout_log_;                 // RUN/valid_rollout.csv, with valid_rollout_every
  std::optional<RolloutScore> best_rollout_;  // the best checkpoint's score
  std::string rollout_text_;                  // the last score, for the progress line
  double batch_weight_ = 0.0;  // predicted nodes of the last batch: the weight of its loss
  // Pushforward: the model's own rollout (no gradient, inference mode) feeds the samples of steps
  // from features.pushforward_from on (steps count from 1 as in the log; `index` from 0; never
  // the normaliser batches, whose indices are < 0).
  Predictor rollout_step_;
  BatchOrder order_;
  std::unique_ptr<Prefetcher> prefetcher_;
  std::optional<double> seconds_to_first_step_;
};

TrainSession::TrainSession(const TrainRequest& request)
    : request_(request), started_(std::chrono::steady_clock::now()) {
  config_ = load_train_config(request);
  threads_ = configure_threads(set_num_threads(requested_threads(request)));
  torch::manual_seed(config_.seed);
  const DistributedSettings& dist = request.distributed;
  if (dist.enabled() && static_cast<int64_t>(dist.world) * config_.optimizer.batch_size > 4096)
    throw InputError("WORLD_SIZE=" + std::to_string(dist.world) +
                     " x optimizer.batch_size=" + std::to_string(config_.optimizer.batch_size) +
                     ": at most 4096 samples per step in all");
  run_ = request.out.empty() ? (fs::path("runs") / fs::path(request.config_path).stem()).string()
                             : request.out;
  // First thing: sessions killed while writing may have left temporary files (those of live
  // processes, e.g. other ranks, are kept).
  for (const std::string& dir : {run_, run_checkpoint_dir(run_), multilevel_cache_dir(run_),
                                 multilevel_cache_dir(config_.data)})
    remove_stale_temporaries(dir);
  train_data_.emplace(Dataset::open_split(config_.data, "train"));
  // A missing valid split validates on training data and says so; a broken one is an error.
  has_valid_ = Dataset::has_split(config_.data, "valid");
  valid_data_.emplace(Dataset::open_split(config_.data, has_valid_ ? "valid" : "train"));
  resolved_ = resolve_model(config_, *train_data_);

  // Data parallelism: every rank has checked its config and data; now they meet.
  if (dist.enabled()) comm_ = std::make_unique<Communicator>(dist);
  rank_ = comm_ ? comm_->rank() : 0;
  world_ = comm_ ? comm_->world() : 1;
  writer_ = rank_ == 0;
  quiet_ = request.quiet || !writer_;
  per_rank_ = config_.optimizer.batch_size;
  if (!has_valid_ && writer_)
    std::cerr << "bsms train: warning: " << one_line(config_.data, 300)
              << " has no valid split; valid_loss is measured on training frames\n";
  checkpoint_ = run_checkpoint_path(run_);
  prepare_run_folder({{"config", to_json(config_)},
                      {"features_resolved", resolved_.spec_json()},
                      {"levels", resolved_.levels},
                      {"world_size", world_},
                      {"config_file", request.config_path}});
  build_model();
}

void TrainSession::prepare_run_folder(const Json& run_json) {
  if (!writer_) {
    const std::string verdict = comm_->share("start", {});
    const size_t newline = verdict.find('\n');
    const int code = std::atoi(verdict.substr(0, newline).c_str());
    if (code != 0) throw SilentExit(code);  // rank 0 reported it
    checkpoint_bytes_ = verdict.substr(newline + 1);
    return;
  }
  try {
    std::error_code ec;
    fs::create_directories(run_checkpoint_dir(run_), ec);
    if (ec) throw InputError(run_ + ": cannot create the run folder (" + ec.message() + ")");
    const std::string legacy = legacy_checkpoint_path(checkpoint_);
    if (!request_.resume && (fs::exists(checkpoint_) || fs::exists(legacy)))
      throw InputError(run_ +
                       ": run folder already holds a checkpoint; pass --resume to continue it "
                       "or --out for a new run");
    if (request_.resume && !fs::exists(checkpoint_) && fs::exists(legacy))
      throw InputError(legacy_checkpoint_message(legacy));
    if (request_.resume && !fs::exists(checkpoint_))
      throw InputError(checkpoint_ +
                       ": nothing to resume (no checkpoint in this run folder; a session "
                       "stopped before its first checkpoint is started again without --resume)");
    if (request_.resume) check_resume(run_json);
    write_json_atomic(run_config_path(run_), run_json);
  } catch (const InputError& e) {
    if (comm_) comm_->share("start", encode_verdict(2, e.what()));
    throw;
  } catch (const IoError& e) {
    if (comm_) comm_->share("start", encode_verdict(4, e.what()));
    throw;
  }
  if (comm_) comm_->share("start", encode_verdict(0, checkpoint_bytes_));
}

void TrainSession::check_resume(const Json& run_json) {
  // Every file the resume reads besides the checkpoint is read and checked here, before
  // anything is trained or written: config.json and train_stats.json (RunFolder), the log.
  // The saved config read back and written again: keys added since it was written
  // (e.g. model.mp_per_level) take their defaults instead of counting as a change.
  const RunFolder before_run = RunFolder::open(run_);
  stats_before_ = before_run.stats;
  if (fs::exists(run_log_path(run_))) (void)read_train_log(run_log_path(run_));
  Json a = to_json(before_run.config), b = run_json["config"];
  for (auto* j : {&a, &b}) {
    j->erase("steps");
    j->erase("time_budget_s");
    j->erase("graph_cache_mb");
    j->erase("valid_rollout_every");
    j->erase("valid_rollout_trajectories");
  }
  if (a != b || before_run.levels != resolved_.levels)
    throw InputError(run_config_path(run_) +
                     ": the run was trained with another configuration; "
                     "only steps, time_budget_s, graph_cache_mb and the valid_rollout keys may "
                     "change on --resume");
  const int before = before_run.world_size;
  if (before != world_)
    std::cerr << "bsms train: warning: " << one_line(run_, 300) << " was trained with " << before
              << " rank(s) of batch size " << config_.optimizer.batch_size << "; continuing with "
              << world_ << ": the sample sequence changed (training goes on correctly, with "
              << world_ * config_.optimizer.batch_size << " samples per step instead of "
              << before * config_.optimizer.batch_size << ")\n";
  // Read once here: every rank (this one too) loads these bytes as an HDF5 file image.
  if (comm_) checkpoint_bytes_ = read_checkpoint_bytes(checkpoint_);
}

void TrainSession::build_model() {
  const std::vector<std::string> cache_dirs = multilevel_cache_dirs(config_.data, run_);
  for (const auto& d : cache_dirs) {
    std::error_code ec;
    fs::create_directories(d, ec);
  }
  store_ = std::make_unique<GraphStore>(config_.model.seeding, resolved_.levels, cache_dirs, 0,
                                        false, config_.graph_cache_mb * (int64_t{1} << 20));
  simulator_ =
      std::make_shared<LearnedSimulator>(resolved_.shape(), config_.model, resolved_.levels);
  optimizer_ = std::make_unique<FusedAdam>(simulator_->parameters(),
                                           torch::optim::AdamOptions(config_.optimizer.lr));
  // Rank 0 alone writes checkpoints, so it alone keeps the average (the ranks' parameters are
  // equal after every step).
  if (config_.optimizer.ema_decay > 0 && writer_)
    ema_ = std::make_unique<ParameterEma>(*simulator_, config_.optimizer.ema_decay);
  if (request_.resume) {
    resumed_ = comm_ ? load_checkpoint_bytes(checkpoint_bytes_, checkpoint_, *simulator_,
                                             optimizer_.get(), ema_.get())
                     : load_checkpoint(checkpoint_, *simulator_, optimizer_.get(), ema_.get());
    step_ = resumed_.step;
    wall_before_ = resumed_.wall_s;
  }
  last_valid_ = {resumed_.valid_loss, resumed_.valid_zero_prediction};
  if (writer_) log_ = open_log(run_log_path(run_), step_, !request_.resume);
  const std::string best = run_best_checkpoint_path(run_);
  if (writer_ && config_.valid_rollout_every > 0) {
    rollout_log_ = open_valid_rollout_log(run_valid_rollout_log_path(run_), step_, !request_.resume,
                                          best_rollout_);
    // A best checkpoint no row of the kept log scored (a fresh run over an old folder) is not
    // this run's.
    std::error_code ec;
    if (!best_rollout_) fs::remove(best, ec);
  } else if (writer_ && fs::exists(best)) {
    std::cerr << "bsms train: warning: " << one_line(best, 300)
              << " is from an earlier session with valid_rollout_every; bsms rollout takes it "
                 "unless given --checkpoint latest\n";
  }
  for (int i = 0; i < config_.valid_samples; ++i)
    valid_refs_.push_back(draw_sample(*valid_data_, config_.seed ^ 0x5bd1e995ull, -1, i));
  rollout_step_ = [this](const Batch& b) {
    torch::NoGradGuard no_grad;
    simulator_->eval();
    torch::Tensor out = simulator_->predict(b);
    simulator_->train();
    return out;
  };
  order_ = BatchOrder{step_, request_.resume ? 0 : config_.normalizer_steps};
  const BatchOrder order = order_;
  prefetcher_ = std::make_unique<Prefetcher>(
      *train_data_, *store_,
      [this, order](int64_t position) {
        std::vector<int64_t> trajectories;
        for (int k = 0; k < per_rank_; ++k)
          trajectories.push_back(draw_sample(*train_data_, config_.seed, order.index_at(position),
                                             rank_ * per_rank_ + k)
                                     .trajectory);
        return trajectories;
      },
      std::clamp<int64_t>(256 / std::max(per_rank_, 1), 1, 8));  // batches ahead, <= 256 samples
}

void TrainSession::log_row(int64_t at, double wall_s, double loss, const Validation* v, double lr) {
  TrainLogRow row;
  row.step = at;
  row.wall_s = wall_s;
  row.loss = loss;
  if (v) {
    row.valid_loss = v->loss;
    row.valid_zero_prediction = v->zero_prediction;
  }
  row.lr = lr;
  log_ << format_train_log_row(row) << '\n';
  if (v) log_.flush();
  if (!log_) throw IoError(run_log_path(run_) + ": cannot write");
}

Validation TrainSession::validate() {
  torch::NoGradGuard no_grad;
  // The loss of what the checkpoint predicts with: the average, when training keeps one.
  const AverageInModule average(ema_.get());
  simulator_->eval();
  double total = 0, zero = 0;
  for (const auto& ref : valid_refs_) {
    const TrainBatch b =
        make_train_batch(resolved_, config_, *valid_data_, *store_, {ref}, nullptr);
    total += simulator_->loss(b.batch, b.target).item<double>();
    zero += simulator_->zero_prediction_loss(b.batch, b.target).item<double>();
  }
  simulator_->train();
  const double n = static_cast<double>(valid_refs_.size());
  return Validation{total / n, zero / n};
}

TrainBatch TrainSession::training_batch(int64_t index) {
  prefetcher_->reached(order_.position_of(index));
  std::vector<SampleRef> refs;
  std::vector<at::Generator> generators;
  for (int k = 0; k < per_rank_; ++k) {
    const int slot = rank_ * per_rank_ + k;
    refs.push_back(draw_sample(*train_data_, config_.seed, index, slot));
    generators.push_back(at::detail::createCPUGenerator(noise_seed(config_.seed, index, slot)));
  }
  const bool push =
      config_.features.pushforward > 0 && index + 1 >= config_.features.pushforward_from;
  TrainBatch b = make_train_batch(resolved_, config_, *train_data_, *store_, refs, &generators,
                                  push ? &rollout_step_ : nullptr);
  batch_weight_ = b.batch.mask.sum().item<double>();
  return b;
}

void TrainSession::settle_normalizers() {
  if (request_.resume) return;
  const bool all_nodes =
      config_.features.output_statistics == "all" ||
      (config_.features.output_statistics == "auto" && train_data_->is_public_layout());
  for (int64_t i = 0; i < config_.normalizer_steps; ++i) {
    const TrainBatch b = training_batch(-2 - i);
    simulator_->accumulate_statistics(b.batch, b.target, all_nodes);
  }
  if (comm_) {
    comm_->broadcast(simulator_->parameters(), 0, "broadcast of the initial parameters");
    comm_->all_reduce_sum(simulator_->normalizer_sums(), 0,
                          "all-reduce of the normalizer statistics");
  }
  if (ema_) ema_->restart();  // from the parameters every rank starts with
}

void TrainSession::print_start() const {
  if (quiet_) return;
  const LagrangianAdapter* lagrangian =
      dynamic_cast<const LagrangianAdapter*>(resolved_.adapter.get());
  std::string contact = "off", momentum = "not conserved";
  if (lagrangian && lagrangian->spec().has_contact())
    contact = "radius " + std::to_string(lagrangian->spec().contact_radius);
  if (lagrangian && lagrangian->spec().has_momentum())
    momentum = std::string(lagrangian->spec().momentum_slip_walls
                               ? "conserved on free bodies and along slip walls"
                               : "conserved on free bodies") +
               " (data residual " + std::to_string(100.0 * resolved_.momentum_residual) + " %)";
  else if (!resolved_.momentum_note.empty())
    momentum += " (" + resolved_.momentum_note + ")";
  std::cerr << "bsms train: " << config_.model.type
            << (resolved_.adapter->kind() == "eulerian" ? " (Eulerian)" : "") << ", "
            << resolved_.levels << " level(s), " << simulator_->num_parameters() << " parameters, "
            << train_data_->num_trajectories() << " training trajectories, contact " << contact
            << ", momentum " << momentum << ", " << threads_ << " thread(s)"
            << (comm_ ? " x " + std::to_string(world_) + " ranks (" +
                            std::to_string(world_ * per_rank_) + " samples per step)"
                      : std::string())
            << (ema_ ? ", parameter average decay " + format_number(ema_->decay(), 6)
                     : std::string())
            << " -> " << run_ << "\n";
}

FitHooks TrainSession::fit_hooks() {
  FitHooks hooks;
  hooks.loss = [this](int64_t index) {
    if (!seconds_to_first_step_)
      seconds_to_first_step_ =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    const TrainBatch b = training_batch(index);
    return simulator_->loss(b.batch, b.target, config_.features.rigid_loss_weight);
  };
  if (comm_) {
    // The loss is a mean over predicted nodes: weighting each rank's gradient by its node count
    // gives the gradient of the mean over all ranks' nodes, as one rank with all samples would.
    // One bucketed all-reduce carries the gradients, the weights, the losses and rank 0's clock.
    const auto parameters = simulator_->parameters();
    hooks.synchronize = [this, parameters](int64_t index, double loss, double wall_s) {
      std::vector<torch::Tensor> tensors;
      auto scalars = torch::tensor({batch_weight_, batch_weight_ * loss, writer_ ? wall_s : 0.0},
                                   torch::kFloat64);
      tensors.push_back(scalars);
      for (const auto& p : parameters) {
        auto& g = p.mutable_grad();
        if (!g.defined()) g = torch::zeros_like(p);
        g.mul_(batch_weight_);
        tensors.push_back(g);
      }
      comm_->all_reduce_sum(tensors, index, "all-reduce of the gradients");
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
  hooks.after_step = [this](const FitStep& s) {
    if (ema_) ema_->update();
    if (!writer_) return std::string();
    const bool checkpoint_now = s.step % config_.valid_every == 0 || s.last;
    if (checkpoint_now) {
      last_valid_ = validate();
      log_row(s.step, s.wall_s, s.loss, &last_valid_, s.lr);
      save_checkpoint(checkpoint_, *simulator_, *optimizer_,
                      {s.step, s.wall_s, s.loss, last_valid_.loss, last_valid_.zero_prediction},
                      ema_.get());
      if (config_.valid_rollout_every > 0 && (s.step % config_.valid_rollout_every == 0 || s.last))
        rollout_text_ = score_by_rollout(s);
    } else {
      log_row(s.step, s.wall_s, s.loss, nullptr, s.lr);
    }
    std::ostringstream extra;
    if (std::isfinite(last_valid_.loss))
      extra << ", valid " << std::setprecision(3) << last_valid_.loss << " (zero "
            << last_valid_.zero_prediction << ")";
    return extra.str() + rollout_text_;
  };
  return hooks;
}

std::string TrainSession::score_by_rollout(const FitStep& s) {
  RolloutRequest request;
  request.run = run_;
  request.split = has_valid_ ? "valid" : "train";
  request.out = (fs::path(run_) / "valid_rollout").string();
  request.max_trajectories = config_.valid_rollout_trajectories;
  request.threads = threads_;
  request.quiet = true;
  request.checkpoint = "latest";
  const RolloutMetrics m = rollout(request);
  // A rollout that diverged on any trajectory is the worst score, whatever its finite part.
  double rmse = std::numeric_limits<double>::infinity();
  if (m.rmse_all && m.diverged.empty()) {
    const double pos = m.rmse_all->at("world_pos");
    rmse = std::isfinite(pos) ? pos : m.rmse_all->total;
  }
  const double reference = m.rmse_all_constant_velocity.value_or(std::nan(""));
  const double ratio = reference > 0 ? rmse / reference : std::nan("");
  const bool best = std::isfinite(rmse) && (!best_rollout_ || rmse < best_rollout_->rmse);
  if (best) {
    AtomicOutput out(run_best_checkpoint_path(run_));
    std::error_code ec;
    fs::copy_file(checkpoint_, out.temp_path(), fs::copy_options::overwrite_existing, ec);
    if (ec) throw IoError(out.final_path() + ": cannot write (" + ec.message() + ")");
    out.commit();
    best_rollout_ = RolloutScore{s.step, rmse};
  }
  auto field = [](double v) {
    std::ostringstream text;
    if (std::isfinite(v)) text << std::setprecision(6) << v;
    return text.str();
  };
  rollout_log_ << s.step << ',' << field(s.wall_s) << ',' << m.num_trajectories << ','
               << (std::isinf(rmse) ? "inf" : field(rmse)) << ',' << field(reference) << ','
               << field(ratio) << ',' << (best ? 1 : 0) << '\n';
  rollout_log_.flush();
  if (!rollout_log_) throw IoError(run_valid_rollout_log_path(run_) + ": cannot write");
  std::ostringstream text;
  text << std::setprecision(3) << ", rollout ";
  if (std::isfinite(ratio))
    text << ratio << "x CV";
  else
    text << rmse;
  if (best_rollout_) text << " (best @ " << best_rollout_->step << ")";
  return text.str();
}

TrainResult TrainSession::run() {
  settle_normalizers();
  print_start();
  FitOptions fit_options;
  fit_options.optimizer = config_.optimizer;
  fit_options.steps = config_.steps;
  fit_options.time_budget_s = config_.time_budget_s;
  fit_options.first_step = step_;
  fit_options.wall_before = wall_before_;
  fit_options.stop_step = request_.until;
  fit_options.quiet = quiet_;
  simulator_->train();
  const int64_t collective_calls_before = comm_ ? comm_->collective_calls : 0;
  const double collective_ms_before = comm_ ? comm_->collective_ms : 0.0;
  const FitResult fitted = fit(*optimizer_, fit_options, fit_hooks());
  step_ = fitted.step;
  // The last step of the session was checkpointed (a time budget's too: FitStep::last); without
  // a step the losses are the checkpoint's.
  const double last_loss = step_ > fit_options.first_step ? fitted.last_loss : resumed_.loss;
  TrainResult result;
  result.run_dir = run_;
  result.steps = step_;
  result.final_loss = last_loss;
  result.final_valid_loss = last_valid_.loss;
  result.train_ms_per_step = fitted.median_step_ms();
  if (!writer_) return result;
  log_.close();
  write_stats(fitted, last_loss, collective_calls_before, collective_ms_before);
  return result;
}

void TrainSession::write_stats(const FitResult& fitted, double last_loss,
                               int64_t collective_calls_before, double collective_ms_before) {
  const double session_steps = static_cast<double>(fitted.step_ms.size());
  TrainStats stats;
  stats.steps = step_;
  stats.train_ms_per_step = fitted.median_step_ms();
  stats.peak_rss_mb_train = peak_rss_mb();
  stats.threads = threads_;
  stats.world_size = world_;
  stats.samples_per_step = world_ * per_rank_;
  stats.wall_s = fitted.wall_s;
  stats.final_loss = last_loss;
  stats.final_valid_loss = last_valid_.loss;
  stats.final_valid_zero_prediction = last_valid_.zero_prediction;
  stats.num_parameters = simulator_->num_parameters();
  stats.valid_split = has_valid_ ? "valid" : "train";
  stats.blas = blas_config();
  stats.matmul = matmul_library();
  stats.allocator = allocator_name();
  stats.seconds_to_first_step = seconds_to_first_step_;
  const GraphStore::Stats graphs = store_->stats();
  stats.graphs_made = graphs.builds;
  stats.graphs_evicted = graphs.evictions;
  stats.graph_cache_peak_mb = static_cast<double>(graphs.peak_bytes) / (1 << 20);
  if (best_rollout_) {
    stats.best_step = best_rollout_->step;
    stats.best_valid_rollout_rmse = best_rollout_->rmse;
  }
  if (comm_ && session_steps > 0) {
    stats.allreduce_ms_per_step = (comm_->collective_ms - collective_ms_before) / session_steps;
    stats.allreduce_calls_per_step =
        static_cast<double>(comm_->collective_calls - collective_calls_before) / session_steps;
  }
  if (stats_before_) {
    // Keep the median of the first session when this one ran no step.
    const TrainStats& before = *stats_before_;
    if (fitted.step_ms.empty()) stats.train_ms_per_step = before.train_ms_per_step;
    stats.peak_rss_mb_train = std::max(before.peak_rss_mb_train, stats.peak_rss_mb_train);
  }
  write_json_atomic(run_stats_path(run_), to_json(stats));
  if (!request_.quiet)
    std::cerr << "bsms train: " << step_ << " steps, loss " << last_loss << ", valid loss "
              << last_valid_.loss << " (zero prediction " << last_valid_.zero_prediction << "), "
              << stats.train_ms_per_step << " ms/step (median), peak RSS " << peak_rss_mb()
              << " MB; graphs: " << graphs.builds << " made, " << graphs.evictions
              << " evicted, peak " << std::fixed << std::setprecision(1)
              << *stats.graph_cache_peak_mb << " MB\n";
}

}  // namespace

TrainResult train(const TrainRequest& request) {
  return TrainSession(request).run();
}

}  // namespace bsms
