// Reading DeepMind's MeshGraphNets format: record read + CRC32C + decode throughput
// from a warm page cache, and the training access pattern (3 frames of one field of a random
// trajectory) against the same data in a bsms HDF5 file.
//
//   build/bench/bench_dataset --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// The synthetic split has CylinderFlow's record size: 1,900 nodes, 600 frames of velocity [2] and
// pressure [1] float32, ~13.7 MB per record, 8 records.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "data/dataset/tfrecord.hpp"
#include "tfrecord_writer.hpp"

namespace {

namespace fs = std::filesystem;
using namespace bsms;

constexpr int64_t kNodes = 1900, kFrames = 600, kRecords = 8;

struct Fixture {
  fs::path dir;
  uint64_t record_bytes = 0;
  Fixture() {
    dir = fs::temp_directory_path() / ("bsms_bench_dataset_" + std::to_string(::getpid()));
    fs::create_directories(dir / "mgn");
    const std::string meta =
        R"({"trajectory_length": 600, "dt": 0.01, "collision_radius": null,
            "field_names": ["cells", "mesh_pos", "node_type", "velocity", "pressure"],
            "features": {
              "cells": {"type": "static", "shape": [1, -1, 3], "dtype": "int32"},
              "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"},
              "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
              "velocity": {"type": "dynamic", "shape": [600, -1, 2], "dtype": "float32"},
              "pressure": {"type": "dynamic", "shape": [600, -1, 1], "dtype": "float32"}}})";
    test::write_file((dir / "mgn" / "meta.json").string(), meta);
    // A strip of triangles over a 2 x 950 grid of nodes.
    std::vector<int32_t> cells, types(kNodes, 0);
    std::vector<float> pos;
    for (int64_t i = 0; i < kNodes; ++i) {
      pos.push_back(static_cast<float>(i / 2) * 0.01f);
      pos.push_back(static_cast<float>(i % 2) * 0.01f);
    }
    for (int32_t k = 0; k + 3 < kNodes; k += 2)
      cells.insert(cells.end(), {k, k + 1, k + 2, k + 1, k + 3, k + 2});
    std::mt19937 rng(1);
    std::normal_distribution<float> normal;
    std::string file;
    fs::create_directories(dir / "h5");
    DatasetWriter writer((dir / "h5" / "train.h5").string(), "{}", 2, 0.01);
    for (int64_t r = 0; r < kRecords; ++r) {
      std::vector<float> velocity(kFrames * kNodes * 2), pressure(kFrames * kNodes);
      for (auto& v : velocity) v = normal(rng);
      for (auto& v : pressure) v = normal(rng);
      const std::string data = test::example({{"cells", test::raw(cells)},
                                              {"mesh_pos", test::raw(pos)},
                                              {"node_type", test::raw(types)},
                                              {"velocity", test::raw(velocity)},
                                              {"pressure", test::raw(pressure)}});
      record_bytes += data.size();
      file += test::frame_record(data);
      Trajectory t;
      t.mesh.dim = 2;
      t.mesh.cell_size = 3;
      t.mesh.cells = cells;
      t.mesh.mesh_pos = pos;
      t.mesh.node_type = types;
      t.mesh.body_id.assign(kNodes, 0);
      t.num_frames = kFrames;
      t.fields["velocity"] = velocity;
      t.fields["pressure"] = pressure;
      writer.add(t);
    }
    writer.commit();
    test::write_file((dir / "mgn" / "train.tfrecord").string(), file);
  }
  ~Fixture() { fs::remove_all(dir); }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

// Whole records: header scan, data CRC, wire walk and conversion of every field, one thread.
void BM_TfRecordDecodeAll(benchmark::State& state) {
  set_num_threads(1);
  Fixture& f = fixture();
  const std::string path = (f.dir / "mgn" / "train.tfrecord").string();
  const tfrecord::Meta meta = tfrecord::read_meta((f.dir / "mgn" / "meta.json").string());
  for (auto _ : state) {
    tfrecord::TfRecordReader reader(path, meta);
    for (int64_t r = 0; r < reader.num_records(); ++r)
      benchmark::DoNotOptimize(reader.decode(r).size());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) *
                          static_cast<int64_t>(f.record_bytes));
}
BENCHMARK(BM_TfRecordDecodeAll)->Unit(benchmark::kMillisecond);

// The training access pattern: 3 consecutive frames of velocity from a random trajectory.
template <bool kTfRecord>
void BM_ReadThreeFrames(benchmark::State& state) {
  set_num_threads(1);
  Fixture& f = fixture();
  const Dataset data = kTfRecord ? Dataset::open_split((f.dir / "mgn").string(), "train")
                                 : Dataset::open_split((f.dir / "h5").string(), "train");
  for (int64_t t = 0; t < data.num_trajectories(); ++t) data.read(t, "velocity", 0, 1);  // warm
  std::mt19937 rng(2);
  for (auto _ : state) {
    const int64_t t = static_cast<int64_t>(rng() % kRecords);
    const int64_t frame = static_cast<int64_t>(rng() % (kFrames - 2));
    benchmark::DoNotOptimize(data.read(t, "velocity", frame, 3).data());
  }
}
BENCHMARK_TEMPLATE(BM_ReadThreeFrames, true)
    ->Name("BM_ReadThreeFrames/tfrecord")
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_ReadThreeFrames, false)
    ->Name("BM_ReadThreeFrames/bsms_hdf5")
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
