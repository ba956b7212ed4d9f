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

// Bounds on what bsms reads as JSON (every JSON file and JSON text it reads goes through
// parse_json_text): nesting deeper than kMaxJsonDepth levels is refused while parsing, before any
// recursive walk of the value (copy, dump, comparison) could overflow the stack; a file larger
// than kMaxJsonBytes is refused before it is read. Configs, run files and dataset metadata are a
// few kilobytes and a few levels deep.
inline constexpr int kMaxJsonDepth = 128;
inline constexpr size_t kMaxJsonBytes = size_t{64} << 20;

// Reads a whole input file of at most `limit` bytes. Only regular files: a FIFO, a device (e.g.
// /dev/zero) or a folder is refused before a byte is read, so reading cannot block or run
// without end. InputError names the path and `what` (e.g. "config file") when the file is
// missing, unreadable, not a regular file or larger than `limit`.
std::string read_text_file(const std::string& path, size_t limit, const std::string& what);

// The check of read_text_file for files read as streams (a training log): InputError unless
// `path` is an existing regular file.
void require_regular_file(const std::string& path, const std::string& what);

// Parses JSON text (comments allowed) from `source` (a file name, or e.g. "PATH: attribute
// scene"): InputError naming the source on malformed text, on nesting deeper than kMaxJsonDepth
// and on a key that appears twice in one object (naming its key path), instead of the last one
// silently winning.
Json parse_json_text(const std::string& text, const std::string& source);

// read_text_file + parse_json_text, and a JSON object at the top level.
Json load_json_file(const std::string& path, const std::string& what = "config file",
                    size_t limit = kMaxJsonBytes);

// A JSON value for a message, never the whole of it: its type and at most about 40 characters
// (a list of 500000 elements; the string "fast"; 1.5).
std::string describe_json(const Json& value);

// At most `max` characters of `text`, "..." marking a cut (keys and values named in messages).
std::string truncate_for_message(const std::string& text, size_t max = 40);

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
  std::string where() const {
    return file + (path.empty() ? "" : ": key '" + truncate_for_message(path, 200) + "'");
  }
};

// Records the key path of every key a JsonObjectReader is asked about (get, opt, has, raw),
// optional keys absent from the object included: what the parsers accept, learnt by running them.
// A test installs one around a parse to check that docs/configs.md names every key; none is
// installed otherwise, which costs one null check per key read. Not thread-safe: install it on the
// thread that parses, with no other parse running.
class ConfigKeyRecorder {
 public:
  struct Key {
    std::string file;  // the reader's JsonContext::file
    std::string path;  // dotted, list elements by index: "bodies.0.shape.type"
  };
  // Installs this recorder until it is destroyed (then the one installed before it is back).
  ConfigKeyRecorder() : previous_(active_) { active_ = this; }
  ~ConfigKeyRecorder() { active_ = previous_; }
  ConfigKeyRecorder(const ConfigKeyRecorder&) = delete;
  ConfigKeyRecorder& operator=(const ConfigKeyRecorder&) = delete;
  const std::vector<Key>& keys() const { return keys_; }
  // Records `key` of the object that `object` names, when a recorder is installed.
  static void record(const JsonContext& object, const std::string& key) {
    if (active_) active_->keys_.push_back({object.file, object.child(key).path});
  }

 private:
  inline static ConfigKeyRecorder* active_ = nullptr;
  ConfigKeyRecorder* previous_;
  std::vector<Key> keys_;
};

// Reads one JSON object strictly: call get/opt for each key, then finish() rejects the rest.
class JsonObjectReader {
 public:
  JsonObjectReader(const Json& object, JsonContext context);

  template <class T>
  T get(const std::string& key);  // required
  template <class T>
  T opt(const std::string& key, const T& fallback);
  bool has(const std::string& key) const {
    ConfigKeyRecorder::record(context_, key);
    return object_.contains(key);
  }
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
