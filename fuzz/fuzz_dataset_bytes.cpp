// libFuzzer target: REAL files, damaged byte by byte. Where fuzz_dataset and fuzz_multilevel
// write valid HDF5 files from structure programs (h5_builder.hpp), this target starts from the
// bytes bsms itself writes: at start-up a small bsms dataset (DatasetWriter: 2 trajectories of a
// 16-node mesh, 4 frames of world_pos, velocity and stress, chunked and gzip-compressed as
// `bsms generate` stores them) and the multilevel graph file of its mesh (write_multilevel_graph,
// as `bsms preprocess` and the run folder's multilevel/ cache hold them). The input damages a
// copy: byte 0 picks the file (bit 0: graph), bytes 1-2 (uint16 LE) a truncation (0: none, else
// the file loses 1 + value % size bytes), then each 3 bytes (uint16 LE offset modulo the size,
// xor mask) flip bits. The copy is opened through the readers `bsms info`, `train` and
// `preprocess` use (Dataset: every mesh, every field of every trajectory, seeds and parameters;
// read_multilevel_graph). A damaged file must end in an InputError or in values that pass every
// check; a crash, a hang, another exception or an accepted file breaking the readers' promises
// fails. Seeds: BSMS_FUZZ_WRITE_SEEDS=DIR fuzz_dataset_bytes writes a few inputs to DIR.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/mesh.hpp"
#include "data/dataset/dataset.hpp"
#include "h5_builder.hpp"
#include "preprocess/multilevel_file.hpp"
#include "preprocess/multilevel_graph.hpp"
#include "seeds.hpp"

namespace {

namespace fs = std::filesystem;

// A 4 x 4 grid of nodes, two triangles per square.
bsms::TrajectoryMesh grid_mesh() {
  bsms::TrajectoryMesh m;
  m.dim = 2;
  m.cell_size = 3;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      m.mesh_pos.push_back(0.1f * i);
      m.mesh_pos.push_back(0.1f * j);
      m.node_type.push_back(i == 0 ? 1 : 0);
      m.body_id.push_back(0);
    }
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const int a = j * 4 + i, b = a + 1, c = a + 4, d = a + 5;
      m.cells.insert(m.cells.end(), {a, b, d, a, d, c});
    }
  return m;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

struct Originals {
  std::string dataset, graph;
};

const Originals& originals() {
  static const Originals o = [] {
    const std::string dir = bsms_fuzz::scratch_dir("dataset_bytes") + "/originals";
    fs::create_directories(dir);
    const bsms::TrajectoryMesh mesh = grid_mesh();
    {
      // A scene as `bsms generate` stores one (a family file), which the reader parses strictly.
      bsms::DatasetWriter w(dir + "/train.h5", R"({"scene": {"dim": 2, "background": {"type": "box",
          "min": [0, 0], "max": [1, 1], "element_size": 0.1}, "solver": {"end_time": 1.0}}})",
                            2, 0.04);
      for (int64_t k = 0; k < 2; ++k) {
        bsms::Trajectory t;
        t.mesh = mesh;
        t.seed = 10 + k;
        t.parameters = R"({"k": )" + std::to_string(k) + "}";
        t.solver_wall_s = 0.5;
        t.num_frames = 4;
        std::vector<float> pos, vel, stress;
        for (int64_t f = 0; f < 4; ++f)
          for (int64_t n = 0; n < mesh.num_nodes(); ++n) {
            pos.push_back(mesh.mesh_pos[2 * n] + 0.01f * f);
            pos.push_back(mesh.mesh_pos[2 * n + 1] - 0.02f * f * k);
            vel.push_back(0.25f);
            vel.push_back(-0.5f * k);
            stress.push_back(100.0f * n + f);
          }
        t.fields = {{"world_pos", pos}, {"velocity", vel}, {"stress", stress}};
        w.add(t);
      }
      w.commit();
    }
    {
      bsms::RowMatrixXd points(mesh.num_nodes(), 2);
      for (int64_t n = 0; n < mesh.num_nodes(); ++n)
        for (int c = 0; c < 2; ++c) points(n, c) = mesh.mesh_pos[2 * n + c];
      bsms::RowMatrixXi64 cells(mesh.num_cells(), 3);
      for (int64_t c = 0; c < mesh.num_cells(); ++c)
        for (int a = 0; a < 3; ++a) cells(c, a) = mesh.cells[3 * c + a];
      bsms::BuildOptions options;
      options.num_levels = 3;
      bsms::write_multilevel_graph(
          bsms::build_multilevel_graph(bsms::make_mesh(2, points, cells), options),
          dir + "/graph.h5");
    }
    Originals out{read_bytes(dir + "/train.h5"), read_bytes(dir + "/graph.h5")};
    // Both must fit the 16-bit offsets of the input encoding.
    if (out.dataset.size() > 65535 || out.graph.size() > 65535) __builtin_trap();
    return out;
  }();
  return o;
}

std::vector<std::vector<uint8_t>> seeds() {
  const Originals& o = originals();
  std::vector<std::vector<uint8_t>> out;
  for (uint8_t mode : {0, 1}) {
    out.push_back({mode, 0, 0});  // the file as written
    const size_t size = mode ? o.graph.size() : o.dataset.size();
    // A flip in the superblock, one in the middle, a truncation by a quarter.
    out.push_back({mode, 0, 0, 20, 0, 0x40});
    out.push_back(
        {mode, 0, 0, static_cast<uint8_t>(size / 2), static_cast<uint8_t>(size / 512), 0x01});
    const uint16_t cut = static_cast<uint16_t>(size / 4 - 1);
    out.push_back({mode, static_cast<uint8_t>(cut & 0xff), static_cast<uint8_t>(cut >> 8)});
  }
  // Found by this target, kept as regressions: a chunk record whose filter mask lost its deflate
  // bit (libhdf5 copied a whole chunk out of a 60-byte buffer), and a damaged chunk record that
  // made libhdf5 allocate 2.3 GB, and one whose stored size under 4 bytes made libhdf5's
  // Fletcher-32 read far out of bounds.
  out.push_back({0x00, 0x00, 0x00, 0x54, 0x12, 0x01});
  out.push_back(
      {0x3e, 0x00, 0x00, 0x2b, 0x27, 0x89, 0x5b, 0x89, 0x89, 0x89, 0x89, 0x8d, 0x2c, 0x03});
  out.push_back({0x9a, 0x00, 0x00, 0x7c, 0x7e, 0x42, 0x23});
  return out;
}

// The dataset walked as `bsms info` and `bsms train` read it.
void walk_dataset(const std::string& path) {
  const bsms::Dataset d(path);
  const int64_t n = d.num_trajectories();
  if (n < 1) __builtin_trap();
  (void)d.dim();
  (void)d.frame_dt();
  (void)d.scene();
  for (int64_t t = 0; t < n && t < 4; ++t) {
    const bsms::TrajectoryMesh& m = d.mesh(t);
    if (static_cast<int64_t>(m.mesh_pos.size()) != m.num_nodes() * m.dim) __builtin_trap();
    for (int32_t c : m.cells)
      if (c < 0 || c >= m.num_nodes()) __builtin_trap();
    (void)d.seed(t);
    (void)d.parameters(t);
    (void)d.solver_wall_s(t);
    const int64_t frames = d.num_frames(t);
    for (const bsms::FieldInfo& f : d.fields()) {
      const std::vector<float> v = d.read(t, f.name, 0, frames);
      if (static_cast<int64_t>(v.size()) != frames * m.num_nodes() * f.width) __builtin_trap();
      for (float x : v)
        if (!(std::abs(x) <= bsms::value_bound(f.name))) __builtin_trap();
    }
  }
}

void walk_graph(const std::string& path) {
  const bsms::MultilevelGraph graph = bsms::read_multilevel_graph(path);
  if (graph.num_levels() < 1) __builtin_trap();
  for (int k = 1; k < graph.num_levels(); ++k)
    for (int64_t v : graph.levels[k].pooled)
      if (v < 0 || v >= graph.levels[k - 1].num_nodes()) __builtin_trap();
}

}  // namespace

// libhdf5 1.10 leaks on some error paths of damaged object headers (64 bytes from H5Dopen2 of a
// dataset whose header is damaged: bsms holds no handle there): not bsms' leak.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libhdf5_serial.so\n";
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  bsms_fuzz::maybe_write_seeds(seeds);
  (void)originals();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const Originals& o = originals();
  const bool graph = size > 0 && (data[0] & 1);
  std::string bytes = graph ? o.graph : o.dataset;
  if (size >= 3) {
    const uint16_t cut = static_cast<uint16_t>(data[1] | (data[2] << 8));
    if (cut != 0) bytes.resize(bytes.size() - 1 - cut % bytes.size());
  }
  for (size_t i = 3; i + 3 <= size && !bytes.empty(); i += 3) {
    const uint16_t offset = static_cast<uint16_t>(data[i] | (data[i + 1] << 8));
    bytes[offset % bytes.size()] ^= static_cast<char>(data[i + 2]);
  }
  const std::string path =
      bsms_fuzz::scratch_dir("dataset_bytes") + (graph ? "/graph.h5" : "/train.h5");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  // BSMS_FUZZ_KEEP=FILE keeps the damaged copy (to open a crash's file with `bsms info`).
  if (const char* keep = std::getenv("BSMS_FUZZ_KEEP"))
    fs::copy_file(path, keep, fs::copy_options::overwrite_existing);
  try {
    if (graph)
      walk_graph(path);
    else
      walk_dataset(path);
  } catch (const bsms::InputError& e) {
    bsms_fuzz::refused(e);
  }
  return 0;
}
