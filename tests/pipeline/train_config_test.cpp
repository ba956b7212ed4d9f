#include "pipeline/runs/train_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/error.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

TEST(TrainConfig, EveryShippedConfigParsesAndRoundTrips) {
  int count = 0;
  for (const auto& entry :
       fs::directory_iterator(fs::path(BSMS_SOURCE_DIR) / "configs" / "train")) {
    if (entry.path().extension() != ".json") continue;
    const TrainConfig c =
        parse_train_config(load_json_file(entry.path().string()), entry.path().string());
    EXPECT_FALSE(c.data.empty());
    EXPECT_GT(c.steps, 0);
    const TrainConfig again = parse_train_config(to_json(c), "resolved");
    EXPECT_EQ(to_json(again), to_json(c));
    ++count;
  }
  EXPECT_GE(count, 2);
}

// A per-level list is kept as given (and written back as a list); an integer stays an integer.
TEST(TrainConfig, PerLevelBlockCountsRoundTrip) {
  const TrainConfig c = parse_train_config(
      Json::parse(R"({"data": "d", "steps": 5, "model": {"mp_per_level": [3, 1, 2, 1]}})"), "t");
  EXPECT_EQ(c.model.mp_per_level_list, (std::vector<int>{3, 1, 2, 1}));
  EXPECT_EQ(c.model.mp_per_level, 3);
  EXPECT_EQ(to_json(c)["model"]["mp_per_level"], Json::parse("[3, 1, 2, 1]"));
  const TrainConfig again = parse_train_config(to_json(c), "resolved");
  EXPECT_EQ(again.model.mp_per_level_list, c.model.mp_per_level_list);
  const TrainConfig plain = parse_train_config(
      Json::parse(R"({"data": "d", "steps": 5, "model": {"mp_per_level": 2}})"), "t");
  EXPECT_TRUE(plain.model.mp_per_level_list.empty());
  EXPECT_EQ(to_json(plain)["model"]["mp_per_level"], Json(2));
}

std::string error_of(const std::string& text) {
  try {
    parse_train_config(Json::parse(text), "t.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TrainConfig, BadValuesNameTheKey) {
  EXPECT_NE(error_of(R"({"steps": 5})").find("'data'"), std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 0})").find("steps"), std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "model": {"type": "gcn"}})").find("model.type"),
            std::string::npos);
  EXPECT_NE(
      error_of(R"({"data": "d", "steps": 5, "model": {"levels": "many"}})").find("model.levels"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "optimizer": {"lr": -1}})").find("optimizer.lr"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"noise_std": "x"}})")
                .find("features.noise_std"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "stepz": 5})").find("stepz"), std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"noise_gamma": 1.5}})")
                .find("features.noise_gamma"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"strain": "on"}})")
                .find("features.strain"),
            std::string::npos);
  for (const char* decay : {"1", "-0.1", "1.5"})
    EXPECT_NE(error_of(std::string(R"({"data": "d", "steps": 5, "optimizer": {"ema_decay": )") +
                       decay + "}}")
                  .find("optimizer.ema_decay"),
              std::string::npos)
        << decay;
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "optimizer": {"warmup_steps": -1}})")
                .find("optimizer.warmup_steps"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "model": {"precision": "fp16"}})")
                .find("model.precision"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "model": {"mp_per_level": 0}})")
                .find("model.mp_per_level"),
            std::string::npos);
  EXPECT_NE(
      error_of(R"({"data": "d", "steps": 5, "features": {"history": 0}})").find("features.history"),
      std::string::npos);
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"history_noise": "gns"}})")
                .find("features.history_noise"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"history": 3,
    "history_noise": "walk"}})"),
            "");
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"rigid_loss_weight": -1}})")
                .find("features.rigid_loss_weight"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"rigid_loss_weight": 4}})"), "");
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"noise_rigid_scale": 1.5}})")
                .find("features.noise_rigid_scale"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"noise_rigid_scale": 0}})"), "");
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"augment": "mirror"}})")
                .find("features.augment"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"augment": "symmetries"}})"), "");
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "features": {"momentum": "walls"}})")
                .find("features.momentum"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"momentum": "free"}})"), "");
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "model": {"levels": 4}})"), "");
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "model": {"mp_per_level": 3}})"), "");
  // Per-level block counts: a list of integers in 1..16, one per level when levels are fixed.
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "model": {"mp_per_level": [2, 1, 1]}})"), "");
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "model": {"levels": 3,
    "mp_per_level": [2, 1, 1]}})"),
            "");
  for (const char* bad : {R"([])", R"([2, 0])", R"([2, 17])", R"([2, 1.5])", R"(["2"])"}) {
    EXPECT_NE(error_of(std::string(R"({"data": "d", "steps": 5, "model": {"mp_per_level": )") +
                       bad + "}}")
                  .find("model.mp_per_level"),
              std::string::npos)
        << bad;
  }
  EXPECT_NE(error_of(R"({"data": "d", "steps": 5, "model": {"levels": 4,
    "mp_per_level": [2, 1, 1]}})")
                .find("4 levels"),
            std::string::npos);
  EXPECT_EQ(error_of(R"({"data": "d", "steps": 5, "features": {"noise_gamma": 0.1,
    "strain": "off"}, "optimizer": {"warmup_steps": 50}})"),
            "");
}

}  // namespace
}  // namespace bsms
