#include "core/config.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/one_line.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

// A file in this test process's own folder.
std::string write_temp(const std::string& name, const std::string& text) {
  static const std::filesystem::path dir = bsms::testing::unique_temp_dir("config");
  const auto path = dir / name;
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

// The recorder sees every key a reader is asked about, read or merely looked for (absent optional
// and missing required keys too), with its full path; a nested recorder hands back to the outer
// one.
TEST(Config, KeyRecorderRecordsEveryKeyAskedAbout) {
  const Json j = Json::parse(R"({"E": 1.0, "list": [{"x": 2}], "name": "bar"})");
  const auto paths = [](const ConfigKeyRecorder& r) {
    std::vector<std::string> out;
    for (const auto& k : r.keys()) out.push_back(k.file + ":" + k.path);
    return out;
  };
  ConfigKeyRecorder outer;
  {
    ConfigKeyRecorder inner;
    JsonObjectReader r(j, {"scene.json", "material"});
    r.get<double>("E");
    r.opt<double>("rho", 1.0);  // absent: still a key the parser accepts
    (void)r.has("name");
    const Json& list = r.raw("list");
    JsonObjectReader element(list[0], r.context("list").child("0"));
    element.get<int>("x");
    EXPECT_THROW(r.get<double>("density"), InputError);  // asked for, though missing
    const std::vector<std::string> expected = {
        "scene.json:material.E",    "scene.json:material.rho",      "scene.json:material.name",
        "scene.json:material.list", "scene.json:material.list.0.x", "scene.json:material.density"};
    EXPECT_EQ(paths(inner), expected);
  }
  JsonObjectReader r(j, {"other.json", ""});
  r.opt<std::string>("name", "");
  EXPECT_EQ(paths(outer), std::vector<std::string>{"other.json:name"});
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

// The one JSON reader's bounds: nesting depth (no stack overflow on 100,000 levels), duplicate
// keys named by their path, and values in messages by type and at most ~40 characters.
TEST(Config, DeepNestingIsRefusedWithoutRecursion) {
  const std::string deep = "{\"a\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
  const std::string msg = message_of([&] { parse_json_text(deep, "deep.json"); });
  EXPECT_NE(msg.find("deep.json: lists and objects nested deeper than 128 levels"),
            std::string::npos)
      << msg;
  EXPECT_LT(msg.size(), 200u);
  // At the bound itself the value is read.
  const std::string at_bound = std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']');
  EXPECT_NO_THROW(parse_json_text(at_bound, "ok.json"));
  const std::string over = "[" + at_bound + "]";
  EXPECT_THROW(parse_json_text(over, "over.json"), InputError);
  // --set nests its key path and its value: the same bound holds for both together.
  Json config = Json::object();
  std::string keys = "a";
  for (int i = 0; i < 200; ++i) keys += ".a";
  EXPECT_NE(message_of([&] { apply_override(config, keys + "=1", "--set"); }).find("key path"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              apply_override(config, "x=" + std::string(60000, '[') + std::string(60000, ']'),
                             "--set");
            }).find("nested deeper"),
            std::string::npos);
}

TEST(Config, DuplicateKeysAreRefusedWithTheirPath) {
  const std::string msg = message_of([] {
    parse_json_text(R"({"model": {"type": "bsms", "list": [{"x": 1, "x": 2}]}})", "t.json");
  });
  EXPECT_NE(msg.find("t.json: duplicate key 'model.list.0.x'"), std::string::npos) << msg;
  EXPECT_NE(message_of([] {
              parse_json_text(R"({"a": 1, "a": 1})", "t.json");
            }).find("duplicate key 'a'"),
            std::string::npos);
  Json config = Json::object();
  EXPECT_NE(message_of([&] {
              apply_override(config, R"(m={"t": 1, "t": 2})", "--set");
            }).find("duplicate key 't'"),
            std::string::npos);
  // Comments stay allowed in files; equal keys in different objects are fine.
  EXPECT_NO_THROW(parse_json_text("{\"a\": {\"x\": 1}, // c\n \"b\": {\"x\": 2}}", "t.json"));
}

TEST(Config, MessagesDescribeValuesWithoutDumpingThem) {
  Json list = Json::array();
  for (int i = 0; i < 500000; ++i) list.push_back(i);
  const Json j = {{"steps", list}, {"name", std::string(100000, 'x')}, {"model", list}};
  JsonObjectReader r(j, {"t.json", ""});
  const std::string steps = message_of([&] { r.get<int>("steps"); });
  EXPECT_EQ(steps, "t.json: key 'steps' must be an integer, got a list of 500000 elements");
  const std::string name = message_of([&] { r.get<double>("name"); });
  EXPECT_LT(name.size(), 120u) << name;
  EXPECT_NE(name.find("the string \"xxxx"), std::string::npos) << name;
  const std::string model = message_of([&] { JsonObjectReader(j["model"], {"t.json", "model"}); });
  EXPECT_EQ(model, "t.json: key 'model' must be a JSON object, got a list of 500000 elements");
  EXPECT_EQ(describe_json(Json::object()), "an object of 0 keys");
  EXPECT_EQ(describe_json(Json(1.5)), "1.5");
  EXPECT_EQ(truncate_for_message("\xc3\xa9\xc3\xa9", 3), "\xc3\xa9...");  // never half a character
}

TEST(Config, OnlyRegularFilesAreRead) {
  EXPECT_NE(message_of([] { load_json_file("/dev/zero"); }).find("a character device"),
            std::string::npos);
  const auto dir = bsms::testing::unique_temp_dir("config_fifo");
  EXPECT_NE(message_of([&] { load_json_file(dir.string()); }).find("a folder"), std::string::npos);
  const auto fifo = dir / "bsms_config_test.fifo";
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // Refused before it is opened: no writer ever comes, so opening it would block.
  EXPECT_NE(message_of([&] { load_json_file(fifo.string()); }).find("a named pipe"),
            std::string::npos);
  std::filesystem::remove(fifo);
  const auto big = write_temp("bsms_big.json", "{\"a\": \"" + std::string(2000, 'x') + "\"}");
  EXPECT_NE(message_of([&] { load_json_file(big, "config file", 1000); }).find("larger than 1000"),
            std::string::npos);
  EXPECT_EQ(read_text_file(big, 5000, "text").size(), 2009u);
}

TEST(Config, OneLineEscapesControlCharactersAndCapsTheLength) {
  EXPECT_EQ(one_line("a\nb\tc\rd\x1b[31me\x7f\x01"), "a\\nb\\tc\\rd\\x1b[31me\\x7f\\x01");
  EXPECT_EQ(one_line("caf\xc3\xa9 \xe2\x80\xa6"), "caf\xc3\xa9 \xe2\x80\xa6");  // UTF-8 kept
  EXPECT_EQ(one_line(std::string("\xc2\x9b") + "2J"), "\\xc2\\x9b2J");          // a C1 control
  EXPECT_EQ(one_line("bad \xff\xc3"), "bad \\xff\\xc3");                        // not UTF-8
  const std::string capped = one_line(std::string(5000, 'x'));
  EXPECT_EQ(capped.size(), 2000u + 3u);
  EXPECT_EQ(capped.substr(2000), "\xe2\x80\xa6");
}

}  // namespace
}  // namespace bsms
