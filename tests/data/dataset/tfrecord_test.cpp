// DeepMind MeshGraphNets datasets as distributed (meta.json + {split}.tfrecord): CRC32C against
// published vectors, the four fixtures against an independent decoder (tfrecord_writer.hpp),
// round trips of every dtype, one InputError per kind of corruption, and the other public layouts
// (single-file {split}.h5, the rejected outputs_{split}/).
#include "data/dataset/tfrecord.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"
#include "tests/data/dataset/tfrecord_writer.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;
using test::example;
using test::frame_record;
using test::raw;

fs::path temp_dir(const std::string& name) {
  return bsms::testing::unique_temp_dir("tfrecord_" + name);
}

// ---- CRC ----

TEST(Crc32c, KnownVectors) {
  const std::string digits = "123456789";
  const std::string zeros(32, '\0'), ones(32, '\xff');
  std::string ascending;
  for (int i = 0; i < 32; ++i) ascending.push_back(static_cast<char>(i));
  struct Case {
    std::string data;
    uint32_t crc;
  };
  // RFC 3720 B.4 and the usual check value.
  for (const Case& c : {Case{digits, 0xE3069283u}, Case{zeros, 0x8A9136AAu},
                        Case{ones, 0x62A8AB43u}, Case{ascending, 0x46DD794Eu}}) {
    EXPECT_EQ(tfrecord::crc32c(c.data.data(), c.data.size()), c.crc);
    EXPECT_EQ(tfrecord::crc32c_portable(c.data.data(), c.data.size()), c.crc);
    EXPECT_EQ(test::bitwise_crc32c(c.data), c.crc);  // the test writer's own CRC
  }
  EXPECT_EQ(tfrecord::crc32c(nullptr, 0), 0u);
}

TEST(Crc32c, ExtendsAndAgreesOnRandomLengths) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    std::string s(rng() % 300, '\0');
    for (char& c : s) c = static_cast<char>(rng());
    const size_t cut = s.empty() ? 0 : rng() % s.size();
    const uint32_t whole = test::bitwise_crc32c(s);
    EXPECT_EQ(tfrecord::crc32c(s.data(), s.size()), whole);
    EXPECT_EQ(tfrecord::crc32c_portable(s.data(), s.size()), whole);
    EXPECT_EQ(tfrecord::crc32c(s.data() + cut, s.size() - cut, tfrecord::crc32c(s.data(), cut)),
              whole);
  }
}

TEST(Crc32c, Mask) {
  EXPECT_EQ(tfrecord::mask_crc(0), 0xa282ead8u);
  EXPECT_EQ(tfrecord::mask_crc(0x00008000u), 0xa282ead9u);  // bit 15 rotates to bit 0
  EXPECT_EQ(tfrecord::mask_crc(1), 0xa282ead8u + (1u << 17));
  EXPECT_EQ(tfrecord::mask_crc(0xE3069283u), test::masked(0xE3069283u));
}

// ---- fixtures ----

const fs::path kFixtures = fs::path(BSMS_FIXTURES_DIR) / "meshgraphnets";

std::vector<double> decode_raw(const std::string& bytes, tfrecord::DType dtype) {
  std::vector<double> out;
  const size_t size = tfrecord::dtype_size(dtype);
  for (size_t i = 0; i + size <= bytes.size(); i += size) {
    const char* p = bytes.data() + i;
    switch (dtype) {
      case tfrecord::DType::kFloat32: {
        float v;
        std::memcpy(&v, p, 4);
        out.push_back(v);
        break;
      }
      case tfrecord::DType::kFloat64: {
        double v;
        std::memcpy(&v, p, 8);
        out.push_back(v);
        break;
      }
      case tfrecord::DType::kInt32: {
        int32_t v;
        std::memcpy(&v, p, 4);
        out.push_back(v);
        break;
      }
      case tfrecord::DType::kInt64: {
        int64_t v;
        std::memcpy(&v, p, 8);
        out.push_back(static_cast<double>(v));
        break;
      }
    }
  }
  return out;
}

class Fixture : public ::testing::TestWithParam<std::string> {};

TEST_P(Fixture, EverySplitAndRecordDecodesLikeTheIndependentParser) {
  const fs::path dir = kFixtures / GetParam();
  ASSERT_TRUE(fs::exists(dir / "meta.json")) << "fixtures not found at " << dir;
  const tfrecord::Meta meta = tfrecord::read_meta((dir / "meta.json").string());
  const int64_t T = meta.trajectory_length;
  for (const std::string split : {"train", "valid", "test"}) {
    SCOPED_TRACE(split);
    ASSERT_TRUE(Dataset::has_split(dir.string(), split));
    const Dataset d = Dataset::open_split(dir.string(), split);
    EXPECT_EQ(d.layout(), DatasetLayout::kMeshGraphNets);
    EXPECT_TRUE(d.is_public_layout());
    EXPECT_DOUBLE_EQ(d.frame_dt(), meta.dt);
    EXPECT_DOUBLE_EQ(d.collision_radius(), meta.collision_radius);
    EXPECT_EQ(d.simulator(), meta.simulator);
    const auto records =
        test::split_records(test::read_file((dir / (split + ".tfrecord")).string()));
    ASSERT_EQ(d.num_trajectories(), static_cast<int64_t>(records.size()));
    ASSERT_GT(records.size(), 0u);
    const tfrecord::TfRecordReader reader((dir / (split + ".tfrecord")).string(), meta);
    for (size_t r = 0; r < records.size(); ++r) {
      SCOPED_TRACE("record " + std::to_string(r));
      const auto bytes = test::parse_example(records[r]);
      const auto decoded = reader.decode(static_cast<int64_t>(r));
      const auto& mesh = d.mesh(static_cast<int64_t>(r));
      const int64_t n = mesh.num_nodes();
      ASSERT_GT(n, 0);
      EXPECT_EQ(d.num_frames(static_cast<int64_t>(r)), T);
      for (const auto& spec : meta.fields) {
        SCOPED_TRACE(spec.name);
        ASSERT_TRUE(bytes.count(spec.name));
        const std::vector<double> want = decode_raw(bytes.at(spec.name), spec.dtype);
        const auto& got = decoded.at(spec.name);
        ASSERT_EQ(got.shape.size(), spec.shape.size());
        EXPECT_EQ(got.shape[0], spec.kind == tfrecord::FieldKind::kStatic ? 1 : T);
        if (spec.name != "cells") {
          EXPECT_EQ(got.shape[1], n);  // N consistent
        }
        EXPECT_EQ(got.shape.back(), spec.width());
        int64_t size = 1;
        for (int64_t v : got.shape) size *= v;
        ASSERT_EQ(size, static_cast<int64_t>(want.size()));
        for (size_t i = 0; i < want.size(); ++i) {
          ASSERT_TRUE(std::isfinite(want[i]));
          const double v = got.floats.empty() ? static_cast<double>(got.ints[i]) : got.floats[i];
          ASSERT_EQ(v, want[i]) << "flat index " << i;
        }
        if (spec.kind != tfrecord::FieldKind::kDynamic) continue;
        // read() of the whole field and of slices equals the independent decode.
        const std::vector<float> full = d.read(static_cast<int64_t>(r), spec.name, 0, T);
        ASSERT_EQ(full.size(), want.size());
        for (size_t i = 0; i < want.size(); ++i) ASSERT_EQ(full[i], static_cast<float>(want[i]));
        const size_t frame = want.size() / T;
        for (const auto& [t0, count] : std::vector<std::pair<int64_t, int64_t>>{
                 {0, 1}, {T - 1, 1}, {T / 2, 3}, {1, T - 2}, {T, 0}}) {
          const auto slice = d.read(static_cast<int64_t>(r), spec.name, t0, count);
          ASSERT_EQ(slice.size(), frame * count);
          for (size_t i = 0; i < slice.size(); ++i)
            ASSERT_EQ(slice[i], full[t0 * frame + i]) << "t0 " << t0 << " count " << count;
        }
        EXPECT_THROW(d.read(static_cast<int64_t>(r), spec.name, T - 1, 2), InputError);
        EXPECT_THROW(d.read(static_cast<int64_t>(r), spec.name, -1, 1), InputError);
      }
      // The mesh: positions finite, cells in range, node_type [N], body_id zeros.
      const auto pos = decode_raw(bytes.at("mesh_pos"), meta.find("mesh_pos")->dtype);
      ASSERT_EQ(mesh.mesh_pos.size(), pos.size());
      for (size_t i = 0; i < pos.size(); ++i) ASSERT_EQ(mesh.mesh_pos[i], pos[i]);
      EXPECT_EQ(mesh.dim, meta.find("mesh_pos")->width());
      EXPECT_EQ(mesh.cell_size, meta.find("cells")->width());
      EXPECT_GT(mesh.num_cells(), 0);
      for (int32_t c : mesh.cells) ASSERT_TRUE(c >= 0 && c < n);
      EXPECT_EQ(mesh.body_id, std::vector<int32_t>(n, 0));
      const auto types = decode_raw(bytes.at("node_type"), meta.find("node_type")->dtype);
      ASSERT_EQ(mesh.node_type.size(), types.size());
      for (size_t i = 0; i < types.size(); ++i) ASSERT_EQ(mesh.node_type[i], types[i]);
    }
    // dim(): world_pos width when present (cloth 3-D on a 2-D mesh), else mesh_pos width.
    const auto* world = meta.find("world_pos");
    EXPECT_EQ(d.dim(), world ? world->width() : meta.find("mesh_pos")->width());
    for (const auto& f : d.fields()) {
      const auto* spec = meta.find(f.name);
      ASSERT_NE(spec, nullptr);
      EXPECT_EQ(spec->kind, tfrecord::FieldKind::kDynamic);
      EXPECT_EQ(f.width, spec->width());
    }
  }
  // The .tfrecord path itself opens too (meta.json beside it).
  EXPECT_EQ(Dataset((dir / "valid.tfrecord").string()).layout(), DatasetLayout::kMeshGraphNets);
}

INSTANTIATE_TEST_SUITE_P(MeshGraphNets, Fixture,
                         ::testing::Values("cylinder_flow", "airfoil", "deforming_plate",
                                           "flag_simple"));

// ---- synthetic data ----

constexpr int kN = 4, kT = 3;

std::string meta_json(const std::string& pos_dtype = "float32",
                      const std::string& cells_dtype = "int32",
                      const std::string& vel_dtype = "float32",
                      const std::string& vel_type = "dynamic") {
  return R"({"simulator": "test", "dt": 0.5, "collision_radius": 0.25, "trajectory_length": 3,
    "field_names": ["cells", "mesh_pos", "node_type", "velocity", "pressure"],
    "features": {
      "cells": {"type": "static", "shape": [1, -1, 3], "dtype": ")" +
         cells_dtype + R"("},
      "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": ")" +
         pos_dtype + R"("},
      "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
      "velocity": {"type": ")" +
         vel_type + R"(", "shape": [3, -1, 2], "dtype": ")" + vel_dtype + R"("},
      "pressure": {"type": "dynamic", "shape": [3, -1, 1], "dtype": "float32"}}})";
}

// The fields of trajectory `r` with known values; `skip` drops one field.
std::vector<std::pair<std::string, std::string>> fields(int r, const std::string& skip = "") {
  std::vector<float> pos = {0, 0, 1, 0, 1, 1, 0, 1}, vel(kT * kN * 2), p(kT * kN);
  for (size_t i = 0; i < vel.size(); ++i) vel[i] = 100.0f * r + 0.5f * static_cast<float>(i);
  for (size_t i = 0; i < p.size(); ++i) p[i] = -static_cast<float>(i) - r;
  std::vector<std::pair<std::string, std::string>> out = {
      {"cells", raw(std::vector<int32_t>{0, 1, 2, 0, 2, 3})},
      {"mesh_pos", raw(pos)},
      {"node_type", raw(std::vector<int32_t>{0, 6, 4, 5})},
      {"velocity", raw(vel)},
      {"pressure", raw(p)}};
  std::vector<std::pair<std::string, std::string>> kept;
  for (auto& f : out)
    if (f.first != skip) kept.push_back(f);
  return kept;
}

// A folder with meta.json and train.tfrecord holding `records` (data of each record).
fs::path make_folder(const std::string& name, const std::string& meta,
                     const std::vector<std::string>& records) {
  const fs::path dir = temp_dir(name);
  test::write_file((dir / "meta.json").string(), meta);
  std::string file;
  for (const auto& r : records) file += frame_record(r);
  test::write_file((dir / "train.tfrecord").string(), file);
  return dir;
}

std::vector<std::string> good_records(int count = 3) {
  std::vector<std::string> out;
  for (int r = 0; r < count; ++r) out.push_back(example(fields(r)));
  return out;
}

TEST(TfRecord, RoundTripKnownValues) {
  const fs::path dir = make_folder("roundtrip", meta_json(), good_records());
  const Dataset d = Dataset::open_split(dir.string(), "train");
  EXPECT_EQ(d.layout(), DatasetLayout::kMeshGraphNets);
  EXPECT_EQ(d.simulator(), "test");
  EXPECT_DOUBLE_EQ(d.frame_dt(), 0.5);
  EXPECT_DOUBLE_EQ(d.collision_radius(), 0.25);
  EXPECT_EQ(d.dim(), 2);
  ASSERT_EQ(d.num_trajectories(), 3);
  EXPECT_EQ(d.num_frames(2), kT);
  ASSERT_EQ(d.fields().size(), 2u);
  EXPECT_EQ(d.fields()[0].name, "velocity");
  EXPECT_EQ(d.fields()[0].width, 2);
  EXPECT_EQ(d.fields()[1].name, "pressure");
  EXPECT_EQ(d.fields()[1].width, 1);
  const auto& m = d.mesh(1);
  EXPECT_EQ(m.num_nodes(), kN);
  EXPECT_EQ(m.num_cells(), 2);
  EXPECT_EQ(m.node_type, (std::vector<int32_t>{0, 6, 4, 5}));
  EXPECT_EQ(m.cells, (std::vector<int32_t>{0, 1, 2, 0, 2, 3}));
  const auto v = d.read(2, "velocity", 1, 2);
  ASSERT_EQ(v.size(), 2u * kN * 2);
  for (size_t i = 0; i < v.size(); ++i) EXPECT_EQ(v[i], 200.0f + 0.5f * (8 + i));
  EXPECT_EQ(d.read(0, "pressure", 2)[3], -11.0f);
  EXPECT_THROW(d.read(0, "density", 0), InputError);
  EXPECT_THROW(d.mesh(3), InputError);
}

TEST(TfRecord, Float64Int64AndTheDtypeSpellingOfOnePublishedMeta) {
  std::vector<double> pos = {0, 0, 1, 0, 1, 1, 0, 1};
  std::vector<int64_t> cells = {0, 1, 2, 0, 2, 3};
  std::vector<double> vel(kT * kN * 2);
  for (size_t i = 0; i < vel.size(); ++i) vel[i] = 0.25 * static_cast<double>(i);
  auto f = fields(0);
  for (auto& [name, bytes] : f) {
    if (name == "mesh_pos") bytes = raw(pos);
    if (name == "cells") bytes = raw(cells);
    if (name == "velocity") bytes = raw(vel);
  }
  const fs::path dir =
      make_folder("dtypes", meta_json("float64", "int64", "<dtype: 'float64'>"), {example(f)});
  const Dataset d = Dataset::open_split(dir.string(), "train");
  EXPECT_EQ(d.mesh(0).cells, (std::vector<int32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(d.mesh(0).mesh_pos, (std::vector<float>{0, 0, 1, 0, 1, 1, 0, 1}));
  const auto v = d.read(0, "velocity", 0, kT);
  for (size_t i = 0; i < v.size(); ++i) EXPECT_EQ(v[i], 0.25f * i);
  // "<dtype: 'float32'>" as well.
  const fs::path dir32 =
      make_folder("dtype_spelling", meta_json("<dtype: 'float32'>"), good_records(1));
  EXPECT_EQ(Dataset::open_split(dir32.string(), "train").mesh(0).mesh_pos[2], 1.0f);
}

TEST(TfRecord, UnknownFeaturesAndFieldOrderDoNotMatter) {
  auto f = fields(0);
  std::reverse(f.begin(), f.end());
  f.insert(f.begin() + 2, {"extra", "ignored"});
  const fs::path dir = make_folder("order", meta_json(), {example(f)});
  EXPECT_EQ(Dataset::open_split(dir.string(), "train").mesh(0).num_nodes(), kN);
}

// Expects an InputError from `f` whose message contains every one of `parts`.
template <class F>
void expect_error(F&& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& p : parts)
      EXPECT_NE(msg.find(p), std::string::npos) << msg << "\nlacks: " << p;
  }
}

// Opens the split and touches every record (mesh and every field).
void open_all(const fs::path& dir) {
  const Dataset d = Dataset::open_split(dir.string(), "train");
  for (int64_t t = 0; t < d.num_trajectories(); ++t) {
    d.mesh(t);
    for (const auto& f : d.fields()) d.read(t, f.name, 0, d.num_frames(t));
  }
}

TEST(TfRecord, OpeningAndMeshesReadHeadersOnly) {
  // A data CRC error in record 1 stops neither the split from opening nor its mesh from being
  // read (the mesh needs only the record's wire); the first read of a dynamic field finds it.
  auto records = good_records();
  const fs::path dir = make_folder("lazy", meta_json(), records);
  std::string file = test::read_file((dir / "train.tfrecord").string());
  file[16 + records[0].size() + 12 + records[1].size() - 2] ^= 1;  // last field's bytes, record 1
  test::write_file((dir / "train.tfrecord").string(), file);
  const Dataset d = Dataset::open_split(dir.string(), "train");
  EXPECT_EQ(d.num_trajectories(), 3);
  for (int64_t t = 0; t < 3; ++t) EXPECT_EQ(d.mesh(t).num_nodes(), kN);
  EXPECT_EQ(d.num_frames(1), kT);
  EXPECT_NO_THROW(d.read(0, "velocity", 0, 1));
  EXPECT_NO_THROW(d.read(2, "velocity", 0, 1));
  expect_error([&] { d.read(1, "velocity", 0, 1); }, {"train.tfrecord", "record 1", "data CRC"});
}

TEST(TfRecordCorrupt, TruncatedData) {
  const fs::path dir = make_folder("trunc_data", meta_json(), good_records());
  std::string file = test::read_file((dir / "train.tfrecord").string());
  file.resize(file.size() - 10);
  test::write_file((dir / "train.tfrecord").string(), file);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 2", "truncated data"});
}

TEST(TfRecordCorrupt, TruncatedHeader) {
  const fs::path dir = make_folder("trunc_header", meta_json(), good_records());
  std::string file = test::read_file((dir / "train.tfrecord").string());
  file += std::string(5, '\0');
  test::write_file((dir / "train.tfrecord").string(), file);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 3", "truncated header"});
}

TEST(TfRecordCorrupt, LengthCrcMismatch) {
  const auto records = good_records();
  const fs::path dir = make_folder("length_crc", meta_json(), records);
  std::string file = test::read_file((dir / "train.tfrecord").string());
  file[16 + records[0].size() + 9] ^= 0x10;  // the length CRC of record 1
  test::write_file((dir / "train.tfrecord").string(), file);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "length CRC"});
}

TEST(TfRecordCorrupt, DataCrcMismatch) {
  const auto records = good_records();
  const fs::path dir = make_folder("data_crc", meta_json(), records);
  std::string file = test::read_file((dir / "train.tfrecord").string());
  file[16 + records[0].size() + 16 + records[1].size() - 2] ^= 0x01;  // CRC of record 1
  test::write_file((dir / "train.tfrecord").string(), file);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "data CRC"});
}

TEST(TfRecordCorrupt, WrongDtype) {
  // meta says float32, the bytes are float64: twice the size, so N no longer agrees.
  auto records = good_records();
  auto f = fields(1);
  f[3].second = raw(std::vector<double>(kT * kN * 2, 1.0));
  records[1] = example(f);
  const fs::path dir = make_folder("wrong_dtype", meta_json(), records);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "'velocity'", "N=8"});
}

TEST(TfRecordCorrupt, ShapeDoesNotDivide) {
  auto records = good_records();
  auto f = fields(1);
  f[3].second = raw(std::vector<float>(kT * kN * 2 + 2, 1.0f));  // 26 floats into [3,-1,2]
  records[1] = example(f);
  const fs::path dir = make_folder("not_divide", meta_json(), records);
  expect_error([&] { open_all(dir); },
               {"train.tfrecord: record 1: field 'velocity': 104 bytes do not divide into "
                "float32 frames of shape [3,-1,2]"});
  f[3].second = std::string(4 * kT * kN * 2 + 3, '\0');  // not a whole number of float32
  records[1] = example(f);
  const fs::path odd = make_folder("odd_bytes", meta_json(), records);
  expect_error([&] { open_all(odd); }, {"record 1", "'velocity'", "do not divide"});
}

TEST(TfRecordCorrupt, MissingField) {
  auto records = good_records();
  records[1] = example(fields(1, "pressure"));
  const fs::path dir = make_folder("missing", meta_json(), records);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "'pressure'", "missing"});
}

TEST(TfRecordCorrupt, MalformedWire) {
  auto records = good_records();
  for (const std::string& bad : {std::string("\x0a\xff\xff\xff\xff\x0f", 6),  // length too big
                                 std::string("\x0a\x05\x0a\x03\x0a", 5),      // nested overrun
                                 std::string("\x0b\x01", 2),  // start group, never ends
                                 std::string("\x0a\x80", 2)}) {
    records[1] = bad;
    const fs::path dir = make_folder("wire", meta_json(), records);
    expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "malformed protobuf"});
  }
  // A field sent as a float_list instead of raw bytes.
  std::string features;
  for (const auto& [name, bytes] : fields(1))
    features += test::ld(1, test::ld(1, name) + test::ld(2, test::ld(name == "pressure" ? 2 : 1,
                                                                     test::ld(1, bytes))));
  records[1] = test::ld(1, features);
  const fs::path dir = make_folder("float_list", meta_json(), records);
  expect_error([&] { open_all(dir); }, {"record 1", "'pressure'", "float_list"});
}

TEST(TfRecordCorrupt, CellsOutOfRangeAndNonFinitePositions) {
  auto records = good_records();
  auto f = fields(1);
  f[0].second = raw(std::vector<int32_t>{0, 1, 2, 0, 2, 4});
  records[1] = example(f);
  const fs::path dir = make_folder("cells", meta_json(), records);
  expect_error([&] { open_all(dir); }, {"train.tfrecord", "record 1", "'cells'", "index 4"});
  f = fields(2);
  f[1].second = raw(std::vector<float>{0, 0, 1, NAN, 1, 1, 0, 1});
  records = good_records();
  records[2] = example(f);
  const fs::path nan = make_folder("nan", meta_json(), records);
  expect_error([&] { open_all(nan); }, {"train.tfrecord", "record 2", "'mesh_pos'", "non-finite"});
}

TEST(TfRecordCorrupt, Meta) {
  const std::string good = meta_json();
  struct Case {
    std::string meta, expect;
  };
  std::string no_features = good;
  no_features.replace(no_features.find("\"features\""), 10, "\"featurez\"");
  for (const Case& c :
       {Case{"{\"dt\": ", "malformed JSON"}, Case{"[]", "JSON object"},
        Case{no_features, "missing key 'features'"},
        Case{meta_json("float16"), "unknown dtype 'float16'"},
        Case{meta_json("float32", "int32", "float32", "sometimes"), "unknown type 'sometimes'"}}) {
    const fs::path dir = make_folder("meta", c.meta, good_records(1));
    expect_error([&] { open_all(dir); }, {"meta.json", c.expect});
  }
  const fs::path dir = make_folder("no_meta", good, good_records(1));
  fs::remove(dir / "meta.json");
  EXPECT_FALSE(Dataset::has_split(dir.string(), "train"));
  expect_error([&] { Dataset((dir / "train.tfrecord").string()); }, {"meta.json"});
}

TEST(TfRecord, VarlenDecodedByTheReaderButRejectedByDataset) {
  // A remeshing-style field: cells vary per frame, row lengths in length_cells.
  const std::string meta = R"({"dt": 0.02, "trajectory_length": 2,
    "field_names": ["cells", "mesh_pos", "node_type", "world_pos"],
    "features": {
      "cells": {"type": "dynamic_varlen", "shape": [2, -1, 3], "dtype": "int32"},
      "mesh_pos": {"type": "static", "shape": [1, -1, 2], "dtype": "float32"},
      "node_type": {"type": "static", "shape": [1, -1, 1], "dtype": "int32"},
      "world_pos": {"type": "dynamic", "shape": [2, -1, 3], "dtype": "float32"}}})";
  const std::vector<int32_t> cells = {0, 1, 2, 0, 1, 2, 0, 2, 3};  // 1 cell, then 2
  const std::vector<std::pair<std::string, std::string>> f = {
      {"cells", raw(cells)},
      {"length_cells", raw(std::vector<int32_t>{1, 2})},
      {"mesh_pos", raw(std::vector<float>(8, 0.5f))},
      {"node_type", raw(std::vector<int32_t>(4, 0))},
      {"world_pos", raw(std::vector<float>(2 * 4 * 3, 1.0f))}};
  const fs::path dir = make_folder("varlen", meta, {example(f)});
  const tfrecord::TfRecordReader reader((dir / "train.tfrecord").string(),
                                        tfrecord::read_meta((dir / "meta.json").string()));
  const auto decoded = reader.decode(0);
  EXPECT_EQ(decoded.at("cells").row_lengths, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(decoded.at("cells").ints, std::vector<int64_t>(cells.begin(), cells.end()));
  expect_error([&] { open_all(dir); },
               {"meta.json", "'cells'", "dynamic_varlen", "remeshing datasets"});
  // Row lengths that do not add up are caught by the reader.
  auto bad = f;
  bad[1].second = raw(std::vector<int32_t>{1, 1});
  const fs::path dir2 = make_folder("varlen_bad", meta, {example(bad)});
  const tfrecord::TfRecordReader reader2((dir2 / "train.tfrecord").string(),
                                         tfrecord::read_meta((dir2 / "meta.json").string()));
  expect_error([&] { reader2.decode(0); }, {"record 0", "'cells'", "row lengths"});
}

TEST(TfRecord, FromBytesMatchesTheFile) {
  const auto records = good_records();
  std::string file;
  for (const auto& r : records) file += frame_record(r);
  const tfrecord::TfRecordReader reader = tfrecord::TfRecordReader::from_bytes(
      file, "memory.tfrecord", tfrecord::parse_meta(meta_json(), "meta.json"));
  ASSERT_EQ(reader.num_records(), 3);
  EXPECT_EQ(reader.read_float(1, "pressure", 0, 1)[1], -2.0f);
  EXPECT_EQ(reader.read_mesh(2).node_type, (std::vector<int32_t>{0, 6, 4, 5}));
}

// ---- the other public layouts ----

TEST(PublicSingleFile, OneGroupPerTrajectory) {
  const fs::path dir = temp_dir("single_file");
  {
    H5File f((dir / "valid.h5").string(), H5File::Mode::kTruncate);
    for (int g : {0, 1, 2, 10}) {
      const std::string p = "/" + std::to_string(g) + "/";
      const int frames = 2 + g % 3;
      std::vector<float> pos = {0, 0, 1, 0, 1, 1, 0, 1}, vel(frames * 4 * 2);
      for (size_t i = 0; i < vel.size(); ++i) vel[i] = static_cast<float>(g * 100 + i);
      // Static fields with a leading time axis in one group, without in the others.
      if (g == 1) {
        std::vector<float> pos_t;
        for (int t = 0; t < frames; ++t) pos_t.insert(pos_t.end(), pos.begin(), pos.end());
        f.write(p + "mesh_pos", pos_t, {static_cast<hsize_t>(frames), 4, 2});
      } else {
        f.write(p + "mesh_pos", pos, {4, 2});
      }
      f.write(p + "cells", std::vector<int32_t>{0, 1, 2, 0, 2, 3}, {2, 3});
      f.write(p + "node_type", std::vector<int32_t>{0, 4, 5, 6}, {4, 1});
      f.write(p + "velocity", vel, {static_cast<hsize_t>(frames), 4, 2});
      f.write(p + "pressure", std::vector<float>(frames * 4, 1.0f),
              {static_cast<hsize_t>(frames), 4, 1});
    }
  }
  const Dataset d = Dataset::open_split(dir.string(), "valid");
  EXPECT_EQ(d.layout(), DatasetLayout::kPublicSingleFile);
  EXPECT_TRUE(d.is_public_layout());
  EXPECT_EQ(d.dim(), 2);
  ASSERT_EQ(d.num_trajectories(), 4);
  EXPECT_EQ(d.num_frames(3), 2 + 10 % 3);  // "10" sorts after "2"
  EXPECT_EQ(d.read(3, "velocity", 1)[0], 1008.0f);
  EXPECT_EQ(d.mesh(1).mesh_pos, (std::vector<float>{0, 0, 1, 0, 1, 1, 0, 1}));
  EXPECT_EQ(d.mesh(2).node_type, (std::vector<int32_t>{0, 4, 5, 6}));
  EXPECT_EQ(d.seed(0), 0);
  ASSERT_EQ(d.fields().size(), 2u);
}

TEST(PublicSingleFile, PlainHdf5WithoutTrajectoriesIsStillRejected) {
  const fs::path dir = temp_dir("single_file_bad");
  {
    H5File f((dir / "train.h5").string(), H5File::Mode::kTruncate);
    f.write("/a/b", std::vector<float>{1, 2}, {2});
  }
  expect_error([&] { Dataset::open_split(dir.string(), "train"); },
               {"train.h5", "not a bsms dataset"});
}

TEST(LegacyOutputs, RejectedWithTheConversionToRun) {
  const fs::path dir = temp_dir("legacy");
  fs::create_directories(dir / "outputs_train");
  test::write_file((dir / "outputs_train" / "meta.json").string(), R"({"normalization_info": {}})");
  EXPECT_TRUE(Dataset::has_split(dir.string(), "train"));
  EXPECT_FALSE(Dataset::has_split(dir.string(), "test"));
  expect_error([&] { Dataset::open_split(dir.string(), "train"); },
               {"outputs_train", "train.tfrecord", "train/{i}.h5"});
  expect_error([&] { Dataset((dir / "outputs_train").string()); },
               {"outputs_train", "train.tfrecord"});
}

TEST(MeshGraphNetsFolder, OpeningTheFolderItselfNamesASplit) {
  const fs::path dir = make_folder("folder", meta_json(), good_records(1));
  expect_error([&] { Dataset d(dir.string()); }, {"MeshGraphNets folder", "train.tfrecord"});
}

}  // namespace
}  // namespace bsms
