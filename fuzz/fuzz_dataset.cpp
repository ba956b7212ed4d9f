// libFuzzer target for the dataset reader: bsms HDF5 datasets and the public
// HDF5 layouts (single file with one group per trajectory; a folder of {i}.h5 files). The input
// is a mode byte (bit 0: folder layout) then an HDF5 structure program (h5_builder.hpp) written
// with the HDF5 API into valid files; in folder mode a next-file op starts another {i}.h5. The
// dataset is opened and walked as training does: trajectories, frames, mesh, seed, parameters,
// solver time, first and last frame of every field. InputError is the only allowed outcome of a
// bad file; what is accepted must be consistent (mesh arrays sized as the reader promises).
// libhdf5's own parser is not fuzzed (see h5_builder.hpp). The MeshGraphNets layout is
// fuzz_tfrecord's. Seeds: BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_dataset writes valid programs to DIR.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "h5_builder.hpp"

namespace {

using bsms_fuzz::kF32;
using bsms_fuzz::kI32;
using bsms_fuzz::Program;
namespace fs = std::filesystem;

std::vector<uint8_t> with_mode(uint8_t mode, const Program& p) {
  std::vector<uint8_t> out{mode};
  out.insert(out.end(), p.bytes.begin(), p.bytes.end());
  return out;
}

void bsms_trajectory(Program& p, const std::string& name) {
  const std::vector<std::string> g = {"trajectories", name};
  p.group(g);
  p.attr_int(g, "seed", 7);
  p.attr_string(g, "parameters", "{\"a\": 1}");
  p.attr_double(g, "solver_wall_s", 1.5);
  auto at = [&](const std::string& d) { return std::vector<std::string>{g[0], g[1], d}; };
  p.dataset(at("cells"), kI32, {1, 3}, {0, 1, 2});
  p.dataset(at("mesh_pos"), kF32, {3, 2}, {0, 0, 1, 0, 0, 1});
  p.dataset(at("node_type"), kI32, {3}, {0, 1, 0});
  p.dataset(at("body_id"), kI32, {3}, {0, 0, 0});
  p.dataset(at("world_pos"), kF32, {2, 3, 2}, {0, 0, 1, 0, 0, 1, 0, 0.25, 1, 0.25, 0, 1.25});
  p.dataset(at("velocity"), kF32, {2, 3, 2}, {0, 0, 0, 0, 0, 0, 0, 0.25, 0, 0.25, 0, 0.25});
  p.dataset(at("stress"), kF32, {2, 3}, {0, 0, 0, 1, 2, 3});
}

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  {
    Program p;
    p.attr_string({}, "format", "bsms-dataset");
    p.attr_int({}, "version", 1);
    p.attr_string({}, "scene", "{}");
    p.attr_int({}, "dim", 2);
    p.attr_double({}, "frame_dt", 0.25);
    p.attr_int({}, "num_trajectories", 2);
    bsms_trajectory(p, "000000");
    bsms_trajectory(p, "000001");
    out.push_back(with_mode(0, p));
  }
  {  // public single file: static fields with a leading time axis
    Program p;
    for (const std::string g : {"0", "1", "10"}) {
      p.dataset({g, "mesh_pos"}, kF32, {1, 3, 2}, {0, 0, 1, 0, 0, 1});
      p.dataset({g, "cells"}, kI32, {1, 1, 3}, {0, 1, 2});
      p.dataset({g, "node_type"}, kI32, {1, 3, 1}, {0, 1, 0});
      p.dataset({g, "world_pos"}, kF32, {2, 3, 3},
                {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1});
    }
    out.push_back(with_mode(0, p));
  }
  {  // public folder: 0.h5, 1.h5
    Program p;
    for (const std::string f : {"0", "1"}) {
      if (f != "0") p.next_file(f);
      p.dataset({"mesh_pos"}, kF32, {3, 2}, {0, 0, 1, 0, 0, 1});
      p.dataset({"cells"}, kI32, {1, 3}, {0, 1, 2});
      p.dataset({"node_type"}, kI32, {3, 1}, {0, 1, 0});
      p.dataset({"velocity"}, kF32, {2, 3, 2}, {0, 0, 1, 0, 0, 1, 0, 0.25, 1, 0.25, 0, 1.25});
      p.dataset({"pressure"}, kF32, {2, 3, 1}, {0, 0, 0, 1, 2, 3});
    }
    out.push_back(with_mode(1, p));
  }
  return out;
}

void walk(const bsms::Dataset& d) {
  const int64_t n = d.num_trajectories();
  if (n < 1) __builtin_trap();
  (void)d.dim();
  (void)d.frame_dt();
  (void)d.scene();
  for (int64_t t = 0; t < n && t < 4; ++t) {
    try {
      const int64_t frames = d.num_frames(t);
      const bsms::TrajectoryMesh& m = d.mesh(t);
      if (m.num_nodes() < 0 || static_cast<int64_t>(m.mesh_pos.size()) != m.num_nodes() * m.dim)
        __builtin_trap();
      if (static_cast<int64_t>(m.body_id.size()) != m.num_nodes()) __builtin_trap();
      for (int32_t c : m.cells)
        if (c < 0 || c >= m.num_nodes()) __builtin_trap();
      (void)d.seed(t);
      (void)d.parameters(t);
      (void)d.solver_wall_s(t);
      for (const bsms::FieldInfo& f : d.fields()) {
        d.read(t, f.name, 0, 1);
        if (frames > 1) d.read(t, f.name, frames - 1, 1);
      }
    } catch (const bsms::InputError& e) {
      bsms_fuzz::refused(e);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& dir = bsms_fuzz::scratch_dir("dataset");
  const bool folder = size > 0 && (data[0] & 1);
  bsms_fuzz::Reader in(size > 0 ? data + 1 : data, size > 0 ? size - 1 : 0);
  std::string location;
  if (folder) {
    location = dir + "/train";
    fs::remove_all(location);
    fs::create_directories(location);
    std::string name = "0";
    int ops = 0;
    for (int files = 0; files < 4; ++files) {
      bsms_fuzz::FileBuilder builder;
      std::string next;
      const bool more = builder.run(in, ops, &next);
      builder.save(location + "/" + name + ".h5");
      if (!more) break;
      name = next;
    }
  } else {
    location = dir + "/train.h5";
    bsms_fuzz::FileBuilder builder;
    int ops = 0;
    std::string ignored;
    while (builder.run(in, ops, &ignored)) {
    }
    builder.save(location);
  }
  try {
    const bsms::Dataset d(location);
    walk(d);
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  return 0;
}
