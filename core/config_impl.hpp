// Template definitions for config.hpp.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>

namespace bsms {

template <class T>
T JsonObjectReader::convert(const Json& value, const std::string& key) const {
  const JsonContext where = context_.child(key);
  try {
    if constexpr (std::is_same_v<T, bool>) {
      if (!value.is_boolean())
        throw InputError(where.where() + " must be true or false, got " + describe_json(value));
    } else if constexpr (std::is_integral_v<T>) {
      if (!value.is_number_integer())
        throw InputError(where.where() + " must be an integer, got " + describe_json(value));
      // In the range of T: a negative seed must not wrap to 2^64 - 1.
      const bool fits =
          value.is_number_unsigned()
              ? value.get<uint64_t>() <= static_cast<uint64_t>(std::numeric_limits<T>::max())
              : value.get<int64_t>() >= static_cast<int64_t>(std::numeric_limits<T>::min()) &&
                    (value.get<int64_t>() < 0 ||
                     static_cast<uint64_t>(value.get<int64_t>()) <=
                         static_cast<uint64_t>(std::numeric_limits<T>::max()));
      if (!fits)
        throw InputError(where.where() + " must be an integer in [" +
                         std::to_string(std::numeric_limits<T>::min()) + ", " +
                         std::to_string(std::numeric_limits<T>::max()) + "], got " +
                         describe_json(value));
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!value.is_number())
        throw InputError(where.where() + " must be a number, got " + describe_json(value));
      const double v = value.get<double>();
      if (!std::isfinite(v)) throw InputError(where.where() + " must be finite");
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!value.is_string())
        throw InputError(where.where() + " must be a string, got " + describe_json(value));
    }
    return value.get<T>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where.where() + " has the wrong type: " + e.what());
  }
}

template <class T>
T JsonObjectReader::get(const std::string& key) {
  ConfigKeyRecorder::record(context_, key);
  if (!object_.contains(key))
    throw InputError(context_.file + ": missing required key '" + context_.child(key).path + "'");
  used_.push_back(key);
  return convert<T>(object_.at(key), key);
}

template <class T>
T JsonObjectReader::opt(const std::string& key, const T& fallback) {
  ConfigKeyRecorder::record(context_, key);
  used_.push_back(key);
  if (!object_.contains(key)) return fallback;
  return convert<T>(object_.at(key), key);
}

}  // namespace bsms
