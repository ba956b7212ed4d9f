// Thin RAII layer over the HDF5 C API: files, groups, typed datasets and attributes.
// Every failure throws (IoError on write, InputError on read) naming the file and the object.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace bsms {

using Shape = std::vector<hsize_t>;

template <class T>
hid_t h5_native_type();
template <>
inline hid_t h5_native_type<int32_t>() {
  return H5T_NATIVE_INT32;
}
template <>
inline hid_t h5_native_type<int64_t>() {
  return H5T_NATIVE_INT64;
}
template <>
inline hid_t h5_native_type<float>() {
  return H5T_NATIVE_FLOAT;
}
template <>
inline hid_t h5_native_type<double>() {
  return H5T_NATIVE_DOUBLE;
}
template <>
inline hid_t h5_native_type<uint8_t>() {
  return H5T_NATIVE_UINT8;
}

// The element type of a stored dataset, for readers that take one type and no conversion.
enum class H5Dtype { kFloat32, kFloat64, kInt64, kInt32, kUInt8, kOther };
const char* h5_dtype_name(H5Dtype dtype);  // "float32", ..., "other"

// What a strict reader checks before reading a dataset (H5File::dataset_info).
struct H5DatasetInfo {
  Shape shape;
  H5Dtype dtype = H5Dtype::kOther;
  size_t element_size = 0;        // bytes per element as stored
  bool contiguous = false;        // contiguous layout (not chunked, compact or virtual)
  hsize_t storage_bytes = 0;      // bytes allocated in the file (H5Dget_storage_size)
  haddr_t address = HADDR_UNDEF;  // file offset of contiguous data (HADDR_UNDEF if unallocated)
  hsize_t elements() const {
    hsize_t n = 1;
    for (hsize_t d : shape) n *= d;
    return n;
  }
};

class H5File {
 public:
  enum class Mode { kRead, kReadWrite, kTruncate };
  H5File(const std::string& path, Mode mode);
  // Creates (truncates) `path` in the HDF5 1.8+ file format, whose superblock, object headers
  // and group indexes carry checksums that libhdf5 verifies when the file is read.
  static H5File create_checksummed(const std::string& path);
  // Opens an HDF5 file image held in memory (read only; the bytes are copied); `name` names the
  // file in errors. InputError when the bytes are not a readable HDF5 file.
  static H5File open_image(const std::string& name, const void* data, size_t size);
  ~H5File();
  H5File(const H5File&) = delete;
  H5File& operator=(const H5File&) = delete;
  H5File(H5File&& other) noexcept;
  H5File& operator=(H5File&& other) noexcept;

  const std::string& path() const { return path_; }
  hid_t id() const { return id_; }
  void flush();
  void close();

  bool exists(const std::string& object) const;  // "/a/b/c", intermediate parts may be missing
  void create_group(const std::string& group);   // creates intermediate groups
  std::vector<std::string> list(const std::string& group) const;  // member names, sorted
  void remove(const std::string& object);                         // unlink (space is not reclaimed)
  void move(const std::string& from, const std::string& to);

  // Writes a whole dataset (creating intermediate groups). `chunk_rows` > 0 enables chunking and
  // gzip level 1 along the first axis; 0 writes a contiguous dataset.
  template <class T>
  void write(const std::string& name, const T* data, const Shape& shape, hsize_t chunk_rows = 0);
  template <class T>
  void write(const std::string& name, const std::vector<T>& data, const Shape& shape,
             hsize_t chunk_rows = 0) {
    write(name, data.data(), shape, chunk_rows);
  }

  // Creates the float32 virtual dataset `name`, [rows] (width 0) or [rows, width], whose values
  // are frame `frame` of the float32 dataset `source_dataset` in `source_file`: the source is
  // [frames, rows(, w)], or [rows(, w)] when `frame` < 0, with w <= width; columns from w on read
  // as 0. Only the mapping is stored (the data stay in the source); a relative `source_file` is
  // looked up in this file's folder when read.
  void write_virtual(const std::string& name, const std::string& source_file,
                     const std::string& source_dataset, const Shape& source_shape, int64_t frame,
                     hsize_t width);

  Shape shape(const std::string& name) const;
  // Shape, stored type, layout and storage of a dataset; InputError naming it when it is missing
  // or not a dataset.
  H5DatasetInfo dataset_info(const std::string& name) const;
  // True when `object` is reached through hard links only (no soft or external link, which a
  // strict reader must not follow: an external link opens another file).
  bool is_hard_link(const std::string& object) const;
  // True when `object` exists and is a group.
  bool is_group(const std::string& object) const;
  // Attribute names of an object, sorted.
  std::vector<std::string> attr_names(const std::string& object) const;
  // Reads a whole dataset, converting to T; checks rank/extent against `expect` where given
  // (0 in `expect` matches any extent).
  template <class T>
  std::vector<T> read(const std::string& name, Shape* shape_out = nullptr,
                      const Shape& expect = {}) const;
  // Reads the hyperslab [offset, offset + count) (count.size() == rank).
  template <class T>
  std::vector<T> read_slab(const std::string& name, const Shape& offset, const Shape& count) const;

  // Attributes on an object ("/" for the root).
  void set_attr(const std::string& object, const std::string& name, const std::string& value);
  void set_attr(const std::string& object, const std::string& name, int64_t value);
  void set_attr(const std::string& object, const std::string& name, double value);
  bool has_attr(const std::string& object, const std::string& name) const;
  std::string attr_string(const std::string& object, const std::string& name) const;
  int64_t attr_int(const std::string& object, const std::string& name) const;
  double attr_double(const std::string& object, const std::string& name) const;

 private:
  H5File(std::string path, hid_t id, bool writable)
      : path_(std::move(path)), id_(id), writable_(writable) {}
  std::string path_;
  hid_t id_ = -1;
  bool writable_ = false;
};

// Inputs of this process: the readers of user data (datasets, meshes) record each file they open,
// and AtomicOutput refuses to replace one (InputError, exit 2), so no command's output, whatever
// its path (the same name, a symlink, a hard link), destroys what the command reads. Files read
// to be resumed or refreshed (checkpoints, run configs, graph caches) are not recorded.
void register_input(const std::string& path);
// InputError naming `output` when it is (the same inode as) a registered input.
void refuse_replacing_input(const std::string& output);

// A file written under a temporary name in the same folder and renamed into place by commit();
// destroyed without commit, the temporary is removed. A reader never sees a partial file. Refuses
// (InputError) a final path that is an input of this process (register_input).
class AtomicOutput {
 public:
  explicit AtomicOutput(std::string final_path);
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  const std::string& temp_path() const { return temp_; }
  const std::string& final_path() const { return final_; }
  void sync();    // fsync of the temporary (commit does it if not done); throws IoError
  void commit();  // fsync + rename; throws IoError

 private:
  std::string final_;
  std::string temp_;
  bool committed_ = false;
  bool synced_ = false;
};

// Throws IoError naming `path` unless its parent folder exists and is writable (creates it).
void ensure_parent_dir(const std::string& path);

}  // namespace bsms
