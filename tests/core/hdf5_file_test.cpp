#include "core/hdf5_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <tuple>
#include <vector>

#include "core/error.hpp"
#include "tests/temp_dir.hpp"

namespace bsms {
namespace {

namespace fs = std::filesystem;

// A file in this test process's own folder.
std::string temp_path(const std::string& name) {
  static const fs::path dir = bsms::testing::unique_temp_dir("h5");
  return (dir / name).string();
}

TEST(Hdf5File, DatasetsAttributesAndSlabsRoundTrip) {
  const std::string path = temp_path("roundtrip.h5");
  {
    H5File f(path, H5File::Mode::kTruncate);
    const std::vector<int64_t> edges = {0, 1, 1, 0, 1, 2, 2, 1};
    f.write("/level_0/edges", edges, {4, 2});
    std::vector<float> frames(3 * 5 * 2);
    for (size_t i = 0; i < frames.size(); ++i) frames[i] = static_cast<float>(i) * 0.5f;
    f.write("/frames/position", frames, {3, 5, 2}, 1);
    f.write("/empty", std::vector<double>{}, {0, 3});
    f.set_attr("/", "format", std::string("bsms-multilevel"));
    f.set_attr("/", "version", int64_t{1});
    f.set_attr("/level_0", "num_nodes", int64_t{3});
    f.set_attr("/frames/position", "dt", 0.25);
  }
  H5File f(path, H5File::Mode::kRead);
  Shape shape;
  EXPECT_EQ(f.read<int64_t>("/level_0/edges", &shape, {0, 2}),
            (std::vector<int64_t>{0, 1, 1, 0, 1, 2, 2, 1}));
  EXPECT_EQ(shape, (Shape{4, 2}));
  EXPECT_EQ(f.read<double>("/empty").size(), 0u);
  EXPECT_EQ(f.attr_string("/", "format"), "bsms-multilevel");
  EXPECT_EQ(f.attr_int("/", "version"), 1);
  EXPECT_EQ(f.attr_int("/level_0", "num_nodes"), 3);
  EXPECT_DOUBLE_EQ(f.attr_double("/frames/position", "dt"), 0.25);
  const auto slab = f.read_slab<float>("/frames/position", {1, 2, 0}, {1, 2, 2});
  EXPECT_EQ(slab, (std::vector<float>{14 * 0.5f, 15 * 0.5f, 16 * 0.5f, 17 * 0.5f}));
  // Reading converts types; shapes and names are checked.
  EXPECT_EQ(f.read<double>("/level_0/edges")[2], 1.0);
  EXPECT_THROW(f.read<int64_t>("/level_0/edges", nullptr, {4, 3}), InputError);
  EXPECT_THROW(f.read<int64_t>("/level_1/edges"), InputError);
  EXPECT_THROW(f.attr_int("/", "missing"), InputError);
  EXPECT_THROW(f.attr_int("/", "format"), InputError);
  EXPECT_EQ(f.list("/"), (std::vector<std::string>{"empty", "frames", "level_0"}));
  EXPECT_TRUE(f.exists("/frames/position"));
  EXPECT_FALSE(f.exists("/frames/velocity/x"));
}

TEST(Hdf5File, OpeningBadFilesIsAnInputError) {
  EXPECT_THROW(H5File(temp_path("missing.h5"), H5File::Mode::kRead), InputError);
  const std::string text = temp_path("text.h5");
  std::ofstream(text) << "not hdf5";
  EXPECT_THROW(H5File(text, H5File::Mode::kRead), InputError);
  // A truncated HDF5 file.
  const std::string full = temp_path("full.h5");
  {
    H5File f(full, H5File::Mode::kTruncate);
    f.write("/x", std::vector<double>(10000, 1.0), {10000});
  }
  const std::string cut = temp_path("cut.h5");
  fs::copy_file(full, cut, fs::copy_options::overwrite_existing);
  fs::resize_file(cut, fs::file_size(full) / 2);
  EXPECT_THROW(
      {
        H5File f(cut, H5File::Mode::kRead);
        f.read<double>("/x");
      },
      InputError);
}

// A file in the format without checksums (older bsms, other tools) whose local heap holding a
// link name is damaged: the name call returns -1, which once sized a string (a crash, exit 1).
TEST(Hdf5File, DamagedLinkNameHeapIsAnInputError) {
  const std::string path = temp_path("legacy_heap.h5");
  {
    const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    H5Gclose(H5Gcreate2(f, "/trajectories", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    H5Gclose(H5Gcreate2(f, "/trajectories/000000", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    H5Fclose(f);
  }
  EXPECT_EQ(H5File(path, H5File::Mode::kRead).list("/trajectories"),
            std::vector<std::string>{"000000"});
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const size_t name = bytes.find("000000");
  const size_t heap = bytes.rfind("HEAP", name);
  ASSERT_NE(name, std::string::npos);
  ASSERT_NE(heap, std::string::npos);
  bytes[heap] ^= 1;
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  try {
    H5File(path, H5File::Mode::kRead).list("/trajectories");
    FAIL() << "a damaged name heap was listed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/trajectories"), std::string::npos) << e.what();
  }
}

TEST(Hdf5File, AtomicOutputLeavesNothingUnlessCommitted) {
  const std::string path = temp_path("atomic.h5");
  fs::remove(path);
  std::string temp;
  {
    AtomicOutput out(path);
    temp = out.temp_path();
    H5File f(out.temp_path(), H5File::Mode::kTruncate);
    f.write("/x", std::vector<int32_t>{1, 2, 3}, {3});
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(temp));
  {
    AtomicOutput out(path);
    {
      H5File f(out.temp_path(), H5File::Mode::kTruncate);
      f.write("/x", std::vector<int32_t>{1, 2, 3}, {3});
    }
    out.commit();
  }
  H5File f(path, H5File::Mode::kRead);
  EXPECT_EQ(f.read<int32_t>("/x"), (std::vector<int32_t>{1, 2, 3}));
  EXPECT_THROW(ensure_parent_dir("/proc/bsms_forbidden/x.h5"), InputError);
}

// Fuzzing regression (fuzz/fuzz_multilevel.cpp): attributes holding several values were read
// into one value's storage (stack-buffer-overflow); they are an InputError.
TEST(Hdf5File, FuzzArrayAttributesAreInputErrors) {
  const std::string path = temp_path("array_attr.h5");
  {
    H5File f(path, H5File::Mode::kTruncate);
    const hsize_t three = 3;
    const hid_t space = H5Screate_simple(1, &three, nullptr);
    const int64_t ints[3] = {1, 2, 3};
    const double reals[3] = {0.5, 1.5, 2.5};
    const char text[3][4] = {"abc", "def", "ghi"};
    const hid_t str = H5Tcopy(H5T_C_S1);
    H5Tset_size(str, 4);
    for (const auto& [name, type, mem, data] : {std::tuple<const char*, hid_t, hid_t, const void*>{
                                                    "ints", H5T_STD_I64LE, H5T_NATIVE_INT64, ints},
                                                {"reals", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, reals},
                                                {"text", str, str, text}}) {
      const hid_t attr = H5Acreate2(f.id(), name, type, space, H5P_DEFAULT, H5P_DEFAULT);
      H5Awrite(attr, mem, data);
      H5Aclose(attr);
    }
    H5Tclose(str);
    H5Sclose(space);
  }
  H5File f(path, H5File::Mode::kRead);
  EXPECT_THROW(f.attr_int("/", "ints"), InputError);
  EXPECT_THROW(f.attr_double("/", "reals"), InputError);
  EXPECT_THROW(f.attr_string("/", "text"), InputError);
  fs::remove(path);
}

}  // namespace
}  // namespace bsms
