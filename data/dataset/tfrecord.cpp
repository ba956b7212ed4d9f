#include "data/dataset/tfrecord.hpp"

#include <fcntl.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream.h>
#include <google/protobuf/wire_format_lite.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <vector>

#ifdef __SSE4_2__
#include <nmmintrin.h>
#endif

#include "core/error.hpp"

namespace bsms::tfrecord {

namespace {

using google::protobuf::internal::WireFormatLite;
using google::protobuf::io::CodedInputStream;
using google::protobuf::io::ZeroCopyInputStream;

constexpr uint32_t kCastagnoli = 0x82F63B78u;  // reflected polynomial

struct CrcTable {
  uint32_t t[256];
  constexpr CrcTable() : t() {
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ kCastagnoli : c >> 1;
      t[i] = c;
    }
  }
};
constexpr CrcTable kCrcTable;

}  // namespace

uint32_t crc32c_portable(const void* data, size_t size, uint32_t crc) {
  const auto* p = static_cast<const uint8_t*>(data);
  uint32_t c = ~crc;
  for (size_t i = 0; i < size; ++i) c = kCrcTable.t[(c ^ p[i]) & 0xFF] ^ (c >> 8);
  return ~c;
}

uint32_t crc32c(const void* data, size_t size, uint32_t crc) {
#ifdef __SSE4_2__
  const auto* p = static_cast<const uint8_t*>(data);
  uint64_t c = ~crc;
  while (size >= 8) {
    uint64_t word;
    std::memcpy(&word, p, 8);
    c = _mm_crc32_u64(c, word);
    p += 8;
    size -= 8;
  }
  uint32_t c32 = static_cast<uint32_t>(c);
  while (size-- > 0) c32 = _mm_crc32_u8(c32, *p++);
  return ~c32;
#else
  return crc32c_portable(data, size, crc);
#endif
}

uint32_t mask_crc(uint32_t crc) {
  return ((crc >> 15) | (crc << 17)) + 0xa282ead8u;
}

// ---------------------------------------------------------------------------------------------
// Reader

namespace {

struct RecordRef {
  uint64_t offset = 0;  // of the data (after the 12-byte header)
  uint64_t length = 0;
};

// Bytes of one field inside a record buffer, as the wire walk found them.
struct WireBytes {
  uint64_t position = 0;  // within the record data
  uint64_t size = 0;
  int values = 0;     // byte strings in the BytesList
  int list_kind = 0;  // 1 bytes_list, 2 float_list, 3 int64_list, 0 none
};

uint64_t load_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
uint32_t load_u32(const uint8_t* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 | uint32_t{p[3]} << 24;
}

template <class T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the data is little-endian, like every supported host
  return v;
}

}  // namespace

struct TfRecordReader::Impl {
  std::string path;
  Meta meta;
  int fd = -1;
  std::string memory;  // in-memory image when fd < 0
  uint64_t size = 0;
  std::vector<RecordRef> records;
  mutable std::mutex mutex;
  mutable std::vector<std::unique_ptr<RecordLayout>> layouts;
  mutable std::vector<char> verified;  // data CRC checked

  ~Impl() {
    if (fd >= 0) ::close(fd);
  }

  std::string rec(int64_t r) const { return path + ": record " + std::to_string(r); }

  // Reads exactly n bytes at `offset`; a short read means the file changed under us.
  void read_at(uint64_t offset, void* dst, size_t n, const std::string& what) const {
    if (n == 0) return;
    if (offset > size || n > size - offset)
      throw InputError(what + ": truncated (" + std::to_string(n) + " bytes at offset " +
                       std::to_string(offset) + ", file has " + std::to_string(size) + ")");
    if (fd < 0) {
      std::memcpy(dst, memory.data() + offset, n);
      return;
    }
    auto* out = static_cast<char*>(dst);
    while (n > 0) {
      const ssize_t got = ::pread(fd, out, n, static_cast<off_t>(offset));
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) throw InputError(what + ": read failed: " + std::strerror(errno));
      if (got == 0)
        throw InputError(what + ": truncated (file ended at offset " + std::to_string(offset) +
                         ")");
      out += got;
      offset += static_cast<uint64_t>(got);
      n -= static_cast<size_t>(got);
    }
  }

  void scan() {
    uint64_t offset = 0;
    while (offset < size) {
      const std::string what = rec(static_cast<int64_t>(records.size()));
      if (size - offset < 12)
        throw InputError(what + ": truncated header (" + std::to_string(size - offset) +
                         " bytes left at offset " + std::to_string(offset) + ", need 12)");
      uint8_t header[12];
      read_at(offset, header, 12, what);
      const uint64_t length = load_u64(header);
      if (mask_crc(crc32c(header, 8)) != load_u32(header + 8))
        throw InputError(what + ": length CRC mismatch at offset " + std::to_string(offset) +
                         " (corrupt or not a TFRecord file)");
      const uint64_t left = size - offset - 12;
      if (left < 4 || length > left - 4)
        throw InputError(what + ": truncated data (header says " + std::to_string(length) +
                         " bytes + 4 CRC bytes, " + std::to_string(left) + " bytes left)");
      records.push_back({offset + 12, length});
      offset += 12 + length + 4;
    }
    layouts.resize(records.size());
    verified.assign(records.size(), 0);
  }

  void check_record(int64_t r) const {
    if (r < 0 || r >= static_cast<int64_t>(records.size()))
      throw InputError(path + ": record " + std::to_string(r) + " out of range (" +
                       std::to_string(records.size()) + " records)");
  }

  // Reads record data and checks its CRC.
  std::unique_ptr<uint8_t[]> read_record(int64_t r) const {
    const RecordRef& ref = records[r];
    if (ref.length > static_cast<uint64_t>(INT_MAX))
      throw InputError(rec(r) + ": " + std::to_string(ref.length) +
                       " bytes; records over 2 GiB are not supported");
    std::unique_ptr<uint8_t[]> data(new uint8_t[ref.length + 4]);
    read_at(ref.offset, data.get(), ref.length + 4, rec(r));
    const uint32_t stored = load_u32(data.get() + ref.length);
    if (mask_crc(crc32c(data.get(), ref.length)) != stored)
      throw InputError(rec(r) + ": data CRC mismatch (corrupt record)");
    return data;
  }

  // Checks the data CRC of record r once: the first time, the record is read through a block
  // buffer.
  void verify(int64_t r) const {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (verified[r]) return;
    }
    const RecordRef& ref = records[r];
    // Large blocks: records are read in random order, and a cold disk serves few large reads
    // faster than many small ones. One buffer per thread, kept: no page faults per record.
    constexpr uint64_t kBlock = uint64_t{16} << 20;
    thread_local std::vector<uint8_t> block;
    block.resize(static_cast<size_t>(std::min(ref.length, kBlock)) + 4);
    uint32_t crc = 0;
    for (uint64_t done = 0; done < ref.length;) {
      const uint64_t n = std::min(kBlock, ref.length - done);
      read_at(ref.offset + done, block.data(), n, rec(r));
      crc = crc32c(block.data(), n, crc);
      done += n;
    }
    uint8_t stored[4];
    read_at(ref.offset + ref.length, stored, 4, rec(r));
    if (mask_crc(crc) != load_u32(stored))
      throw InputError(rec(r) + ": data CRC mismatch (corrupt record)");
    std::lock_guard<std::mutex> lock(mutex);
    verified[r] = 1;
  }

  RecordLayout walk(int64_t r) const;
  const RecordLayout& layout_of(int64_t r) const;
  const FieldSlice& slice(int64_t r, const std::string& field, const FieldSpec** spec) const;
};

namespace {

// Record data read on demand, a block at a time, by `read(offset, dst, n)` (the reader's
// read_at: a file or a memory image): the wire walk reads tags, keys and lengths and skips the
// payloads without reading them.
class BlockStream : public ZeroCopyInputStream {
 public:
  using Read = std::function<void(uint64_t offset, void* dst, size_t n)>;
  BlockStream(Read read, uint64_t begin, uint64_t length)
      : read_(std::move(read)), begin_(begin), length_(length) {}

  bool Next(const void** data, int* size) override {
    if (pos_ >= buffer_start_ && pos_ < buffer_end_) {  // what BackUp returned
      *data = buffer_.data() + (pos_ - buffer_start_);
      *size = static_cast<int>(buffer_end_ - pos_);
      pos_ = buffer_end_;
      return true;
    }
    if (pos_ >= length_) return false;
    const size_t n = static_cast<size_t>(std::min<uint64_t>(buffer_.size(), length_ - pos_));
    read_(begin_ + pos_, buffer_.data(), n);
    buffer_start_ = pos_;
    buffer_end_ = pos_ + n;
    *data = buffer_.data();
    *size = static_cast<int>(n);
    pos_ = buffer_end_;
    return true;
  }
  void BackUp(int count) override { pos_ -= static_cast<uint64_t>(count); }
  bool Skip(int count) override {
    if (count < 0) return false;
    if (static_cast<uint64_t>(count) > length_ - pos_) {
      pos_ = length_;
      return false;
    }
    pos_ += static_cast<uint64_t>(count);
    return true;
  }
  int64_t ByteCount() const override { return static_cast<int64_t>(pos_); }

 private:
  Read read_;
  uint64_t begin_, length_;
  std::array<uint8_t, 4096> buffer_{};
  uint64_t pos_ = 0, buffer_start_ = 0, buffer_end_ = 0;
};

// Walks a tf.train.Example: Example{features=1}, Features{map<string, Feature> feature=1},
// Feature{bytes_list=1 | float_list=2 | int64_list=3}, BytesList{repeated bytes value=1}.
class ExampleWalker {
 public:
  ExampleWalker(ZeroCopyInputStream* stream, int size, std::string what)
      : in_(stream), size_(size), what_(std::move(what)) {
    in_.SetTotalBytesLimit(size);
  }

  std::map<std::string, WireBytes> run() {
    const auto limit = in_.PushLimit(size_);
    message([&](uint32_t field) {
      if (field != 1) return false;
      nested([&] {
        message([&](uint32_t f) {
          if (f != 1) return false;
          nested([&] { map_entry(); });
          return true;
        });
      });
      return true;
    });
    in_.PopLimit(limit);
    return std::move(out_);
  }

 private:
  [[noreturn]] void malformed(const std::string& why) {
    throw InputError(what_ + ": malformed protobuf wire at byte " +
                     std::to_string(in_.CurrentPosition()) + " (" + why + ")");
  }

  // Reads tags until the current limit; `on_field(number)` consumes a length-delimited field it
  // knows and returns true, anything else is skipped.
  template <class F>
  void message(F&& on_field) {
    for (;;) {
      if (in_.BytesUntilLimit() == 0) return;
      const uint32_t tag = in_.ReadTag();
      if (tag == 0) malformed("bad tag or unexpected end");
      const uint32_t number = WireFormatLite::GetTagFieldNumber(tag);
      if (WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_LENGTH_DELIMITED &&
          on_field(number))
        continue;
      if (!WireFormatLite::SkipField(&in_, tag))
        malformed("cannot skip field " + std::to_string(number));
    }
  }

  uint32_t length() {
    uint32_t n = 0;
    if (!in_.ReadVarint32(&n)) malformed("bad length varint");
    const int left = in_.BytesUntilLimit();
    if (left < 0 || n > static_cast<uint32_t>(left))
      malformed("length " + std::to_string(n) + " runs past its message");
    return n;
  }

  template <class F>
  void nested(F&& body) {
    const uint32_t n = length();
    if (++depth_ > 8) malformed("nesting too deep");
    const auto limit = in_.PushLimit(static_cast<int>(n));
    body();
    in_.PopLimit(limit);
    --depth_;
  }

  void map_entry() {
    std::string key;
    bool has_key = false;
    WireBytes value;
    message([&](uint32_t f) {
      if (f == 1) {
        const uint32_t n = length();
        if (!in_.ReadString(&key, static_cast<int>(n))) malformed("bad key");
        has_key = true;
        return true;
      }
      if (f != 2) return false;
      value = WireBytes{};
      nested([&] { feature(&value); });
      return true;
    });
    if (!has_key) malformed("feature map entry without a key");
    out_[key] = value;
  }

  void feature(WireBytes* v) {
    message([&](uint32_t f) {
      if (f < 1 || f > 3) return false;
      v->list_kind = static_cast<int>(f);
      v->values = 0;
      if (f != 1) {
        const uint32_t n = length();
        if (!in_.Skip(static_cast<int>(n))) malformed("truncated list");
        return true;
      }
      nested([&] {
        message([&](uint32_t g) {
          if (g != 1) return false;
          const uint32_t n = length();
          v->position = static_cast<uint64_t>(in_.CurrentPosition());
          v->size = n;
          ++v->values;
          if (!in_.Skip(static_cast<int>(n))) malformed("truncated bytes");
          return true;
        });
      });
      return true;
    });
  }

  CodedInputStream in_;
  int size_;
  std::string what_;
  int depth_ = 0;
  std::map<std::string, WireBytes> out_;
};

// Count of the -1 dimension of `shape` for `elements` values, or -1 when they do not fit.
int64_t resolve_count(const std::vector<int64_t>& shape, uint64_t elements, bool* has_unknown) {
  uint64_t known = 1;
  *has_unknown = false;
  for (int64_t v : shape) {
    if (v == -1)
      *has_unknown = true;
    else
      known *= static_cast<uint64_t>(v);  // bounded by parse_meta
  }
  if (elements % known != 0) return -1;
  if (!*has_unknown) return elements == known ? 1 : -1;
  return static_cast<int64_t>(elements / known);
}

}  // namespace

RecordLayout TfRecordReader::Impl::walk(int64_t r) const {
  const std::string what = rec(r);
  const uint64_t base = records[r].offset;
  const uint64_t length = records[r].length;
  if (length > static_cast<uint64_t>(INT_MAX))
    throw InputError(what + ": " + std::to_string(length) +
                     " bytes; records over 2 GiB are not supported");
  BlockStream in([&](uint64_t offset, void* dst, size_t n) { read_at(offset, dst, n, what); }, base,
                 length);
  const std::map<std::string, WireBytes> wire =
      ExampleWalker(&in, static_cast<int>(length), what).run();
  RecordLayout layout;
  std::string n_field;
  auto bytes_of = [&](const std::string& name, const std::string& where) -> const WireBytes& {
    auto it = wire.find(name);
    if (it == wire.end()) throw InputError(where + " missing from the record");
    const WireBytes& w = it->second;
    if (w.list_kind != 1)
      throw InputError(where + ": expected a bytes_list, found " +
                       (w.list_kind == 2   ? "a float_list"
                        : w.list_kind == 3 ? "an int64_list"
                                           : "no value"));
    if (w.values != 1)
      throw InputError(where + ": expected one byte string, found " + std::to_string(w.values));
    return w;
  };
  for (const FieldSpec& spec : meta.fields) {
    const std::string where = what + ": field '" + spec.name + "'";
    const WireBytes& w = bytes_of(spec.name, where);
    FieldSlice s;
    s.offset = base + w.position;
    s.bytes = w.size;
    s.shape = spec.shape;
    const size_t esize = dtype_size(spec.dtype);
    const std::string mismatch = where + ": " + std::to_string(w.size) +
                                 " bytes do not divide into " + dtype_name(spec.dtype) +
                                 " frames of shape " + shape_string(spec.shape);
    if (w.size % esize != 0) throw InputError(mismatch);
    const uint64_t elements = w.size / esize;
    if (spec.kind == FieldKind::kDynamicVarlen) {
      const std::string cname = "length_" + spec.name;
      const std::string cwhere = what + ": field '" + cname + "'";
      const WireBytes& lw = bytes_of(cname, cwhere);
      const DType ltype = spec.length_dtype;
      const size_t lsize = dtype_size(ltype);
      if (lw.size != static_cast<uint64_t>(spec.shape[0]) * lsize)
        throw InputError(cwhere + ": " + std::to_string(lw.size) + " bytes, expected " +
                         std::to_string(spec.shape[0]) + " " + dtype_name(ltype) + " values");
      std::vector<uint8_t> lengths(lw.size);
      read_at(base + lw.position, lengths.data(), lw.size, cwhere);
      uint64_t rows = 0;
      for (int64_t t = 0; t < spec.shape[0]; ++t) {
        const uint8_t* p = lengths.data() + t * lsize;
        const int64_t len = ltype == DType::kInt32 ? load<int32_t>(p) : load<int64_t>(p);
        if (len < 0 || len > INT32_MAX)
          throw InputError(cwhere + ": row length " + std::to_string(len) + " of frame " +
                           std::to_string(t) + " out of range");
        s.row_lengths.push_back(len);
        rows += static_cast<uint64_t>(len);
      }
      uint64_t per_row = 1;
      for (size_t i = 2; i < spec.shape.size(); ++i) per_row *= spec.shape[i];
      if (rows > elements / per_row || rows * per_row != elements)
        throw InputError(where + ": " + std::to_string(elements) + " values, but its row lengths" +
                         " sum to " + std::to_string(rows) + " rows of " + std::to_string(per_row));
      s.count = static_cast<int64_t>(rows);
      layout.fields.push_back(std::move(s));
      continue;
    }
    bool has_unknown = false;
    const int64_t count = resolve_count(spec.shape, elements, &has_unknown);
    if (count < 0) throw InputError(mismatch);
    if (count == 0) throw InputError(where + ": empty (no nodes or cells)");
    s.count = count;
    for (auto& v : s.shape)
      if (v == -1) v = count;
    if (has_unknown && spec.name != "cells") {
      if (layout.num_nodes < 0) {
        layout.num_nodes = count;
        n_field = spec.name;
      } else if (layout.num_nodes != count) {
        throw InputError(where + " has N=" + std::to_string(count) + " nodes, field '" + n_field +
                         "' has " + std::to_string(layout.num_nodes));
      }
    }
    layout.fields.push_back(std::move(s));
  }
  return layout;
}

const RecordLayout& TfRecordReader::Impl::layout_of(int64_t r) const {
  // Caller holds the mutex.
  if (!layouts[r]) layouts[r] = std::make_unique<RecordLayout>(walk(r));
  return *layouts[r];
}

const FieldSlice& TfRecordReader::Impl::slice(int64_t r, const std::string& field,
                                              const FieldSpec** spec) const {
  // Caller holds the mutex.
  check_record(r);
  for (size_t i = 0; i < meta.fields.size(); ++i) {
    if (meta.fields[i].name != field) continue;
    *spec = &meta.fields[i];
    return layout_of(r).fields[i];
  }
  throw InputError(path + ": no field '" + field + "' in " + meta.path);
}

namespace {

template <class Out>
void convert(const uint8_t* p, size_t n, DType dtype, Out* out) {
  switch (dtype) {
    case DType::kFloat32:
      for (size_t i = 0; i < n; ++i) out[i] = static_cast<Out>(load<float>(p + 4 * i));
      break;
    case DType::kFloat64:
      for (size_t i = 0; i < n; ++i) out[i] = static_cast<Out>(load<double>(p + 8 * i));
      break;
    case DType::kInt32:
      for (size_t i = 0; i < n; ++i) out[i] = static_cast<Out>(load<int32_t>(p + 4 * i));
      break;
    case DType::kInt64:
      for (size_t i = 0; i < n; ++i) out[i] = static_cast<Out>(load<int64_t>(p + 8 * i));
      break;
  }
}

}  // namespace

TfRecordReader::TfRecordReader() : impl_(std::make_unique<Impl>()) {}

TfRecordReader::TfRecordReader(const std::string& path, Meta meta) : TfRecordReader() {
  auto& d = *impl_;
  d.path = path;
  d.meta = std::move(meta);
  d.fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (d.fd < 0) throw InputError(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(d.fd, &st) != 0 || !S_ISREG(st.st_mode))
    throw InputError(path + ": not a regular file");
  d.size = static_cast<uint64_t>(st.st_size);
  d.scan();
}

TfRecordReader TfRecordReader::from_bytes(std::string bytes, const std::string& name, Meta meta) {
  TfRecordReader reader;
  auto& d = *reader.impl_;
  d.path = name;
  d.meta = std::move(meta);
  d.memory = std::move(bytes);
  d.size = d.memory.size();
  d.scan();
  return reader;
}

TfRecordReader::~TfRecordReader() = default;
TfRecordReader::TfRecordReader(TfRecordReader&&) noexcept = default;
TfRecordReader& TfRecordReader::operator=(TfRecordReader&&) noexcept = default;

const std::string& TfRecordReader::path() const {
  return impl_->path;
}
const Meta& TfRecordReader::meta() const {
  return impl_->meta;
}
int64_t TfRecordReader::num_records() const {
  return static_cast<int64_t>(impl_->records.size());
}
uint64_t TfRecordReader::record_bytes(int64_t r) const {
  impl_->check_record(r);
  return impl_->records[r].length;
}

const RecordLayout& TfRecordReader::layout(int64_t r) const {
  impl_->check_record(r);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->layout_of(r);
}

std::vector<float> TfRecordReader::read_float(int64_t r, const std::string& field, int64_t t0,
                                              int64_t count) const {
  const FieldSpec* spec = nullptr;
  FieldSlice s;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    s = impl_->slice(r, field, &spec);
  }
  const std::string where = impl_->rec(r) + ": field '" + field + "'";
  if (spec->kind == FieldKind::kDynamicVarlen)
    throw InputError(where + " is dynamic_varlen; read it whole with decode()");
  if (spec->kind != FieldKind::kStatic) impl_->verify(r);
  const int64_t frames = s.frames();
  if (t0 < 0 || count < 0 || t0 > frames || count > frames - t0)
    throw InputError(where + ": frames " + std::to_string(t0) + ".." +
                     std::to_string(t0 + count - 1) + " out of range (T=" + std::to_string(frames) +
                     ")");
  const uint64_t frame_bytes = s.bytes / static_cast<uint64_t>(frames);
  const size_t esize = dtype_size(spec->dtype);
  const uint64_t bytes = frame_bytes * static_cast<uint64_t>(count);
  std::vector<float> out(bytes / esize);
  const uint64_t offset = s.offset + frame_bytes * static_cast<uint64_t>(t0);
  if (spec->dtype == DType::kFloat32) {
    impl_->read_at(offset, out.data(), bytes, where);
  } else {
    std::unique_ptr<uint8_t[]> raw(new uint8_t[bytes]);
    impl_->read_at(offset, raw.get(), bytes, where);
    convert(raw.get(), out.size(), spec->dtype, out.data());
  }
  return out;
}

std::vector<int32_t> TfRecordReader::read_int32(int64_t r, const std::string& field) const {
  const FieldSpec* spec = nullptr;
  FieldSlice s;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    s = impl_->slice(r, field, &spec);
  }
  const std::string where = impl_->rec(r) + ": field '" + field + "'";
  if (spec->dtype != DType::kInt32 && spec->dtype != DType::kInt64)
    throw InputError(where + ": expected int32 or int64, meta says " + dtype_name(spec->dtype));
  if (spec->kind != FieldKind::kStatic) impl_->verify(r);
  const size_t esize = dtype_size(spec->dtype);
  std::vector<int32_t> out(s.bytes / esize);
  if (spec->dtype == DType::kInt32) {
    impl_->read_at(s.offset, out.data(), s.bytes, where);
    return out;
  }
  std::unique_ptr<uint8_t[]> raw(new uint8_t[s.bytes]);
  impl_->read_at(s.offset, raw.get(), s.bytes, where);
  for (size_t i = 0; i < out.size(); ++i) {
    const int64_t v = load<int64_t>(raw.get() + 8 * i);
    if (v < INT32_MIN || v > INT32_MAX)
      throw InputError(where + ": value " + std::to_string(v) + " at flat index " +
                       std::to_string(i) + " does not fit int32");
    out[i] = static_cast<int32_t>(v);
  }
  return out;
}

MeshArrays TfRecordReader::read_mesh(int64_t r) const {
  const Meta& meta = impl_->meta;
  const std::string what = impl_->rec(r);
  for (const char* name : {"mesh_pos", "cells", "node_type"}) {
    const FieldSpec* spec = meta.find(name);
    if (!spec) throw InputError(meta.path + ": no field '" + name + "' (needed for the mesh)");
    if (spec->kind != FieldKind::kStatic)
      throw InputError(meta.path + ": field '" + name + "' must be static, not " +
                       kind_name(spec->kind));
  }
  const RecordLayout& layout = this->layout(r);
  auto slice_of = [&](const char* name) -> const FieldSlice& {
    for (size_t i = 0; i < meta.fields.size(); ++i)
      if (meta.fields[i].name == name) return layout.fields[i];
    throw InputError(meta.path + ": no field '" + std::string(name) + "'");
  };
  const FieldSlice& pos = slice_of("mesh_pos");
  const FieldSlice& cells = slice_of("cells");
  const FieldSlice& types = slice_of("node_type");
  if (pos.shape.size() != 3 || pos.shape[2] < 1 || pos.shape[2] > 3)
    throw InputError(meta.path + ": field 'mesh_pos' shape " +
                     shape_string(meta.find("mesh_pos")->shape) + " must be [1,-1,dim<=3]");
  if (cells.shape.size() != 3 || cells.shape[2] < 2 || cells.shape[2] > 8)
    throw InputError(meta.path + ": field 'cells' shape " +
                     shape_string(meta.find("cells")->shape) + " must be [1,-1,k] (k 2..8)");
  const int64_t n = pos.shape[1];
  int64_t type_count = 1;
  for (size_t i = 1; i < types.shape.size(); ++i) type_count *= types.shape[i];
  if (type_count != n)
    throw InputError(what + ": field 'node_type' has " + std::to_string(type_count) +
                     " values for N=" + std::to_string(n) + " nodes");
  MeshArrays m;
  m.dim = static_cast<int>(pos.shape[2]);
  m.cell_size = static_cast<int>(cells.shape[2]);
  m.mesh_pos = read_float(r, "mesh_pos", 0, 1);
  for (size_t i = 0; i < m.mesh_pos.size(); ++i)
    if (!std::isfinite(m.mesh_pos[i]))
      throw InputError(what + ": field 'mesh_pos': non-finite value at flat index " +
                       std::to_string(i));
  m.cells = read_int32(r, "cells");
  for (size_t i = 0; i < m.cells.size(); ++i)
    if (m.cells[i] < 0 || m.cells[i] >= n)
      throw InputError(what + ": field 'cells': index " + std::to_string(m.cells[i]) +
                       " at flat index " + std::to_string(i) + " out of range 0.." +
                       std::to_string(n - 1));
  m.node_type = read_int32(r, "node_type");
  return m;
}

std::map<std::string, DecodedField> TfRecordReader::decode(int64_t r) const {
  impl_->check_record(r);
  const auto data = impl_->read_record(r);
  const RecordLayout* layout = nullptr;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->verified[r] = 1;
    layout = &impl_->layout_of(r);
  }
  const uint64_t base = impl_->records[r].offset;
  std::map<std::string, DecodedField> out;
  for (size_t i = 0; i < impl_->meta.fields.size(); ++i) {
    const FieldSpec& spec = impl_->meta.fields[i];
    const FieldSlice& s = layout->fields[i];
    DecodedField f;
    f.shape = s.shape;
    f.row_lengths = s.row_lengths;
    const size_t n = s.bytes / dtype_size(spec.dtype);
    const uint8_t* p = data.get() + (s.offset - base);
    if (spec.dtype == DType::kFloat32 || spec.dtype == DType::kFloat64) {
      f.floats.resize(n);
      convert(p, n, spec.dtype, f.floats.data());
    } else {
      f.ints.resize(n);
      convert(p, n, spec.dtype, f.ints.data());
    }
    out.emplace(spec.name, std::move(f));
  }
  return out;
}

}  // namespace bsms::tfrecord
