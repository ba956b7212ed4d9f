// bsms generate FAMILY.json --out DIR --trajectories N [--split 80:10:10] [--seed S] [--threads T]
//               [--shard k/n] [--set key=value]   randomized UMLS-MPM trajectories ->
//               DIR/{split}.h5
// bsms generate --merge SHARD_DIR... --out DIR    combines the parts of shard runs
#include <filesystem>
#include <iostream>

#include "cli/command.hpp"
#include "cli/programs.hpp"
#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/generate/generator.hpp"

namespace {

struct GenerateCliOptions {
  std::vector<std::string> inputs;
  std::string out;
  int64_t trajectories = 0;
  std::string split = "80:10:10";
  int64_t seed = 0;
  int threads = 0;
  std::string shard = "1/1";
  bool merge = false;
  std::vector<std::string> sets;
};

void run(const GenerateCliOptions& o) {
  namespace gen = bsms::generate;
  namespace fs = std::filesystem;
  bsms::cli::require_creatable_dir(o.out);
  // A failed run leaves no folder it created, unless finished trajectories (resumable) are in it.
  const bsms::cli::RemoveOnFailure cleanup(o.out, [&o] {
    std::error_code ec;
    for (fs::recursive_directory_iterator it(o.out, ec), end; !ec && it != end; it.increment(ec))
      if (it->path().extension() == ".h5") return true;
    return false;
  });
  if (o.merge) {
    const gen::GenerateSummary s = gen::merge_parts(o.inputs, o.out);
    std::cout << "generate: merged " << o.inputs.size() << " shard folder(s) into " << o.out << ": "
              << s.summary_line() << '\n';
    return;
  }
  if (o.inputs.size() != 1)
    throw bsms::InputError("generate: expected one family config file (or --merge SHARD_DIR...)");
  if (o.trajectories < 1) throw bsms::InputError("generate: --trajectories N (N >= 1) is required");
  gen::GenerateOptions options;
  options.out_dir = o.out;
  options.trajectories = o.trajectories;
  options.split = gen::parse_split(o.split, "--split");
  options.shard = gen::parse_shard(o.shard, "--shard");
  options.seed = o.seed;
  const gen::FamilyConfig family = gen::load_family(o.inputs[0], o.sets);
  options.threads = bsms::set_num_threads(o.threads);
  options.progress = true;
  // On stdout with the summary: stderr holds the progress and, on failure, one error line.
  std::cout << "generate: " << o.inputs[0] << " (family " << family.family << ", " << o.trajectories
            << " trajectories, split " << o.split << ", seed " << o.seed << ", shard "
            << options.shard.index << "/" << options.shard.count << ", " << options.threads
            << " concurrent single-threaded solves)" << std::endl;
  const gen::GenerateSummary s = gen::generate_dataset(family, options);
  std::cout << "generate: " << s.summary_line() << '\n';
  if (s.generated > 0)
    std::cout << "generate: solver time " << s.solver_s << " s, " << s.solver_s / s.generated
              << " s per trajectory; " << 60.0 * s.generated / s.wall_s
              << " trajectories per minute with " << options.threads << " concurrent solves\n";
  if (s.merged)
    std::cout << "generate: wrote " << o.out << "/train.h5, valid.h5, test.h5\n";
  else
    std::cout << "generate: parts of shard " << options.shard.index << "/" << options.shard.count
              << " are in " << o.out << "/.parts; combine all shards with "
              << "`bsms generate --merge DIR... --out DIR`\n";
}

}  // namespace

BSMS_COMMAND("generate", bsms::cli::handed_command_help("generate"), [](CLI::App& sub) {
  auto o = std::make_shared<GenerateCliOptions>();
  sub.add_option("inputs", o->inputs,
                 "family config (configs/families/disks2d.json, ...), or with --merge the "
                 "shard output folders")
      ->required();
  sub.add_option("--out", o->out, "output folder: train.h5, valid.h5, test.h5, generate.json")
      ->required();
  sub.add_option("--trajectories", o->trajectories, "number of trajectories over all splits")
      ->check(CLI::Range(int64_t{0}, int64_t{100000000}));
  sub.add_option("--split", o->split, "train:valid:test weights")->default_val("80:10:10");
  sub.add_option("--seed", o->seed, "run seed (trajectory i uses a seed derived from it)")
      ->default_val(0);
  sub.add_option("--shard", o->shard,
                 "k/n: make only trajectories i with i % n == k - 1 (1-based k)")
      ->default_val("1/1");
  sub.add_flag("--merge", o->merge, "combine the parts of shard folders given as inputs");
  bsms::cli::add_set_option(sub, o->sets);
  bsms::cli::add_threads_option(sub, o->threads);
  sub.callback([o] { run(*o); });
});
