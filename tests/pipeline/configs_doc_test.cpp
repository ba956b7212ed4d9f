// docs/configs.md against the parsers. ConfigKeyRecorder records every key the scene, family and
// training parsers ask about while they parse every shipped config (and a few variants that take
// the branches no shipped config takes); the doc's tables for that config type must name exactly
// those keys: a key the parser accepts without a row fails, and so does a row for a key no parser
// reads. In this executable because it is the one that links all three parsers.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "data/generate/family.hpp"
#include "data/mpm/scene_config.hpp"
#include "pipeline/runs/train_config.hpp"

namespace bsms {
namespace configs_doc {

namespace fs = std::filesystem;

const fs::path kRoot = BSMS_SOURCE_DIR;
const fs::path kDoc = kRoot / "docs" / "configs.md";

// Headings of docs/configs.md whose tables list the keys (a heading line starts with these).
const std::string kSceneSection = "## Scene configs";
const std::string kFamilyTopSection = "### Family top level";
const std::string kRangeSection = "### Ranges";
const std::string kTrainSection = "## Training configs";
const std::string kShippedSection = "## Shipped configs";
std::string family_section(const std::string& family) {
  return "### `sample` of family `" + family + "`";
}

// Key path -> the first config file it was recorded from (for messages).
using KeyPaths = std::map<std::string, std::string>;

// A recorded path as the doc writes it: list elements as [] ("bodies.0.shape.type" ->
// "bodies[].shape.type"). The key of a range object ("sample.load.log_uniform", the range form
// {"log_uniform": [min, max]} of any range) is the one row "log_uniform" of the ranges table.
std::string doc_path(const std::string& path) {
  std::string out, part, last;
  std::stringstream parts(path);
  while (std::getline(parts, part, '.')) {
    if (!part.empty() && part.find_first_not_of("0123456789") == std::string::npos)
      out += "[]";
    else
      out += (out.empty() ? "" : ".") + part;
    last = part;
  }
  return last == "log_uniform" ? last : out;
}

std::vector<std::string> doc_lines() {
  std::ifstream in(kDoc);
  EXPECT_TRUE(in.good()) << kDoc;
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

int heading_level(const std::string& line) {
  const size_t n = line.find_first_not_of('#');
  return n != std::string::npos && n > 0 && line[n] == ' ' ? static_cast<int>(n) : 0;
}

// The lines of the section whose heading starts with `heading`, up to the next heading of the same
// or a higher level (headings inside ``` blocks do not count).
std::vector<std::string> section(const std::string& heading) {
  const std::vector<std::string> lines = doc_lines();
  std::vector<std::string> out;
  int level = 0;
  bool fenced = false;
  for (const std::string& line : lines) {
    if (line.rfind("```", 0) == 0) fenced = !fenced;
    const int h = fenced ? 0 : heading_level(line);
    if (level > 0) {
      if (h > 0 && h <= level) break;
      out.push_back(line);
    } else if (line.rfind(heading, 0) == 0) {
      level = h;
    }
  }
  EXPECT_GT(level, 0) << kDoc << ": no heading '" << heading << "'";
  return out;
}

// The key paths of the section's tables: the first cell of each row, in backticks.
std::set<std::string> documented_keys(const std::string& heading) {
  std::set<std::string> keys;
  for (const std::string& line : section(heading)) {
    if (line.rfind("| `", 0) != 0) continue;
    const size_t end = line.find('`', 3);
    if (end != std::string::npos) keys.insert(line.substr(3, end - 3));
  }
  return keys;
}

// Both ways: every recorded key has a row, every row is a recorded key.
void expect_documented(const KeyPaths& recorded, const std::string& heading) {
  const std::set<std::string> rows = documented_keys(heading);
  for (const auto& [path, file] : recorded)
    EXPECT_TRUE(rows.count(path) == 1)
        << kDoc << ", section '" << heading << "': no row for key `" << path
        << "`, which the parser accepts (asked for while parsing " << file << ")";
  for (const std::string& row : rows)
    EXPECT_TRUE(recorded.count(row) == 1)
        << kDoc << ", section '" << heading << "': row `" << row
        << "` is no key the parser asked for in any config this test parses (a key removed from "
           "the parser, or a branch no input takes: add a variant here)";
}

void add(KeyPaths& paths, const std::string& path, const std::string& file) {
  paths.emplace(doc_path(path), file);
}

std::vector<fs::path> shipped(const std::string& folder) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(kRoot / "configs" / folder))
    if (entry.path().extension() == ".json") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// The keys of scene configs: the shipped scenes, the scenes drawn from the shipped families (their
// parse_family parses one draw), and variants for the branches none of them takes.
TEST(ConfigsDoc, EverySceneKeyHasARowAndEveryRowIsAKey) {
  ConfigKeyRecorder recorder;
  for (const fs::path& file : shipped("scenes")) (void)mpm::load_scene(file.string());
  const std::string disks = (kRoot / "configs/scenes/colliding_disks.json").string();
  const std::string sphere = (kRoot / "configs/scenes/sphere_expansion.json").string();
  // Mesh files are named, not read, by the parser.
  (void)mpm::load_scene(disks,
                        {"background={\"type\": \"mesh\", \"path\": \"background.msh\"}",
                         "bodies.0.shape={\"type\": \"mesh\", \"path\": \"body.msh\"}",
                         "bodies.1.velocity={\"type\": \"rotation\", \"center\": [0.5, 0.5], "
                         "\"angular_velocity\": 1.0}"});
  (void)mpm::load_scene(sphere, {"bodies.0.shape={\"type\": \"sphere\", \"center\": [0, 0, 0], "
                                 "\"radius\": 0.1}",
                                 "bodies.0.sampling=nodes"});
  for (const fs::path& file : shipped("families")) (void)generate::load_family(file.string());
  KeyPaths scene;
  for (const auto& key : recorder.keys()) {
    const bool family = key.file.rfind((kRoot / "configs/families").string(), 0) == 0;
    // A family's own keys are checked below; the scene drawn from it is "FILE (scene drawn ...)".
    if (!family || key.file.find(" (scene drawn") != std::string::npos)
      add(scene, key.path, key.file);
  }
  EXPECT_GE(scene.size(), 40u);
  expect_documented(scene, kSceneSection);
}

// The keys of family configs: the top level, each family's `sample` and the range form.
TEST(ConfigsDoc, EveryFamilyKeyHasARowAndEveryRowIsAKey) {
  KeyPaths top, ranges;
  std::map<std::string, KeyPaths> samples;  // family -> its sample keys
  const auto parse = [&](const fs::path& file, const std::vector<std::string>& sets) {
    ConfigKeyRecorder recorder;
    const generate::FamilyConfig config = generate::load_family(file.string(), sets);
    for (const auto& key : recorder.keys()) {
      if (key.file != file.string()) continue;  // the scene drawn from it (scene keys)
      const std::string path = doc_path(key.path);
      KeyPaths& into = path == "log_uniform"           ? ranges
                       : path.rfind("sample.", 0) == 0 ? samples[config.family]
                                                       : top;
      into.emplace(path, file.string());
    }
  };
  for (const fs::path& file : shipped("families")) parse(file, {});
  // No shipped family uses the log-uniform form (allowed wherever a range is).
  parse(kRoot / "configs/families/cantilever2d.json",
        {R"(sample.load={"log_uniform": [5.0, 15.0]})"});
  EXPECT_EQ(samples.size(), 5u) << "a shipped config per family (disks, press, cantilever, union, "
                                   "bodies)";
  expect_documented(top, kFamilyTopSection);
  expect_documented(ranges, kRangeSection);
  for (const auto& [family, keys] : samples) expect_documented(keys, family_section(family));
}

TEST(ConfigsDoc, EveryTrainingKeyHasARowAndEveryRowIsAKey) {
  ConfigKeyRecorder recorder;
  for (const fs::path& file : shipped("train"))
    (void)parse_train_config(load_json_file(file.string()), file.string());
  KeyPaths keys;
  for (const auto& key : recorder.keys()) add(keys, key.path, key.file);
  EXPECT_GE(keys.size(), 30u);
  expect_documented(keys, kTrainSection);
}

// The doc lists every file under configs/ (one line each), and only those.
TEST(ConfigsDoc, EveryShippedConfigFileIsListed) {
  std::set<std::string> files, listed;
  for (const auto& entry : fs::recursive_directory_iterator(kRoot / "configs"))
    if (entry.is_regular_file()) files.insert(fs::relative(entry.path(), kRoot).generic_string());
  for (const std::string& line : section(kShippedSection)) {
    const std::string item = "- `configs/";
    if (line.rfind(item, 0) != 0) continue;
    const size_t end = line.find('`', 3);
    if (end != std::string::npos) listed.insert(line.substr(3, end - 3));
  }
  for (const std::string& f : files)
    EXPECT_TRUE(listed.count(f) == 1) << kDoc << ": shipped config " << f << " is not listed";
  for (const std::string& f : listed)
    EXPECT_TRUE(files.count(f) == 1) << kDoc << ": lists " << f << ", which is not in configs/";
  EXPECT_GE(files.size(), 22u);
}

}  // namespace configs_doc
}  // namespace bsms
