#include "core/config.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace bsms {
namespace {

std::string write_temp(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, LoadReportsMissingAndMalformedFiles) {
  EXPECT_NE(message_of([] { load_json_file("/nonexistent/x.json"); }).find("/nonexistent/x.json"),
            std::string::npos);
  const auto bad = write_temp("bsms_bad.json", "{\"a\": 1,");
  const std::string msg = message_of([&] { load_json_file(bad); });
  EXPECT_NE(msg.find(bad), std::string::npos);
  EXPECT_NE(msg.find("malformed"), std::string::npos);
  const auto list = write_temp("bsms_list.json", "[1, 2]");
  EXPECT_NE(message_of([&] { load_json_file(list); }).find("object"), std::string::npos);
}

TEST(Config, OverridesParseJsonValuesAndCreateNestedKeys) {
  Json j = Json::parse(R"({"solver": {"cfl": 0.5, "kernel": "umls"}})");
  apply_override(j, "solver.cfl=0.25", "--set");
  apply_override(j, "solver.kernel=fem", "--set");
  apply_override(j, "output.frames=[1,2]", "--set");
  EXPECT_DOUBLE_EQ(j["solver"]["cfl"].get<double>(), 0.25);
  EXPECT_EQ(j["solver"]["kernel"].get<std::string>(), "fem");
  EXPECT_EQ(j["output"]["frames"].size(), 2u);
  EXPECT_THROW(apply_override(j, "novalue", "--set"), InputError);
  EXPECT_THROW(apply_override(j, "solver.cfl.x=1", "--set"), InputError);
  EXPECT_THROW(apply_override(j, "a..b=1", "--set"), InputError);
  // A list index too large for std::stoul is out of range, not a crash.
  EXPECT_THROW(apply_override(j, "output.frames.99999999999999999999999=1", "--set"), InputError);
}

TEST(Config, IntegersMustFitTheirType) {
  const Json j = Json::parse(
      R"({"seed": -1, "big": 18446744073709551615, "steps": 3000000000, "ok": 7, "neg": -5})");
  JsonObjectReader r(j, {"train.json", ""});
  const std::string seed = message_of([&] { r.get<uint64_t>("seed"); });
  EXPECT_NE(seed.find("seed"), std::string::npos) << seed;
  EXPECT_NE(seed.find("[0, 18446744073709551615]"), std::string::npos) << seed;
  EXPECT_NE(message_of([&] { r.get<int>("steps"); }).find("[-2147483648, 2147483647]"),
            std::string::npos);
  EXPECT_NE(message_of([&] { r.get<int64_t>("big"); }).find("got 18446744073709551615"),
            std::string::npos);
  EXPECT_EQ(r.get<uint64_t>("big"), 18446744073709551615ull);
  EXPECT_EQ(r.get<int64_t>("steps"), 3000000000);
  EXPECT_EQ(r.get<uint64_t>("ok"), 7u);
  EXPECT_EQ(r.get<int>("neg"), -5);
}

TEST(Config, ReaderRejectsUnknownMissingAndMistypedKeys) {
  const Json j = Json::parse(R"({"E": 100.0, "nu": 0.3, "name": "bar", "steps": 10, "typo": 1})");
  JsonObjectReader r(j, {"scene.json", "material"});
  EXPECT_DOUBLE_EQ(r.get<double>("E"), 100.0);
  EXPECT_DOUBLE_EQ(r.opt<double>("rho", 1.0), 1.0);
  EXPECT_EQ(r.get<int>("steps"), 10);
  EXPECT_EQ(r.get<std::string>("name"), "bar");
  const std::string wrong = message_of([&] { r.get<int>("nu"); });
  EXPECT_NE(wrong.find("material.nu"), std::string::npos);
  EXPECT_NE(wrong.find("integer"), std::string::npos);
  const std::string missing = message_of([&] { r.get<double>("density"); });
  EXPECT_NE(missing.find("material.density"), std::string::npos);
  const std::string unknown = message_of([&] { r.finish(); });
  EXPECT_NE(unknown.find("scene.json"), std::string::npos);
  EXPECT_NE(unknown.find("material.typo"), std::string::npos);
  EXPECT_NE(unknown.find("allowed: E,"), std::string::npos);
  const std::string range = message_of([] { require(false, {"s.json", "material.E"}, "> 0"); });
  EXPECT_EQ(range, "s.json: key 'material.E' must be > 0");
}

// Fuzzing regressions (fuzz/fuzz_config.cpp): a number JSON cannot hold and bytes that are not
// UTF-8 are InputErrors (they escaped as nlohmann's out_of_range and type_error).
TEST(Config, FuzzNumberOverflowAndNonUtf8AreInputErrors) {
  const auto huge = write_temp("bsms_huge_number.json", R"({"dt": 0.49E4422222222222})");
  EXPECT_NE(message_of([&] { load_json_file(huge); }).find("malformed"), std::string::npos);
  Json j = Json::parse(R"({"solver": {"cfl": 0.5}})");
  apply_override(j, "solver.cfl=1e99999", "--set");  // taken as a string, like a bare word
  EXPECT_EQ(j["solver"]["cfl"], "1e99999");
  EXPECT_NE(message_of([&] {
              apply_override(j, "sample.count=[0,\xcd\xa2\xff]", "--set");
            }).find("UTF-8"),
            std::string::npos);
  EXPECT_NE(message_of([&] { apply_override(j, "a\xff=1", "--set"); }).find("UTF-8"),
            std::string::npos);
  EXPECT_NO_THROW(j.dump());
}

}  // namespace
}  // namespace bsms
