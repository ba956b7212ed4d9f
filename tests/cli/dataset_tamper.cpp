// dataset_tamper FILE DATASET INDEX VALUE: sets the value at flat INDEX of an HDF5 dataset (float
// or integer) to VALUE (strtod: "inf", "nan", "3e38" ...) and rewrites it with its shape, so the
// bad-input corpus can make damaged-but-well-formed datasets (an infinite velocity, a repeated
// node in a cell) from a real one; --legacy-copy rewrites a dataset in the older HDF5 format.
// Test helper, not installed.
#include <hdf5.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/hdf5_file.hpp"

namespace {

template <class T>
void patch(bsms::H5File& f, const std::string& name, size_t index, T value) {
  bsms::Shape shape;
  std::vector<T> values = f.read<T>(name, &shape);
  if (index >= values.size())
    throw std::runtime_error(name + ": index " + std::to_string(index) + " outside " +
                             std::to_string(values.size()) + " values");
  values[index] = value;
  // Dynamic fields are chunked by frame, as the dataset writer stores them.
  f.write(name, values, shape,
          shape.size() >= 2 && name.find("/cells") == std::string::npos &&
                  name.find("/mesh_pos") == std::string::npos
              ? 1
              : 0);
}

}  // namespace

// Root attributes copied one by one (H5Ocopy copies objects below the root only).
herr_t copy_attribute(hid_t from, const char* name, const H5A_info_t*, void* to) {
  const hid_t a = H5Aopen(from, name, H5P_DEFAULT);
  const hid_t type = H5Aget_type(a), space = H5Aget_space(a);
  std::vector<char> value(H5Tget_size(type) * H5Sget_simple_extent_npoints(space));
  H5Aread(a, type, value.data());
  const hid_t b = H5Acreate2(*static_cast<hid_t*>(to), name, type, space, H5P_DEFAULT, H5P_DEFAULT);
  const herr_t status = H5Awrite(b, type, value.data());
  H5Aclose(b);
  H5Sclose(space);
  H5Tclose(type);
  H5Aclose(a);
  return status;
}

// DST: the dataset SRC in the HDF5 format bsms wrote before it chose the 1.8 format (groups with
// local heaps, no checksums), as older datasets and other tools' files are.
int legacy_copy(const char* src, const char* dst) {
  const hid_t in = H5Fopen(src, H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t out = H5Fcreate(dst, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (in < 0 || out < 0) return 1;
  // In the order DatasetWriter wrote them: root attributes, /trajectories, then per trajectory
  // its group, its attributes and its datasets.
  auto copy_attributes = [](hid_t from_file, hid_t to_file, const std::string& object) {
    hid_t from = H5Oopen(from_file, object.c_str(), H5P_DEFAULT);
    hid_t to = H5Oopen(to_file, object.c_str(), H5P_DEFAULT);
    hsize_t at = 0;
    const herr_t status = H5Aiterate2(from, H5_INDEX_NAME, H5_ITER_INC, &at, copy_attribute, &to);
    H5Oclose(to);
    H5Oclose(from);
    return status >= 0;
  };
  if (!copy_attributes(in, out, "/")) return 1;
  H5Gclose(H5Gcreate2(out, "/trajectories", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  for (const std::string& t : bsms::H5File(src, bsms::H5File::Mode::kRead).list("/trajectories")) {
    const std::string group = "/trajectories/" + t;
    H5Gclose(H5Gcreate2(out, group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    if (!copy_attributes(in, out, group)) return 1;
    for (const std::string& d : bsms::H5File(src, bsms::H5File::Mode::kRead).list(group)) {
      const std::string name = group + "/" + d;
      if (H5Ocopy(in, name.c_str(), out, name.c_str(), H5P_DEFAULT, H5P_DEFAULT) < 0) return 1;
    }
  }
  H5Fclose(in);
  return H5Fclose(out) < 0 ? 1 : 0;
}

int main(int argc, char** argv) {
  if (argc == 4 && std::string(argv[1]) == "--legacy-copy") return legacy_copy(argv[2], argv[3]);
  if (argc != 5) {
    std::fprintf(stderr,
                 "usage: dataset_tamper FILE DATASET INDEX VALUE\n"
                 "       dataset_tamper --legacy-copy SRC DST\n");
    return 1;
  }
  try {
    bsms::H5File f(argv[1], bsms::H5File::Mode::kReadWrite);
    const std::string name = argv[2];
    const size_t index = std::strtoull(argv[3], nullptr, 10);
    const double value = std::strtod(argv[4], nullptr);
    const hid_t set = H5Dopen2(f.id(), name.c_str(), H5P_DEFAULT);
    if (set < 0) throw std::runtime_error(name + ": no such dataset");
    const hid_t type = H5Dget_type(set);
    const bool is_float = H5Tget_class(type) == H5T_FLOAT;
    H5Tclose(type);
    H5Dclose(set);
    if (is_float)
      patch<float>(f, name, index, static_cast<float>(value));
    else
      patch<int32_t>(f, name, index, static_cast<int32_t>(value));
    f.close();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dataset_tamper: %s\n", e.what());
    return 1;
  }
  return 0;
}
