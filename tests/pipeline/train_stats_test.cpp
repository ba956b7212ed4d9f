// RUN/train_stats.json (pipeline/runs/train_stats.hpp): what bsms train writes its reader reads
// back unchanged (a non-finite loss as null, read back as NaN), and a missing, mistyped, impossible
// or unknown key is one InputError naming the file and the key.
#include "pipeline/runs/train_stats.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/error.hpp"

namespace bsms {
namespace {

TrainStats distributed_stats() {
  TrainStats s;
  s.steps = 1200;
  s.train_ms_per_step = 21.5;
  s.peak_rss_mb_train = 372;
  s.threads = 2;
  s.world_size = 2;
  s.samples_per_step = 4;
  s.wall_s = 60.25;
  s.final_loss = 0.31;
  s.final_valid_loss = std::nan("");  // no validation ran
  s.final_valid_zero_prediction = std::nan("");
  s.num_parameters = 779970;
  s.valid_split = "train";
  s.allreduce_ms_per_step = 1.5;
  s.allreduce_calls_per_step = 1.0;
  s.blas = "OpenBLAS 0.3.21 NO_LAPACKE DYNAMIC_ARCH NO_AFFINITY SkylakeX MAX_THREADS=64";
  s.allocator = "gperftools 2.10 tcmalloc";
  s.matmul = "oneDNN 2.6.3 sgemm, avx512_core_bf16";
  return s;
}

std::string stats_error(const Json& json) {
  try {
    train_stats_from_json(json, "RUN/train_stats.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(TrainStatsFile, RoundTripsThroughTheFile) {
  const TrainStats s = distributed_stats();
  const Json written = Json::parse(to_json(s).dump());
  EXPECT_TRUE(written["final_valid_loss"].is_null());
  const TrainStats back = train_stats_from_json(written, "RUN/train_stats.json");
  EXPECT_EQ(back.steps, 1200);
  EXPECT_EQ(back.world_size, 2);
  EXPECT_EQ(back.samples_per_step, 4);
  EXPECT_DOUBLE_EQ(back.train_ms_per_step, 21.5);
  EXPECT_DOUBLE_EQ(back.final_loss, 0.31);
  EXPECT_TRUE(std::isnan(back.final_valid_loss));
  EXPECT_EQ(back.valid_split, "train");
  EXPECT_EQ(back.blas, s.blas);
  EXPECT_EQ(back.allocator, "gperftools 2.10 tcmalloc");
  EXPECT_EQ(back.matmul, s.matmul);
  ASSERT_TRUE(back.allreduce_ms_per_step.has_value());
  EXPECT_DOUBLE_EQ(*back.allreduce_ms_per_step, 1.5);
  EXPECT_EQ(to_json(back).dump(), written.dump());

  // A single process writes no all-reduce figures and reads none back.
  TrainStats alone = s;
  alone.allreduce_ms_per_step.reset();
  alone.allreduce_calls_per_step.reset();
  const Json j = to_json(alone);
  EXPECT_FALSE(j.contains("allreduce_ms_per_step"));
  EXPECT_FALSE(train_stats_from_json(j, "f").allreduce_ms_per_step.has_value());

  // Files of sessions that did not record their BLAS or malloc (older runs) read back empty.
  Json older = to_json(s);
  older.erase("blas");
  older.erase("allocator");
  const TrainStats old_back = train_stats_from_json(older, "f");
  EXPECT_TRUE(old_back.blas.empty());
  EXPECT_TRUE(old_back.allocator.empty());
  EXPECT_FALSE(to_json(old_back).contains("allocator"));
}

TEST(TrainStatsFile, BadFilesNameTheKey) {
  const Json good = to_json(distributed_stats());
  Json missing = good;
  missing.erase("num_parameters");
  EXPECT_NE(stats_error(missing).find("num_parameters"), std::string::npos);
  Json typo = good;
  typo["steps"] = "many";
  EXPECT_NE(stats_error(typo).find("steps"), std::string::npos);
  Json impossible = good;
  impossible["world_size"] = 0;
  EXPECT_NE(stats_error(impossible).find("world_size"), std::string::npos);
  Json split = good;
  split["valid_split"] = "test";
  EXPECT_NE(stats_error(split).find("valid_split"), std::string::npos);
  Json unknown = good;
  unknown["stepz"] = 3;
  EXPECT_NE(stats_error(unknown).find("stepz"), std::string::npos);
  EXPECT_NE(stats_error(Json::array()).find("RUN/train_stats.json"), std::string::npos);
  EXPECT_EQ(stats_error(good), "no error");
  EXPECT_THROW(read_train_stats("/nonexistent/train_stats.json"), InputError);
  // Numbers out of their range, named with the file and the field.
  for (const char* key : {"train_ms_per_step", "peak_rss_mb_train", "wall_s", "final_loss", "steps",
                          "num_parameters", "allreduce_ms_per_step"}) {
    Json negative = good;
    negative[key] = -1;
    EXPECT_NE(stats_error(negative).find("RUN/train_stats.json: key '" + std::string(key) + "'"),
              std::string::npos)
        << key << ": " << stats_error(negative);
  }
  Json no_threads = good;
  no_threads["threads"] = 0;
  EXPECT_NE(stats_error(no_threads).find("'threads'"), std::string::npos);
}

}  // namespace
}  // namespace bsms
