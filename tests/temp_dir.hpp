// Scratch folders for the tests. ctest runs every test in its own process, several at a time, and
// a long-lived machine reuses process ids: a folder named by the process id can already hold an
// earlier run's files (a run folder with a checkpoint makes `bsms train` refuse to start). Each
// folder here is new (mkdtemp) and is removed when the test process exits, unless
// BSMS_KEEP_TEST_DIRS is set, for looking at a failed test's files.
#pragma once

#include <stdlib.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace bsms::testing {

namespace detail {
struct TempDirRegistry {
  std::mutex mutex;
  std::vector<std::filesystem::path> dirs;
  ~TempDirRegistry() {
    if (std::getenv("BSMS_KEEP_TEST_DIRS")) return;
    for (const auto& d : dirs) {
      std::error_code ec;
      std::filesystem::remove_all(d, ec);
    }
  }
};
inline TempDirRegistry& temp_dir_registry() {
  static TempDirRegistry registry;
  return registry;
}
}  // namespace detail

// A new empty folder /tmp/bsms_<tag>_XXXXXX of this process.
inline std::filesystem::path unique_temp_dir(const std::string& tag) {
  std::string name =
      (std::filesystem::temp_directory_path() / ("bsms_" + tag + "_XXXXXX")).string();
  if (::mkdtemp(name.data()) == nullptr)
    throw std::runtime_error("cannot create a temporary folder " + name);
  auto& registry = detail::temp_dir_registry();
  std::lock_guard<std::mutex> lock(registry.mutex);
  registry.dirs.emplace_back(name);
  return name;
}

}  // namespace bsms::testing
