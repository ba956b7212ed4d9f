#include "core/gmsh_worker.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.hpp"
#include "core/gmsh_result.hpp"
#include "core/gmsh_session.hpp"
#include "core/mesh.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

class GmshWorker : public ::testing::Test {
 protected:
  void SetUp() override {
    saved_ = gmsh_limits();
    dir_ = bsms::testing::unique_temp_dir("gmsh_worker");
  }
  void TearDown() override {
    set_gmsh_limits(saved_);
    fs::remove_all(dir_);
  }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  void limits(double seconds, double gib, bool allow) {
    GmshLimits l;
    l.time_limit_s = seconds;
    l.memory_limit_gib = gib;
    l.allow_geo_commands = allow;
    set_gmsh_limits(l);
  }
  static std::string error_of(const std::string& path) {
    try {
      read_mesh(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  GmshLimits saved_;
  fs::path dir_;
};

void expect_same_mesh(const Mesh& a, const Mesh& b) {
  EXPECT_EQ(a.dim, b.dim);
  EXPECT_EQ(a.cell_dim, b.cell_dim);
  EXPECT_TRUE(a.points == b.points);  // bit for bit
  EXPECT_TRUE(a.cells == b.cells);
  EXPECT_EQ(a.node_tags, b.node_tags);
  EXPECT_EQ(a.node_groups, b.node_groups);
}

// The worker gives the mesh gmsh gives in this process, for the shipped geometries.
TEST_F(GmshWorker, ShippedGeometriesMeshAsInProcess) {
  for (const char* name : {"plate_hole.geo", "plate_with_holes.geo"}) {
    const std::string geo = (fs::path(BSMS_SOURCE_DIR) / "configs/geometry" / name).string();
    const Mesh child = read_mesh(geo);
    EXPECT_GT(child.num_nodes(), 100) << name;
    expect_same_mesh(child, read_mesh_with_gmsh_here(geo));
  }
}

TEST_F(GmshWorker, ExitEndsTheWorkerNotTheCaller) {
  const std::string geo = write("e.geo", "Point(1) = {0, 0, 0, .1};\nExit;\n");
  limits(60, 0, false);
  EXPECT_NE(error_of(geo).find(":2: gmsh command 'Exit' ends the process; refused"),
            std::string::npos);
  limits(60, 0, true);  // run it: the worker ends, bsms reports it
  const std::string error = error_of(geo);
  EXPECT_EQ(error.find(geo + ": gmsh stopped before it gave a mesh (exit status"), 0u) << error;
}

TEST_F(GmshWorker, EndlessLoopMeetsTheTimeLimit) {
  const std::string geo = write("loop.geo", "For i In {1:1e12}\nx = i;\nEndFor\n");
  limits(1.5, 0, false);
  const auto start = std::chrono::steady_clock::now();
  const std::string error = error_of(geo);
  EXPECT_EQ(error.find(geo + ": gmsh did not finish within 1.5 s"), 0u) << error;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 30);
}

TEST_F(GmshWorker, HugeTransfiniteMeetsTheMemoryLimit) {
  const std::string geo =
      write("huge.geo",
            "Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0};\n"
            "Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 1};\n"
            "Curve Loop(1) = {1, 2, 3}; Plane Surface(1) = {1};\n"
            "Transfinite Curve{1} = 3e7;\n");
  limits(60, 0.5, false);
  const std::string error = error_of(geo);
  EXPECT_EQ(error.find(geo + ": gmsh ran out of its memory limit of 0.5 GiB"), 0u) << error;
}

TEST_F(GmshWorker, SyntaxErrorNamesTheLine) {
  const std::string geo = write("syntax.geo", "Point(1) = {0, 0, 0};\nPoint(2) = {1, 0, 0;\n");
  const std::string error = error_of(geo);
  EXPECT_EQ(error.find(geo + ": gmsh cannot read this file ("), 0u) << error;
  EXPECT_NE(error.find("line 2"), std::string::npos) << error;
}

// The kernel layer under the check: a worker started without --allow-commands runs no program,
// even on a script the check would have refused.
TEST_F(GmshWorker, SandboxedWorkerRunsNoCommand) {
  const fs::path pwned = dir_ / "pwned";
  const std::string geo = write(
      "call.geo", "SystemCall \"touch " + pwned.string() + "\";\nNonBlockingSystemCall \"touch " +
                      pwned.string() + "\";\nSave \"" + (dir_ / "saved.msh").string() + "\";\n");
  const std::string command =
      "exec " + gmsh_worker_path() + " --memory 8000000000 --cpu 60 --parent " +
      std::to_string(::getpid()) + " -- " + geo + " 3>/dev/null 2>/dev/null";
  const int status = std::system(command.c_str());
  (void)status;
  ::usleep(200000);  // a NonBlockingSystemCall would have had time to run
  EXPECT_FALSE(fs::exists(pwned));
  EXPECT_FALSE(fs::exists(dir_ / "saved.msh"));
  // With --allow-geo-commands the user's commands run (the user's risk).
  limits(60, 0, true);
  const std::string touch =
      write("touch.geo", "SystemCall \"touch " + pwned.string() + "\";\nPoint(1) = {0, 0, 0};\n");
  error_of(touch);
  EXPECT_TRUE(fs::exists(pwned));
}

TEST_F(GmshWorker, CompressedFilesAreRefused) {
  const std::string gz = write("m.msh.gz", "\x1f\x8b not really");
  EXPECT_EQ(error_of(gz), gz + ": a gzip-compressed file; uncompress it first");
}

TEST_F(GmshWorker, LimitsFromTheEnvironment) {
  ::setenv("BSMS_GEO_TIME_LIMIT", "7.5", 1);
  ::setenv("BSMS_GEO_MEMORY_LIMIT", "2", 1);
  GmshLimits l = gmsh_limits_from_environment();
  EXPECT_EQ(l.time_limit_s, 7.5);
  EXPECT_EQ(l.memory_limit_gib, 2.0);
  EXPECT_FALSE(l.allow_geo_commands);
  for (const char* bad : {"nan", "-1", "0", "12s", "inf"}) {
    ::setenv("BSMS_GEO_TIME_LIMIT", bad, 1);
    try {
      gmsh_limits_from_environment();
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("BSMS_GEO_TIME_LIMIT"), std::string::npos);
    }
  }
  ::unsetenv("BSMS_GEO_TIME_LIMIT");
  ::unsetenv("BSMS_GEO_MEMORY_LIMIT");
  l = gmsh_limits_from_environment();
  EXPECT_EQ(l.time_limit_s, 120.0);
  EXPECT_EQ(l.memory_limit_gib, 0.0);
  EXPECT_GE(default_gmsh_memory_gib(), 1.0);
}

TEST(GmshResult, RoundTripsAndRefusesEveryCut) {
  GmshResult r;
  r.mesh = make_mesh(2, (RowMatrixXd(3, 2) << 0, 0, 1, 0, 0, 1).finished(),
                     (RowMatrixXi64(1, 3) << 0, 1, 2).finished());
  r.mesh.node_groups["wall"] = {0, 2};
  r.mesh.node_groups[""] = {};
  char name[] = "/tmp/bsms_gmsh_result_XXXXXX";
  const int fd = ::mkstemp(name);
  ASSERT_GE(fd, 0);
  ::unlink(name);
  ASSERT_TRUE(write_gmsh_result(fd, r));
  std::string bytes(static_cast<std::size_t>(::lseek(fd, 0, SEEK_END)), '\0');
  ASSERT_EQ(::pread(fd, bytes.data(), bytes.size(), 0), static_cast<ssize_t>(bytes.size()));
  ::close(fd);
  const GmshResult back = parse_gmsh_result(bytes);
  ASSERT_EQ(back.status, GmshResult::Status::Mesh);
  expect_same_mesh(back.mesh, r.mesh);
  for (std::size_t cut = 0; cut < bytes.size(); ++cut)
    EXPECT_THROW(parse_gmsh_result(std::string_view(bytes).substr(0, cut)), std::runtime_error);
  EXPECT_THROW(parse_gmsh_result(bytes + "x"), std::runtime_error);
  std::string flipped = bytes;
  flipped[8] = 9;  // unknown status
  EXPECT_THROW(parse_gmsh_result(flipped), std::runtime_error);
}

}  // namespace
}  // namespace bsms
