#include "core/hdf5_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

#include "core/error.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// HDF5 prints its own error stack by default; bsms reports errors itself.
void silence_hdf5() {
  static const bool once = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)once;
}

// Closes an HDF5 handle of any kind when it leaves scope.
class Handle {
 public:
  explicit Handle(hid_t id = -1) : id_(id) {}
  ~Handle() {
    if (id_ >= 0) H5Idec_ref(id_);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  hid_t get() const { return id_; }
  bool ok() const { return id_ >= 0; }

 private:
  hid_t id_;
};

std::string shape_string(const Shape& s) {
  std::string out = "[";
  for (size_t i = 0; i < s.size(); ++i) out += (i ? ", " : "") + std::to_string(s[i]);
  return out + "]";
}

// Values a read of `dims` makes room for. A damaged dataspace can state any extent: the product
// must not overflow, and no dataset expands to more than 4096 times its file (gzip of constant
// data stays well under that) or past 64 MiB for a small file, so no damaged header makes bsms
// allocate gigabytes.
hsize_t checked_elements(const std::string& path, const Shape& dims, size_t value_size,
                         const std::string& name) {
  std::error_code ec;
  const uintmax_t file_bytes = fs::file_size(path, ec);
  const long double limit =
      std::max<long double>(64.0L * 1024 * 1024, 4096.0L * (ec ? 0 : file_bytes));
  long double bytes = static_cast<long double>(value_size);
  hsize_t total = 1;
  for (hsize_t d : dims) {
    bytes *= static_cast<long double>(d);
    total *= d;
  }
  if (bytes > limit)
    throw InputError(path + ": dataset " + name + " states the shape " + shape_string(dims) +
                     ", more than the file can hold (corrupt file?)");
  return total;
}

// Before libhdf5 reads [offset, offset + count) of a dataset of a file that may be damaged: a
// numeric type of at most 8 bytes, stored bytes no more than the file holds, and for each chunk
// read a record that fits the file and, where no decompressing filter was applied (filter mask),
// a stored size equal to the chunk's. libhdf5 1.10 trusts these records: it allocates what they
// state (gigabytes), copies a whole chunk out of a shorter buffer, and checksums a chunk of under
// 4 bytes over an underflowed length.
void check_stored(hid_t set, const std::string& path, const std::string& name, const Shape& offset,
                  const Shape& count) {
  Handle type(H5Dget_type(set));
  const H5T_class_t type_class = type.ok() ? H5Tget_class(type.get()) : H5T_NO_CLASS;
  const size_t type_size = type.ok() ? H5Tget_size(type.get()) : 0;
  if ((type_class != H5T_INTEGER && type_class != H5T_FLOAT) || type_size == 0 || type_size > 8)
    throw InputError(path + ": dataset " + name + " is not of a numeric type (corrupt file?)");
  std::error_code ec;
  const uintmax_t file_bytes = fs::file_size(path, ec);
  if (ec) return;
  const std::string damaged =
      path + ": dataset " + name + " has a damaged chunk record (corrupt file?)";
  if (H5Dget_storage_size(set) > file_bytes) throw InputError(damaged);
  Handle create(H5Dget_create_plist(set));
  if (!create.ok() || H5Pget_layout(create.get()) != H5D_CHUNKED) return;
  const int rank = static_cast<int>(offset.size());
  Shape chunk(offset.size(), 0);
  if (rank == 0 || H5Pget_chunk(create.get(), rank, chunk.data()) != rank)
    throw InputError(damaged);
  const int filters = H5Pget_nfilters(create.get());
  if (filters < 0 || filters > 32) throw InputError(damaged);
  unsigned checksum_bits = 0, other_bits = 0;
  for (int k = 0; k < filters; ++k) {
    unsigned flags = 0, config = 0;
    size_t values = 0;
    const H5Z_filter_t id = H5Pget_filter2(create.get(), static_cast<unsigned>(k), &flags, &values,
                                           nullptr, 0, nullptr, &config);
    (id == H5Z_FILTER_FLETCHER32 ? checksum_bits : other_bits) |= 1u << k;
  }
  long double chunk_bytes = static_cast<long double>(type_size);
  Shape first(offset.size()), last(offset.size());
  long double chunks = 1;
  for (int i = 0; i < rank; ++i) {
    if (chunk[i] == 0 || count[i] == 0) return;
    chunk_bytes *= chunk[i];
    first[i] = offset[i] / chunk[i];
    last[i] = (offset[i] + count[i] - 1) / chunk[i];
    chunks *= static_cast<long double>(last[i] - first[i] + 1);
  }
  if (chunks > (1 << 20)) return;  // no real file reads so many chunks at once: not checked
  Shape index = first, at(offset.size());
  for (;;) {
    for (int i = 0; i < rank; ++i) at[i] = index[i] * chunk[i];
    unsigned mask = 0;
    haddr_t address = HADDR_UNDEF;
    hsize_t size = 0;
    if (H5Dget_chunk_info_by_coord(set, at.data(), &mask, &address, &size) < 0)
      throw InputError(damaged);
    if (address != HADDR_UNDEF) {
      if (address > file_bytes || size > file_bytes - address) throw InputError(damaged);
      // Fletcher-32 checksums the bytes before its own 4: a shorter chunk underflows that length.
      if (size == 0 || ((checksum_bits & ~mask) && size <= 4)) throw InputError(damaged);
      if ((other_bits & ~mask) == 0) {
        const long double expected = chunk_bytes + ((checksum_bits & ~mask) ? 4 : 0);
        if (static_cast<long double>(size) != expected) throw InputError(damaged);
      }
    }
    int i = rank - 1;
    for (; i >= 0; --i) {
      if (index[i] < last[i]) {
        ++index[i];
        break;
      }
      index[i] = first[i];
    }
    if (i < 0) break;
  }
}

std::vector<std::string> split_path(const std::string& path) {
  std::vector<std::string> parts;
  std::stringstream in(path);
  std::string part;
  while (std::getline(in, part, '/'))
    if (!part.empty()) parts.push_back(part);
  return parts;
}

}  // namespace

H5File::H5File(const std::string& path, Mode mode) : path_(path) {
  silence_hdf5();
  switch (mode) {
    case Mode::kRead:
      if (!fs::exists(path)) throw InputError(path + ": file not found");
      if (H5Fis_hdf5(path.c_str()) <= 0) throw InputError(path + ": not an HDF5 file");
      id_ = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      if (id_ < 0) throw InputError(path + ": cannot open HDF5 file (corrupt or truncated?)");
      break;
    case Mode::kReadWrite:
      if (!fs::exists(path)) throw InputError(path + ": file not found");
      id_ = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
      if (id_ < 0) throw IoError(path + ": cannot open HDF5 file for writing");
      writable_ = true;
      break;
    case Mode::kTruncate: {
      // The 1.8 file format and up: superblock, object headers, heaps and B-trees carry
      // checksums, so libhdf5 refuses damaged metadata instead of parsing it (libhdf5 1.10 reads
      // out of bounds on some damaged version-1 object headers; fuzz/fuzz_dataset_bytes.cpp).
      Handle access(H5Pcreate(H5P_FILE_ACCESS));
      if (!access.ok() || H5Pset_libver_bounds(access.get(), H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0)
        throw IoError(path + ": cannot set the HDF5 file format");
      Handle create(H5Pcreate(H5P_FILE_CREATE));
      if (!create.ok() || H5Pset_obj_track_times(create.get(), 0) < 0)
        throw IoError(path + ": cannot set the HDF5 file format");
      id_ = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, create.get(), access.get());
      if (id_ < 0) throw IoError(path + ": cannot create HDF5 file");
      writable_ = true;
      break;
    }
  }
}

H5File H5File::create_checksummed(const std::string& path) {
  silence_hdf5();
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS));
  if (!fapl.ok() || H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_LATEST) < 0)
    throw IoError(path + ": cannot set up the HDF5 file format");
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE));
  if (!fcpl.ok() || H5Pset_obj_track_times(fcpl.get(), 0) < 0)
    throw IoError(path + ": cannot set up the HDF5 file format");
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get());
  if (id < 0) throw IoError(path + ": cannot create HDF5 file");
  return H5File(path, id, true);
}

H5File H5File::open_image(const std::string& name, const void* data, size_t size) {
  silence_hdf5();
  // libhdf5 takes two open files of the core driver with one name for the same file: each image
  // gets a name of its own (the user's name stays in path() for messages).
  static std::atomic<uint64_t> images{0};
  const std::string internal = name + "#image" + std::to_string(images++);
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS));
  if (!fapl.ok() || H5Pset_fapl_core(fapl.get(), 1 << 16, /*backing_store=*/0) < 0 ||
      H5Pset_file_image(fapl.get(), const_cast<void*>(data), size) < 0)
    throw InputError(name + ": cannot hold the file in memory (" + std::to_string(size) +
                     " bytes)");
  const hid_t id = H5Fopen(internal.c_str(), H5F_ACC_RDONLY, fapl.get());
  if (id < 0) throw InputError(name + ": not a readable HDF5 file (truncated or corrupt)");
  return H5File(name, id, false);
}

H5File::~H5File() {
  if (id_ >= 0) H5Fclose(id_);
}

H5File::H5File(H5File&& other) noexcept
    : path_(std::move(other.path_)), id_(other.id_), writable_(other.writable_) {
  other.id_ = -1;
}

H5File& H5File::operator=(H5File&& other) noexcept {
  if (this != &other) {
    if (id_ >= 0) H5Fclose(id_);
    path_ = std::move(other.path_);
    id_ = other.id_;
    writable_ = other.writable_;
    other.id_ = -1;
  }
  return *this;
}

void H5File::flush() {
  if (id_ >= 0 && H5Fflush(id_, H5F_SCOPE_GLOBAL) < 0) throw IoError(path_ + ": flush failed");
}

void H5File::close() {
  if (id_ >= 0) {
    const herr_t status = H5Fclose(id_);
    id_ = -1;
    if (status < 0) throw IoError(path_ + ": close failed (disk full?)");
  }
}

bool H5File::exists(const std::string& object) const {
  if (object == "/" || object.empty()) return true;
  std::string walked;
  for (const auto& part : split_path(object)) {
    walked += "/" + part;
    if (H5Lexists(id_, walked.c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return true;
}

void H5File::create_group(const std::string& group) {
  std::string walked;
  for (const auto& part : split_path(group)) {
    walked += "/" + part;
    if (H5Lexists(id_, walked.c_str(), H5P_DEFAULT) > 0) continue;
    // No modification times (here and on datasets): the same content gives the same bytes, so
    // outputs can be compared with cmp and are reproducible.
    Handle gcpl(H5Pcreate(H5P_GROUP_CREATE));
    if (!gcpl.ok() || H5Pset_obj_track_times(gcpl.get(), 0) < 0)
      throw IoError(path_ + ": cannot describe group " + walked);
    Handle g(H5Gcreate2(id_, walked.c_str(), H5P_DEFAULT, gcpl.get(), H5P_DEFAULT));
    if (!g.ok()) throw IoError(path_ + ": cannot create group " + walked);
  }
}

namespace {
herr_t collect_link_name(hid_t, const char* name, const H5L_info_t*, void* names) noexcept {
  try {
    static_cast<std::vector<std::string>*>(names)->emplace_back(name);
    return 0;
  } catch (...) {
    return -1;
  }
}
}  // namespace

std::vector<std::string> H5File::list(const std::string& group) const {
  std::vector<std::string> names;
  Handle g(H5Gopen2(id_, group.c_str(), H5P_DEFAULT));
  if (!g.ok()) throw InputError(path_ + ": missing group " + group);
  // Iterating in native order walks a large group's name index directly; looking names up by
  // position (or iterating in a set order) builds a table of its links first, and libhdf5 1.10
  // frees pointers it never set when a damaged link fails half-way through that table (a crash,
  // found by fuzzing checkpoints). The names are sorted here.
  hsize_t at = 0;
  if (H5Literate(g.get(), H5_INDEX_NAME, H5_ITER_NATIVE, &at, collect_link_name, &names) < 0)
    throw InputError(path_ + ": cannot read the members of group " + group + " (damaged?)");
  std::sort(names.begin(), names.end());
  return names;
}

void H5File::remove(const std::string& object) {
  if (H5Ldelete(id_, object.c_str(), H5P_DEFAULT) < 0)
    throw IoError(path_ + ": cannot remove " + object);
}

void H5File::move(const std::string& from, const std::string& to) {
  if (H5Lmove(id_, from.c_str(), id_, to.c_str(), H5P_DEFAULT, H5P_DEFAULT) < 0)
    throw IoError(path_ + ": cannot move " + from + " to " + to);
}

template <class T>
void H5File::write(const std::string& name, const T* data, const Shape& shape, hsize_t chunk_rows) {
  const auto slash = name.rfind('/');
  if (slash != std::string::npos && slash > 0) create_group(name.substr(0, slash));
  if (H5Lexists(id_, name.c_str(), H5P_DEFAULT) > 0) remove(name);
  Handle space(H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr));
  Handle plist(H5Pcreate(H5P_DATASET_CREATE));
  if (!space.ok() || !plist.ok() || H5Pset_obj_track_times(plist.get(), 0) < 0)
    throw IoError(path_ + ": cannot describe dataset " + name + " of shape " + shape_string(shape));
  hsize_t total = 1;
  for (hsize_t s : shape) total *= s;
  if (chunk_rows > 0 && !shape.empty() && total > 0) {
    Shape chunk = shape;
    chunk[0] = std::min<hsize_t>(chunk_rows, std::max<hsize_t>(shape[0], 1));
    // Fletcher-32 per chunk: a damaged chunk fails its read instead of inflating to garbage.
    if (H5Pset_chunk(plist.get(), static_cast<int>(chunk.size()), chunk.data()) < 0 ||
        H5Pset_deflate(plist.get(), 1) < 0 || H5Pset_fletcher32(plist.get()) < 0)
      throw IoError(path_ + ": cannot set the chunking of dataset " + name);
  }
  Handle set(H5Dcreate2(id_, name.c_str(), h5_native_type<T>(), space.get(), H5P_DEFAULT,
                        plist.get(), H5P_DEFAULT));
  if (!set.ok()) throw IoError(path_ + ": cannot create dataset " + name);
  if (total > 0 &&
      H5Dwrite(set.get(), h5_native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    throw IoError(path_ + ": cannot write dataset " + name + " (disk full?)");
}

void H5File::write_virtual(const std::string& name, const std::string& source_file,
                           const std::string& source_dataset, const Shape& source_shape,
                           int64_t frame, hsize_t width) {
  const size_t lead = frame >= 0 ? 1 : 0;
  if (source_shape.size() < lead + 1 || source_shape.size() > lead + 2 ||
      (frame >= 0 && static_cast<hsize_t>(frame) >= source_shape[0]))
    throw IoError(path_ + ": virtual dataset " + name + ": bad source shape or frame");
  const hsize_t rows = source_shape[lead];
  const hsize_t source_width = source_shape.size() == lead + 2 ? source_shape[lead + 1] : 1;
  if (width > 0 ? source_width > width : source_width != 1)
    throw IoError(path_ + ": virtual dataset " + name + " is narrower than its source");
  const auto slash = name.rfind('/');
  if (slash != std::string::npos && slash > 0) create_group(name.substr(0, slash));
  if (H5Lexists(id_, name.c_str(), H5P_DEFAULT) > 0) remove(name);

  const Shape extent = width > 0 ? Shape{rows, width} : Shape{rows};
  Handle space(H5Screate_simple(static_cast<int>(extent.size()), extent.data(), nullptr));
  Handle mapped(H5Scopy(space.get()));
  const Shape zero(extent.size(), 0);
  const Shape block = width > 0 ? Shape{rows, source_width} : Shape{rows};
  Handle source(
      H5Screate_simple(static_cast<int>(source_shape.size()), source_shape.data(), nullptr));
  Shape start(source_shape.size(), 0), count = source_shape;
  if (frame >= 0) {
    start[0] = static_cast<hsize_t>(frame);
    count[0] = 1;
  }
  Handle plist(H5Pcreate(H5P_DATASET_CREATE));
  const float fill = 0.0f;
  if (!space.ok() || !mapped.ok() || !source.ok() || !plist.ok() ||
      H5Sselect_hyperslab(mapped.get(), H5S_SELECT_SET, zero.data(), nullptr, block.data(),
                          nullptr) < 0 ||
      H5Sselect_hyperslab(source.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                          nullptr) < 0 ||
      H5Pset_obj_track_times(plist.get(), 0) < 0 ||
      H5Pset_fill_value(plist.get(), H5T_NATIVE_FLOAT, &fill) < 0 ||
      H5Pset_virtual(plist.get(), mapped.get(), source_file.c_str(), source_dataset.c_str(),
                     source.get()) < 0)
    throw IoError(path_ + ": cannot map virtual dataset " + name);
  Handle set(H5Dcreate2(id_, name.c_str(), H5T_IEEE_F32LE, space.get(), H5P_DEFAULT, plist.get(),
                        H5P_DEFAULT));
  if (!set.ok()) throw IoError(path_ + ": cannot create virtual dataset " + name);
}

Shape H5File::shape(const std::string& name) const {
  if (!exists(name)) throw InputError(path_ + ": missing dataset " + name);
  Handle set(H5Dopen2(id_, name.c_str(), H5P_DEFAULT));
  if (!set.ok()) throw InputError(path_ + ": " + name + " is not a dataset");
  Handle space(H5Dget_space(set.get()));
  const int rank = space.ok() ? H5Sget_simple_extent_ndims(space.get()) : -1;
  if (rank < 0 || rank > H5S_MAX_RANK)
    throw InputError(path_ + ": cannot read the shape of " + name + " (corrupt file?)");
  Shape dims(static_cast<size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr) != rank)
    throw InputError(path_ + ": cannot read the shape of " + name + " (corrupt file?)");
  return dims;
}

const char* h5_dtype_name(H5Dtype dtype) {
  switch (dtype) {
    case H5Dtype::kFloat32:
      return "float32";
    case H5Dtype::kFloat64:
      return "float64";
    case H5Dtype::kInt64:
      return "int64";
    case H5Dtype::kInt32:
      return "int32";
    case H5Dtype::kUInt8:
      return "uint8";
    case H5Dtype::kOther:
      break;
  }
  return "other";
}

H5DatasetInfo H5File::dataset_info(const std::string& name) const {
  if (!exists(name)) throw InputError(path_ + ": missing dataset " + name);
  H5O_info_t object{};
  if (H5Oget_info_by_name(id_, name.c_str(), &object, H5P_DEFAULT) < 0)
    throw InputError(path_ + ": cannot read object " + name + " (damaged?)");
  if (object.type != H5O_TYPE_DATASET) throw InputError(path_ + ": " + name + " is not a dataset");
  Handle set(H5Dopen2(id_, name.c_str(), H5P_DEFAULT));
  if (!set.ok()) throw InputError(path_ + ": cannot open dataset " + name + " (damaged?)");
  H5DatasetInfo info;
  Handle space(H5Dget_space(set.get()));
  const int rank = space.ok() ? H5Sget_simple_extent_ndims(space.get()) : -1;
  if (rank < 0) throw InputError(path_ + ": cannot read the shape of " + name);
  info.shape.resize(static_cast<size_t>(rank));
  if (rank > 0 && H5Sget_simple_extent_dims(space.get(), info.shape.data(), nullptr) < 0)
    throw InputError(path_ + ": cannot read the shape of " + name);
  Handle type(H5Dget_type(set.get()));
  if (!type.ok()) throw InputError(path_ + ": cannot read the type of " + name);
  info.element_size = H5Tget_size(type.get());
  const std::pair<hid_t, H5Dtype> known[] = {
      {H5T_IEEE_F32LE, H5Dtype::kFloat32}, {H5T_IEEE_F32BE, H5Dtype::kFloat32},
      {H5T_IEEE_F64LE, H5Dtype::kFloat64}, {H5T_IEEE_F64BE, H5Dtype::kFloat64},
      {H5T_STD_I64LE, H5Dtype::kInt64},    {H5T_STD_I64BE, H5Dtype::kInt64},
      {H5T_STD_I32LE, H5Dtype::kInt32},    {H5T_STD_I32BE, H5Dtype::kInt32},
      {H5T_STD_U8LE, H5Dtype::kUInt8},     {H5T_STD_U8BE, H5Dtype::kUInt8}};
  for (const auto& [h5, dtype] : known)
    if (H5Tequal(type.get(), h5) > 0) {
      info.dtype = dtype;
      break;
    }
  Handle plist(H5Dget_create_plist(set.get()));
  info.contiguous = plist.ok() && H5Pget_layout(plist.get()) == H5D_CONTIGUOUS;
  info.storage_bytes = H5Dget_storage_size(set.get());
  if (info.contiguous) info.address = H5Dget_offset(set.get());
  return info;
}

bool H5File::is_hard_link(const std::string& object) const {
  std::string walked;
  for (const auto& part : split_path(object)) {
    walked += "/" + part;
    H5L_info_t info{};
    if (H5Lexists(id_, walked.c_str(), H5P_DEFAULT) <= 0 ||
        H5Lget_info(id_, walked.c_str(), &info, H5P_DEFAULT) < 0 || info.type != H5L_TYPE_HARD)
      return false;
  }
  return true;
}

bool H5File::is_group(const std::string& object) const {
  if (!exists(object)) return false;
  H5O_info_t info{};
  return H5Oget_info_by_name(id_, object.c_str(), &info, H5P_DEFAULT) >= 0 &&
         info.type == H5O_TYPE_GROUP;
}

std::vector<std::string> H5File::attr_names(const std::string& object) const {
  Handle obj(H5Oopen(id_, object.c_str(), H5P_DEFAULT));
  if (!obj.ok()) throw InputError(path_ + ": missing object " + object);
  H5O_info_t info{};
  if (H5Oget_info(obj.get(), &info) < 0) throw InputError(path_ + ": cannot read object " + object);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.num_attrs; ++i) {
    const ssize_t len =
        H5Aget_name_by_idx(obj.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    if (len < 0) throw InputError(path_ + ": cannot read the attributes of " + object);
    std::string name(static_cast<size_t>(len), '\0');
    H5Aget_name_by_idx(obj.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(),
                       static_cast<size_t>(len) + 1, H5P_DEFAULT);
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

template <class T>
std::vector<T> H5File::read(const std::string& name, Shape* shape_out, const Shape& expect) const {
  const Shape dims = shape(name);
  if (!expect.empty()) {
    bool ok = expect.size() == dims.size();
    for (size_t i = 0; ok && i < dims.size(); ++i) ok = expect[i] == 0 || expect[i] == dims[i];
    if (!ok)
      throw InputError(path_ + ": dataset " + name + " has shape " + shape_string(dims) +
                       ", expected " + shape_string(expect) + " (0 = any)");
  }
  const hsize_t total = checked_elements(path_, dims, sizeof(T), name);
  std::vector<T> out(total);
  if (total > 0) {
    Handle set(H5Dopen2(id_, name.c_str(), H5P_DEFAULT));
    if (set.ok() && !writable_) check_stored(set.get(), path_, name, Shape(dims.size(), 0), dims);
    if (!set.ok() ||
        H5Dread(set.get(), h5_native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
      throw InputError(path_ + ": cannot read dataset " + name + " (corrupt, or wrong type)");
  }
  if (shape_out) *shape_out = dims;
  return out;
}

template <class T>
std::vector<T> H5File::read_slab(const std::string& name, const Shape& offset,
                                 const Shape& count) const {
  const Shape dims = shape(name);
  if (offset.size() != dims.size() || count.size() != dims.size())
    throw InputError(path_ + ": slab of " + name + " has the wrong rank");
  for (size_t i = 0; i < dims.size(); ++i)
    if (offset[i] > dims[i] || count[i] > dims[i] - offset[i])
      throw InputError(path_ + ": slab outside dataset " + name + " of shape " +
                       shape_string(dims));
  const hsize_t total = checked_elements(path_, count, sizeof(T), name);
  std::vector<T> out(total);
  if (total == 0) return out;
  Handle set(H5Dopen2(id_, name.c_str(), H5P_DEFAULT));
  if (set.ok() && !writable_) check_stored(set.get(), path_, name, offset, count);
  Handle file_space(set.ok() ? H5Dget_space(set.get()) : -1);
  Handle mem_space(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr));
  if (!file_space.ok() || !mem_space.ok() ||
      H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, offset.data(), nullptr, count.data(),
                          nullptr) < 0 ||
      H5Dread(set.get(), h5_native_type<T>(), mem_space.get(), file_space.get(), H5P_DEFAULT,
              out.data()) < 0)
    throw InputError(path_ + ": cannot read a slab of " + name);
  return out;
}

#define BSMS_H5_INSTANTIATE(T)                                                                 \
  template void H5File::write<T>(const std::string&, const T*, const Shape&, hsize_t);         \
  template std::vector<T> H5File::read<T>(const std::string&, Shape*, const Shape&) const;     \
  template std::vector<T> H5File::read_slab<T>(const std::string&, const Shape&, const Shape&) \
      const;
BSMS_H5_INSTANTIATE(int32_t)
BSMS_H5_INSTANTIATE(int64_t)
BSMS_H5_INSTANTIATE(float)
BSMS_H5_INSTANTIATE(double)
BSMS_H5_INSTANTIATE(uint8_t)
#undef BSMS_H5_INSTANTIATE

namespace {
void write_attr(hid_t file, const std::string& path, const std::string& object,
                const std::string& name, hid_t type, const void* value) {
  Handle obj(H5Oopen(file, object.c_str(), H5P_DEFAULT));
  if (!obj.ok()) throw IoError(path + ": missing object " + object);
  if (H5Aexists(obj.get(), name.c_str()) > 0 && H5Adelete(obj.get(), name.c_str()) < 0)
    throw IoError(path + ": cannot replace attribute " + object + "@" + name);
  Handle space(H5Screate(H5S_SCALAR));
  if (type < 0 || !space.ok())
    throw IoError(path + ": cannot describe attribute " + object + "@" + name);
  Handle attr(H5Acreate2(obj.get(), name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT));
  if (!attr.ok() || H5Awrite(attr.get(), type, value) < 0)
    throw IoError(path + ": cannot write attribute " + object + "@" + name);
}
}  // namespace

void H5File::set_attr(const std::string& object, const std::string& name,
                      const std::string& value) {
  Handle type(H5Tcopy(H5T_C_S1));
  if (!type.ok() || H5Tset_size(type.get(), std::max<size_t>(value.size(), 1)) < 0 ||
      H5Tset_strpad(type.get(), H5T_STR_NULLTERM) < 0 || H5Tset_cset(type.get(), H5T_CSET_UTF8) < 0)
    throw IoError(path_ + ": cannot make the string type of attribute " + object + "@" + name);
  std::string padded = value;
  if (padded.empty()) padded.push_back('\0');
  write_attr(id_, path_, object, name, type.get(), padded.data());
}

void H5File::set_attr(const std::string& object, const std::string& name, int64_t value) {
  write_attr(id_, path_, object, name, H5T_NATIVE_INT64, &value);
}

void H5File::set_attr(const std::string& object, const std::string& name, double value) {
  write_attr(id_, path_, object, name, H5T_NATIVE_DOUBLE, &value);
}

bool H5File::has_attr(const std::string& object, const std::string& name) const {
  if (!exists(object)) return false;
  return H5Aexists_by_name(id_, object.c_str(), name.c_str(), H5P_DEFAULT) > 0;
}

namespace {
hid_t open_attr(hid_t file, const std::string& path, const std::string& object,
                const std::string& name) {
  if (H5Lexists(file, object.c_str(), H5P_DEFAULT) <= 0 && object != "/")
    throw InputError(path + ": missing object " + object);
  if (H5Aexists_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT) <= 0)
    throw InputError(path + ": missing attribute " + object + "@" + name);
  const hid_t attr = H5Aopen_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  if (attr < 0) throw InputError(path + ": cannot open attribute " + object + "@" + name);
  // The readers below read one value: an array attribute would be written past its end.
  const hid_t space = H5Aget_space(attr);
  const hssize_t points = space < 0 ? -1 : H5Sget_simple_extent_npoints(space);
  if (space >= 0) H5Sclose(space);
  if (points != 1) {
    H5Aclose(attr);
    throw InputError(path + ": attribute " + object + "@" + name + " is not a single value");
  }
  return attr;
}
}  // namespace

std::string H5File::attr_string(const std::string& object, const std::string& name) const {
  Handle attr(open_attr(id_, path_, object, name));
  Handle type(H5Aget_type(attr.get()));
  if (!type.ok())
    throw InputError(path_ + ": cannot read the type of attribute " + object + "@" + name);
  if (H5Tget_class(type.get()) != H5T_STRING)
    throw InputError(path_ + ": attribute " + object + "@" + name + " is not a string");
  const htri_t variable = H5Tis_variable_str(type.get());
  if (variable < 0)
    throw InputError(path_ + ": cannot read the type of attribute " + object + "@" + name);
  if (variable > 0) {
    char* buffer = nullptr;
    Handle mem(H5Tcopy(H5T_C_S1));
    if (!mem.ok() || H5Tset_size(mem.get(), H5T_VARIABLE) < 0 ||
        H5Aread(attr.get(), mem.get(), &buffer) < 0 || buffer == nullptr)
      throw InputError(path_ + ": cannot read attribute " + object + "@" + name);
    std::string out(buffer);
    H5free_memory(buffer);
    return out;
  }
  // A fixed-length string holds exactly its stored bytes, and no bsms string attribute (the scene
  // JSON included) comes near 256 MiB: a damaged type size is not a length to allocate.
  const size_t size = H5Tget_size(type.get());
  if (size == 0 || size > (size_t{256} << 20) || H5Aget_storage_size(attr.get()) < size)
    throw InputError(path_ + ": attribute " + object + "@" + name + " is damaged");
  std::string out(size, '\0');
  if (H5Aread(attr.get(), type.get(), out.data()) < 0)
    throw InputError(path_ + ": cannot read attribute " + object + "@" + name);
  out.resize(std::strlen(out.c_str()));
  return out;
}

int64_t H5File::attr_int(const std::string& object, const std::string& name) const {
  Handle attr(open_attr(id_, path_, object, name));
  Handle type(H5Aget_type(attr.get()));
  if (!type.ok() || H5Tget_class(type.get()) != H5T_INTEGER)
    throw InputError(path_ + ": attribute " + object + "@" + name + " is not an integer");
  int64_t value = 0;
  if (H5Aread(attr.get(), H5T_NATIVE_INT64, &value) < 0)
    throw InputError(path_ + ": cannot read attribute " + object + "@" + name);
  return value;
}

double H5File::attr_double(const std::string& object, const std::string& name) const {
  Handle attr(open_attr(id_, path_, object, name));
  Handle type(H5Aget_type(attr.get()));
  const H5T_class_t type_class = type.ok() ? H5Tget_class(type.get()) : H5T_NO_CLASS;
  if (type_class != H5T_FLOAT && type_class != H5T_INTEGER)
    throw InputError(path_ + ": attribute " + object + "@" + name + " is not a number");
  double value = 0;
  if (H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value) < 0)
    throw InputError(path_ + ": cannot read attribute " + object + "@" + name);
  return value;
}

namespace {

struct InputRegistry {
  std::mutex mutex;
  std::map<std::pair<dev_t, ino_t>, std::string> names;
  // Files this process wrote: reading one back (a rollout's XDMF views) does not make it an
  // input, so a later output of the same process may replace it.
  std::set<std::pair<dev_t, ino_t>> outputs;
};

InputRegistry& input_registry() {
  static InputRegistry registry;
  return registry;
}

}  // namespace

void register_input(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;
  auto& r = input_registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (r.outputs.count({st.st_dev, st.st_ino})) return;
  r.names.emplace(std::make_pair(st.st_dev, st.st_ino), path);
}

void refuse_replacing_input(const std::string& output) {
  struct stat st {};
  if (::stat(output.c_str(), &st) != 0) return;
  auto& r = input_registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  const auto it = r.names.find({st.st_dev, st.st_ino});
  if (it == r.names.end()) return;
  throw InputError(output + ": is an input of this command" +
                   (it->second == output ? std::string() : " (" + it->second + ")") +
                   "; writing it would destroy it: choose another output path");
}

AtomicOutput::AtomicOutput(std::string final_path) : final_(std::move(final_path)) {
  static std::atomic<int> counter{0};
  refuse_replacing_input(final_);
  ensure_parent_dir(final_);
  temp_ = final_ + ".tmp." + std::to_string(getpid()) + "." + std::to_string(counter++);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) std::remove(temp_.c_str());
}

void AtomicOutput::sync() {
  if (synced_) return;
  const int fd = ::open(temp_.c_str(), O_RDONLY);
  if (fd < 0) throw IoError(temp_ + ": temporary output vanished before commit");
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) throw IoError(temp_ + ": fsync failed (disk full?)");
  synced_ = true;
}

void AtomicOutput::commit() {
  sync();
  // An input may have been read after this output was started.
  refuse_replacing_input(final_);
  if (std::rename(temp_.c_str(), final_.c_str()) != 0)
    throw IoError(final_ + ": cannot rename the finished temporary file into place");
  committed_ = true;
  struct stat st {};
  if (::stat(final_.c_str(), &st) == 0) {
    auto& r = input_registry();
    const std::lock_guard<std::mutex> lock(r.mutex);
    // An input of that inode was deleted (inodes are reused): the name is now this output.
    r.names.erase({st.st_dev, st.st_ino});
    r.outputs.insert({st.st_dev, st.st_ino});
  }
}

void ensure_parent_dir(const std::string& path) {
  fs::path parent = fs::path(path).parent_path();
  if (parent.empty()) parent = ".";
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec || !fs::is_directory(parent))
    throw InputError(path + ": cannot create output folder " + parent.string() + " (" +
                     ec.message() + ")");
  if (::access(parent.c_str(), W_OK) != 0)
    throw InputError(path + ": output folder " + parent.string() + " is not writable");
}

}  // namespace bsms
