// libFuzzer target for the JSON configs: the input is a config file's text,
// optionally followed by NUL-separated `--set key.path=value` overrides. The text is loaded with
// load_json_file (from a file, as the CLI does), the overrides are applied with apply_override,
// and the result is read as a train config (and its to_json round trip), as a scene (parse_scene
// and check_scene_size with a fixed 1 GB memory limit, never meshed) and as a scene family
// (parse_family, which draws and parses one scene; never meshed). InputError is the only allowed
// outcome of bad input. Built with -DBSMS_FUZZ=ON and clang (`make fuzz`).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "core/error.hpp"
#include "data/generate/family.hpp"
#include "data/mpm/scene_config.hpp"
#include "data/mpm/scene_size.hpp"
#include "pipeline/runs/train_config.hpp"
#include "seeds.hpp"

namespace {

// A per-process file on tmpfs where possible, removed when the process exits normally.
const std::string& config_path() {
  struct Scratch {
    std::string path;
    ~Scratch() { std::remove(path.c_str()); }
  };
  static const Scratch scratch{std::string(::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp") +
                               "/bsms-fuzz-config-" + std::to_string(::getpid()) + ".json"};
  return scratch.path;
}

void write_file(const std::string& path, const std::string& text) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) __builtin_trap();
  if (!text.empty() && std::fwrite(text.data(), 1, text.size(), f) != text.size()) __builtin_trap();
  std::fclose(f);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> parts;
  size_t start = 0;
  for (;;) {
    const size_t nul = input.find('\0', start);
    parts.push_back(
        input.substr(start, nul == std::string::npos ? std::string::npos : nul - start));
    if (nul == std::string::npos || parts.size() == 9) break;
    start = nul + 1;
  }
  write_file(config_path(), parts[0]);
  bsms::Json json;
  try {
    json = bsms::load_json_file(config_path());
    for (size_t i = 1; i < parts.size(); ++i)
      bsms::apply_override(json, parts[i], "--set " + parts[i]);
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
    return 0;
  }
  try {
    const bsms::TrainConfig config = bsms::parse_train_config(json, "fuzz/train.json");
    // What a run saves must read back (resume compares them).
    const bsms::TrainConfig again =
        bsms::parse_train_config(bsms::to_json(config), "fuzz/train.json (saved)");
    if (bsms::to_json(again) != bsms::to_json(config)) __builtin_trap();
    (void)bsms::learning_rate(config.optimizer, config.optimizer.warmup_steps / 2, 0.5);
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  try {
    const bsms::mpm::Scene scene = bsms::mpm::parse_scene(json, "fuzz/scene.json");
    bsms::mpm::check_scene_size(scene, 1e9);
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  try {
    const bsms::generate::FamilyConfig family =
        bsms::generate::parse_family(json, "fuzz/family.json");
    (void)family;
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  return 0;
}
