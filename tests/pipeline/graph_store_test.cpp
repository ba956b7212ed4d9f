// The multilevel-graph cache of training and rollout: damaged entries and unwritable folders are
// said on one line (never silently), random seeding's graphs are cached per seed, a memory cap
// evicts the least recently used entries, and concurrent requests build an entry once.
#include "pipeline/graphs/graph_store.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <thread>
#include <vector>

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
  const auto g = store.get(mesh);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(g->multilevel.num_levels(), 2);
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
  EXPECT_EQ(store.get(testing::dragged_plate(0, 1, 4).mesh)->multilevel.num_levels(), 2);
  EXPECT_EQ(store.get(testing::dragged_plate(0, 1, 5).mesh)->multilevel.num_levels(), 2);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(count_of(err, "kept in memory only"), 1u) << err;
}

TEST(GraphStore, CapEvictsTheLeastRecentlyUsedAndHandedOutEntriesLiveOn) {
  const TrajectoryMesh a = testing::dragged_plate(0, 1, 4).mesh;
  const TrajectoryMesh b = testing::dragged_plate(0, 1, 5).mesh;
  const TrajectoryMesh c = testing::dragged_plate(0, 1, 6).mesh;
  GraphStore probe(Seeding::kCloseCenter, 2, {});
  const int64_t size_a = resident_bytes(*probe.get(a)), size_b = resident_bytes(*probe.get(b)),
                size_c = resident_bytes(*probe.get(c));
  ASSERT_TRUE(0 < size_a && size_a < size_b && size_b < size_c);  // 25, 36, 49 nodes
  // Room for a and c (so for a and b), not for all three.
  const int64_t cap = size_a + size_c;
  GraphStore store(Seeding::kCloseCenter, 2, {}, 0, false, cap);
  const auto held = store.get(a);
  store.get(b);
  store.get(a);  // a is now the most recent, b the least
  store.get(c);  // evicts b
  GraphStore::Stats s = store.stats();
  EXPECT_EQ(s.builds, 3);
  EXPECT_EQ(s.evictions, 1);
  EXPECT_EQ(s.entries, 2);
  EXPECT_EQ(s.bytes, size_a + size_c);
  EXPECT_EQ(s.peak_bytes, size_a + size_b + size_c);  // before the eviction
  store.get(a);                                       // still resident: no build
  EXPECT_EQ(store.stats().builds, 3);
  store.get(b);  // evicted: built again, and c (least recent) goes
  s = store.stats();
  EXPECT_EQ(s.builds, 4);
  EXPECT_EQ(s.evictions, 2);
  // An entry handed out stays valid however much is evicted after.
  GraphStore tiny(Seeding::kCloseCenter, 2, {}, 0, false, 1);
  const auto first = tiny.get(a);
  tiny.get(b);
  tiny.get(c);
  EXPECT_EQ(tiny.stats().entries, 1);
  EXPECT_EQ(first->multilevel.num_levels(), 2);
  EXPECT_EQ(first->hierarchy.num_nodes(0), a.num_nodes());
  EXPECT_EQ(held->hierarchy.num_nodes(0), a.num_nodes());
}

TEST(GraphStore, ThreadsAskingForOneMeshBuildItOnce) {
  const TrajectoryMesh mesh = testing::dragged_plate(0, 1, 7).mesh;
  GraphStore store(Seeding::kCloseCenter, 2, {});
  std::vector<std::shared_ptr<const MeshGraphs>> got(4);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < got.size(); ++i)
    threads.emplace_back([&, i] { got[i] = store.get(mesh); });
  for (auto& t : threads) t.join();
  EXPECT_EQ(store.stats().builds, 1);
  for (const auto& g : got) EXPECT_EQ(g.get(), got[0].get());
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
