// Built-in seeds of the fuzz targets whose inputs are encoded structures (no shipped file has
// their format): `BSMS_FUZZ_WRITE_SEEDS=DIR <target>` writes them to DIR and exits.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

namespace bsms_fuzz {

// Writes the seeds `make_seeds()` returns into $BSMS_FUZZ_WRITE_SEEDS and exits, when it is set.
template <class F>
void maybe_write_seeds(F make_seeds) {
  const char* dir = std::getenv("BSMS_FUZZ_WRITE_SEEDS");
  if (!dir) return;
  std::filesystem::create_directories(dir);
  int i = 0;
  for (const std::vector<uint8_t>& seed : make_seeds()) {
    const std::string path = std::string(dir) + "/seed-" + std::to_string(i++);
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f || std::fwrite(seed.data(), 1, seed.size(), f) != seed.size()) std::exit(1);
    std::fclose(f);
  }
  std::printf("wrote %d seeds to %s\n", i, dir);
  std::exit(0);
}

// With BSMS_FUZZ_VERBOSE set, says why an input was refused (to check seeds and crashes).
inline void refused(const std::exception& e) {
  static const bool verbose = std::getenv("BSMS_FUZZ_VERBOSE") != nullptr;
  if (verbose) std::fprintf(stderr, "refused: %s\n", e.what());
}

}  // namespace bsms_fuzz
