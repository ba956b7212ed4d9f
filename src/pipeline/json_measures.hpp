// Measures in the run files' JSON: JSON has no NaN, so a non-finite measure (an error, a loss) is
// written as null and read back as NaN, and a figure that may be absent is std::optional, null
// when absent. Shared by the typed run files (rollout_metrics, train_stats).
#pragma once

#include <cmath>
#include <optional>

#include "core/config.hpp"

namespace bsms {

inline Json measure_json(double value) {
  return std::isfinite(value) ? Json(value) : Json(nullptr);
}

inline Json nullable_json(const std::optional<double>& value) {
  return value ? Json(*value) : Json(nullptr);
}

// A number, or null read as NaN.
inline double measure_from_json(const Json& value, const JsonContext& where) {
  if (value.is_null()) return std::nan("");
  require(value.is_number(), where, "a number or null");
  return value.get<double>();
}

inline double read_measure(JsonObjectReader& r, const std::string& key) {
  return measure_from_json(r.raw(key), r.context(key));
}

// A number, or null for none.
inline std::optional<double> read_nullable(JsonObjectReader& r, const std::string& key) {
  const Json& value = r.raw(key);
  if (value.is_null()) return std::nullopt;
  require(value.is_number(), r.context(key), "a number or null");
  return value.get<double>();
}

}  // namespace bsms
