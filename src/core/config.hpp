// JSON configuration: loading, `--set key.path=value` overrides, strict key checking.
// Each config concern is one typed struct read through these helpers; an unknown, missing or
// mistyped key is an InputError naming the file, the key and what is allowed.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace bsms {

using Json = nlohmann::json;

// Parses a JSON file; InputError names the file and the parse position on failure.
Json load_json_file(const std::string& path);

// Applies "a.b.c=value" (value parsed as JSON, else taken as a string). Creates missing keys;
// the typed reader then rejects keys it does not know. `source` names the origin in errors.
void apply_override(Json& config, const std::string& assignment, const std::string& source);

// Context for error messages: the file and the key path inside it.
struct JsonContext {
  std::string file;
  std::string path;  // e.g. "solver.material"
  JsonContext child(const std::string& key) const {
    return {file, path.empty() ? key : path + "." + key};
  }
  std::string where() const { return file + (path.empty() ? "" : ": key '" + path + "'"); }
};

// Reads one JSON object strictly: call get/opt for each key, then finish() rejects the rest.
class JsonObjectReader {
 public:
  JsonObjectReader(const Json& object, JsonContext context);

  template <class T>
  T get(const std::string& key);  // required
  template <class T>
  T opt(const std::string& key, const T& fallback);
  bool has(const std::string& key) const { return object_.contains(key); }
  const Json& raw(const std::string& key);  // required, any type; marks the key used
  JsonContext context(const std::string& key) const { return context_.child(key); }
  void finish() const;  // InputError on any key never read, listing the allowed keys

 private:
  template <class T>
  T convert(const Json& value, const std::string& key) const;
  const Json& object_;
  JsonContext context_;
  std::vector<std::string> used_;
};

// Range checks that produce uniform messages: "<where>: <value> is not <expectation>".
void require(bool ok, const JsonContext& where, const std::string& expectation);

}  // namespace bsms

#include "core/config_impl.hpp"
