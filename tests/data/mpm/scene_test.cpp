// Scene files: every shipped scene parses; bad scenes give one InputError naming file and key;
// `simulate_scene` writes the frames file of docs/design.md and nothing on failure.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/mpm/scene_builder.hpp"
#include "data/mpm/scene_size.hpp"
#include "data/mpm/simulation.hpp"
#include "tests/temp_dir.hpp"

namespace bsms::mpm {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = std::string(BSMS_SOURCE_DIR) + "/configs/scenes/";
const std::string kBad = std::string(BSMS_SOURCE_DIR) + "/tests/data/mpm/scenes/";

std::string input_error(const std::string& path, const std::vector<std::string>& sets = {}) {
  try {
    const Scene scene = load_scene(path, sets);
    if (scene.dim == 2) build_scene<2>(scene);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Scene, EveryShippedSceneParsesAndBuilds) {
  // Every file in configs/scenes/ is a scene of `bsms simulate` (dataset families are in
  // configs/families/, parsed by tests/data/generate).
  int count = 0;
  for (const auto& entry : fs::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".json") continue;
    // Parsed and built (gmsh meshing, particles seeded at body nodes inside the background).
    try {
      const Scene scene = load_scene(entry.path().string());
      int64_t particles = 0;
      if (scene.dim == 2) {
        particles = build_scene<2>(scene).particles.size();
      } else {
        particles = build_scene<3>(scene).particles.size();
      }
      EXPECT_GT(particles, 0) << entry.path();
    } catch (const std::exception& e) {
      ADD_FAILURE() << entry.path() << ": " << e.what();
    }
    ++count;
  }
  EXPECT_GE(count, 5);
}

// A unit typo is refused from the JSON alone, before meshing, with the estimate and the limit.
TEST(Scene, HugeScenesAreRefusedBeforeMeshing) {
  const std::string square = kScenes + "rotating_square.json";
  struct Case {
    std::vector<std::string> sets;
    std::string key, figure;
  };
  const Case cases[] = {
      {{"bodies.0.spacing=1e-7"}, "key 'bodies.0.spacing'", "about 4e+12 particles"},
      {{"background.element_size=1e-6"},
       "key 'background.element_size'",
       "about 1.2e+12 background nodes"},
      {{"solver.dt=1e-12"}, "key 'solver.dt'", "about 1e+12 time steps"},
      {{"solver.end_time=9000"}, "key 'solver.dt'", "particle-and-node steps"},
  };
  for (const Case& c : cases) {
    const auto start = std::chrono::steady_clock::now();
    const std::string m = input_error(square, c.sets);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_NE(m.find(square), std::string::npos) << m;
    EXPECT_NE(m.find(c.key), std::string::npos) << m;
    EXPECT_NE(m.find(c.figure), std::string::npos) << m;
    EXPECT_NE(m.find("limit"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    EXPECT_LT(seconds, 1.0) << m;
  }
  // Memory: against a given limit (the default is the machine's physical memory).
  const Scene scene = load_scene(square);
  try {
    check_scene_size(scene, 1e6);
    ADD_FAILURE() << "a 1 MB limit passed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("GB of memory estimated"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(check_scene_size(scene));
}

// The estimates are honest: within a factor 2 of what gmsh and the scene builder make, for
// every shipped scene, and far below the limits.
TEST(Scene, SizeEstimatesMatchTheBuiltShippedScenes) {
  for (const auto& entry : fs::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".json") continue;
    const Scene scene = load_scene(entry.path().string());
    const SceneEstimate e = estimate_scene(scene);
    double particles = 0.0, nodes = 0.0;
    if (scene.dim == 2) {
      const BuiltScene<2> b = build_scene<2>(scene);
      particles = b.particles.size();
      nodes = b.background.num_domain_nodes;
    } else {
      const BuiltScene<3> b = build_scene<3>(scene);
      particles = b.particles.size();
      nodes = b.background.num_domain_nodes;
    }
    std::printf(
        "%s: particles %.0f (estimate %.0f), nodes %.0f (estimate %.0f), steps %.3g, "
        "memory %.3g GB\n",
        entry.path().filename().c_str(), particles, e.particles, nodes, e.nodes, e.steps,
        e.bytes / 1e9);
    EXPECT_LT(e.particles, 2.0 * particles) << entry.path();
    EXPECT_GT(e.particles, 0.5 * particles) << entry.path();
    EXPECT_LT(e.nodes, 2.0 * nodes) << entry.path();
    EXPECT_GT(e.nodes, 0.5 * nodes) << entry.path();
    EXPECT_LT((e.particles + e.nodes) * e.steps, 0.01 * kMaxNodeSteps) << entry.path();
  }
}

// An input mesh with a zero-area cell is refused by the solver, naming the file and the cell.
TEST(Scene, BackgroundMeshWithCollinearTriangleIsRefused) {
  const fs::path dir = bsms::testing::unique_temp_dir("badmesh");
  std::ofstream(dir / "bad.msh") << R"($MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
5
1 0 0 0
2 1 0 0
3 1 1 0
4 0 1 0
5 2 2 0
$EndNodes
$Elements
3
1 2 2 0 1 1 2 3
2 2 2 0 1 1 3 4
3 2 2 0 1 1 3 5
$EndElements
)";
  Json scene = load_json_file(kScenes + "rotating_square.json");
  scene["background"] = {{"type", "mesh"}, {"path", "bad.msh"}};
  const std::string file = (dir / "scene.json").string();
  std::ofstream(file) << scene.dump();
  const std::string m = input_error(file);
  EXPECT_NE(m.find("key 'background.path'"), std::string::npos) << m;
  EXPECT_NE(m.find("bad.msh"), std::string::npos) << m;
  EXPECT_NE(m.find("1 zero-measure"), std::string::npos) << m;
  EXPECT_NE(m.find("first: cell 2"), std::string::npos) << m;
  fs::remove_all(dir);
}

TEST(Scene, BadScenesNameFileAndKey) {
  std::string m = input_error(kBad + "unknown_key.json");
  EXPECT_NE(m.find("unknown_key.json"), std::string::npos) << m;
  EXPECT_NE(m.find("bodies.0.colour"), std::string::npos) << m;
  m = input_error(kBad + "negative_modulus.json");
  EXPECT_NE(m.find("bodies.0.material.youngs_modulus"), std::string::npos) << m;
  m = input_error(kBad + "incompressible.json");
  EXPECT_NE(m.find("poisson_ratio"), std::string::npos) << m;
  m = input_error(kBad + "missing_mesh.json");
  EXPECT_NE(m.find("no_such_background.msh"), std::string::npos) << m;
  m = input_error(kScenes + "rotating_square.json", {"solver.kernel=quartic"});
  EXPECT_NE(m.find("solver.kernel"), std::string::npos) << m;
  m = input_error(kScenes + "vibrating_bar.json", {"boundaries.0.group=nowhere"});
  EXPECT_NE(m.find("nowhere"), std::string::npos) << m;
  m = input_error(kScenes + "vibrating_bar.json", {"bodies.0.shape.max=[40.0, 1.0]"});
  EXPECT_NE(m.find("outside the background"), std::string::npos) << m;
  m = input_error(kScenes + "rotating_square.json",
                  {"solver.kernel=bspline", "background.kernel_width=0.1"});
  EXPECT_NE(m.find("background.kernel_width"), std::string::npos) << m;
  m = input_error(kScenes + "rotating_square.json", {"background.kernel_width=1e-4"});
  EXPECT_NE(m.find("kernel_width"), std::string::npos) << m;
  EXPECT_NE(m.find("longest edge"), std::string::npos) << m;
  m = input_error(kScenes + "rotating_square.json", {"background.kernel_width=-1"});
  EXPECT_NE(m.find("background.kernel_width"), std::string::npos) << m;
  EXPECT_NE(input_error(kScenes + "vibrating_bar.json", {"dim=4"}), "");
  EXPECT_NE(input_error(kScenes + "vibrating_bar.json", {"solver.cfl=0"}), "");
}

TEST(Simulation, WritesFramesFileAsSpecified) {
  const fs::path dir = bsms::testing::unique_temp_dir("frames") / "run";
  const Scene scene = load_scene(kScenes + "rotating_square.json",
                                 {"background.element_size=0.05", "solver.dt=1e-4",
                                  "solver.end_time=0.01", "output.frames=5"});
  const SimulationSummary s = simulate_scene(scene, dir.string(), false);
  EXPECT_EQ(s.steps, 100);
  EXPECT_EQ(s.particles, 400);
  H5File f((dir / "frames.h5").string(), H5File::Mode::kRead);
  EXPECT_EQ(f.attr_string("/", "format"), "bsms-frames");
  EXPECT_EQ(f.attr_int("/", "version"), 1);
  EXPECT_EQ(f.attr_int("/", "dim"), 2);
  EXPECT_EQ(f.attr_string("/", "kernel"), "umls");
  EXPECT_EQ(f.attr_string("/", "transfer"), "apic");
  EXPECT_NO_THROW(Json::parse(f.attr_string("/", "scene")));
  EXPECT_EQ(f.shape("/particles/mass"), (Shape{400}));
  EXPECT_EQ(f.shape("/particles/volume0"), (Shape{400}));
  EXPECT_EQ(f.shape("/frames/time"), (Shape{5}));
  EXPECT_EQ(f.shape("/frames/position"), (Shape{5, 400, 2}));
  EXPECT_EQ(f.shape("/frames/velocity"), (Shape{5, 400, 2}));
  EXPECT_EQ(f.shape("/frames/stress"), (Shape{5, 400}));
  EXPECT_EQ(f.shape("/frames/energy"), (Shape{5, 3}));
  EXPECT_EQ(f.shape("/frames/momentum"), (Shape{5, 2}));
  EXPECT_EQ(f.shape("/frames/angular_momentum"), (Shape{5, 1}));
  const auto time = f.read<double>("/frames/time");
  EXPECT_DOUBLE_EQ(time.back(), 0.01);
  for (float x : f.read<float>("/frames/position")) ASSERT_TRUE(std::isfinite(x));
  std::ifstream xdmf(dir / "frames.xdmf");
  std::stringstream text;
  text << xdmf.rdbuf();
  // The form every ParaView reader opens (data/dataset/xdmf.hpp): no HyperSlab items; each frame
  // a view of frames.h5 in frames.xdmf.h5, positions with 3 components; explicit vertex cells.
  EXPECT_NE(text.str().find("Polyvertex"), std::string::npos);
  EXPECT_EQ(text.str().find("HyperSlab"), std::string::npos);
  EXPECT_NE(text.str().find("Dimensions=\"400 3\" NumberType=\"Float\" Precision=\"4\" "
                            "Format=\"HDF\">frames.xdmf.h5:/position/000004<"),
            std::string::npos);
  EXPECT_NE(text.str().find(">frames.xdmf.h5:/connectivity<"), std::string::npos);
  {
    const H5File views((dir / "frames.xdmf.h5").string(), H5File::Mode::kRead);
    const auto position = f.read<float>("/frames/position");
    Shape shape;
    const auto last = views.read<float>("/position/000004", &shape);
    EXPECT_EQ(shape, (Shape{400, 3}));
    EXPECT_EQ(last[3 * 7 + 1], position[(4 * 400 + 7) * 2 + 1]);
    EXPECT_EQ(last[3 * 7 + 2], 0.0f);
    EXPECT_EQ(views.read<float>("/von_mises/000002").size(), 400u);
    EXPECT_EQ(views.read<int32_t>("/connectivity")[399], 399);
  }
  EXPECT_TRUE(fs::exists(dir / "scene.json"));
  fs::remove_all(dir);
}

TEST(Simulation, FailedRunLeavesNoFramesFile) {
  const fs::path dir = bsms::testing::unique_temp_dir("fail") / "run";
  const Scene scene =
      load_scene(kScenes + "rotating_square.json",
                 {"background.element_size=0.05", "solver.dt=0.005", "solver.end_time=0.2"});
  EXPECT_THROW(simulate_scene(scene, dir.string(), false), NumericalError);
  EXPECT_FALSE(fs::exists(dir / "frames.h5"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bsms::mpm
