// Measures in the run files' JSON: JSON has no NaN, so a non-finite measure (an error, a loss) is
// written as null and read back as NaN, and a figure that may be absent is std::optional, null
// when absent. Shared by the typed run files (rollout_metrics, train_stats).
#pragma once

#include <cmath>
#include <optional>
#include <string>

#include "core/config.hpp"

namespace bsms {

inline Json measure_json(double value) {
  return std::isfinite(value) ? Json(value) : Json(nullptr);
}

inline Json nullable_json(const std::optional<double>& value) {
  return value ? Json(*value) : Json(nullptr);
}

// Every number is checked where it is read: JSON numbers are finite (the reader refuses 1e999),
// and each figure has its range. Errors, losses, times, sizes and counts are >= 0.

// A number >= `lowest`; the message names the file, the key and the value.
inline double number_at_least(const Json& value, double lowest, const JsonContext& where) {
  if (!value.is_number() || !(value.get<double>() >= lowest))
    throw InputError(where.where() + " must be a number >= " + Json(lowest).dump() + ", got " +
                     describe_json(value));
  return value.get<double>();
}

inline double read_at_least(JsonObjectReader& r, const std::string& key, double lowest = 0.0) {
  return number_at_least(r.raw(key), lowest, r.context(key));
}

// An integer >= `lowest`.
template <class T>
T read_int_at_least(JsonObjectReader& r, const std::string& key, T lowest) {
  const T value = r.get<T>(key);
  if (value < lowest)
    throw InputError(r.context(key).where() + " must be an integer >= " + std::to_string(lowest) +
                     ", got " + std::to_string(value));
  return value;
}

// A measure (an error or a loss, >= 0), or null read as NaN (it diverged; a value built in
// memory, not read from a file, may hold the NaN itself).
inline double measure_from_json(const Json& value, const JsonContext& where) {
  if (value.is_null() || (value.is_number_float() && std::isnan(value.get<double>())))
    return std::nan("");
  if (!value.is_number() || !(value.get<double>() >= 0.0))
    throw InputError(where.where() + " must be a number >= 0 or null, got " + describe_json(value));
  return value.get<double>();
}

inline double read_measure(JsonObjectReader& r, const std::string& key) {
  return measure_from_json(r.raw(key), r.context(key));
}

// A figure >= 0, or null for none.
inline std::optional<double> read_nullable(JsonObjectReader& r, const std::string& key) {
  const Json& value = r.raw(key);
  if (value.is_null()) return std::nullopt;
  return number_at_least(value, 0.0, r.context(key));
}

}  // namespace bsms
