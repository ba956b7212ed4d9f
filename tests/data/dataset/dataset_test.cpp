#include "data/dataset/dataset.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/xdmf.hpp"
#include "data/mpm/scene_config.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  return bsms::testing::unique_temp_dir("dataset_" + name);
}

// A scene as `bsms generate` stores it: its family file, whose "scene" is the base scene.
const char* const kFamilyScene = R"({"family": "disks", "scene": {"dim": 2,
    "background": {"type": "box", "min": [0, 0], "max": [1, 1], "element_size": 0.04},
    "solver": {"end_time": 1.0}}, "sample": {}})";

Trajectory make_trajectory(int64_t seed, int64_t frames) {
  Trajectory t;
  t.mesh.dim = 2;
  t.mesh.cell_size = 3;
  t.mesh.cells = {0, 1, 2, 0, 2, 3};
  t.mesh.mesh_pos = {0, 0, 1, 0, 1, 1, 0, 1};
  t.mesh.node_type = {0, 1, 0, 2};
  t.mesh.body_id = {0, 0, 1, 1};
  t.seed = seed;
  t.parameters = R"({"radius": 0.5})";
  t.num_frames = frames;
  t.solver_wall_s = seed == 7 ? 1.5 : -1.0;
  std::vector<float> pos(frames * 4 * 2), vel(frames * 4 * 2), stress(frames * 4);
  for (size_t i = 0; i < pos.size(); ++i) pos[i] = static_cast<float>(seed * 1000 + i);
  for (size_t i = 0; i < vel.size(); ++i) vel[i] = -static_cast<float>(i);
  for (size_t i = 0; i < stress.size(); ++i) stress[i] = 0.5f * static_cast<float>(i);
  t.fields = {{"world_pos", pos}, {"velocity", vel}, {"stress", stress}};
  return t;
}

TEST(Dataset, WriteThenRandomAccessRead) {
  const fs::path dir = temp_dir("roundtrip");
  {
    DatasetWriter w((dir / "train.h5").string(), kFamilyScene, 2, 0.01);
    w.add(make_trajectory(7, 5));
    w.add(make_trajectory(8, 3));
    w.commit();
  }
  const Dataset d = Dataset::open_split(dir.string(), "train");
  EXPECT_FALSE(d.is_public_layout());
  EXPECT_EQ(d.dim(), 2);
  EXPECT_DOUBLE_EQ(d.frame_dt(), 0.01);
  EXPECT_EQ(d.scene(), kFamilyScene);
  ASSERT_EQ(d.num_trajectories(), 2);
  EXPECT_EQ(d.num_frames(0), 5);
  EXPECT_EQ(d.num_frames(1), 3);
  EXPECT_EQ(d.seed(1), 8);
  EXPECT_DOUBLE_EQ(d.solver_wall_s(0), 1.5);
  EXPECT_LT(d.solver_wall_s(1), 0.0);
  EXPECT_EQ(d.parameters(0), R"({"radius": 0.5})");
  EXPECT_TRUE(d.has_field("stress"));
  const auto& m = d.mesh(1);
  EXPECT_EQ(m.num_nodes(), 4);
  EXPECT_EQ(m.num_cells(), 2);
  EXPECT_EQ(m.node_type, (std::vector<int32_t>{0, 1, 0, 2}));
  EXPECT_EQ(m.body_id, (std::vector<int32_t>{0, 0, 1, 1}));
  // Frame 2 of trajectory 1: flat offset 2 * 4 * 2 = 16.
  const auto pos = d.read(1, "world_pos", 2);
  ASSERT_EQ(pos.size(), 8u);
  EXPECT_EQ(pos[0], 8016.0f);
  EXPECT_EQ(pos[7], 8023.0f);
  const auto stress = d.read(0, "stress", 1, 2);
  ASSERT_EQ(stress.size(), 8u);
  EXPECT_EQ(stress[0], 2.0f);
  EXPECT_THROW(d.read(1, "world_pos", 3), InputError);
  EXPECT_THROW(d.read(2, "world_pos", 0), InputError);
  EXPECT_THROW(d.read(0, "pressure", 0), InputError);
}

TEST(Dataset, WriterRejectsNaNAndLeavesNoFile) {
  const fs::path dir = temp_dir("nan");
  const std::string path = (dir / "train.h5").string();
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    Trajectory t = make_trajectory(1, 2);
    t.fields["velocity"][3] = std::nanf("");
    EXPECT_THROW(w.add(t), InputError);
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::is_empty(dir));
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

// The stored scene is read strictly when the dataset opens: a family file gives its base scene
// (the parser's defaults filled in), "{}" none, and a bad value is an InputError naming the file
// and the key, never a dataset without a scene.
TEST(Dataset, StoredSceneIsTypedWhenOpenedAndABadOneNamesItsKey) {
  const fs::path dir = temp_dir("scene");
  const std::string path = (dir / "train.h5").string();
  auto write = [&](const std::string& scene) {
    DatasetWriter w(path, scene, 2, 0.01);
    w.add(make_trajectory(1, 2));
    w.commit();
  };
  write(kFamilyScene);
  {
    const Dataset d(path);
    ASSERT_TRUE(d.parsed_scene().has_value());
    EXPECT_EQ(d.parsed_scene()->background.type, "box");
    EXPECT_EQ(d.parsed_scene()->background.max, (std::vector<double>{1.0, 1.0}));
    EXPECT_EQ(d.parsed_scene()->background.element_size, 0.04);
    EXPECT_TRUE(d.parsed_scene()->bodies.empty());                          // the draws bring them
    EXPECT_EQ(d.parsed_scene()->gravity, (std::vector<double>{0.0, 0.0}));  // the default
  }
  write("{}");
  EXPECT_FALSE(Dataset(path).parsed_scene().has_value());
  const std::string box = R"("dim": 2, "solver": {"end_time": 1.0}, "background": {"type": "box",
      "min": [0, 0], "max": [1, 1], )";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {R"({"scene": {)" + box + R"("element_size": -0.04}}})", "'scene.background.element_size'"},
      {R"({"scene": {)" + box + R"("element_size": "fine"}}})", "'scene.background.element_size'"},
      {R"({"scene": {)" + box + R"("element_size": 0.04, "colour": "red"}}})",
       "'scene.background.colour'"},
      {R"({"scene": {"dim": 2, "solver": {"end_time": 1.0}, "background": {"type": "grid"}}})",
       "'scene.background.type'"},
      {R"({"scene": {"dim": 3, "solver": {"end_time": 1.0}, "background": {"type": "box",
          "min": [0, 0, 0], "max": [1, 1, 1], "element_size": 0.04}}})",
       "'scene.dim'"},  // a 3-D scene in 2-D data
      // Not a family file: read as a scene file, which has a dim.
      {R"({"name": "disks2d"})", "'dim'"},
      {"[1, 2]", "attribute 'scene'"},
      {"{\"scene\": ", "attribute 'scene'"}};
  for (const auto& [scene, key] : bad) {
    SCOPED_TRACE(scene);
    write(scene);
    const std::string e = error_of([&] { Dataset d(path); });
    EXPECT_NE(e.find(path), std::string::npos) << e;
    EXPECT_NE(e.find(key), std::string::npos) << e;
  }
}

// Sets one value of a dataset in a written file, as damage (or a bad converter) would.
template <class T>
void set_value(const std::string& path, const std::string& name, size_t index, T value) {
  H5File f(path, H5File::Mode::kReadWrite);
  Shape shape;
  std::vector<T> values = f.read<T>(name, &shape);
  values[index] = value;
  f.write(name, values, shape, shape.size() >= 2 ? 1 : 0);
  f.close();
}

// Every value read is checked where it is read: non-finite or beyond the documented bound, named
// by file, trajectory, field, frame, node and component, in any field of the trajectory (the first
// read of a trajectory checks them all) and in the mesh.
TEST(Dataset, ReadChecksValuesAndNamesFileTrajectoryFieldFrameNode) {
  const fs::path dir = temp_dir("values");
  const std::string path = (dir / "train.h5").string();
  auto write = [&] {
    // A scene: simulated data, whose node types are bsms's 0..3.
    DatasetWriter w(path, kFamilyScene, 2, 0.01);
    w.add(make_trajectory(1, 4));
    w.add(make_trajectory(2, 4));
    w.commit();
  };
  // velocity [T=4, N=4, 2] of trajectory 1: frame 2, node 3, component 1.
  write();
  set_value<float>(path, "/trajectories/000001/velocity", 2 * 8 + 3 * 2 + 1,
                   std::numeric_limits<float>::infinity());
  {
    const Dataset d(path);
    EXPECT_EQ(d.read(0, "world_pos", 0).size(), 8u);  // trajectory 0 is intact
    const std::string e = error_of([&] { d.read(1, "world_pos", 0); });
    EXPECT_NE(e.find("train.h5: trajectory 1, field 'velocity' frame 2 node 3 component 1: inf"),
              std::string::npos)
        << e;
  }
  write();
  set_value<float>(path, "/trajectories/000000/world_pos", 5, 3e38f);
  EXPECT_NE(error_of([&] { Dataset(path).read(0, "world_pos", 3); })
                .find("field 'world_pos' frame 0 node 2 component 1: 3e+38, expected a finite "
                      "value within ±1e+06"),
            std::string::npos);
  write();
  set_value<float>(path, "/trajectories/000000/stress", 6, std::nanf(""));
  EXPECT_NE(error_of([&] {
              Dataset(path).read(0, "world_pos", 0);
            }).find("field 'stress' frame 1 node 2: nan"),
            std::string::npos);
  // Stress may be large (Pa), positions may not.
  write();
  set_value<float>(path, "/trajectories/000000/stress", 6, 1e12f);
  EXPECT_NO_THROW(Dataset(path).read(0, "world_pos", 0));
  // Mesh: a position beyond the bound, a node type outside bsms's set, a cell repeating a node.
  write();
  set_value<float>(path, "/trajectories/000001/mesh_pos", 3, -2e6f);
  EXPECT_NE(error_of([&] {
              Dataset(path).mesh(1);
            }).find("train.h5: trajectory 1, field 'mesh_pos' node 1 component 1: -2e+06"),
            std::string::npos);
  write();
  set_value<int32_t>(path, "/trajectories/000000/node_type", 2, 9);
  EXPECT_NE(error_of([&] {
              Dataset(path).mesh(0);
            }).find("train.h5: trajectory 0: node_type of node 2 is 9, expected 0..3"),
            std::string::npos);
  // Public data converted to a bsms file (no scene) keeps its codes: 0..63.
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    w.add(make_trajectory(1, 4));
    w.commit();
  }
  set_value<int32_t>(path, "/trajectories/000000/node_type", 2, 9);
  EXPECT_EQ(Dataset(path).mesh(0).node_type[2], 9);
  set_value<int32_t>(path, "/trajectories/000000/node_type", 2, 64);
  EXPECT_NE(error_of([&] { Dataset(path).mesh(0); }).find("is 64, expected 0..63"),
            std::string::npos);
  write();
  set_value<int32_t>(path, "/trajectories/000001/cells", 4, 0);
  EXPECT_NE(error_of([&] {
              Dataset(path).mesh(1);
            }).find("train.h5: trajectory 1: cells: cell 1 repeats node 0"),
            std::string::npos);
}

// No output of a process replaces a file it read as input, whatever the path spelling (a
// symlink); its own outputs, read back, may be replaced.
TEST(Dataset, OutputsNeverReplaceInputs) {
  const fs::path dir = temp_dir("out_in");
  const std::string path = (dir / "train.h5").string();
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    w.add(make_trajectory(1, 3));
    w.commit();
  }
  const Dataset written(path);  // our own output: may be replaced
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    w.add(make_trajectory(2, 3));
    w.commit();
  }
  const fs::path input = dir / "input.h5";
  fs::copy_file(path, input);
  fs::create_symlink(input, dir / "link.h5");
  const Dataset d(input.string());
  EXPECT_NE(error_of([&] {
              DatasetWriter((dir / "link.h5").string(), "{}", 2, 0.01);
            }).find("link.h5: is an input of this command"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              DatasetWriter(input.string(), "{}", 2, 0.01);
            }).find("input.h5: is an input of this command"),
            std::string::npos);
  EXPECT_EQ(Dataset(input.string()).seed(0), 2);
}

TEST(Dataset, ReadsPublicMeshGraphNetsLayout) {
  // Public converted layout: {split}/{i}.h5, static fields with a leading time axis of 1.
  const fs::path dir = temp_dir("public");
  fs::create_directories(dir / "valid");
  for (int i = 0; i < 3; ++i) {
    H5File f((dir / "valid" / (std::to_string(i) + ".h5")).string(), H5File::Mode::kTruncate);
    f.write("/mesh_pos", std::vector<float>{0, 0, 1, 0, 0, 1}, {1, 3, 2});
    f.write("/cells", std::vector<int32_t>{0, 1, 2}, {1, 1, 3});
    f.write("/node_type", std::vector<int32_t>{0, 4, 6}, {1, 3, 1});
    std::vector<float> velocity(4 * 3 * 2, static_cast<float>(i));
    f.write("/velocity", velocity, {4, 3, 2});
    f.write("/pressure", std::vector<float>(4 * 3, 1.5f), {4, 3, 1});
  }
  const Dataset d = Dataset::open_split(dir.string(), "valid");
  EXPECT_TRUE(d.is_public_layout());
  EXPECT_EQ(d.num_trajectories(), 3);
  EXPECT_EQ(d.dim(), 2);
  EXPECT_EQ(d.num_frames(2), 4);
  const auto& m = d.mesh(2);
  EXPECT_EQ(m.num_nodes(), 3);
  EXPECT_EQ(m.cell_size, 3);
  EXPECT_EQ(m.node_type, (std::vector<int32_t>{0, 4, 6}));
  EXPECT_EQ(m.body_id, (std::vector<int32_t>{0, 0, 0}));
  const auto v = d.read(2, "velocity", 3);
  EXPECT_EQ(v, std::vector<float>(6, 2.0f));
  EXPECT_EQ(d.read(0, "pressure", 0).size(), 3u);
  EXPECT_THROW(Dataset::open_split(dir.string(), "test"), InputError);
}

TEST(Dataset, RejectsFilesThatAreNotDatasets) {
  const fs::path dir = temp_dir("bad");
  {
    H5File f((dir / "train.h5").string(), H5File::Mode::kTruncate);
    f.set_attr("/", "format", std::string("bsms-multilevel"));
  }
  try {
    Dataset d((dir / "train.h5").string());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a bsms dataset"), std::string::npos);
  }
}

// Fuzzing regression (fuzz/fuzz_dataset.cpp): a body_id dataset with fewer entries than nodes
// was accepted, and users of TrajectoryMesh index body_id by node.
TEST(Dataset, FuzzShortBodyIdIsAnInputError) {
  const fs::path dir = temp_dir("short_body_id");
  const std::string path = (dir / "train.h5").string();
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    w.add(make_trajectory(7, 2));
    w.commit();
  }
  {
    H5File f(path, H5File::Mode::kReadWrite);
    f.write<int32_t>("/trajectories/000000/body_id", std::vector<int32_t>{}, {0});
  }
  const Dataset d(path);
  try {
    d.mesh(0);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("body_id"), std::string::npos) << e.what();
  }
}

// Fuzzing regression (fuzz/fuzz_dataset.cpp): only the first trajectory's fields are checked on
// opening; a later trajectory whose field is a scalar dataset made num_frames and read index an
// empty shape (null dereference).
TEST(Dataset, FuzzScalarFieldInALaterTrajectoryIsAnInputError) {
  const fs::path dir = temp_dir("scalar_field");
  const std::string path = (dir / "train.h5").string();
  {
    DatasetWriter w(path, "{}", 2, 0.01);
    w.add(make_trajectory(7, 2));
    w.add(make_trajectory(8, 2));
    w.commit();
  }
  {
    H5File f(path, H5File::Mode::kReadWrite);
    f.remove("/trajectories/000001/stress");  // fields[0]: names sort
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t set = H5Dcreate2(f.id(), "/trajectories/000001/stress", H5T_NATIVE_FLOAT, space,
                                 H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const float value = 1.0f;
    H5Dwrite(set, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value);
    H5Dclose(set);
    H5Sclose(space);
  }
  const Dataset d(path);
  EXPECT_EQ(d.num_frames(0), 2);
  EXPECT_THROW(d.num_frames(1), InputError);
  EXPECT_THROW(d.read(1, "stress", 0), InputError);
}

// Fuzzing regression (fuzz/fuzz_dataset.cpp): a scalar mesh_pos in a public single-file dataset
// made the reader take the last extent of an empty shape (null dereference).
TEST(Dataset, FuzzScalarMeshPosIsAnInputError) {
  const fs::path dir = temp_dir("scalar_mesh_pos");
  const std::string path = (dir / "train.h5").string();
  {
    H5File f(path, H5File::Mode::kTruncate);
    f.create_group("/0");
    const hid_t space = H5Screate(H5S_SCALAR);
    const hid_t set = H5Dcreate2(f.id(), "/0/mesh_pos", H5T_NATIVE_FLOAT, space, H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT);
    const float value = 1.0f;
    H5Dwrite(set, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value);
    H5Dclose(set);
    H5Sclose(space);
    f.write<int32_t>("/0/cells", std::vector<int32_t>{0, 1, 2}, {1, 3});
    f.write<int32_t>("/0/node_type", std::vector<int32_t>{0, 0, 0}, {3});
    f.write<float>("/0/velocity", std::vector<float>(12, 0.0f), {2, 3, 2});
  }
  try {
    Dataset d(path);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh_pos"), std::string::npos) << e.what();
  }
}

// XDMF for ParaView (data/dataset/xdmf.hpp): the form every ParaView 5.11 reader opens cleanly
// (tests/cli/paraview_xdmf.sh opens it in ParaView where installed). No HyperSlab items, XYZ
// geometry and 3-component vectors, each frame a dataset of the views file that maps the source.
std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(Xdmf, LagrangianFramesAreViewsWithoutHyperSlabs) {
  const fs::path dir = temp_dir("xdmf_lagrangian");
  {
    DatasetWriter w((dir / "train.h5").string(), "{}", 2, 0.01);
    w.add(make_trajectory(7, 5));
    w.add(make_trajectory(8, 3));
    w.commit();
  }
  const Dataset d((dir / "train.h5").string());
  fs::create_directories(dir / "view");
  const fs::path xdmf = dir / "view" / "train_000001.xdmf";
  write_trajectory_xdmf(d, 1, xdmf.string());
  const std::string text = read_text(xdmf);
  EXPECT_EQ(count(text, "HyperSlab"), 0u);
  EXPECT_EQ(count(text, "<Time "), 3u);
  EXPECT_EQ(count(text, "GeometryType=\"XYZ\""), 3u);
  EXPECT_EQ(count(text, "<Geometry"), 3u);
  EXPECT_EQ(count(text, "AttributeType=\"Vector\""), 3u);  // velocity in each frame
  EXPECT_NE(text.find("<Topology TopologyType=\"Triangle\" NumberOfElements=\"2\">"),
            std::string::npos);
  // Static arrays from the dataset file, relative to the XDMF's folder; frames from the views.
  EXPECT_NE(text.find(">../train.h5:/trajectories/000001/cells<"), std::string::npos);
  EXPECT_NE(text.find("Dimensions=\"4 3\" NumberType=\"Float\" Precision=\"4\" "
                      "Format=\"HDF\">train_000001.xdmf.h5:/world_pos/000002<"),
            std::string::npos);
  EXPECT_NE(text.find("Dimensions=\"4\" NumberType=\"Float\" Precision=\"4\" "
                      "Format=\"HDF\">train_000001.xdmf.h5:/stress/000000<"),
            std::string::npos);
  EXPECT_EQ(count(text, "world_pos/"), 3u);  // geometry only: no world_pos attribute

  ASSERT_EQ(xdmf_views_path(xdmf.string()), xdmf.string() + ".h5");
  const H5File views(xdmf_views_path(xdmf.string()), H5File::Mode::kRead);
  EXPECT_EQ(views.attr_string("/", "format"), "bsms-xdmf-views");
  Shape shape;
  // Frame 2 of trajectory 1: world_pos values 8016.. (see make_trajectory), z read as 0.
  const auto pos = views.read<float>("/world_pos/000002", &shape);
  EXPECT_EQ(shape, (Shape{4, 3}));
  EXPECT_EQ(pos, (std::vector<float>{8016, 8017, 0, 8018, 8019, 0, 8020, 8021, 0, 8022, 8023, 0}));
  const auto vel = views.read<float>("/velocity/000001", &shape);
  EXPECT_EQ(shape, (Shape{4, 3}));
  EXPECT_EQ(vel[0], -8.0f);
  EXPECT_EQ(vel[1], -9.0f);
  EXPECT_EQ(vel[2], 0.0f);
  const auto stress = views.read<float>("/stress/000002", &shape);
  EXPECT_EQ(shape, (Shape{4}));
  EXPECT_EQ(stress[3], 0.5f * 11);
  EXPECT_FALSE(views.exists("/world_pos/000003"));  // trajectory 1 has 3 frames
}

TEST(Xdmf, EulerianGeometryIsTheMesh) {
  const fs::path dir = temp_dir("xdmf_eulerian");
  Trajectory t = make_trajectory(7, 2);
  t.fields = {{"velocity", t.fields["velocity"]}, {"pressure", t.fields["stress"]}};
  {
    DatasetWriter w((dir / "test.h5").string(), "{}", 2, 0.5);
    w.add(t);
    w.commit();
  }
  const Dataset d((dir / "test.h5").string());
  const fs::path xdmf = dir / "test_000000.xdmf";
  write_trajectory_xdmf(d, 0, xdmf.string());
  const std::string text = read_text(xdmf);
  EXPECT_EQ(count(text, "HyperSlab"), 0u);
  EXPECT_EQ(count(text, ">test_000000.xdmf.h5:/mesh_pos<"), 2u);
  EXPECT_NE(text.find("<Time Value=\"0.5\"/>"), std::string::npos);
  EXPECT_NE(text.find(">test.h5:/trajectories/000000/node_type<"), std::string::npos);
  const H5File views(xdmf_views_path(xdmf.string()), H5File::Mode::kRead);
  Shape shape;
  EXPECT_EQ(views.read<float>("/mesh_pos", &shape),
            (std::vector<float>{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}));
  EXPECT_EQ(views.read<float>("/pressure/000001")[0], 2.0f);
}

TEST(Xdmf, PublicLayoutsAreConvertedFirst) {
  const Dataset d =
      Dataset::open_split(std::string(BSMS_FIXTURES_DIR) + "/meshgraphnets/cylinder_flow", "train");
  const fs::path dir = temp_dir("xdmf_public");
  EXPECT_THROW(write_trajectory_xdmf(d, 0, (dir / "x.xdmf").string()), InputError);
  EXPECT_FALSE(fs::exists(dir / "x.xdmf"));
}

}  // namespace
}  // namespace bsms
