// Test-only TFRecord / tf.train.Example writer and parser, written independently of the reader
// under test (bitwise CRC, hand-rolled varints): builds MeshGraphNets-style inputs and decodes
// the fixtures for comparison.
#pragma once

#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bsms::test {

// CRC32C, one bit at a time.
inline uint32_t bitwise_crc32c(const std::string& s) {
  uint32_t c = 0xFFFFFFFFu;
  for (unsigned char byte : s) {
    c ^= byte;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82F63B78u & (0u - (c & 1u)));
  }
  return ~c;
}

inline uint32_t masked(uint32_t crc) {
  return ((crc >> 15) | (crc << 17)) + 0xa282ead8u;
}

inline std::string le_bytes(uint64_t v, int n) {
  std::string s;
  for (int i = 0; i < n; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  return s;
}

// One framed record: length, masked CRC of the length, data, masked CRC of the data.
inline std::string frame_record(const std::string& data) {
  const std::string len = le_bytes(data.size(), 8);
  return len + le_bytes(masked(bitwise_crc32c(len)), 4) + data +
         le_bytes(masked(bitwise_crc32c(data)), 4);
}

inline std::string varint(uint64_t v) {
  std::string s;
  while (v >= 0x80) {
    s.push_back(static_cast<char>((v & 0x7F) | 0x80));
    v >>= 7;
  }
  s.push_back(static_cast<char>(v));
  return s;
}

// A length-delimited field: tag (number, wire type 2), length, payload.
inline std::string ld(int number, const std::string& payload) {
  return varint(static_cast<uint64_t>(number) << 3 | 2) + varint(payload.size()) + payload;
}

template <class T>
std::string raw(const std::vector<T>& values) {
  std::string s(values.size() * sizeof(T), '\0');
  if (!values.empty()) std::memcpy(&s[0], values.data(), s.size());
  return s;
}

// A tf.train.Example with one BytesList per (name, raw bytes).
inline std::string example(const std::vector<std::pair<std::string, std::string>>& fields) {
  std::string features;
  for (const auto& [name, bytes] : fields)
    features += ld(1, ld(1, name) + ld(2, ld(1, ld(1, bytes))));
  return ld(1, features);
}

inline void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// ---- independent parser (for the fixtures) ----

inline uint64_t get_varint(const std::string& s, size_t* pos) {
  uint64_t v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*pos >= s.size()) throw std::runtime_error("varint past end");
    const auto b = static_cast<unsigned char>(s[(*pos)++]);
    v |= static_cast<uint64_t>(b & 0x7F) << shift;
    if (!(b & 0x80)) return v;
  }
  throw std::runtime_error("varint too long");
}

// Length-delimited fields of a message: (number, payload); other wire types are skipped.
inline std::vector<std::pair<int, std::string>> ld_fields(const std::string& s) {
  std::vector<std::pair<int, std::string>> out;
  size_t pos = 0;
  while (pos < s.size()) {
    const uint64_t tag = get_varint(s, &pos);
    const int type = static_cast<int>(tag & 7);
    if (type == 0) {
      get_varint(s, &pos);
    } else if (type == 1) {
      pos += 8;
    } else if (type == 5) {
      pos += 4;
    } else if (type == 2) {
      const uint64_t n = get_varint(s, &pos);
      if (n > s.size() - pos) throw std::runtime_error("length past end");
      out.emplace_back(static_cast<int>(tag >> 3), s.substr(pos, n));
      pos += n;
    } else {
      throw std::runtime_error("unsupported wire type");
    }
  }
  return out;
}

// Example -> {name: raw bytes of its single BytesList value}.
inline std::map<std::string, std::string> parse_example(const std::string& data) {
  std::map<std::string, std::string> out;
  for (const auto& [n1, features] : ld_fields(data)) {
    if (n1 != 1) continue;
    for (const auto& [n2, entry] : ld_fields(features)) {
      if (n2 != 1) continue;
      std::string key, value;
      for (const auto& [n3, part] : ld_fields(entry)) {
        if (n3 == 1) key = part;
        if (n3 == 2)
          for (const auto& [n4, list] : ld_fields(part))
            if (n4 == 1)
              for (const auto& [n5, bytes] : ld_fields(list))
                if (n5 == 1) value = bytes;
      }
      out[key] = value;
    }
  }
  return out;
}

// The data of every record of a TFRecord file (CRCs checked with the bitwise CRC).
inline std::vector<std::string> split_records(const std::string& file) {
  std::vector<std::string> out;
  size_t pos = 0;
  while (pos < file.size()) {
    uint64_t len = 0;
    for (int i = 7; i >= 0; --i) len = len << 8 | static_cast<unsigned char>(file[pos + i]);
    std::string data = file.substr(pos + 12, len);
    uint32_t crc = 0;
    for (int i = 3; i >= 0; --i)
      crc = crc << 8 | static_cast<unsigned char>(file[pos + 12 + len + i]);
    if (crc != masked(bitwise_crc32c(data))) throw std::runtime_error("fixture CRC mismatch");
    out.push_back(std::move(data));
    pos += 16 + len;
  }
  return out;
}

}  // namespace bsms::test
