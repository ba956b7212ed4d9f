// libFuzzer target for the one JSON reader (core/config.hpp) and the message printer
// (core/one_line.hpp). The input is JSON text, optionally followed by NUL-separated `--set
// key.path=value` overrides. Checked on every input:
// - parse_json_text returns a value or throws InputError (never a crash, never a stack overflow:
//   the depth bound holds while parsing, and the value is then copied, dumped and compared, the
//   recursive walks that overflowed before);
// - it agrees with nlohmann's own parser: text it reads as a value nlohmann reads as the same
//   value, and text it calls malformed nlohmann rejects too; what it refuses beyond that is deeper
//   than kMaxJsonDepth or holds a duplicate key;
// - messages stay short: describe_json at most ~60 bytes, an InputError's message bounded, and
//   one_line of any message has no control character and at most 2000 bytes plus the ellipsis;
// - JsonObjectReader on the value (every key read as an integer, then finish) and apply_override
//   with the overrides refuse with InputError only, and keep the depth bound.
// Built with -DBSMS_FUZZ=ON and clang (`make fuzz`).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/config.hpp"
#include "core/error.hpp"
#include "core/one_line.hpp"
#include "seeds.hpp"

namespace {

// Nesting depth without recursion (a top-level scalar is 0, [] is 1).
int depth_of(const bsms::Json& root) {
  int deepest = 0;
  std::vector<std::pair<const bsms::Json*, int>> stack{{&root, 0}};
  while (!stack.empty()) {
    const auto [value, depth] = stack.back();
    stack.pop_back();
    if (!value->is_structured()) continue;
    deepest = std::max(deepest, depth + 1);
    for (const auto& child : *value) stack.push_back({&child, depth + 1});
  }
  return deepest;
}

void check_message(const std::string& message, size_t bound) {
  if (message.empty() || message.size() > bound) __builtin_trap();
  const std::string line = bsms::one_line(message);
  if (line.size() > 2000 + 3) __builtin_trap();
  for (const char c : line)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) __builtin_trap();
}

// Messages name a source and a key path (each cut to a few dozen characters) and at most 240
// characters of the parser's text.
constexpr size_t kMessageBound = 1200;

std::vector<uint8_t> bytes(const std::string& s) {
  return {s.begin(), s.end()};
}

// Seeds beside the shipped configs (`make fuzz` copies those): nesting around the bound, a long
// list, duplicate keys, control characters in keys and values, overrides.
std::vector<std::vector<uint8_t>> make_seeds() {
  const auto nested = [](int depth) {
    return "{\"a\": " + std::string(depth, '[') + std::string(depth, ']') + "}";
  };
  std::string list = "{\"model\": [";
  for (int i = 0; i < 5000; ++i) list += (i ? ",0" : "0");
  list += "]}";
  return {bytes(nested(bsms::kMaxJsonDepth - 1)),
          bytes(nested(bsms::kMaxJsonDepth)),
          bytes(nested(400)),
          bytes(std::string(300, '[')),
          bytes("[{\"a\": [{\"b\": [{\"c\": {\"d\": [[[1, 2], {\"e\": null}]]}}]}]}]"),
          bytes(list),
          bytes(R"({"model": {"type": "bsms", "latent": 8, "type": "mgn"}})"),
          bytes(R"({"a": [{"x": 1}, {"x": 2, "y": 3, "x": 4}]})"),
          bytes("{\"col\\u001b[31mour\\n\": \"v\\u0000\\r\", \"\\u0085\": 1e308}"),
          bytes("{\"a\": 1, // comment\n \"b\": /* c */ [true, false, null, -0.0, 1e-320]}"),
          bytes(std::string("{\"solver\": {\"cfl\": 0.5}}") + '\0' + "solver.cfl=[[1]]" + '\0' +
                "output.frames.0=2" + '\0' + "m={\"t\": 1, \"t\": 2}"),
          bytes(std::string("{\"bodies\": [{\"spacing\": 1}]}") + '\0' + "bodies.0.spacing=" +
                std::string(200, '[') + '\0' + "a.a.a.a.a.a.a.a.a.a.a.a.a.a.a.a=1")};
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(make_seeds);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> parts;
  for (size_t start = 0;;) {
    const size_t nul = input.find('\0', start);
    parts.push_back(input.substr(start, nul == std::string::npos ? nul : nul - start));
    if (nul == std::string::npos || parts.size() == 5) break;
    start = nul + 1;
  }
  const std::string& text = parts[0];

  bsms::Json value;
  bool parsed = false;
  try {
    value = bsms::parse_json_text(text, "fuzz.json");
    parsed = true;
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
    check_message(e.what(), kMessageBound);
    const std::string what = e.what();
    // Malformed for this reader is malformed for nlohmann's.
    if (what.find("malformed JSON") != std::string::npos &&
        bsms::Json::accept(text, /*ignore_comments=*/true))
      __builtin_trap();
  }
  if (parsed) {
    if (depth_of(value) > bsms::kMaxJsonDepth) __builtin_trap();
    const bsms::Json reference = bsms::Json::parse(text, nullptr, false, true);
    if (reference.is_discarded() || reference != value) __builtin_trap();
    // The walks that recursed without end on deep input: copy, dump, compare.
    const bsms::Json copy = value;
    const std::string dumped = copy.dump(-1, ' ', false, bsms::Json::error_handler_t::replace);
    if (copy != value || dumped.empty()) __builtin_trap();
    if (bsms::describe_json(value).size() > 60) __builtin_trap();
    if (value.is_object()) {
      try {
        bsms::JsonObjectReader reader(value, {"fuzz.json", "top"});
        for (const auto& item : value.items()) {
          try {
            (void)reader.get<int>(item.key());
          } catch (const bsms::InputError& e) {
            check_message(e.what(), kMessageBound);
          }
          if (bsms::describe_json(item.value()).size() > 60) __builtin_trap();
        }
        reader.finish();
      } catch (const bsms::InputError& e) {
        check_message(e.what(), kMessageBound);
      }
      bsms::Json changed = value;
      try {
        for (size_t i = 1; i < parts.size(); ++i)
          bsms::apply_override(changed, parts[i], "--set " + parts[i]);
        if (depth_of(changed) > bsms::kMaxJsonDepth) __builtin_trap();
        (void)changed.dump(-1, ' ', false, bsms::Json::error_handler_t::replace);
      } catch (const bsms::InputError& e) {
        bsms_fuzz::refused(e);
        check_message(e.what(), kMessageBound);
      }
    }
  }
  return 0;
}
