// Scene files: every shipped scene parses; bad scenes give one InputError naming file and key;
// `simulate_scene` writes the frames file of DESIGN.md and nothing on failure.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/mpm/simulation.hpp"

namespace bsms::mpm {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = std::string(BSMS_SOURCE_DIR) + "/configs/scenes/";
const std::string kBad = std::string(BSMS_SOURCE_DIR) + "/tests/data/scenes/";

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
  // Scenes of `bsms simulate`; dataset family files beside them are parsed by tests/generate.
  int count = 0;
  for (const auto& entry : fs::directory_iterator(kScenes)) {
    if (entry.path().extension() != ".json") continue;
    if (load_json_file(entry.path().string()).contains("family"))
      continue;  // dataset families (generate)
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
  EXPECT_NE(input_error(kScenes + "vibrating_bar.json", {"dim=4"}), "");
  EXPECT_NE(input_error(kScenes + "vibrating_bar.json", {"solver.cfl=0"}), "");
}

TEST(Simulation, WritesFramesFileAsSpecified) {
  const fs::path dir = fs::temp_directory_path() / ("bsms_frames_" + std::to_string(::getpid()));
  fs::remove_all(dir);
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
  EXPECT_NE(text.str().find("Polyvertex"), std::string::npos);
  EXPECT_NE(text.str().find("frames.h5:/frames/position"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "scene.json"));
  fs::remove_all(dir);
}

TEST(Simulation, FailedRunLeavesNoFramesFile) {
  const fs::path dir = fs::temp_directory_path() / ("bsms_fail_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const Scene scene =
      load_scene(kScenes + "rotating_square.json",
                 {"background.element_size=0.05", "solver.dt=0.005", "solver.end_time=0.2"});
  EXPECT_THROW(simulate_scene(scene, dir.string(), false), NumericalError);
  EXPECT_FALSE(fs::exists(dir / "frames.h5"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bsms::mpm
