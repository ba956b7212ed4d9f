// `bsms generate`: randomized UMLS-MPM trajectories written to crash-safe HDF5 datasets.
//
// Layout of an output folder DIR:
//   DIR/generate.json         the resolved family config, trajectory count, split and seed; a
//                             rerun with other settings is refused (InputError)
//   DIR/.parts/traj_NNNNNN.h5 one finished trajectory (global index NNNNNN), a one-trajectory
//                             bsms dataset written atomically: its existence means "done"
//   DIR/train.h5, valid.h5, test.h5   merged from the parts in index order (atomic), after which
//                             the parts are removed (a shard run keeps them for --merge)
// Trajectory i of a run with seed S is drawn from Rng(trajectory_seed(S, i, attempt)) and solved by
// trajectory_solver.hpp; a draw whose solve fails (NumericalError) is reported and replaced by
// attempt + 1. Nothing that depends on time, threads or interruption enters the files except each
// trajectory's solver_wall_s.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"

namespace bsms::generate {

struct SplitCounts {
  int64_t train = 0, valid = 0, test = 0;
};

// Splits `total` trajectories by integer weights (e.g. 80:10:10) with the largest-remainder rule
// (ties to the earlier split), so the counts sum to `total`. Global indices [0, train) are train,
// then valid, then test.
SplitCounts split_counts(int64_t total, const std::array<int64_t, 3>& weights);
// Parses "80:10:10"; InputError naming `where` for anything else (negative, all zero, not 3).
std::array<int64_t, 3> parse_split(const std::string& text, const std::string& where);

struct Shard {
  int64_t index = 1,
          count = 1;  // shard `index` of `count`, 1-based: owns i with i % count == index − 1
  bool owns(int64_t i) const { return i % count == index - 1; }
};
Shard parse_shard(const std::string& text, const std::string& where);  // "k/n", 1 ≤ k ≤ n

struct GenerateOptions {
  std::string out_dir;
  int64_t trajectories = 0;
  std::array<int64_t, 3> split{80, 10, 10};
  int64_t seed = 0;
  int threads = 1;        // trajectories solved at once (each solve single-threaded)
  Shard shard;            // count > 1: only this shard's parts; merge them with merge_parts
  int max_attempts = 20;  // unstable draws per trajectory before giving up (NumericalError)
  bool progress = false;  // progress bar on stderr
  // Told after each finished trajectory (from the solving threads, one call at a time):
  // trajectories finished by this call, trajectories it has to solve. An exception it throws
  // stops the run as a failed solve does (finished parts stay, a rerun resumes).
  std::function<void(int64_t done, int64_t total)> on_progress;
  // Stops after this many new parts without merging (< 0: no limit). Simulates an interrupted run.
  int64_t stop_after = -1;
};

struct GenerateSummary {
  int64_t generated = 0;  // trajectories solved by this call
  int64_t resumed = 0;    // parts found done from an earlier call
  int64_t redraws = 0;    // unstable draws replaced
  double wall_s = 0.0;    // wall time of this call, s
  double solver_s = 0.0;  // summed solver time of the trajectories solved by this call, s
  bool merged = false;    // split files written
  SplitCounts counts;
  std::string summary_line() const;
};

// Generates (or resumes) a dataset as described at the top of this file.
GenerateSummary generate_dataset(const FamilyConfig& family, const GenerateOptions& options);

// Combines the parts of shard folders (each made with the same family, count, split and seed)
// into out_dir/{train,valid,test}.h5 and out_dir/generate.json. InputError lists missing parts.
GenerateSummary merge_parts(const std::vector<std::string>& shard_dirs, const std::string& out_dir);

}  // namespace bsms::generate
