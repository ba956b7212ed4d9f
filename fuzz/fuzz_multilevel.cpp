// libFuzzer target for the multilevel graph file reader. The input is an HDF5
// structure program (h5_builder.hpp): groups, datasets, attributes and links written with the
// HDF5 API into a valid file, which read_multilevel_graph then reads from disk. Mutating the
// program reaches bsms' own checks (format, version, seeding, level count, num_nodes, dataset
// ranks, shapes and types, edge order, symmetry, pooled order, weights) rather than libhdf5's
// parser, whose crashes on damaged bytes are not bsms' to fix. InputError is the only allowed
// outcome; an accepted file must satisfy the invariants the reader promises.
// Seeds: BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_multilevel writes valid files' programs to DIR.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "h5_builder.hpp"
#include "preprocess/multilevel_file.hpp"

namespace {

using bsms_fuzz::Program;

// A valid file: a triangle (3 nodes), pooled to 2 nodes, then to 1.
Program valid_file(int levels, const std::string& seeding) {
  Program p;
  p.attr_string({}, "format", "bsms-multilevel");
  p.attr_int({}, "version", 1);
  p.attr_string({}, "seeding", seeding);
  p.attr_int({}, "num_levels", levels);
  p.group({"level_0"});
  p.attr_int({"level_0"}, "num_nodes", 3);
  p.dataset({"level_0", "edges"}, bsms_fuzz::kI64, {6, 2}, {0, 1, 0, 2, 1, 0, 1, 2, 2, 0, 2, 1});
  if (levels >= 2) {
    p.group({"level_1"});
    p.attr_int({"level_1"}, "num_nodes", 2);
    p.dataset({"level_1", "edges"}, bsms_fuzz::kI64, {2, 2}, {0, 1, 1, 0});
    p.dataset({"level_1", "pooled"}, bsms_fuzz::kI64, {2}, {0, 2});
    p.dataset({"level_1", "down_weight"}, bsms_fuzz::kF32, {6}, {0.5, 0.5, 0.25, 1, 0.5, 0.75});
  }
  if (levels >= 3) {
    p.group({"level_2"});
    p.attr_int({"level_2"}, "num_nodes", 1);
    p.dataset({"level_2", "edges"}, bsms_fuzz::kI64, {0, 2}, {});
    p.dataset({"level_2", "pooled"}, bsms_fuzz::kI64, {1}, {1});
    p.dataset({"level_2", "down_weight"}, bsms_fuzz::kF32, {2}, {1, 1});
  }
  return p;
}

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  out.push_back(valid_file(1, "minave").bytes);
  out.push_back(valid_file(2, "closecenter").bytes);
  out.push_back(valid_file(3, "random").bytes);
  Program strings_as_vlen = valid_file(2, "minave");
  strings_as_vlen.attr_string({}, "format", "bsms-multilevel", /*variable=*/true);
  out.push_back(strings_as_vlen.bytes);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = bsms_fuzz::scratch_dir("multilevel") + "/graph.h5";
  {
    bsms_fuzz::Reader in(data, size);
    bsms_fuzz::FileBuilder builder;
    int ops = 0;
    std::string ignored;
    while (builder.run(in, ops, &ignored)) {
    }
    builder.save(path);
  }
  try {
    const bsms::MultilevelGraph graph = bsms::read_multilevel_graph(path);
    // What the reader accepts must hold together: pooled indices address the finer level and
    // every level's CSR arrays match its node count.
    if (graph.num_levels() < 1) __builtin_trap();
    for (int k = 0; k < graph.num_levels(); ++k) {
      const bsms::GraphLevel& level = graph.levels[k];
      if (static_cast<int64_t>(level.graph.offsets.size()) != level.num_nodes() + 1)
        __builtin_trap();
      if (k == 0) continue;
      const bsms::GraphLevel& fine = graph.levels[k - 1];
      if (static_cast<int64_t>(level.pooled.size()) != level.num_nodes()) __builtin_trap();
      for (int64_t v : level.pooled)
        if (v < 0 || v >= fine.num_nodes()) __builtin_trap();
      if (static_cast<int64_t>(level.down_weight.size()) != fine.graph.num_edges())
        __builtin_trap();
    }
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  return 0;
}
