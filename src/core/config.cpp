#include "core/config.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>

namespace bsms {

Json load_json_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open config file (missing or unreadable)");
  std::stringstream buffer;
  buffer << in.rdbuf();
  try {
    Json j = Json::parse(buffer.str(), nullptr, true, /*ignore_comments=*/true);
    if (!j.is_object()) throw InputError(path + ": expected a JSON object at the top level");
    return j;
  } catch (const nlohmann::json::exception& e) {  // parse_error, or out_of_range: 1e999
    throw InputError(path + ": malformed JSON (" + std::string(e.what()) + ")");
  }
}

void apply_override(Json& config, const std::string& assignment, const std::string& source) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(source + ": --set '" + assignment + "' must look like key.path=value");
  // JSON strings are UTF-8: other bytes would make every later dump() of the config (error
  // messages, the resolved config written next to outputs) throw nlohmann's type_error.
  try {
    (void)Json(assignment).dump();
  } catch (const nlohmann::json::type_error&) {
    throw InputError(source + ": --set assignment is not valid UTF-8 text");
  }
  const std::string key_path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  Json value;
  try {
    value = Json::parse(text);
  } catch (const nlohmann::json::exception&) {
    // Bare words are strings (--set solver.kernel=umls), and so is a number JSON cannot hold.
    value = text;
  }
  Json* node = &config;
  std::stringstream parts(key_path);
  std::string part, walked;
  std::vector<std::string> keys;
  while (std::getline(parts, part, '.')) {
    if (part.empty()) throw InputError(source + ": --set '" + assignment + "' has an empty key");
    keys.push_back(part);
  }
  for (size_t i = 0; i < keys.size(); ++i) {
    walked += (i ? "." : "") + keys[i];
    // A list element by index: bodies.0.spacing=0.1 (the index must exist).
    if (node->is_array() && !keys[i].empty() &&
        keys[i].find_first_not_of("0123456789") == std::string::npos) {
      // More digits than any list has elements: out of range without std::stoul's overflow.
      const size_t index = keys[i].size() > 9 ? node->size() : std::stoul(keys[i]);
      if (index >= node->size())
        throw InputError(source + ": --set '" + assignment + "': index " + keys[i] +
                         " is beyond the " + std::to_string(node->size()) + " elements of '" +
                         walked + "'");
      if (i + 1 == keys.size()) {
        (*node)[index] = value;
      } else {
        node = &(*node)[index];
      }
      continue;
    }
    if (!node->is_object())
      throw InputError(source + ": --set '" + assignment + "': '" + walked +
                       "' is inside a value that is not an object");
    if (i + 1 == keys.size()) {
      (*node)[keys[i]] = value;
    } else {
      node = &(*node)[keys[i]];
      if (node->is_null()) *node = Json::object();
    }
  }
}

JsonObjectReader::JsonObjectReader(const Json& object, JsonContext context)
    : object_(object), context_(std::move(context)) {
  if (!object_.is_object()) throw InputError(context_.where() + " must be a JSON object");
}

const Json& JsonObjectReader::raw(const std::string& key) {
  if (!object_.contains(key))
    throw InputError(context_.file + ": missing required key '" + context_.child(key).path + "'");
  used_.push_back(key);
  return object_.at(key);
}

void JsonObjectReader::finish() const {
  for (const auto& item : object_.items()) {
    if (std::find(used_.begin(), used_.end(), item.key()) != used_.end()) continue;
    std::vector<std::string> allowed = used_;
    std::sort(allowed.begin(), allowed.end());
    allowed.erase(std::unique(allowed.begin(), allowed.end()), allowed.end());
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    throw InputError(context_.file + ": unknown key '" + context_.child(item.key()).path +
                     "' (allowed: " + list + ")");
  }
}

void require(bool ok, const JsonContext& where, const std::string& expectation) {
  if (!ok) throw InputError(where.where() + " must be " + expectation);
}

}  // namespace bsms
