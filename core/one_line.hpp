// Messages for a terminal: one line, printable, bounded. Error messages and warnings name files,
// keys and values that come from the user or from a damaged file; a newline there would split
// the one line a caller reads, an escape sequence would drive the terminal, and a long value
// would bury the point.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>

namespace bsms {

// `text` with control characters escaped (\n, \t, \r, \x1b, any other byte below 0x20 and 0x7f
// as \xNN; so are the C1 controls U+0080..U+009F and bytes that are not UTF-8), valid UTF-8 kept
// as it is, and cut after `max` bytes with "…".
inline std::string one_line(const std::string& text, size_t max = 2000) {
  static const char* const kHex = "0123456789abcdef";
  std::string out;
  out.reserve(std::min(text.size(), max) + 16);
  const auto escape = [&](unsigned char c) {
    out += "\\x";
    out += kHex[c >> 4];
    out += kHex[c & 15];
  };
  size_t i = 0;
  while (i < text.size() && out.size() < max) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) {
      if (c == '\n') {
        out += "\\n";
      } else if (c == '\t') {
        out += "\\t";
      } else if (c == '\r') {
        out += "\\r";
      } else {
        escape(c);
      }
      ++i;
      continue;
    }
    if (c < 0x80) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    // A UTF-8 sequence: its length from the lead byte, then the continuation bytes checked
    // (overlong forms and surrogates are not UTF-8 either).
    const size_t length = c >= 0xc2 && c <= 0xdf   ? 2
                          : c >= 0xe0 && c <= 0xef ? 3
                          : c >= 0xf0 && c <= 0xf4 ? 4
                                                   : 0;
    bool valid = length > 0 && i + length <= text.size();
    for (size_t k = 1; valid && k < length; ++k)
      valid = (static_cast<unsigned char>(text[i + k]) & 0xc0) == 0x80;
    if (valid) {
      const auto second = static_cast<unsigned char>(text[i + 1]);
      if ((c == 0xe0 && second < 0xa0) || (c == 0xed && second >= 0xa0) ||
          (c == 0xf0 && second < 0x90) || (c == 0xf4 && second >= 0x90))
        valid = false;
      if (c == 0xc2 && second < 0xa0) valid = false;  // U+0080..U+009F: C1 controls
    }
    if (!valid) {
      escape(c);
      ++i;
      continue;
    }
    out.append(text, i, length);
    i += length;
  }
  if (i < text.size()) out += "\u2026";
  return out;
}

}  // namespace bsms
