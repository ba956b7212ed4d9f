// Strict readers of a family's "sample" ranges (family.hpp): a number (fixed) or [min, max]
// (uniform), integer ranges, per-component vector ranges and materials with a range per numeric
// parameter. Each names the file and key of a bad value (InputError). A positive quantity that
// spans decades (a Young's modulus swept from jelly to rubber) may be {"log_uniform": [min, max]}:
// uniform in log, so that every decade gets as many draws.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/config.hpp"
#include "data/generate/rng.hpp"

namespace bsms::generate::families {

struct Range {
  double min = 0.0, max = 0.0;
  bool log = false;  // log-uniform (min > 0)
  // One uniform draw either way, so a draw's other values do not depend on this choice.
  double sample(Rng& rng) const {
    return log ? std::exp(rng.uniform(std::log(min), std::log(max))) : rng.uniform(min, max);
  }
};

// `kPositive`: both ends must be > 0 (sizes, moduli, densities); `kNonNegative`: ≥ 0 (speeds,
// gaps).
enum class Sign { kAny, kNonNegative, kPositive };

Range range_from(const Json& j, const JsonContext& ctx, Sign sign);
Range read_range(JsonObjectReader& r, const std::string& key, Sign sign);

struct IntRange {
  int64_t min = 0, max = 0;
};

// Inclusive; both ends at least `lowest`.
IntRange read_int_range(JsonObjectReader& r, const std::string& key, int64_t lowest);

// Per-component ranges of a vector, e.g. gravity [[0, 0], [-9.81, -1]].
std::vector<Range> read_vector_range(JsonObjectReader& r, const std::string& key, int dim);
std::vector<double> sample_vector(const std::vector<Range>& ranges, Rng& rng);

// A material with a range per numeric parameter; string parameters (the model) are copied.
struct MaterialRange {
  std::vector<std::pair<std::string, std::string>> strings;
  std::vector<std::pair<std::string, Range>> numbers;
  Json sample(Rng& rng) const;
};

MaterialRange read_material(JsonObjectReader& r, const std::string& key);

}  // namespace bsms::generate::families
