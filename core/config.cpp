#include "core/config.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <sstream>

namespace bsms {

std::string truncate_for_message(const std::string& text, size_t max) {
  if (text.size() <= max) return text;
  size_t cut = max;
  // Never half a UTF-8 character: back up to the start of the one the cut falls in.
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
  return text.substr(0, cut) + "...";
}

std::string describe_json(const Json& value) {
  const auto count = [](size_t n, const char* one, const char* many) {
    return std::to_string(n) + " " + (n == 1 ? one : many);
  };
  switch (value.type()) {
    case Json::value_t::array:
      return "a list of " + count(value.size(), "element", "elements");
    case Json::value_t::object:
      return "an object of " + count(value.size(), "key", "keys");
    case Json::value_t::string:
      // ensure_ascii: escapes only, so the cut cannot split a character.
      return "the string " +
             truncate_for_message(value.dump(-1, ' ', true, Json::error_handler_t::replace));
    case Json::value_t::binary:
      return "binary data";
    case Json::value_t::discarded:
      return "no value";
    default:  // null, true, false, a number
      return truncate_for_message(value.dump());
  }
}

namespace {

std::string byte_size(size_t bytes) {
  if (bytes % (size_t{1} << 20) == 0) return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

std::string file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a named pipe";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

struct FileDescriptor {
  int fd = -1;
  ~FileDescriptor() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

void require_regular_file(const std::string& path, const std::string& what) {
  // stat, not open: opening some devices has effects of its own, and opening a FIFO waits for a
  // writer.
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    throw InputError(path + ": cannot open " + what + " (" + std::strerror(err) + ")");
  }
  if (!S_ISREG(st.st_mode))
    throw InputError(path + ": cannot read " + what + " (" + file_kind(st.st_mode) +
                     ", not a regular file)");
}

std::string read_text_file(const std::string& path, size_t limit, const std::string& what) {
  const auto refused = [&](const std::string& why) {
    return InputError(path + ": cannot read " + what + " (" + why + ")");
  };
  require_regular_file(path, what);
  struct stat st {};
  // Opened without blocking and checked again: the path may have been replaced since the stat.
  FileDescriptor file{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  if (file.fd < 0) {
    const int err = errno;
    throw InputError(path + ": cannot open " + what + " (" + std::strerror(err) + ")");
  }
  if (::fstat(file.fd, &st) != 0 || !S_ISREG(st.st_mode))
    throw refused(file_kind(st.st_mode) + ", not a regular file");
  const std::string too_large = "larger than " + byte_size(limit);
  if (static_cast<uint64_t>(st.st_size) > limit) throw refused(too_large);
  std::string text;
  text.reserve(static_cast<size_t>(st.st_size));
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(file.fd, buffer, sizeof buffer);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw refused(std::strerror(errno));
    }
    if (n == 0) break;
    // The size may grow while it is read (a file still being written): the bound holds anyway.
    if (text.size() + static_cast<size_t>(n) > limit) throw refused(too_large);
    text.append(buffer, static_cast<size_t>(n));
  }
  return text;
}

namespace {

// Builds the value of a SAX parse like nlohmann's DOM parser, with an explicit stack (no
// recursion), a bound on nesting and a refusal of duplicate keys.
class BoundedJsonBuilder {
 public:
  using number_integer_t = Json::number_integer_t;
  using number_unsigned_t = Json::number_unsigned_t;
  using number_float_t = Json::number_float_t;
  using string_t = Json::string_t;
  using binary_t = Json::binary_t;

  enum class Failure { kNone, kMalformed, kBounds };

  BoundedJsonBuilder(std::string source, int max_depth)
      : source_(std::move(source)), max_depth_(max_depth) {}

  bool null() { return add(Json(nullptr)); }
  bool boolean(bool v) { return add(Json(v)); }
  bool number_integer(number_integer_t v) { return add(Json(v)); }
  bool number_unsigned(number_unsigned_t v) { return add(Json(v)); }
  bool number_float(number_float_t v, const string_t&) { return add(Json(v)); }
  bool string(string_t& v) { return add(Json(std::move(v))); }
  bool binary(binary_t& v) { return add(Json::binary(std::move(v))); }
  bool start_object(std::size_t) { return open(Json::object()); }
  bool start_array(std::size_t) { return open(Json::array()); }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool key(string_t& k) {
    Frame& top = stack_.back();
    if (top.value.contains(k))
      return fail(Failure::kBounds, source_ + ": duplicate key '" + path(&k) +
                                        "' (a key may appear once in an object; which one "
                                        "counts would be a guess)");
    top.key = std::move(k);
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) {
    // The parser's message names the line and column; its last token is cut short.
    return fail(Failure::kMalformed,
                source_ + ": malformed JSON (" + truncate_for_message(e.what(), 240) + ")");
  }

  bool refuse(const std::string& why) { return fail(Failure::kBounds, source_ + ": " + why); }
  Failure failure() const { return failure_; }
  const std::string& error() const { return error_; }
  Json take() { return std::move(result_); }

 private:
  struct Frame {
    Json value;
    std::string key;  // objects: the key of the value being read
  };

  bool fail(Failure kind, std::string message) {
    if (failure_ == Failure::kNone) {
      failure_ = kind;
      error_ = std::move(message);
    }
    return false;
  }
  // The key path of the value being read ("model.mp_per_level.2"), then `last`.
  std::string path(const std::string* last = nullptr) const {
    std::string p;
    for (const Frame& f : stack_) {
      if (&f == &stack_.back() && last) break;
      p += (p.empty() ? "" : ".") +
           (f.value.is_array() ? std::to_string(f.value.size()) : truncate_for_message(f.key));
    }
    if (last) p += (p.empty() ? "" : ".") + truncate_for_message(*last);
    return truncate_for_message(p, 200);
  }
  bool open(Json container) {
    if (static_cast<int>(stack_.size()) >= max_depth_) {
      const std::string where = path();
      return fail(
          Failure::kBounds,
          source_ + ": lists and objects nested deeper than " + std::to_string(max_depth_) +
              " levels" +
              (where.empty() ? std::string() : " (at '" + truncate_for_message(where, 60) + "')"));
    }
    stack_.push_back({std::move(container), {}});
    return true;
  }
  bool close() {
    Json done = std::move(stack_.back().value);
    stack_.pop_back();
    return add(std::move(done));
  }
  bool add(Json v) {
    if (stack_.empty()) {
      result_ = std::move(v);
      return true;
    }
    Frame& top = stack_.back();
    if (top.value.is_object())
      top.value.get_ref<Json::object_t&>().emplace(std::move(top.key), std::move(v));
    else
      top.value.get_ref<Json::array_t&>().push_back(std::move(v));
    return true;
  }

  std::string source_;
  int max_depth_;
  std::vector<Frame> stack_;
  Json result_;
  Failure failure_ = Failure::kNone;
  std::string error_;
};

// Parses `text`; on failure returns false with the builder's verdict.
bool parse_bounded(const std::string& text, bool comments, BoundedJsonBuilder& builder) {
  if (text.size() > kMaxJsonBytes) return builder.refuse("larger than " + byte_size(kMaxJsonBytes));
  return Json::sax_parse(text, &builder, Json::input_format_t::json, /*strict=*/true, comments);
}

}  // namespace

Json parse_json_text(const std::string& text, const std::string& source) {
  BoundedJsonBuilder builder(source, kMaxJsonDepth);
  if (!parse_bounded(text, /*comments=*/true, builder)) throw InputError(builder.error());
  return builder.take();
}

Json load_json_file(const std::string& path, const std::string& what, size_t limit) {
  Json j = parse_json_text(read_text_file(path, limit, what), path);
  if (!j.is_object())
    throw InputError(path + ": expected a JSON object at the top level, got " + describe_json(j));
  return j;
}

void apply_override(Json& config, const std::string& assignment, const std::string& source_in) {
  // Callers name the assignment in `source`; neither is shown whole.
  const std::string source = truncate_for_message(source_in, 120);
  const std::string shown = truncate_for_message(assignment, 80);
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(source + ": --set '" + shown + "' must look like key.path=value");
  // JSON strings are UTF-8: other bytes would make every later dump() of the config (error
  // messages, the resolved config written next to outputs) throw nlohmann's type_error.
  try {
    (void)Json(assignment).dump();
  } catch (const nlohmann::json::type_error&) {
    throw InputError(source + ": --set assignment is not valid UTF-8 text");
  }
  const std::string key_path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  std::stringstream parts(key_path);
  std::string part, walked;
  std::vector<std::string> keys;
  while (std::getline(parts, part, '.')) {
    if (part.empty()) throw InputError(source + ": --set '" + shown + "' has an empty key");
    keys.push_back(part);
  }
  // The key path and the value nest together: the bound on files holds for the result.
  if (keys.size() >= static_cast<size_t>(kMaxJsonDepth))
    throw InputError(source + ": --set key path of " + std::to_string(keys.size()) +
                     " keys (at most " + std::to_string(kMaxJsonDepth - 1) + ")");
  Json value;
  BoundedJsonBuilder builder(source + ": --set value of '" + truncate_for_message(key_path) + "'",
                             kMaxJsonDepth - static_cast<int>(keys.size()));
  if (parse_bounded(text, /*comments=*/false, builder)) {
    value = builder.take();
  } else if (builder.failure() == BoundedJsonBuilder::Failure::kMalformed) {
    // Bare words are strings (--set solver.kernel=umls), and so is a number JSON cannot hold.
    value = text;
  } else {
    throw InputError(builder.error());  // too deep, or a duplicate key
  }
  Json* node = &config;
  for (size_t i = 0; i < keys.size(); ++i) {
    walked += (i ? "." : "") + keys[i];
    // A list element by index: bodies.0.spacing=0.1 (the index must exist).
    if (node->is_array() && !keys[i].empty() &&
        keys[i].find_first_not_of("0123456789") == std::string::npos) {
      // More digits than any list has elements: out of range without std::stoul's overflow.
      const size_t index = keys[i].size() > 9 ? node->size() : std::stoul(keys[i]);
      if (index >= node->size())
        throw InputError(source + ": --set '" + shown + "': index " +
                         truncate_for_message(keys[i]) + " is beyond the " +
                         std::to_string(node->size()) + " elements of '" +
                         truncate_for_message(walked, 80) + "'");
      if (i + 1 == keys.size()) {
        (*node)[index] = std::move(value);
      } else {
        node = &(*node)[index];
      }
      continue;
    }
    if (!node->is_object())
      throw InputError(source + ": --set '" + shown + "': '" + truncate_for_message(walked, 80) +
                       "' is inside a value that is not an object");
    if (i + 1 == keys.size()) {
      (*node)[keys[i]] = std::move(value);
    } else {
      node = &(*node)[keys[i]];
      if (node->is_null()) *node = Json::object();
    }
  }
}

JsonObjectReader::JsonObjectReader(const Json& object, JsonContext context)
    : object_(object), context_(std::move(context)) {
  if (!object_.is_object())
    throw InputError(context_.where() + " must be a JSON object, got " + describe_json(object_));
}

const Json& JsonObjectReader::raw(const std::string& key) {
  ConfigKeyRecorder::record(context_, key);
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
    throw InputError(context_.file + ": unknown key '" +
                     context_.child(truncate_for_message(item.key(), 60)).path +
                     "' (allowed: " + list + ")");
  }
}

void require(bool ok, const JsonContext& where, const std::string& expectation) {
  if (!ok) throw InputError(where.where() + " must be " + expectation);
}

}  // namespace bsms
