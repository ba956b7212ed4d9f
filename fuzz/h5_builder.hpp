// Structure-level HDF5 inputs for the fuzz targets of HDF5 readers (fuzz_multilevel,
// fuzz_dataset). libhdf5 itself is not fuzzed (its own parser crashes on damaged bytes, which is
// not bsms' bug): the fuzz input is a small program of groups, datasets (type, rank, shape,
// values), attributes (scalar int / double / float / string, fixed or variable length, or
// arrays) and soft links, with names from the readers' vocabulary. The program is written with
// the HDF5 API into valid files, which the reader under test then opens from disk, so every byte
// the fuzzer changes lands on a value, shape, type or name that bsms' own checks must handle.
// Program encoding (read front to back; missing bytes read as 0):
//   op byte % 5: 0 group <path> | 1 dataset <path> <type> <rank> <dims...> <values...>
//                | 2 attribute <path> <name> <kind> <value> | 3 next file <name> | 4 soft link
//   path: byte (count = 1 + b % 3, b >= 192 means "/" for attributes) then count name bytes
//   numbers: LEB128 varints; signed ones zigzag; floats are zigzag / 4 or a special value.
#pragma once

#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "seeds.hpp"

namespace bsms_fuzz {

inline const std::vector<std::string>& names() {
  static const std::vector<std::string> v = {
      "level_0",     "level_1",      "level_2",  "level_3",   "edges",   "pooled",
      "down_weight", "trajectories", "000000",   "000001",    "0",       "1",
      "2",           "mesh_pos",     "cells",    "node_type", "body_id", "world_pos",
      "velocity",    "stress",       "pressure", "density",   "x",       "10"};
  return v;
}
inline const std::vector<std::string>& attr_names() {
  static const std::vector<std::string> v = {
      "format",   "version", "seeding",          "num_levels", "num_nodes",  "dim",
      "frame_dt", "scene",   "num_trajectories", "seed",       "parameters", "solver_wall_s"};
  return v;
}
inline const std::vector<std::string>& strings() {
  static const std::vector<std::string> v = {
      "bsms-multilevel", "bsms-dataset", "minave", "closecenter", "random", "{}", "", "{\"a\": 1}"};
  return v;
}
inline const std::vector<std::string>& file_names() {
  static const std::vector<std::string> v = {"0", "1", "2", "10", "x", "01", "-1"};
  return v;
}

inline int index_of(const std::vector<std::string>& list, const std::string& name) {
  for (size_t i = 0; i < list.size(); ++i)
    if (list[i] == name) return static_cast<int>(i);
  __builtin_trap();  // a seed names something outside the vocabulary
}

enum Op { kGroup = 0, kDataset = 1, kAttribute = 2, kNextFile = 3, kSoftLink = 4 };
enum Type { kI32 = 0, kI64 = 1, kF32 = 2, kF64 = 3, kU8 = 4, kStr = 5 };
enum AttrKind {
  kAttrInt = 0,
  kAttrDouble = 1,
  kAttrString = 2,
  kAttrVarString = 3,
  kAttrIntArray = 4,
  kAttrFloat = 5
};
constexpr int64_t kNaN = 1000001, kInf = 1000002, kNegInf = 1000003;
constexpr uint64_t kMaxElements = 4096;
constexpr int kMaxOps = 96;

class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : p_(data), n_(size) {}
  bool done() const { return i_ >= n_; }
  uint8_t byte() { return i_ < n_ ? p_[i_++] : 0; }
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const uint8_t b = byte();
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) break;
    }
    return v;
  }
  int64_t signed_varint() {
    const uint64_t v = varint();
    return static_cast<int64_t>(v >> 1) ^ -static_cast<int64_t>(v & 1);
  }
  double real() {
    const int64_t v = signed_varint();
    if (v == kNaN) return std::numeric_limits<double>::quiet_NaN();
    if (v == kInf) return std::numeric_limits<double>::infinity();
    if (v == kNegInf) return -std::numeric_limits<double>::infinity();
    return static_cast<double>(v) / 4.0;
  }
  std::string text() {
    const uint8_t b = byte();
    if (b < 128) return strings()[b % strings().size()];
    std::string s(b % 24, '\0');
    for (char& c : s) c = static_cast<char>(byte());
    return s;
  }
  std::string path(bool allow_root) {
    const uint8_t b = byte();
    if (allow_root && b >= 192) return "/";
    std::string p;
    for (int k = 0; k < 1 + b % 3; ++k) p += "/" + names()[byte() % names().size()];
    return p;
  }

 private:
  const uint8_t* p_;
  size_t n_;
  size_t i_ = 0;
};

// Encoder of the same program format, for the built-in seeds.
class Program {
 public:
  std::vector<uint8_t> bytes;
  void group(const std::vector<std::string>& path) {
    put(kGroup);
    put_path(path);
  }
  void dataset(const std::vector<std::string>& path, Type type, const std::vector<uint64_t>& dims,
               const std::vector<double>& values) {
    put(kDataset);
    put_path(path);
    put(type);
    put(static_cast<uint8_t>(dims.size()));
    for (uint64_t d : dims) put_varint(d);
    for (double v : values) {
      if (type == kF32 || type == kF64) {
        put_real(v);
      } else {
        const auto i = static_cast<int64_t>(v);
        put_varint((static_cast<uint64_t>(i) << 1) ^ static_cast<uint64_t>(i >> 63));
      }
    }
  }
  void attr_int(const std::vector<std::string>& path, const std::string& name, int64_t v) {
    attr_head(path, name, kAttrInt);
    put_varint((static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63));
  }
  void attr_double(const std::vector<std::string>& path, const std::string& name, double v) {
    attr_head(path, name, kAttrDouble);
    put_real(v);
  }
  void attr_string(const std::vector<std::string>& path, const std::string& name,
                   const std::string& v, bool variable = false) {
    attr_head(path, name, variable ? kAttrVarString : kAttrString);
    for (size_t i = 0; i < strings().size(); ++i)
      if (strings()[i] == v) return put(static_cast<uint8_t>(i));
    put(static_cast<uint8_t>(128 + v.size()));
    for (char c : v) put(static_cast<uint8_t>(c));
  }
  void next_file(const std::string& name) {
    put(kNextFile);
    put(static_cast<uint8_t>(index_of(file_names(), name)));
  }

 private:
  void put(uint8_t b) { bytes.push_back(b); }
  void put_varint(uint64_t v) {
    do {
      uint8_t b = v & 0x7f;
      v >>= 7;
      if (v) b |= 0x80;
      put(b);
    } while (v);
  }
  void put_real(double v) {  // multiples of 1/4 only (seeds)
    const int64_t q = std::isnan(v)   ? kNaN
                      : std::isinf(v) ? (v > 0 ? kInf : kNegInf)
                                      : static_cast<int64_t>(v * 4.0);
    put_varint((static_cast<uint64_t>(q) << 1) ^ static_cast<uint64_t>(q >> 63));
  }
  void put_path(const std::vector<std::string>& path) {
    if (path.empty()) return put(192);
    put(static_cast<uint8_t>(path.size() - 1));
    for (const auto& p : path) put(static_cast<uint8_t>(index_of(names(), p)));
  }
  void attr_head(const std::vector<std::string>& path, const std::string& name, AttrKind kind) {
    put(kAttribute);
    put_path(path);
    put(static_cast<uint8_t>(index_of(attr_names(), name)));
    put(kind);
  }
};

// Closes an HDF5 id when it leaves scope.
struct Id {
  hid_t id;
  explicit Id(hid_t i) : id(i) {}
  ~Id() {
    if (id >= 0) H5Idec_ref(id);
  }
  Id(const Id&) = delete;
  Id& operator=(const Id&) = delete;
};

// Builds one in-memory HDF5 file (core driver) and writes its image to `path`.
class FileBuilder {
 public:
  FileBuilder() {
    static const bool once = [] {
      H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
      // Keep freed blocks on HDF5's free lists (the default caps a list at 64 KB, so the 512 KB
      // metadata cache of every file open goes back to the system and comes back page by page,
      // which made a file round trip cost ~4 ms under ASan).
      H5set_free_list_limits(-1, -1, -1, -1, -1, -1);
      return true;
    }();
    (void)once;
    Id fapl(H5Pcreate(H5P_FILE_ACCESS));
    H5Pset_fapl_core(fapl.id, 1 << 16, 0);
    file_ = H5Fcreate("bsms-fuzz-image.h5", H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id);
    if (file_ < 0) __builtin_trap();
    lcpl_ = H5Pcreate(H5P_LINK_CREATE);
    H5Pset_create_intermediate_group(lcpl_, 1);
  }
  ~FileBuilder() {
    H5Pclose(lcpl_);
    if (file_ >= 0) H5Fclose(file_);
  }
  FileBuilder(const FileBuilder&) = delete;
  FileBuilder& operator=(const FileBuilder&) = delete;

  void save(const std::string& path) {
    if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) __builtin_trap();
    const ssize_t size = H5Fget_file_image(file_, nullptr, 0);
    if (size <= 0) __builtin_trap();
    std::vector<char> image(static_cast<size_t>(size));
    if (H5Fget_file_image(file_, image.data(), image.size()) != size) __builtin_trap();
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) __builtin_trap();
    if (std::fwrite(image.data(), 1, image.size(), f) != image.size()) __builtin_trap();
    std::fclose(f);
  }

  // Runs ops until the input ends, a next-file op (returns true with its name) or kMaxOps.
  bool run(Reader& in, int& ops, std::string* next_file) {
    while (!in.done() && ops < kMaxOps) {
      ++ops;
      switch (in.byte() % 5) {
        case kGroup: {
          const std::string p = in.path(false);
          Id g(H5Gcreate2(file_, p.c_str(), lcpl_, H5P_DEFAULT, H5P_DEFAULT));
          break;
        }
        case kDataset:
          dataset(in);
          break;
        case kAttribute:
          attribute(in);
          break;
        case kNextFile:
          *next_file = file_names()[in.byte() % file_names().size()];
          return true;
        case kSoftLink: {
          const std::string from = in.path(false), to = in.path(false);
          H5Lcreate_soft(to.c_str(), file_, from.c_str(), lcpl_, H5P_DEFAULT);
          break;
        }
      }
    }
    return false;
  }

 private:
  void dataset(Reader& in) {
    const std::string p = in.path(false);
    const uint8_t type_byte = in.byte();
    const int type = type_byte % 6;
    const bool chunked = type_byte & 0x80;
    const int rank = in.byte() % 4;
    std::vector<hsize_t> dims(rank);
    uint64_t total = 1;
    for (auto& d : dims) {
      d = in.varint() % (kMaxElements + 1);
      total *= d;
      if (total > kMaxElements) total = kMaxElements + 1;
    }
    if (total > kMaxElements) {
      total = 1;
      for (auto& d : dims) total *= (d %= 9);
    }
    Id space(rank == 0 ? H5Screate(H5S_SCALAR) : H5Screate_simple(rank, dims.data(), nullptr));
    Id dcpl(H5Pcreate(H5P_DATASET_CREATE));
    if (chunked && rank > 0 && total > 0) {
      std::vector<hsize_t> chunk(dims);
      chunk[0] = 1;
      H5Pset_chunk(dcpl.id, rank, chunk.data());
    }
    hid_t mem = H5T_NATIVE_INT64;
    Id str_type(H5Tcopy(H5T_C_S1));
    H5Tset_size(str_type.id, 4);
    switch (type) {
      case kI32:
        mem = H5T_NATIVE_INT32;
        break;
      case kI64:
        mem = H5T_NATIVE_INT64;
        break;
      case kF32:
        mem = H5T_NATIVE_FLOAT;
        break;
      case kF64:
        mem = H5T_NATIVE_DOUBLE;
        break;
      case kU8:
        mem = H5T_NATIVE_UINT8;
        break;
      default:
        mem = str_type.id;
        break;
    }
    Id set(H5Dcreate2(file_, p.c_str(), mem, space.id, lcpl_, dcpl.id, H5P_DEFAULT));
    if (set.id < 0 || total == 0) return;
    std::vector<unsigned char> buffer(total * 8);
    for (uint64_t i = 0; i < total; ++i) {
      unsigned char* at = buffer.data() + i * 8;
      if (type == kF32) {
        const float v = static_cast<float>(in.real());
        std::memcpy(at, &v, sizeof v);
      } else if (type == kF64) {
        const double v = in.real();
        std::memcpy(at, &v, sizeof v);
      } else {
        const int64_t v = in.signed_varint();
        const int32_t v32 = static_cast<int32_t>(v);
        const uint8_t v8 = static_cast<uint8_t>(v);
        if (type == kI64) std::memcpy(at, &v, sizeof v);
        if (type == kI32 || type == kStr) std::memcpy(at, &v32, sizeof v32);
        if (type == kU8) std::memcpy(at, &v8, sizeof v8);
      }
    }
    // Values were laid out 8 bytes apart: pack them to the element size.
    const size_t elem = H5Tget_size(mem);
    for (uint64_t i = 1; i < total; ++i) std::memmove(&buffer[i * elem], &buffer[i * 8], elem);
    H5Dwrite(set.id, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer.data());
  }

  void attribute(Reader& in) {
    const std::string object = in.path(true);
    const std::string name = attr_names()[in.byte() % attr_names().size()];
    const int kind = in.byte() % 6;
    Id obj(H5Oopen(file_, object.c_str(), H5P_DEFAULT));
    if (obj.id < 0) {
      in.varint();  // keep the value's bytes in place
      return;
    }
    if (H5Aexists(obj.id, name.c_str()) > 0) H5Adelete(obj.id, name.c_str());
    Id scalar(H5Screate(H5S_SCALAR));
    switch (kind) {
      case kAttrInt: {
        const int64_t v = in.signed_varint();
        Id a(H5Acreate2(obj.id, name.c_str(), H5T_STD_I64LE, scalar.id, H5P_DEFAULT, H5P_DEFAULT));
        if (a.id >= 0) H5Awrite(a.id, H5T_NATIVE_INT64, &v);
        break;
      }
      case kAttrDouble:
      case kAttrFloat: {
        const double v = in.real();
        const hid_t t = kind == kAttrDouble ? H5T_IEEE_F64LE : H5T_IEEE_F32LE;
        Id a(H5Acreate2(obj.id, name.c_str(), t, scalar.id, H5P_DEFAULT, H5P_DEFAULT));
        if (a.id >= 0) H5Awrite(a.id, H5T_NATIVE_DOUBLE, &v);
        break;
      }
      case kAttrString: {
        std::string v = in.text();
        Id t(H5Tcopy(H5T_C_S1));
        H5Tset_size(t.id, std::max<size_t>(v.size(), 1));
        H5Tset_strpad(t.id, H5T_STR_NULLTERM);
        v.resize(std::max<size_t>(v.size(), 1));
        Id a(H5Acreate2(obj.id, name.c_str(), t.id, scalar.id, H5P_DEFAULT, H5P_DEFAULT));
        if (a.id >= 0) H5Awrite(a.id, t.id, v.data());
        break;
      }
      case kAttrVarString: {
        const std::string v = in.text();
        const char* c = v.c_str();
        Id t(H5Tcopy(H5T_C_S1));
        H5Tset_size(t.id, H5T_VARIABLE);
        Id a(H5Acreate2(obj.id, name.c_str(), t.id, scalar.id, H5P_DEFAULT, H5P_DEFAULT));
        if (a.id >= 0) H5Awrite(a.id, t.id, &c);
        break;
      }
      case kAttrIntArray: {
        const int64_t v[2] = {in.signed_varint(), in.signed_varint()};
        const hsize_t two = 2;
        Id space(H5Screate_simple(1, &two, nullptr));
        Id a(H5Acreate2(obj.id, name.c_str(), H5T_STD_I64LE, space.id, H5P_DEFAULT, H5P_DEFAULT));
        if (a.id >= 0) H5Awrite(a.id, H5T_NATIVE_INT64, v);
        break;
      }
    }
  }

  hid_t file_ = -1;
  hid_t lcpl_ = -1;
};

// A per-process scratch folder on tmpfs where possible, removed when the process exits normally.
inline const std::string& scratch_dir(const std::string& target) {
  struct Scratch {
    std::string dir;
    ~Scratch() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  };
  static const Scratch scratch = [&] {
    const char* base = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    Scratch s{std::string(base) + "/bsms-" + target + "-" + std::to_string(::getpid())};
    std::filesystem::create_directories(s.dir);
    return s;
  }();
  return scratch.dir;
}

}  // namespace bsms_fuzz
