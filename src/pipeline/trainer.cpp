#include "pipeline/trainer.hpp"

#include <ATen/CPUGeneratorImpl.h>
#include <signal.h>
#include <torch/torch.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <memory>
#include <set>
#include <sstream>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/hdf5_file.hpp"
#include "core/runtime.hpp"
#include "models/graph_ops.hpp"
#include "models/layers.hpp"
#include "pipeline/eulerian.hpp"
#include "pipeline/fit.hpp"
#include "pipeline/lagrangian.hpp"
#include "pipeline/run_files.hpp"
#include "pipeline/simulator.hpp"

namespace bsms {
namespace fs = std::filesystem;

std::string run_config_path(const std::string& run) {
  return (fs::path(run) / "config.json").string();
}
std::string run_checkpoint_path(const std::string& run) {
  return (fs::path(run) / "checkpoints" / "latest.pt").string();
}
std::string run_log_path(const std::string& run) {
  return (fs::path(run) / "train_log.csv").string();
}
std::string run_stats_path(const std::string& run) {
  return (fs::path(run) / "train_stats.json").string();
}

namespace {

struct SampleRef {
  int64_t trajectory;
  int64_t frame;  // t: uses t-1, t, t+1
};

// Deterministic in (seed, step, slot): a resumed run draws exactly the samples it would have.
// Data-parallel rank r of N draws slots r*b .. r*b+b-1 of the N*b of a step, so that N ranks of
// batch size b train on the samples (and noise: noise_seed) of one rank of batch size N*b.
SampleRef draw_sample(const Dataset& data, uint64_t seed, int64_t step, int slot) {
  const uint64_t h = splitmix64(seed * 0x100000001b3ull ^ splitmix64(step * 4096 + slot));
  const int64_t t = static_cast<int64_t>(h % static_cast<uint64_t>(data.num_trajectories()));
  const int64_t frames = data.num_frames(t);
  const int64_t f = 1 + static_cast<int64_t>(splitmix64(h) % static_cast<uint64_t>(frames - 2));
  return {t, f};
}

// The training noise of slot `slot` of step `step`: one generator per sample.
uint64_t noise_seed(uint64_t seed, int64_t step, int slot) {
  return splitmix64(splitmix64(seed ^ (0x1234567ull + static_cast<uint64_t>(step))) ^
                    static_cast<uint64_t>(slot));
}

std::string position_field(const Dataset& data) {
  if (data.has_field("world_pos")) return "world_pos";
  throw InputError(data.location() + ": a Lagrangian model needs the field world_pos");
}

struct LoadedSample {
  FrameState state;
  torch::Tensor next;
};

LoadedSample load_sample(const Dataset& data, GraphStore& store, const SampleRef& ref) {
  const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
  const int64_t n = mesh.num_nodes();
  const int dim = data.dim();
  auto frames = data.read(ref.trajectory, position_field(data), ref.frame - 1, 3);
  auto x = torch::from_blob(frames.data(), {3, n, dim}, torch::kFloat32).clone();
  LoadedSample s;
  s.state.graphs = &store.get(mesh);
  s.state.mesh = &mesh;
  s.state.prev = x[0];
  s.state.cur = x[1];
  s.state.next = x[2];
  s.next = x[2];
  return s;
}

// RMS strain |x_ij| / |X_ij| - 1 over the mesh edges of up to 64 training frames (deterministic
// in the seed); 0 when the data does not deform (the strain channel is then left out).
double rms_strain(const Dataset& data, GraphStore& store, uint64_t seed) {
  double sum = 0;
  int64_t count = 0;
  for (int i = 0; i < 64; ++i) {
    const SampleRef ref = draw_sample(data, seed ^ 0x9e3779b97f4a7c15ull, -3, i);
    const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
    const MeshGraphs& graphs = store.get(mesh);
    const int64_t n = mesh.num_nodes();
    auto frame = data.read(ref.trajectory, position_field(data), ref.frame, 1);
    const auto x = torch::from_blob(frame.data(), {n, data.dim()}, torch::kFloat32);
    const auto X =
        torch::from_blob(const_cast<float*>(mesh.mesh_pos.data()), {n, mesh.dim}, torch::kFloat32);
    const auto& edges = graphs.hierarchy.edge_sets[0][0];
    if (edges.num_edges() == 0) continue;
    const auto strain = edge_features({X, x}, {}, edges, EdgeStretch{0, 1, 1.0});
    sum += strain.square().sum().item<double>();
    count += strain.size(0);
  }
  const double rms = count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  return rms > 1e-6 ? rms : 0.0;
}

// Momentum "auto" keeps conservation only when the data holds it to this relative residual.
constexpr double kMomentumTolerance = 0.05;

// Relative residual sqrt(sum m |a - P a|^2 / sum m |a|^2) of the true accelerations of free
// groups (P = project_momentum) over up to 64 training frames; NaN when no frame has a free group.
double momentum_residual(const Dataset& data, GraphStore& store, const LagrangianSpec& spec,
                         uint64_t seed) {
  LagrangianAdapter adapter(spec);
  double off = 0, all = 0;
  for (int i = 0; i < 64; ++i) {
    const SampleRef ref = draw_sample(data, seed ^ 0x7f4a7c159e3779b9ull, -4, i);
    LoadedSample s = load_sample(data, store, ref);
    const Batch batch = adapter.make_batch({s.state});
    if (batch.num_groups == 0) continue;
    const auto a = adapter.target(batch, s.next).to(torch::kFloat64);
    const auto m = (batch.mass.to(torch::kFloat64) * (batch.group >= 0)).unsqueeze(1);
    off += (m * (a - project_momentum(batch, a)).square()).sum().item<double>();
    all += (m * a.square()).sum().item<double>();
  }
  return all > 0 ? std::sqrt(off / all) : std::nan("");
}

// Resolves what the data decides: the kind of model, dimensions, node types, position scale,
// contact, levels.
struct Resolved {
  bool eulerian = false;  // fields on a fixed mesh (velocity, no world_pos)
  LagrangianSpec spec;
  EulerianSpec eulerian_spec;
  int levels = 1;
  std::string momentum_note;      // why momentum conservation is off ("" when on or not asked)
  double momentum_residual = -1;  // measured on the training data when on

  Json spec_json() const { return eulerian ? to_json(eulerian_spec) : to_json(spec); }
  ModelShape shape() const { return eulerian ? model_shape(eulerian_spec) : model_shape(spec); }
};

Resolved resolve(const TrainConfig& config, const Dataset& train_data) {
  Resolved r;
  if (!train_data.has_field("world_pos")) {
    if (!train_data.has_field("velocity"))
      throw InputError(train_data.location() +
                       ": needs the field world_pos (a Lagrangian model) or velocity (an "
                       "Eulerian model)");
    r.eulerian = true;
  }
  const bool public_layout = train_data.is_public_layout();
  const int mesh_dim = train_data.mesh(0).dim;
  int max_type = 0;
  bool several_bodies = false;
  for (int64_t t = 0; t < train_data.num_trajectories(); ++t) {
    const auto& m = train_data.mesh(t);
    if (m.dim != mesh_dim)
      throw InputError(train_data.location() + ": trajectory " + std::to_string(t) +
                       " has mesh dimension " + std::to_string(m.dim) + ", expected " +
                       std::to_string(mesh_dim));
    if (train_data.num_frames(t) < 3)
      throw InputError(train_data.location() + ": trajectory " + std::to_string(t) +
                       " has fewer than 3 frames");
    for (int32_t v : m.node_type) max_type = std::max(max_type, v);
    std::set<int32_t> bodies(m.body_id.begin(), m.body_id.end());
    several_bodies = several_bodies || bodies.size() > 1;
  }
  // Public data: MeshGraphNets' one-hot of width 9 (NORMAL 0 ... WALL_BOUNDARY 6).
  const int num_node_types = config.features.num_node_types > 0 ? config.features.num_node_types
                             : public_layout                    ? std::max(max_type + 1, 9)
                                                                : std::max(max_type + 1, 4);
  // Position scale: mean mesh edge length of the first training mesh.
  GraphStore probe(Seeding::kCloseCenter, 1, {});
  const double edge = probe.get(train_data.mesh(0)).mean_edge_length;
  if (config.model.type == "mgn") {
    r.levels = 1;
  } else {
    r.levels = config.model.levels > 0 ? config.model.levels
                                       : auto_levels(train_data.mesh(0), config.model.seeding);
  }
  if (r.eulerian) {
    EulerianSpec& e = r.eulerian_spec;
    e.dim = mesh_dim;
    const auto fields = train_data.fields();
    for (const auto& f : fields)
      if (f.name == "velocity" && f.width != mesh_dim)
        throw InputError(train_data.location() + ": velocity has " + std::to_string(f.width) +
                         " components, the mesh " + std::to_string(mesh_dim) + " dimensions");
    e.num_node_types = num_node_types;
    e.position_scale = edge > 0 ? edge : 1.0;
    e.multilevel = config.model.type == "bsms";
    e.density = train_data.has_field("density");
    e.pressure = train_data.has_field("pressure");
    return r;
  }
  LagrangianSpec& s = r.spec;
  s.dim = train_data.dim();
  s.mesh_dim = mesh_dim;
  s.public_layout = public_layout;
  s.multilevel = config.model.type == "bsms";
  s.num_node_types = num_node_types;
  s.position_scale = edge > 0 ? edge : 1.0;
  s.first_order = config.features.output == "velocity";
  s.kinematic_input = config.features.kinematic_input == "on" ||
                      (config.features.kinematic_input == "auto" && public_layout);
  s.velocity_input = config.features.velocity_input == "on" ||
                     (config.features.velocity_input == "auto" && !s.first_order);
  if (config.features.contact_radius < 0) {
    // Public data states the radius of its world edges (DeformingPlate's collision_radius).
    if (train_data.collision_radius() > 0)
      s.contact_radius = train_data.collision_radius();
    else if (several_bodies)
      resolve_contact_radius(s, train_data.scene(), edge);
  } else {
    s.contact_radius = config.features.contact_radius;
  }
  if (config.features.strain == "auto") s.strain_scale = rms_strain(train_data, probe, config.seed);
  // Walls: nodes see them from 4 mesh edges away (~2-4 frames of travel at the demo's speeds).
  if (config.features.walls == "auto") resolve_walls(s, train_data.scene(), 4.0 * s.position_scale);
  if (config.features.momentum == "auto") {
    r.momentum_note = resolve_momentum(s, train_data.scene());
    if (s.has_momentum()) {
      const double residual = momentum_residual(train_data, probe, s, config.seed);
      if (!(residual <= kMomentumTolerance)) {
        r.momentum_note = std::isnan(residual)
                              ? std::string("the training data has no free body")
                              : "the training data's free bodies do not conserve it (" +
                                    std::to_string(100.0 * residual) + " % residual)";
        s.momentum_radius = s.momentum_wall_range = 0.0;
      } else {
        r.momentum_residual = residual;
      }
    }
  }
  return r;
}

// One training or validation batch and its target.
struct TrainBatch {
  Batch batch;
  torch::Tensor target;
};

// The adapter-specific part of training: samples of a dataset -> a batch and its target. The noise
// of refs[k] is drawn from generators[k] (no noise without generators).
TrainBatch make_train_batch(const Resolved& r, const TrainConfig& config, const Dataset& data,
                            GraphStore& store, const std::vector<SampleRef>& refs,
                            std::vector<at::Generator>* generators) {
  TrainBatch b;
  const bool noisy = generators != nullptr;
  if (noisy && generators->size() != refs.size())
    throw std::logic_error("make_train_batch: one generator per sample expected");
  if (r.eulerian) {
    const EulerianAdapter adapter(r.eulerian_spec);
    std::vector<EulerianFrame> frames;
    std::vector<torch::Tensor> nexts, pressures;
    for (const SampleRef& ref : refs) {
      const TrajectoryMesh& mesh = data.mesh(ref.trajectory);
      const auto state = read_eulerian_state(data, r.eulerian_spec, ref.trajectory, ref.frame, 2);
      frames.push_back({&store.get(mesh), &mesh, state[0]});
      nexts.push_back(state[1]);
      if (r.eulerian_spec.pressure)
        pressures.push_back(
            read_eulerian_pressure(data, r.eulerian_spec, ref.trajectory, ref.frame + 1, 1)[0]);
    }
    std::vector<double> noise;
    std::vector<at::Generator*> per_frame;
    if (noisy) {
      noise.assign(r.eulerian_spec.dim, config.features.noise_std);
      if (r.eulerian_spec.density) noise.push_back(config.features.density_noise_std);
      for (auto& g : *generators) per_frame.push_back(&g);
    }
    b.batch = adapter.make_batch(frames, noise, per_frame);
    b.target = adapter.target(b.batch, torch::cat(nexts, 0),
                              pressures.empty() ? torch::Tensor() : torch::cat(pressures, 0),
                              noisy ? config.features.noise_gamma : 1.0);
    return b;
  }
  const LagrangianAdapter adapter(r.spec);
  std::vector<FrameState> states;
  std::vector<torch::Tensor> nexts, noise;
  for (size_t k = 0; k < refs.size(); ++k) {
    LoadedSample s = load_sample(data, store, refs[k]);
    states.push_back(s.state);
    nexts.push_back(s.next);
    if (noisy)
      noise.push_back(torch::randn(s.state.cur.sizes(), (*generators)[k], torch::kFloat32) *
                      config.features.noise_std);
  }
  b.batch = adapter.make_batch(states, noise);
  b.target =
      adapter.target(b.batch, torch::cat(nexts, 0), noisy ? config.features.noise_gamma : 1.0);
  return b;
}

// A log row's step, or -1 unless `line` is a whole row (a step and 5 more fields).
int64_t log_row_step(const std::string& line) {
  if (std::count(line.begin(), line.end(), ',') != 5) return -1;
  const std::string step = line.substr(0, line.find(','));
  if (step.empty() || step.size() > 18 ||
      !std::all_of(step.begin(), step.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return -1;
  return std::stoll(step);
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
      const int64_t row = log_row_step(line);
      if (row <= last || row > keep_until_step) continue;  // header, torn or past the checkpoint
      kept.push_back(line);
      last = row;
    }
  }
  {
    AtomicOutput out(path);
    std::ofstream f(out.temp_path());
    f << "step,wall_s,loss,valid_loss,valid_baseline,lr\n";
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

TrainResult train(const TrainRequest& request) {
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
  const Resolved resolved = resolve(config, train_data);

  // Data parallelism: every rank has checked its config and data; now they meet.
  std::unique_ptr<Communicator> comm;
  if (dist.enabled()) comm = std::make_unique<Communicator>(dist);
  const int rank = comm ? comm->rank() : 0;
  const int world = comm ? comm->world() : 1;
  const bool writer = rank == 0;  // rank 0 alone writes the run folder
  const bool quiet = request.quiet || !writer;
  if (!has_valid && writer)
    std::cerr << "bsms train: warning: " << config.data
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
  if (writer) {
    try {
      std::error_code ec;
      fs::create_directories(fs::path(run) / "checkpoints", ec);
      if (ec) throw InputError(run + ": cannot create the run folder (" + ec.message() + ")");
      if (!request.resume && fs::exists(checkpoint))
        throw InputError(run +
                         ": run folder already holds a checkpoint; pass --resume to continue it "
                         "or --out for a new run");
      if (request.resume && !fs::exists(checkpoint))
        throw InputError(checkpoint +
                         ": nothing to resume (no checkpoint in this run folder; a session "
                         "stopped before its first checkpoint is started again without --resume)");
      if (request.resume) {
        const Json saved = load_json_file(run_config_path(run));
        Json a = saved.value("config", Json::object()), b = run_json["config"];
        for (auto* j : {&a, &b}) {
          j->erase("steps");
          j->erase("time_budget_s");
        }
        if (a != b || saved.value("levels", -1) != resolved.levels)
          throw InputError(run_config_path(run) +
                           ": the run was trained with another configuration; "
                           "only steps and time_budget_s may change on --resume");
        const int before = saved.value("world_size", 1);
        if (before != world)
          std::cerr << "bsms train: warning: " << run << " was trained with " << before
                    << " rank(s) of batch size " << config.optimizer.batch_size
                    << "; continuing with " << world
                    << ": the sample sequence changed (training goes on correctly, with "
                    << world * config.optimizer.batch_size << " samples per step instead of "
                    << before * config.optimizer.batch_size << ")\n";
        if (comm) {
          std::ifstream in(checkpoint, std::ios::binary);
          checkpoint_bytes.assign(std::istreambuf_iterator<char>(in), {});
          if (!in.good() && !in.eof()) throw InputError(checkpoint + ": cannot read");
        }
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
  GraphStore store(config.model.seeding, resolved.levels, cache_dirs);
  auto simulator =
      std::make_shared<LearnedSimulator>(resolved.shape(), config.model, resolved.levels);
  torch::optim::Adam optimizer(simulator->parameters(),
                               torch::optim::AdamOptions(config.optimizer.lr));

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
    log << at << ',' << std::setprecision(6) << wall_s << ',' << loss << ',';
    if (v)
      log << v->loss << ',' << v->baseline;
    else
      log << ',';
    log << ',' << lr << '\n';
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
  auto training_batch = [&](int64_t index) {
    std::vector<SampleRef> refs;
    std::vector<at::Generator> generators;
    for (int k = 0; k < per_rank; ++k) {
      const int slot = rank * per_rank + k;
      refs.push_back(draw_sample(train_data, config.seed, index, slot));
      generators.push_back(at::detail::createCPUGenerator(noise_seed(config.seed, index, slot)));
    }
    TrainBatch b = make_train_batch(resolved, config, train_data, store, refs, &generators);
    batch_weight = b.batch.mask.sum().item<double>();
    return b;
  };
  // Normaliser statistics are settled before the optimiser moves (batches -1, -2, ... are
  // drawn apart from the training steps'), summed over the ranks. A resumed run has them in its
  // checkpoint; a fresh one starts every rank from rank 0's parameters.
  if (!request.resume) {
    for (int64_t i = 0; i < config.normalizer_steps; ++i) {
      const TrainBatch b = training_batch(-2 - i);
      simulator->accumulate_statistics(b.batch, b.target);
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
                      ? "conserved on free bodies (data residual " +
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
  hooks.loss = [&](int64_t index) {
    const TrainBatch b = training_batch(index);
    return simulator->loss(b.batch, b.target);
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
  Json stats = {
      {"steps", step},
      {"train_ms_per_step", result.train_ms_per_step},
      {"peak_rss_mb_train", peak_rss_mb()},
      {"threads", threads},
      {"world_size", world},
      {"samples_per_step", world * per_rank},
      {"wall_s", fitted.wall_s},
      {"final_loss", last_loss},
      {"final_valid_loss", std::isfinite(last_valid.loss) ? Json(last_valid.loss) : Json(nullptr)},
      {"final_valid_baseline",
       std::isfinite(last_valid.baseline) ? Json(last_valid.baseline) : Json(nullptr)},
      {"num_parameters", simulator->num_parameters()},
      {"valid_split", has_valid ? "valid" : "train"}};
  if (comm && session_steps > 0) {
    // Rank 0's time in the gradient all-reduce (waiting for slower ranks included).
    stats["allreduce_ms_per_step"] = (comm->collective_ms - collective_ms_before) / session_steps;
    stats["allreduce_calls_per_step"] =
        static_cast<double>(comm->collective_calls - collective_calls_before) / session_steps;
  }
  if (request.resume && fs::exists(run_stats_path(run))) {
    // Keep the median of the first session when this one ran no step.
    const Json old = load_json_file(run_stats_path(run));
    if (fitted.step_ms.empty()) stats["train_ms_per_step"] = old.value("train_ms_per_step", 0.0);
    stats["peak_rss_mb_train"] = std::max(old.value("peak_rss_mb_train", 0.0), peak_rss_mb());
  }
  write_json_atomic(run_stats_path(run), stats);
  if (!request.quiet)
    std::cerr << "bsms train: " << step << " steps, loss " << last_loss << ", valid loss "
              << last_valid.loss << " (zero prediction " << last_valid.baseline << "), "
              << result.train_ms_per_step << " ms/step (median), peak RSS " << peak_rss_mb()
              << " MB\n";
  return result;
}

}  // namespace bsms
