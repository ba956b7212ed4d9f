#include "preprocess/multilevel_file.hpp"

#include <gmsh.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"
#include "core/hdf5_file.hpp"
#include "test_graphs.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() { path_ = bsms::testing::unique_temp_dir("preprocess_test"); }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::vector<std::string> entries() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(path_)) out.push_back(e.path().filename());
    return out;
  }

 private:
  fs::path path_;
};

MultilevelGraph sample_graph(Seeding seeding = Seeding::kMinAve) {
  std::mt19937_64 rng(1);
  const auto g = test::grid_triangles(9, 7, 0.1, 0.3, rng);
  BuildOptions options;
  options.seeding = seeding;
  options.num_levels = 4;
  return build_multilevel_graph(g.graph, g.positions, options);
}

TEST(MultilevelFile, RoundTrip) {
  TempDir dir;
  const MultilevelGraph ml = sample_graph();
  const std::string path = dir.file("ml.h5");
  write_multilevel_graph(ml, path);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"ml.h5"});  // no temporary left
  const MultilevelGraph back = read_multilevel_graph(path);
  EXPECT_EQ(back.seeding, Seeding::kMinAve);
  ASSERT_EQ(back.num_levels(), ml.num_levels());
  for (int k = 0; k < ml.num_levels(); ++k) {
    EXPECT_EQ(back.levels[k].graph.num_nodes, ml.levels[k].graph.num_nodes);
    EXPECT_EQ(back.levels[k].graph.offsets, ml.levels[k].graph.offsets);
    EXPECT_EQ(back.levels[k].graph.targets, ml.levels[k].graph.targets);
    EXPECT_EQ(back.levels[k].pooled, ml.levels[k].pooled);
    EXPECT_EQ(back.levels[k].down_weight, ml.levels[k].down_weight);
  }
  EXPECT_FALSE(back.thinned);
}

TEST(MultilevelFile, ThinnedFlagRoundTrips) {
  TempDir dir;
  std::mt19937_64 rng(1);
  const auto g = test::grid_triangles(30, 30, 0.0, 0.3, rng);
  const MultilevelGraph ml = build_multilevel_graph(g.graph, g.positions, BuildOptions{});
  ASSERT_TRUE(ml.thinned);
  write_multilevel_graph(ml, dir.file("thin.h5"));
  const MultilevelGraph back = read_multilevel_graph(dir.file("thin.h5"));
  EXPECT_TRUE(back.thinned);
  ASSERT_EQ(back.num_levels(), ml.num_levels());
  EXPECT_EQ(back.levels.back().graph.targets, ml.levels.back().graph.targets);
  H5File file(dir.file("thin.h5"), H5File::Mode::kRead);
  EXPECT_EQ(file.attr_string("/", "coarse_edges"), "thinned");
}

TEST(MultilevelFile, LayoutFollowsDesign) {
  TempDir dir;
  const MultilevelGraph ml = sample_graph(Seeding::kRandom);
  const std::string path = dir.file("ml.h5");
  write_multilevel_graph(ml, path);
  H5File file(path, H5File::Mode::kRead);
  EXPECT_EQ(file.attr_string("/", "format"), "bsms-multilevel");
  EXPECT_EQ(file.attr_int("/", "version"), 1);
  EXPECT_EQ(file.attr_string("/", "seeding"), "random");
  EXPECT_EQ(file.attr_int("/", "num_levels"), 4);
  EXPECT_FALSE(file.exists("/level_0/pooled"));
  EXPECT_FALSE(file.exists("/level_0/down_weight"));
  for (int k = 0; k < 4; ++k) {
    const std::string g = "/level_" + std::to_string(k);
    EXPECT_EQ(file.attr_int(g, "num_nodes"), ml.levels[k].num_nodes());
    Shape shape;
    const auto edges = file.read<int64_t>(g + "/edges", &shape);
    EXPECT_EQ(shape, (Shape{static_cast<hsize_t>(ml.levels[k].graph.num_edges()), 2}));
    EXPECT_EQ(edges, ml.levels[k].graph.edges().data);
    if (k > 0) {
      EXPECT_EQ(file.shape(g + "/pooled"), Shape{static_cast<hsize_t>(ml.levels[k].num_nodes())});
      EXPECT_EQ(file.shape(g + "/down_weight"),
                Shape{static_cast<hsize_t>(ml.levels[k - 1].graph.num_edges())});
    }
    // Stored types are exactly int64 / float32.
    const hid_t set = H5Dopen2(file.id(), (g + "/edges").c_str(), H5P_DEFAULT);
    const hid_t type = H5Dget_type(set);
    EXPECT_TRUE(H5Tequal(type, H5T_STD_I64LE) > 0);
    H5Tclose(type);
    H5Dclose(set);
    if (k > 0) {
      const hid_t wset = H5Dopen2(file.id(), (g + "/down_weight").c_str(), H5P_DEFAULT);
      const hid_t wtype = H5Dget_type(wset);
      EXPECT_TRUE(H5Tequal(wtype, H5T_IEEE_F32LE) > 0);
      H5Tclose(wtype);
      H5Dclose(wset);
    }
  }
}

// Writes a valid file, applies `damage`, expects InputError mentioning `expected` and the file.
void expect_rejected(const std::function<void(H5File&)>& damage, const std::string& expected) {
  TempDir dir;
  const std::string path = dir.file("bad.h5");
  write_multilevel_graph(sample_graph(), path);
  {
    H5File file(path, H5File::Mode::kReadWrite);
    damage(file);
  }
  try {
    read_multilevel_graph(path);
    ADD_FAILURE() << "accepted a damaged file (" << expected << ")";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find(expected), std::string::npos) << what;
  }
}

TEST(MultilevelFile, ReaderRejectsDamagedFiles) {
  expect_rejected([](H5File& f) { f.set_attr("/", "format", std::string("other")); }, "format");
  expect_rejected([](H5File& f) { f.set_attr("/", "version", int64_t{2}); }, "version");
  expect_rejected([](H5File& f) { f.set_attr("/", "seeding", std::string("best")); }, "seeding");
  expect_rejected([](H5File& f) { f.set_attr("/", "coarse_edges", std::string("some")); },
                  "coarse_edges");
  expect_rejected([](H5File& f) { f.set_attr("/", "num_levels", int64_t{5}); }, "level_4");
  expect_rejected([](H5File& f) { f.remove("/level_2/pooled"); }, "/level_2/pooled");
  expect_rejected([](H5File& f) { f.remove("/level_1/edges"); }, "/level_1/edges");
  expect_rejected(
      [](H5File& f) { f.write<float>("/level_1/down_weight", std::vector<float>(3, 0.5f), {3}); },
      "/level_1/down_weight");
  expect_rejected(
      [](H5File& f) {
        auto e = f.read<int64_t>("/level_0/edges");
        std::swap(e[1], e[3]);  // the first two receivers: unsorted
        f.write<int64_t>("/level_0/edges", e, {e.size() / 2, 2});
      },
      "/level_0/edges");
  expect_rejected(
      [](H5File& f) {
        auto e = f.read<int64_t>("/level_1/edges");
        e.resize(e.size() - 2);  // drop the last edge: its reverse is left alone
        f.write<int64_t>("/level_1/edges", e, {e.size() / 2, 2});
      },
      "reverse");
  expect_rejected(
      [](H5File& f) {
        auto p = f.read<int64_t>("/level_1/pooled");
        p.back() = 100000;
        f.write<int64_t>("/level_1/pooled", p, {p.size()});
      },
      "/level_1/pooled");
  expect_rejected(
      [](H5File& f) {
        auto e = f.read<int64_t>("/level_0/edges");
        f.write<int64_t>("/level_0/edges", e, {e.size()});  // rank 1
      },
      "/level_0/edges");
}

TEST(MultilevelFile, MissingOrForeignFiles) {
  TempDir dir;
  EXPECT_THROW(read_multilevel_graph(dir.file("none.h5")), InputError);
  {
    H5File f(dir.file("other.h5"), H5File::Mode::kTruncate);
    f.set_attr("/", "format", std::string("bsms-frames"));
  }
  EXPECT_THROW(read_multilevel_graph(dir.file("other.h5")), InputError);
}

TEST(MultilevelFile, UnwritableOutputLeavesNothing) {
  TempDir dir;
  { std::ofstream(dir.file("plain")) << "a file, not a folder"; }
  EXPECT_THROW(write_multilevel_graph(sample_graph(), dir.file("plain/x.h5")), InputError);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"plain"});
}

// The same geometry written by gmsh as .msh 2.2 and 4.1 gives the same multilevel graph.
TEST(MeshFormats, Msh22And41GiveTheSameGraph) {
  TempDir dir;
  {
    GmshSession session;
    gmsh::model::add("plate");
    const int plate = gmsh::model::occ::addRectangle(0, 0, 0, 2, 1);
    const int hole = gmsh::model::occ::addDisk(0.7, 0.5, 0, 0.2, 0.2);
    std::vector<std::pair<int, int>> out;
    std::vector<std::vector<std::pair<int, int>>> map;
    gmsh::model::occ::cut({{2, plate}}, {{2, hole}}, out, map);
    gmsh::model::occ::synchronize();
    gmsh::option::setNumber("Mesh.CharacteristicLengthMax", 0.08);
    gmsh::model::mesh::generate(2);
    gmsh::option::setNumber("Mesh.MshFileVersion", 2.2);
    gmsh::write(dir.file("plate22.msh"));
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::write(dir.file("plate41.msh"));
  }
  const Mesh a = read_mesh(dir.file("plate22.msh"));
  const Mesh b = read_mesh(dir.file("plate41.msh"));
  ASSERT_GT(a.num_nodes(), 100);
  ASSERT_EQ(a.num_nodes(), b.num_nodes());
  EXPECT_TRUE(a.points.isApprox(b.points, 1e-12));
  for (Seeding seeding : {Seeding::kCloseCenter, Seeding::kMinAve}) {
    BuildOptions options;
    options.seeding = seeding;
    const MultilevelGraph ma = build_multilevel_graph(a, options);
    const MultilevelGraph mb = build_multilevel_graph(b, options);
    ASSERT_EQ(ma.num_levels(), mb.num_levels());
    EXPECT_GE(ma.num_levels(), 3);
    for (int k = 0; k < ma.num_levels(); ++k) {
      EXPECT_EQ(ma.levels[k].graph.targets, mb.levels[k].graph.targets);
      EXPECT_EQ(ma.levels[k].pooled, mb.levels[k].pooled);
      EXPECT_EQ(ma.levels[k].down_weight, mb.levels[k].down_weight);
    }
  }
}

// Fuzzing regression (fuzz/fuzz_multilevel.cpp): an array attribute where the reader expects
// one value (num_levels of two int64) was read into a single int64 (stack-buffer-overflow).
TEST(MultilevelFile, FuzzArrayAttributeIsAnInputError) {
  expect_rejected(
      [](H5File& f) {
        H5Adelete_by_name(f.id(), "/", "num_levels", H5P_DEFAULT);
        const hsize_t two = 2;
        const int64_t values[2] = {3, 3};
        const hid_t space = H5Screate_simple(1, &two, nullptr);
        const hid_t attr =
            H5Acreate2(f.id(), "num_levels", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
        H5Awrite(attr, H5T_NATIVE_INT64, values);
        H5Aclose(attr);
        H5Sclose(space);
      },
      "num_levels");
}

// Fuzzing regression (fuzz/fuzz_multilevel.cpp): num_nodes sized the CSR arrays before any check,
// so a huge value threw std::length_error or exhausted memory instead of an InputError.
TEST(MultilevelFile, FuzzHugeNumNodesIsAnInputError) {
  expect_rejected([](H5File& f) { f.set_attr("/level_0", "num_nodes", int64_t{1} << 40); },
                  "/level_0@num_nodes");
  expect_rejected(
      [](H5File& f) { f.set_attr("/level_0", "num_nodes", int64_t{9223372024274241681}); },
      "/level_0@num_nodes");
  expect_rejected([](H5File& f) { f.set_attr("/level_1", "num_nodes", int64_t{1} << 40); },
                  "/level_1/pooled");
}

// Found by fuzz_multilevel: a 0 in the reader's expected shape accepts any length, so a level
// without edges let a down_weight (or pooled) array of any length through.
TEST(MultilevelFile, FuzzLengthsAreCheckedWhenALevelHasNoEdges) {
  auto write = [](const std::string& path, int64_t coarse_nodes, std::vector<int64_t> pooled,
                  std::vector<float> weights) {
    H5File f(path, H5File::Mode::kTruncate);
    f.set_attr("/", "format", std::string("bsms-multilevel"));
    f.set_attr("/", "version", int64_t{1});
    f.set_attr("/", "seeding", std::string("minave"));
    f.set_attr("/", "num_levels", int64_t{2});
    f.create_group("/level_0");
    f.set_attr("/level_0", "num_nodes", int64_t{3});
    f.write("/level_0/edges", std::vector<int64_t>{}, {0, 2});
    f.create_group("/level_1");
    f.set_attr("/level_1", "num_nodes", coarse_nodes);
    f.write("/level_1/edges", std::vector<int64_t>{}, {0, 2});
    f.write("/level_1/pooled", pooled, {static_cast<hsize_t>(pooled.size())});
    f.write("/level_1/down_weight", weights, {static_cast<hsize_t>(weights.size())});
  };
  TempDir dir;
  const std::string good = dir.file("good.h5"), weights = dir.file("weights.h5"),
                    pooled = dir.file("pooled.h5");
  write(good, 1, {0}, {});
  EXPECT_EQ(read_multilevel_graph(good).levels[1].num_nodes(), 1);
  write(weights, 1, {0}, {1.0f, 1.0f, 1.0f});
  write(pooled, 0, {0}, {});
  for (const auto& [path, key] : {std::pair{weights, std::string("/level_1/down_weight has 3")},
                                  std::pair{pooled, std::string("/level_1/pooled has 1")}}) {
    try {
      read_multilevel_graph(path);
      ADD_FAILURE() << "accepted " << key;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace bsms
