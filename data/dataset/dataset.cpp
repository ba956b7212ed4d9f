#include "data/dataset/dataset.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>

#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/tfrecord.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms {
namespace fs = std::filesystem;

std::optional<mpm::Scene> parse_dataset_scene(const std::string& text, int dim,
                                              const std::string& source) {
  const Json json = parse_json_text(text, source);
  if (json.is_object() && json.empty()) return std::nullopt;
  if (!json.is_object())
    throw InputError(source + " must be a JSON object, got " + describe_json(json));
  const bool family = json.contains("scene");
  mpm::Scene scene = family ? mpm::parse_base_scene(json["scene"], JsonContext{source, "scene"})
                            : mpm::parse_scene(json, source);
  // The walls and symmetries read from it index positions by axis.
  if (scene.dim != dim)
    throw InputError(JsonContext{source, family ? "scene.dim" : "dim"}.where() + ": " +
                     std::to_string(scene.dim) + " is not the dataset's dim " +
                     std::to_string(dim));
  return scene;
}

bool is_static_field(const std::string& name) {
  return name == "cells" || name == "mesh_pos" || name == "node_type" || name == "body_id";
}

double value_bound(const std::string& field) {
  return field == "mesh_pos" || field == "world_pos" || field == "velocity" ? kPositionBound
                                                                            : kFieldBound;
}

namespace {

std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

void check_field_values(const float* values, size_t count, int64_t nodes, int64_t width,
                        int64_t first_frame, const std::string& where, const std::string& field) {
  const float bound = static_cast<float>(value_bound(field));
  // One branch-free pass (vectorised): a NaN fails the comparison like an out-of-range value.
  size_t bad = 0;
  for (size_t i = 0; i < count; ++i) bad += !(std::fabs(values[i]) <= bound);
  if (bad == 0) return;
  size_t i = 0;
  while (std::fabs(values[i]) <= bound) ++i;
  const int64_t per_frame = std::max<int64_t>(nodes * width, 1);
  const int64_t flat = static_cast<int64_t>(i);
  const int64_t node = (flat % per_frame) / std::max<int64_t>(width, 1);
  std::string at = where + ", field '" + field + "'";
  if (first_frame >= 0) at += " frame " + std::to_string(first_frame + flat / per_frame);
  at += " node " + std::to_string(node);
  if (width > 1) at += " component " + std::to_string(flat % width);
  const bool position = value_bound(field) == kPositionBound;
  throw InputError(at + ": " + number_text(values[i]) + ", expected a finite value within ±" +
                   number_text(bound) + " (the bound on " +
                   (position ? "positions and velocities" : "fields other than positions") +
                   ", docs/hardening.md)");
}

const char* layout_name(DatasetLayout layout) {
  switch (layout) {
    case DatasetLayout::kBsms:
      return "bsms dataset";
    case DatasetLayout::kPublicFolder:
      return "public per-trajectory HDF5 folder";
    case DatasetLayout::kMeshGraphNets:
      return "MeshGraphNets TFRecord";
    case DatasetLayout::kPublicSingleFile:
      return "public single-file HDF5";
  }
  return "?";
}

struct Dataset::Impl {
  std::string location;
  DatasetLayout layout = DatasetLayout::kBsms;
  bool public_layout = false;  // layout != kBsms
  int dim = 0;
  double frame_dt = 0.0;
  double collision_radius = 0.0;
  std::string simulator;
  std::string scene = "{}";
  std::optional<mpm::Scene> parsed_scene;  // scene, typed; none for "{}"
  // bsms layout: one file, one group per trajectory; public folder: one file per trajectory;
  // public single file: one group per trajectory; MeshGraphNets: one record per trajectory.
  std::unique_ptr<H5File> file;
  std::vector<std::string> groups;        // bsms: "/trajectories/000000"; single file: "/0"
  std::vector<std::string> public_files;  // public folder: paths
  std::unique_ptr<tfrecord::TfRecordReader> records;
  std::vector<FieldInfo> fields;
  mutable std::mutex mutex;
  mutable std::map<int64_t, TrajectoryMesh> meshes;
  mutable std::map<int64_t, std::unique_ptr<H5File>> open_files;
  // Trajectories whose every dynamic value was checked (Dataset::read, first access).
  mutable std::set<int64_t> checked;

  const H5File& file_of(int64_t t) const {
    if (layout != DatasetLayout::kPublicFolder) return *file;
    auto it = open_files.find(t);
    if (it == open_files.end())
      it = open_files.emplace(t, std::make_unique<H5File>(public_files[t], H5File::Mode::kRead))
               .first;
    return *it->second;
  }
  std::string prefix(int64_t t) const {
    return layout == DatasetLayout::kPublicFolder ? "/" : groups[t] + "/";
  }
  void open_tfrecord(const std::string& path);
  void open_public_single_file();
};

namespace {

// Reads a static field that may carry a leading time axis ([1 or T, ...]); returns the first frame.
template <class T>
std::vector<T> read_static(const H5File& f, const std::string& name, size_t base_rank,
                           Shape* shape) {
  Shape dims = f.shape(name);
  if (dims.size() == base_rank + 1) {
    Shape offset(dims.size(), 0), count = dims;
    count[0] = 1;
    dims.erase(dims.begin());
    *shape = dims;
    return f.read_slab<T>(name, offset, count);
  }
  *shape = dims;
  return f.read<T>(name);
}

// Shape of a dynamic field of one trajectory: [T, N] or [T, N, width]. Only the first
// trajectory's fields are listed when the dataset is opened; the others are checked here.
Shape field_shape(const H5File& f, const std::string& name) {
  Shape dims = f.shape(name);
  if (dims.size() < 2)
    throw InputError(f.path() + ": " + name + " has rank " + std::to_string(dims.size()) +
                     ", expected a [T, N, ...] field");
  return dims;
}

// Width (dim) of mesh_pos, [N, dim] or [T, N, dim].
int mesh_pos_width(const H5File& f, const std::string& name) {
  const Shape dims = f.shape(name);
  if (dims.size() < 2)
    throw InputError(f.path() + ": " + name + " has rank " + std::to_string(dims.size()) +
                     ", expected [N, dim] or [T, N, dim]");
  return static_cast<int>(dims.back());
}

std::vector<FieldInfo> dynamic_fields(const H5File& f, const std::string& prefix) {
  std::vector<FieldInfo> out;
  for (const auto& name : f.list(prefix == "/" ? "/" : prefix.substr(0, prefix.size() - 1))) {
    if (is_static_field(name)) continue;
    const Shape dims = f.shape(prefix + name);
    if (dims.size() < 2) continue;
    out.push_back({name, dims.size() == 3 ? static_cast<int64_t>(dims[2]) : 1});
  }
  return out;
}

}  // namespace

namespace {

bool is_index_name(const std::string& s) {
  return !s.empty() && s.size() < 19 &&
         std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string legacy_message(const std::string& folder, const std::string& split) {
  return folder +
         ": BSMS-GNN's older converted layout (outputs_{split}/ with normalization_info in "
         "meta.json) is not read; run bsms on the DeepMind meta.json + " +
         split + ".tfrecord folder the converter started from, or BSMS-GNN's converter to " +
         split + "/{i}.h5";
}

}  // namespace

void Dataset::Impl::open_tfrecord(const std::string& path) {
  layout = DatasetLayout::kMeshGraphNets;
  public_layout = true;
  const std::string meta_path = (fs::path(path).parent_path() / "meta.json").string();
  tfrecord::Meta meta = tfrecord::read_meta(meta_path);
  for (const auto& f : meta.fields)
    if (f.kind == tfrecord::FieldKind::kDynamicVarlen)
      throw InputError(meta_path + ": field '" + f.name +
                       "' is dynamic_varlen: remeshing datasets (flag_dynamic, sphere_dynamic) "
                       "are not supported by fixed-topology models");
  for (const char* name : {"mesh_pos", "cells", "node_type"}) {
    const tfrecord::FieldSpec* f = meta.find(name);
    if (!f) throw InputError(meta_path + ": no field '" + name + "' (every trajectory needs it)");
    if (f->kind != tfrecord::FieldKind::kStatic)
      throw InputError(meta_path + ": field '" + name + "' must be static");
  }
  dim = static_cast<int>(meta.find("mesh_pos")->width());
  for (const auto& f : meta.fields) {
    if (f.kind != tfrecord::FieldKind::kDynamic || is_static_field(f.name)) continue;
    fields.push_back({f.name, f.width()});
    if (f.name == "world_pos") dim = static_cast<int>(f.width());
  }
  frame_dt = meta.dt;
  collision_radius = meta.collision_radius;
  simulator = meta.simulator;
  records = std::make_unique<tfrecord::TfRecordReader>(path, std::move(meta));
  if (records->num_records() == 0) throw InputError(path + ": holds no records (trajectories)");
}

void Dataset::Impl::open_public_single_file() {
  layout = DatasetLayout::kPublicSingleFile;
  public_layout = true;
  std::vector<std::string> names;
  for (const auto& name : file->list("/"))
    if (file->exists("/" + name + "/mesh_pos")) names.push_back(name);
  const bool numeric = std::all_of(names.begin(), names.end(), is_index_name);
  std::sort(names.begin(), names.end(), [&](const std::string& x, const std::string& y) {
    return numeric ? std::stoll(x) < std::stoll(y) : x < y;
  });
  for (const auto& name : names) groups.push_back("/" + name);
  const std::string first = groups[0];
  if (!file->exists(first + "/cells") || !file->exists(first + "/node_type"))
    throw InputError(location + ": group " + first +
                     " needs datasets mesh_pos, cells and node_type");
  fields = dynamic_fields(*file, first + "/");
  dim = mesh_pos_width(*file, first + "/mesh_pos");
  for (const auto& field : fields)
    if (field.name == "world_pos") dim = static_cast<int>(field.width);
}

Dataset::Dataset(const std::string& location) : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.location = location;
  std::error_code ec;
  if (fs::is_directory(location, ec)) {
    d.layout = DatasetLayout::kPublicFolder;
    d.public_layout = true;
    std::vector<std::pair<long long, std::string>> files;
    bool tfrecords = false;
    for (const auto& entry : fs::directory_iterator(location)) {
      if (entry.path().extension() == ".tfrecord") tfrecords = true;
      if (entry.path().extension() != ".h5") continue;
      const std::string stem = entry.path().stem().string();
      char* end = nullptr;
      const long long index = std::strtoll(stem.c_str(), &end, 10);
      if (stem.empty() || *end != '\0')
        throw InputError(entry.path().string() + ": public-layout files must be named {i}.h5");
      files.emplace_back(index, entry.path().string());
    }
    std::sort(files.begin(), files.end());
    if (files.empty() && tfrecords && fs::exists(fs::path(location) / "meta.json", ec))
      throw InputError(location + ": a MeshGraphNets folder; open one split, e.g. " +
                       (fs::path(location) / "train.tfrecord").string());
    fs::path normal = fs::path(location).lexically_normal();
    if (normal.filename().empty()) normal = normal.parent_path();  // "DIR/outputs_train/"
    const std::string base = normal.filename().string();
    if (files.empty() && base.rfind("outputs_", 0) == 0)
      throw InputError(legacy_message(location, base.substr(8)));
    if (files.empty()) throw InputError(location + ": folder holds no {i}.h5 trajectory files");
    for (auto& [index, path] : files) d.public_files.push_back(path);
    const H5File& first = d.file_of(0);
    if (!first.exists("/mesh_pos") || !first.exists("/cells") || !first.exists("/node_type"))
      throw InputError(d.public_files[0] + ": expected datasets mesh_pos, cells and node_type");
    d.fields = dynamic_fields(first, "/");
    d.dim = mesh_pos_width(first, "/mesh_pos");
    for (const auto& field : d.fields)
      if (field.name == "world_pos") d.dim = static_cast<int>(field.width);
  } else if (fs::path(location).extension() == ".tfrecord") {
    d.open_tfrecord(location);
  } else {
    d.file = std::make_unique<H5File>(location, H5File::Mode::kRead);
    const bool has_format = d.file->has_attr("/", "format");
    bool single_file = false;
    if (!has_format)
      for (const auto& name : d.file->list("/"))
        if (d.file->exists("/" + name + "/mesh_pos")) single_file = true;
    if (single_file) {
      d.open_public_single_file();
    } else {
      if (!has_format || d.file->attr_string("/", "format") != kDatasetFormat)
        throw InputError(location + ": not a bsms dataset (root attribute format must be \"" +
                         kDatasetFormat +
                         "\", or the root must hold one group per trajectory with " + "mesh_pos)");
      const int64_t version = d.file->attr_int("/", "version");
      if (version != kDatasetVersion)
        throw InputError(location + ": dataset version " + std::to_string(version) +
                         " is not supported (expected 1)");
      d.dim = static_cast<int>(d.file->attr_int("/", "dim"));
      d.frame_dt = d.file->attr_double("/", "frame_dt");
      d.scene = d.file->attr_string("/", "scene");
      d.parsed_scene = parse_dataset_scene(d.scene, d.dim, location + ": attribute 'scene'");
      for (const auto& name : d.file->list("/trajectories"))
        d.groups.push_back("/trajectories/" + name);
      if (d.groups.empty()) throw InputError(location + ": dataset holds no trajectories");
      d.fields = dynamic_fields(*d.file, d.groups[0] + "/");
    }
  }
  if (d.fields.empty()) throw InputError(location + ": no dynamic fields ([T, N, ...] datasets)");
  // No output of this process may replace the data it reads (hdf5_file.hpp, AtomicOutput).
  if (d.records) {
    register_input(location);
    register_input((fs::path(location).parent_path() / "meta.json").string());
  } else if (d.file) {
    register_input(location);
  }
  for (const auto& path : d.public_files) register_input(path);
}

Dataset Dataset::open_split(const std::string& dir, const std::string& split) {
  const fs::path file = fs::path(dir) / (split + ".h5");
  if (fs::exists(file)) return Dataset(file.string());
  const fs::path folder = fs::path(dir) / split;
  if (fs::is_directory(folder)) return Dataset(folder.string());
  const fs::path record = fs::path(dir) / (split + ".tfrecord");
  if (fs::exists(record) && fs::exists(fs::path(dir) / "meta.json"))
    return Dataset(record.string());
  const fs::path legacy = fs::path(dir) / ("outputs_" + split);
  if (fs::is_directory(legacy)) throw InputError(legacy_message(legacy.string() + "/", split));
  throw InputError(dir + ": no split '" + split + "' (expected " + file.string() + ", " +
                   folder.string() + "/ or meta.json + " + record.string() + ")");
}

bool Dataset::has_split(const std::string& dir, const std::string& split) {
  const fs::path d(dir);
  return fs::exists(d / (split + ".h5")) || fs::is_directory(d / split) ||
         (fs::exists(d / (split + ".tfrecord")) && fs::exists(d / "meta.json")) ||
         fs::is_directory(d / ("outputs_" + split));
}

Dataset::~Dataset() = default;
Dataset::Dataset(Dataset&&) noexcept = default;
Dataset& Dataset::operator=(Dataset&&) noexcept = default;

const std::string& Dataset::location() const {
  return impl_->location;
}
DatasetLayout Dataset::layout() const {
  return impl_->layout;
}
bool Dataset::is_public_layout() const {
  return impl_->public_layout;
}
// Public data keeps its own codes, also in bsms files converted from it or rolled out on it
// (their scene is "{}").
bool Dataset::has_simulated_node_types() const {
  return !impl_->public_layout && impl_->scene != "{}";
}
double Dataset::collision_radius() const {
  return impl_->collision_radius;
}
std::string Dataset::simulator() const {
  return impl_->simulator;
}
int Dataset::dim() const {
  return impl_->dim;
}
double Dataset::frame_dt() const {
  return impl_->frame_dt;
}
const std::string& Dataset::scene() const {
  return impl_->scene;
}
const std::optional<mpm::Scene>& Dataset::parsed_scene() const {
  return impl_->parsed_scene;
}
int64_t Dataset::num_trajectories() const {
  switch (impl_->layout) {
    case DatasetLayout::kPublicFolder:
      return static_cast<int64_t>(impl_->public_files.size());
    case DatasetLayout::kMeshGraphNets:
      return impl_->records->num_records();
    default:
      return static_cast<int64_t>(impl_->groups.size());
  }
}
std::vector<FieldInfo> Dataset::fields() const {
  return impl_->fields;
}
bool Dataset::has_field(const std::string& name) const {
  for (const auto& f : impl_->fields)
    if (f.name == name) return true;
  return false;
}

namespace {
void check_index(const Dataset& d, int64_t t) {
  if (t < 0 || t >= d.num_trajectories())
    throw InputError(d.location() + ": trajectory " + std::to_string(t) + " out of range 0.." +
                     std::to_string(d.num_trajectories() - 1));
}
}  // namespace

int64_t Dataset::num_frames(int64_t t) const {
  check_index(*this, t);
  if (impl_->records) return impl_->records->meta().trajectory_length;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const H5File& f = impl_->file_of(t);
  return static_cast<int64_t>(field_shape(f, impl_->prefix(t) + impl_->fields[0].name)[0]);
}

// Where a dataset's mesh is read (Dataset::mesh), naming the file and the trajectory, so that later
// stages (graphs, one-hot inputs, the solver's mesh checks) may trust it.
void check_trajectory_mesh(const TrajectoryMesh& m, const std::string& where,
                           bool bsms_node_types) {
  if (m.dim < 1 || m.dim > 3)
    throw InputError(where + ": mesh_pos has " + std::to_string(m.dim) +
                     " components per node, expected 1 to 3");
  const int64_t n = m.num_nodes();
  if (n == 0 || static_cast<int64_t>(m.mesh_pos.size()) != n * m.dim)
    throw InputError(where + ": mesh_pos has " + std::to_string(m.mesh_pos.size()) +
                     " values for " + std::to_string(n) + " nodes of dimension " +
                     std::to_string(m.dim));
  if (m.cell_size < 2 || m.cell_size > m.dim + 1 || m.cells.empty() ||
      m.cells.size() % static_cast<size_t>(m.cell_size) != 0)
    throw InputError(where + ": cells must be [C, k] with C >= 1 and k in 2.." +
                     std::to_string(m.dim + 1) + " (lines to simplices of the mesh dimension " +
                     std::to_string(m.dim) + "), got k = " + std::to_string(m.cell_size));
  check_field_values(m.mesh_pos.data(), m.mesh_pos.size(), n, m.dim, -1, where, "mesh_pos");
  const int k = m.cell_size;
  for (int64_t c = 0; c < m.num_cells(); ++c) {
    const int32_t* cell = &m.cells[static_cast<size_t>(c * k)];
    for (int a = 0; a < k; ++a) {
      if (cell[a] < 0 || cell[a] >= n)
        throw InputError(where + ": cells: cell " + std::to_string(c) + " references node " +
                         std::to_string(cell[a]) + " outside 0.." + std::to_string(n - 1));
      for (int b = 0; b < a; ++b)
        if (cell[b] == cell[a])
          throw InputError(where + ": cells: cell " + std::to_string(c) + " repeats node " +
                           std::to_string(cell[a]) + " (degenerate cell)");
    }
  }
  // Simulated data (bsms generate: a scene) has NodeType 0..3; public data keeps its own codes
  // (MeshGraphNets: 0..8), also in bsms files converted from it or rolled out on it (scene "{}"),
  // one-hot encoded with at most 64 classes.
  const int32_t max_type =
      bsms_node_types ? static_cast<int32_t>(NodeType::kSlip) : kMaxPublicNodeType;
  for (int64_t i = 0; i < n; ++i)
    if (m.node_type[i] < 0 || m.node_type[i] > max_type)
      throw InputError(where + ": node_type of node " + std::to_string(i) + " is " +
                       std::to_string(m.node_type[i]) + ", expected 0.." +
                       std::to_string(max_type));
  if (static_cast<int64_t>(m.body_id.size()) != n)
    throw InputError(where + ": body_id has " + std::to_string(m.body_id.size()) + " entries for " +
                     std::to_string(n) + " nodes");
  for (int64_t i = 0; i < n; ++i)
    if (m.body_id[i] < 0)
      throw InputError(where + ": body_id of node " + std::to_string(i) + " is " +
                       std::to_string(m.body_id[i]) + ", expected >= 0");
}

std::string Dataset::describe(int64_t t) const {
  const std::string file =
      impl_->layout == DatasetLayout::kPublicFolder ? impl_->public_files[t] : impl_->location;
  return file + ": trajectory " + std::to_string(t);
}

const TrajectoryMesh& Dataset::mesh(int64_t t) const {
  check_index(*this, t);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto it = impl_->meshes.find(t);
  if (it != impl_->meshes.end()) return it->second;
  TrajectoryMesh m;
  if (impl_->records) {
    tfrecord::MeshArrays a = impl_->records->read_mesh(t);
    m.dim = a.dim;
    m.cell_size = a.cell_size;
    m.mesh_pos = std::move(a.mesh_pos);
    m.cells = std::move(a.cells);
    m.node_type = std::move(a.node_type);
    m.body_id.assign(m.node_type.size(), 0);
  } else {
    const H5File& f = impl_->file_of(t);
    const std::string p = impl_->prefix(t);
    Shape pos_shape, cell_shape, type_shape;
    m.mesh_pos = read_static<float>(f, p + "mesh_pos", 2, &pos_shape);
    m.cells = read_static<int32_t>(f, p + "cells", 2, &cell_shape);
    Shape raw_type = f.shape(p + "node_type");
    // node_type: [N], [N, 1], [1, N, 1] or [T, N, 1].
    const size_t base = (raw_type.size() >= 2 && raw_type.back() == 1) ? 2 : 1;
    m.node_type = read_static<int32_t>(f, p + "node_type", base, &type_shape);
    if (pos_shape.size() != 2 || cell_shape.size() != 2)
      throw InputError(describe(t) + ": mesh_pos must be [N, dim] and cells [C, k]");
    if (pos_shape[1] > 3 || cell_shape[1] > 8)
      throw InputError(describe(t) + ": mesh_pos [N, " + std::to_string(pos_shape[1]) +
                       "] or cells [C, " + std::to_string(cell_shape[1]) +
                       "] is too wide (dim 1..3, cells of 2..4 nodes)");
    m.dim = static_cast<int>(pos_shape[1]);
    m.cell_size = static_cast<int>(cell_shape[1]);
    const int64_t n = static_cast<int64_t>(pos_shape[0]);
    if (m.num_nodes() != n)
      throw InputError(describe(t) + ": node_type has " + std::to_string(m.num_nodes()) +
                       " entries, mesh_pos " + std::to_string(n) + " nodes");
    if (f.exists(p + "body_id")) {
      Shape body_shape;
      m.body_id = read_static<int32_t>(f, p + "body_id", 1, &body_shape);
    } else {
      m.body_id.assign(n, 0);
    }
  }
  check_trajectory_mesh(m, describe(t), has_simulated_node_types());
  return impl_->meshes.emplace(t, std::move(m)).first->second;
}

int64_t Dataset::seed(int64_t t) const {
  check_index(*this, t);
  if (impl_->public_layout) return 0;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->file->attr_int(impl_->groups[t], "seed");
}

std::string Dataset::parameters(int64_t t) const {
  check_index(*this, t);
  if (impl_->public_layout) return "{}";
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->file->attr_string(impl_->groups[t], "parameters");
}

double Dataset::solver_wall_s(int64_t t) const {
  check_index(*this, t);
  if (impl_->public_layout) return -1.0;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (!impl_->file->has_attr(impl_->groups[t], "solver_wall_s")) return -1.0;
  return impl_->file->attr_double(impl_->groups[t], "solver_wall_s");
}

std::vector<float> Dataset::read_unchecked(int64_t t, const std::string& field, int64_t t0,
                                           int64_t count, int64_t nodes) const {
  int64_t width = 1;
  for (const auto& f : impl_->fields)
    if (f.name == field) width = f.width;
  std::vector<float> out;
  if (impl_->records) {
    out = impl_->records->read_float(t, field, t0, count);
  } else {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    const H5File& f = impl_->file_of(t);
    const std::string name = impl_->prefix(t) + field;
    const Shape dims = field_shape(f, name);
    if (t0 < 0 || count < 0 || static_cast<hsize_t>(t0) > dims[0] ||
        static_cast<hsize_t>(count) > dims[0] - static_cast<hsize_t>(t0))
      throw InputError(f.path() + ": frames " + std::to_string(t0) + ".." +
                       std::to_string(t0 + count - 1) + " of '" + field +
                       "' out of range (T=" + std::to_string(dims[0]) + ")");
    const int64_t have_width = dims.size() == 3 ? static_cast<int64_t>(dims[2]) : 1;
    if (dims.size() > 3 || static_cast<int64_t>(dims[1]) != nodes || have_width != width)
      throw InputError(describe(t) + ": field '" + field + "' has shape [" +
                       std::to_string(dims[0]) + ", " + std::to_string(dims[1]) +
                       (dims.size() >= 3 ? ", " + std::to_string(dims[2]) : std::string()) +
                       (dims.size() > 3 ? ", ..." : "") + "], expected [T, " +
                       std::to_string(nodes) + (width > 1 ? ", " + std::to_string(width) : "") +
                       "] (the mesh has " + std::to_string(nodes) + " nodes)");
    Shape offset(dims.size(), 0), extent = dims;
    offset[0] = static_cast<hsize_t>(t0);
    extent[0] = static_cast<hsize_t>(count);
    out = f.read_slab<float>(name, offset, extent);
  }
  if (static_cast<int64_t>(out.size()) != count * nodes * width)
    throw InputError(describe(t) + ": field '" + field + "' holds " + std::to_string(out.size()) +
                     " values for " + std::to_string(count) + " frame(s) of " +
                     std::to_string(nodes) + " nodes x " + std::to_string(width));
  return out;
}

void Dataset::check_trajectory(int64_t t) const {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->checked.count(t)) return;
  }
  const int64_t nodes = mesh(t).num_nodes();
  // Every dynamic field once, in blocks of frames (bounded memory): a value a model never reads
  // (bsms data's stored velocity, say) is still damage in the file, and reported as such.
  for (const auto& f : impl_->fields) {
    int64_t frames = 0;
    if (impl_->records) {
      frames = impl_->records->meta().trajectory_length;
    } else {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      const H5File& file = impl_->file_of(t);
      frames = static_cast<int64_t>(field_shape(file, impl_->prefix(t) + f.name)[0]);
    }
    const int64_t block =
        std::max<int64_t>(1, (int64_t{1} << 22) / std::max<int64_t>(nodes * f.width, 1));
    for (int64_t t0 = 0; t0 < frames; t0 += block) {
      const int64_t count = std::min(block, frames - t0);
      const std::vector<float> values = read_unchecked(t, f.name, t0, count, nodes);
      check_field_values(values.data(), values.size(), nodes, f.width, t0, describe(t), f.name);
    }
  }
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->checked.insert(t);
}

std::vector<float> Dataset::read(int64_t t, const std::string& field, int64_t t0,
                                 int64_t count) const {
  check_index(*this, t);
  if (!has_field(field)) throw InputError(impl_->location + ": no field '" + field + "'");
  check_trajectory(t);
  return read_unchecked(t, field, t0, count, mesh(t).num_nodes());
}

}  // namespace bsms
