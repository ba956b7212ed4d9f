// Counts the images of a GIF file (its frames when animated), walking its block structure.
#pragma once

#include <cstdint>
#include <string>

namespace bsms::testing {

// The number of image descriptors in `gif` (the file's bytes), or -1 when it is not a whole GIF.
inline int gif_frames(const std::string& gif) {
  size_t p = 0;
  auto byte = [&](size_t at) { return static_cast<uint8_t>(gif[at]); };
  auto skip_sub_blocks = [&]() {  // data sub-blocks: a length byte, then data; 0 ends them
    while (p < gif.size() && byte(p) != 0) p += 1 + byte(p);
    if (p >= gif.size()) return false;
    ++p;
    return true;
  };
  if (gif.size() < 13 || gif.compare(0, 3, "GIF") != 0) return -1;
  const uint8_t screen_flags = byte(10);
  p = 13;
  if (screen_flags & 0x80) p += 3u << ((screen_flags & 7) + 1);
  int images = 0;
  while (p < gif.size()) {
    const uint8_t kind = byte(p++);
    if (kind == 0x3B) return images;  // trailer
    if (kind == 0x21) {               // extension: label, sub-blocks
      ++p;
      if (!skip_sub_blocks()) return -1;
    } else if (kind == 0x2C) {  // image: descriptor, local table, LZW code size, sub-blocks
      if (p + 9 > gif.size()) return -1;
      const uint8_t flags = byte(p + 8);
      p += 9;
      if (flags & 0x80) p += 3u << ((flags & 7) + 1);
      ++p;
      if (!skip_sub_blocks()) return -1;
      ++images;
    } else {
      return -1;
    }
  }
  return -1;
}

}  // namespace bsms::testing
