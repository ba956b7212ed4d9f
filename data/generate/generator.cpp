#include "data/generate/generator.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include <unistd.h>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "core/runtime.hpp"
#include "data/generate/trajectory_solver.hpp"

namespace bsms::generate {

namespace fs = std::filesystem;

namespace {

constexpr const char* kManifest = "generate.json";
constexpr const char* kPartsDir = ".parts";
constexpr const char* kWorkDir = ".work";
// As bsms generate --trajectories allows; split weights bounded so that their products with the
// count cannot overflow.
constexpr int64_t kMaxTrajectories = 100000000;
constexpr int64_t kMaxSplitWeight = 1000000;
const char* const kSplitNames[3] = {"train", "valid", "test"};

std::string part_name(int64_t index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "traj_%06lld.h5", static_cast<long long>(index));
  return buf;
}

std::string part_path(const std::string& dir, int64_t index) {
  return (fs::path(dir) / kPartsDir / part_name(index)).string();
}

Json manifest(const FamilyConfig& family, int64_t trajectories, const std::array<int64_t, 3>& split,
              int64_t seed) {
  return {{"format", "bsms-generate"},
          {"version", 1},
          {"config", family.source},
          {"dim", family.dim},
          {"frame_dt", family.frame_dt},
          {"trajectories", trajectories},
          {"split", {split[0], split[1], split[2]}},
          {"seed", seed}};
}

void write_json_atomic(const std::string& path, const Json& json) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path());
    f << json.dump(2) << '\n';
    if (!f) throw IoError(out.temp_path() + ": write failed");
  }
  out.commit();
}

// Creates DIR (InputError when impossible) and checks that files can be created in it.
void require_writable_dir(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw InputError(dir + ": cannot create the output folder (" +
                     (ec ? ec.message() : std::string("not a folder")) + ")");
  const fs::path probe = fs::path(dir) / (".write_probe." + std::to_string(::getpid()));
  {
    std::ofstream f(probe);
    if (!f) throw InputError(dir + ": output folder is not writable");
  }
  fs::remove(probe, ec);
}

// A manifest as manifest() writes it, typed and in range, before anything is made from it.
void check_manifest(const Json& j, const std::string& path) {
  JsonObjectReader r(j, {path, ""});
  require(r.get<std::string>("format") == "bsms-generate", r.context("format"),
          "\"bsms-generate\"");
  require(r.get<int>("version") == 1, r.context("version"), "1");
  require(r.raw("config").is_object(), r.context("config"), "the family config object");
  const int dim = r.get<int>("dim");
  require(dim == 2 || dim == 3, r.context("dim"), "2 or 3");
  require(r.get<double>("frame_dt") > 0, r.context("frame_dt"), "> 0");
  const int64_t n = r.get<int64_t>("trajectories");
  require(n >= 1 && n <= kMaxTrajectories, r.context("trajectories"),
          "in [1, " + std::to_string(kMaxTrajectories) + "]");
  const Json& split = r.raw("split");
  bool ok = split.is_array() && split.size() == 3;
  int64_t sum = 0;
  for (size_t i = 0; ok && i < 3; ++i) {
    ok = split[i].is_number_integer() && split[i].get<int64_t>() >= 0 &&
         split[i].get<int64_t>() <= kMaxSplitWeight;
    if (ok) sum += split[i].get<int64_t>();
  }
  require(
      ok && sum > 0, r.context("split"),
      "[train, valid, test] weights in [0, " + std::to_string(kMaxSplitWeight) + "], not all 0");
  (void)r.get<int64_t>("seed");
  r.finish();
}

// Records the run settings in DIR, or checks them against an earlier call's.
void claim_dir(const std::string& dir, const Json& wanted) {
  const std::string path = (fs::path(dir) / kManifest).string();
  if (fs::exists(path)) {
    const Json have = load_json_file(path);
    if (have != wanted)
      throw InputError(path +
                       ": this folder holds a dataset generated with other settings "
                       "(family config, --trajectories, --split or --seed); use another --out");
    return;
  }
  write_json_atomic(path, wanted);
}

// A finished trajectory, read back for the merge with every value checked like any dataset.
Trajectory read_part(const std::string& path) {
  try {
    const Dataset d(path);
    if (d.num_trajectories() != 1) throw InputError(path + ": a part must hold one trajectory");
    Trajectory t;
    t.mesh = d.mesh(0);
    t.seed = d.seed(0);
    t.parameters = d.parameters(0);
    t.solver_wall_s = d.solver_wall_s(0);
    t.num_frames = d.num_frames(0);
    for (const FieldInfo& f : d.fields()) t.fields[f.name] = d.read(0, f.name, 0, t.num_frames);
    return t;
  } catch (const InputError& e) {
    // A part exists only once its trajectory was written whole, so a damaged one was changed
    // afterwards; removing it makes the next call solve that trajectory again (deterministic).
    throw InputError(std::string(e.what()) +
                     "; no split file was written: delete this part and run generate again to "
                     "solve its trajectory anew");
  }
}

// Writes the split files of `out_dir` from the parts found in `dirs` (first folder wins).
SplitCounts write_splits(const Json& settings, const std::vector<std::string>& dirs,
                         const std::string& out_dir) {
  const int64_t total = settings.at("trajectories").get<int64_t>();
  const auto split = settings.at("split").get<std::array<int64_t, 3>>();
  const SplitCounts counts = split_counts(total, split);
  std::vector<std::string> parts(total);
  int64_t missing = 0, first_missing = -1;
  for (int64_t i = 0; i < total; ++i) {
    for (const auto& dir : dirs)
      if (fs::exists(part_path(dir, i))) {
        parts[i] = part_path(dir, i);
        break;
      }
    if (parts[i].empty() && missing++ == 0) first_missing = i;
  }
  if (missing > 0)
    throw InputError(out_dir + ": " + std::to_string(missing) + " of " + std::to_string(total) +
                     " trajectories are missing (first: " + part_name(first_missing) +
                     "); run the missing shards first");
  const std::string scene = settings.at("config").dump();
  const int dim = settings.at("dim").get<int>();
  const double frame_dt = settings.at("frame_dt").get<double>();
  const int64_t sizes[3] = {counts.train, counts.valid, counts.test};
  // All or nothing: the three splits are written and synced under temporary names, and renamed
  // into place only when all are complete. A failure (a damaged part, a full disk) removes the
  // temporaries and leaves the folder as it was: the parts, for the next call to resume.
  std::vector<std::unique_ptr<DatasetWriter>> writers;
  int64_t next = 0;
  for (int s = 0; s < 3; ++s) {
    writers.push_back(std::make_unique<DatasetWriter>(
        (fs::path(out_dir) / (std::string(kSplitNames[s]) + ".h5")).string(), scene, dim,
        frame_dt));
    for (int64_t k = 0; k < sizes[s]; ++k, ++next) writers.back()->add(read_part(parts[next]));
  }
  for (auto& writer : writers) writer->finish();
  for (auto& writer : writers) writer->commit();
  return counts;
}

// Removes temporaries of split files and of generate.json whose writer was killed before its
// rename (parts' temporaries go with the .parts folder).
void remove_stale_temporaries(const std::string& dir) {
  std::vector<std::string> prefixes = {std::string(kManifest) + ".tmp."};
  for (const char* split : kSplitNames) prefixes.push_back(std::string(split) + ".h5.tmp.");
  std::error_code ec;
  std::vector<fs::path> stale;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    for (const auto& prefix : prefixes)
      if (name.rfind(prefix, 0) == 0) stale.push_back(entry.path());
  }
  for (const auto& path : stale) fs::remove(path, ec);
}

// Whether DIR holds the three split files and no parts: an earlier call finished.
bool splits_complete(const std::string& dir) {
  const bool complete = std::all_of(std::begin(kSplitNames), std::end(kSplitNames), [&](auto s) {
    return fs::exists(fs::path(dir) / (std::string(s) + ".h5"));
  });
  return complete && !fs::exists(fs::path(dir) / kPartsDir);
}

// This shard's trajectories without a part file, ascending; those with one counted as resumed.
std::vector<int64_t> pending_trajectories(const std::string& dir, const GenerateOptions& options,
                                          GenerateSummary& summary) {
  std::vector<int64_t> pending;
  for (int64_t i = 0; i < options.trajectories; ++i) {
    if (!options.shard.owns(i)) continue;
    if (fs::exists(part_path(dir, i)))
      ++summary.resumed;
    else
      pending.push_back(i);
  }
  return pending;
}

// Solves pending[0, limit) on up to options.threads threads (this one among them), each
// trajectory written to its part file under DIR as soon as it is solved; scratch files under
// `work`. The first error is rethrown once every thread has stopped. Sets summary.generated,
// redraws and solver_s.
void solve_pending(const FamilyConfig& family, const GenerateOptions& options, const Json& settings,
                   const std::string& dir, const std::string& work,
                   const std::vector<int64_t>& pending, int64_t limit, GenerateSummary& summary) {
  std::mutex log_mutex, io_mutex;
  std::unique_ptr<ProgressBar> bar;
  if (options.progress && !pending.empty())
    bar = std::make_unique<ProgressBar>("generate", static_cast<int64_t>(pending.size()));
  std::atomic<int64_t> next{0}, done{0}, redraws{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  double solver_s = 0.0;
  auto worker = [&] {
    try {
      while (!failed) {
        const int64_t k = next++;
        if (k >= limit) break;
        const int64_t index = pending[k];
        Trajectory t =
            generate_trajectory(family, options.seed, index, options.max_attempts,
                                (fs::path(work) / ("traj_" + std::to_string(index))).string(),
                                [&](const std::string& line) {
                                  ++redraws;
                                  const std::lock_guard<std::mutex> lock(log_mutex);
                                  std::cerr << "generate: " << line << '\n';
                                });
        {
          // Part files are small; serialising them keeps HDF5 safe without a thread-safe build.
          const std::lock_guard<std::mutex> io(io_mutex);
          DatasetWriter part(part_path(dir, index), settings.at("config").dump(), family.dim,
                             family.frame_dt);
          part.add(t);
          part.commit();
        }
        const std::lock_guard<std::mutex> lock(log_mutex);
        solver_s += t.solver_wall_s;
        const int64_t finished = ++done;
        if (bar) bar->update(finished, std::to_string(t.mesh.num_nodes()) + " nodes");
        if (options.on_progress)
          options.on_progress(finished, static_cast<int64_t>(pending.size()));
      }
    } catch (...) {
      const std::lock_guard<std::mutex> lock(log_mutex);
      if (!failed.exchange(true)) error = std::current_exception();
    }
  };
  const int threads =
      static_cast<int>(std::min<int64_t>(options.threads, std::max<int64_t>(limit, 1)));
  std::vector<std::thread> pool;
  for (int w = 1; w < threads; ++w) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  if (bar) bar->finish();
  summary.generated = done;
  summary.redraws = redraws;
  summary.solver_s = solver_s;
}

}  // namespace

std::string GenerateSummary::summary_line() const {
  std::ostringstream s;
  s.precision(3);
  s << generated << " trajectories solved in " << wall_s << " s";
  if (generated > 0 && wall_s > 0) s << " (" << 60.0 * generated / wall_s << " per minute)";
  s << ", " << resumed << " resumed, " << redraws << " unstable draws replaced";
  if (merged)
    s << "; split " << counts.train << "/" << counts.valid << "/" << counts.test
      << " (train/valid/test)";
  return s.str();
}

SplitCounts split_counts(int64_t total, const std::array<int64_t, 3>& weights) {
  const int64_t sum = weights[0] + weights[1] + weights[2];
  int64_t base[3], rem[3], assigned = 0;
  for (int s = 0; s < 3; ++s) {
    base[s] = total * weights[s] / sum;
    rem[s] = total * weights[s] % sum;
    assigned += base[s];
  }
  for (int64_t left = total - assigned; left > 0; --left) {
    int best = 0;
    for (int s = 1; s < 3; ++s)
      if (rem[s] > rem[best]) best = s;
    ++base[best];
    rem[best] = -1;
  }
  return {base[0], base[1], base[2]};
}

std::array<int64_t, 3> parse_split(const std::string& text, const std::string& where) {
  std::array<int64_t, 3> w{};
  std::istringstream in(text);
  char c1 = 0, c2 = 0;
  std::string rest;
  if (!(in >> w[0] >> c1 >> w[1] >> c2 >> w[2]) || c1 != ':' || c2 != ':' || (in >> rest) ||
      w[0] < 0 || w[1] < 0 || w[2] < 0 || w[0] > kMaxSplitWeight || w[1] > kMaxSplitWeight ||
      w[2] > kMaxSplitWeight || w[0] + w[1] + w[2] == 0)
    throw InputError(where + ": '" + truncate_for_message(text) +
                     "' is not a split TRAIN:VALID:TEST of integers in [0, " +
                     std::to_string(kMaxSplitWeight) + "], e.g. 80:10:10");
  return w;
}

Shard parse_shard(const std::string& text, const std::string& where) {
  Shard s;
  std::istringstream in(text);
  char slash = 0;
  std::string rest;
  if (!(in >> s.index >> slash >> s.count) || slash != '/' || (in >> rest) || s.count < 1 ||
      s.index < 1 || s.index > s.count)
    throw InputError(where + ": '" + truncate_for_message(text) +
                     "' is not a shard k/n with 1 <= k <= n");
  return s;
}

GenerateSummary generate_dataset(const FamilyConfig& family, const GenerateOptions& options) {
  if (options.trajectories < 1) throw InputError("--trajectories must be at least 1");
  if (options.threads < 1) throw InputError("--threads must be at least 1");
  Stopwatch clock;
  const std::string dir = options.out_dir;
  require_writable_dir(dir);
  const Json settings = manifest(family, options.trajectories, options.split, options.seed);
  claim_dir(dir, settings);

  GenerateSummary summary;
  if (splits_complete(dir) && options.shard.count == 1) {
    remove_stale_temporaries(dir);
    summary.merged = true;
    summary.resumed = options.trajectories;
    summary.counts = split_counts(options.trajectories, options.split);
    summary.wall_s = clock.seconds();
    return summary;
  }
  fs::create_directories(fs::path(dir) / kPartsDir);
  fs::create_directories(fs::path(dir) / kWorkDir);
  const std::string work = fs::absolute(fs::path(dir) / kWorkDir).string();

  const std::vector<int64_t> pending = pending_trajectories(dir, options, summary);
  const int64_t limit = options.stop_after < 0
                            ? static_cast<int64_t>(pending.size())
                            : std::min<int64_t>(options.stop_after, pending.size());
  solve_pending(family, options, settings, dir, work, pending, limit, summary);

  const bool stopped = limit < static_cast<int64_t>(pending.size());
  if (!stopped && options.shard.count == 1) {
    summary.counts = write_splits(settings, {dir}, dir);
    summary.merged = true;
    std::error_code ec;
    fs::remove_all(fs::path(dir) / kPartsDir, ec);
    fs::remove_all(fs::path(dir) / kWorkDir, ec);
    remove_stale_temporaries(dir);
  }
  summary.wall_s = clock.seconds();
  return summary;
}

GenerateSummary merge_parts(const std::vector<std::string>& shard_dirs,
                            const std::string& out_dir) {
  if (shard_dirs.empty()) throw InputError("--merge needs at least one shard folder");
  Stopwatch clock;
  Json settings;
  for (const auto& dir : shard_dirs) {
    const std::string path = (fs::path(dir) / kManifest).string();
    if (!fs::exists(path))
      throw InputError(dir + ": not a bsms generate folder (no " + std::string(kManifest) + ")");
    const Json j = load_json_file(path, "generate manifest");
    check_manifest(j, path);
    if (settings.is_null()) settings = j;
    if (j != settings)
      throw InputError(path + ": generated with other settings than " + shard_dirs[0] +
                       " (family config, --trajectories, --split or --seed)");
  }
  require_writable_dir(out_dir);
  claim_dir(out_dir, settings);
  GenerateSummary summary;
  summary.counts = write_splits(settings, shard_dirs, out_dir);
  summary.merged = true;
  summary.resumed = settings.at("trajectories").get<int64_t>();
  summary.wall_s = clock.seconds();
  return summary;
}

}  // namespace bsms::generate
