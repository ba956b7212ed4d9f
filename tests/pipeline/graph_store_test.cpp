// The multilevel-graph cache of training and rollout: damaged entries and unwritable folders are
// said on one line (never silently), and random seeding's graphs are cached per seed.
#include "pipeline/graphs/graph_store.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "plate_data.hpp"
#include "preprocess/multilevel_file.hpp"

namespace bsms {
namespace {

size_t count_of(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(GraphStore, DamagedCacheEntryIsRebuiltWithAWarning) {
  const auto dir = testing::fresh_dir("graph_store_damaged");
  const TrajectoryMesh mesh = testing::dragged_plate(0, 1, 4).mesh;
  const std::string path =
      (dir / multilevel_cache_name(Seeding::kCloseCenter, 2, topology_key(mesh))).string();
  std::ofstream(path) << "not an HDF5 file";
  GraphStore store(Seeding::kCloseCenter, 2, {dir.string()});
  ::testing::internal::CaptureStderr();
  const MeshGraphs& g = store.get(mesh);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(g.multilevel.num_levels(), 2);
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_NE(err.find("rebuilding"), std::string::npos) << err;
  // The rebuilt entry replaced the damaged one, and a new store reads it without a word.
  EXPECT_EQ(read_multilevel_graph(path).num_levels(), 2);
  GraphStore again(Seeding::kCloseCenter, 2, {dir.string()});
  ::testing::internal::CaptureStderr();
  again.get(mesh);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

TEST(GraphStore, UnwritableCacheIsSaidOnceAndGraphsStayInMemory) {
  GraphStore store(Seeding::kCloseCenter, 2, {"/proc/bsms_no_such_cache"});
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(store.get(testing::dragged_plate(0, 1, 4).mesh).multilevel.num_levels(), 2);
  EXPECT_EQ(store.get(testing::dragged_plate(0, 1, 5).mesh).multilevel.num_levels(), 2);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(count_of(err, "kept in memory only"), 1u) << err;
}

TEST(GraphStore, RandomSeedingIsCachedPerSeed) {
  EXPECT_NE(multilevel_cache_name(Seeding::kRandom, 3, "k", 1),
            multilevel_cache_name(Seeding::kRandom, 3, "k", 2));
  EXPECT_EQ(multilevel_cache_name(Seeding::kMinAve, 3, "k", 1),
            multilevel_cache_name(Seeding::kMinAve, 3, "k", 2));
  EXPECT_EQ(multilevel_cache_name(Seeding::kCloseCenter, 3, "abc"), "closecenter-L3-abc.h5");
}

}  // namespace
}  // namespace bsms
