#include "data/dataset/dataset.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <set>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

constexpr const char* kFormat = "bsms-dataset";
constexpr int64_t kVersion = 1;
const std::set<std::string> kStaticFields = {"cells", "mesh_pos", "node_type", "body_id"};

std::string trajectory_name(int64_t index) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%06lld", static_cast<long long>(index));
  return buf;
}

void check_finite(const std::vector<float>& values, const std::string& what) {
  for (size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      throw InputError(what + ": non-finite value at flat index " + std::to_string(i) +
                       " (NaN is never stored)");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
struct DatasetWriter::Impl {
  AtomicOutput output;
  H5File file;
  int dim;
  int64_t count = 0;
  Impl(const std::string& path, int d)
      : output(path), file(output.temp_path(), H5File::Mode::kTruncate), dim(d) {}
};

DatasetWriter::DatasetWriter(const std::string& path, const std::string& scene_json, int dim,
                             double frame_dt) {
  if (dim < 1 || dim > 3) throw InputError(path + ": dataset dimension must be 1, 2 or 3");
  impl_ = std::make_unique<Impl>(path, dim);
  auto& f = impl_->file;
  f.set_attr("/", "format", std::string(kFormat));
  f.set_attr("/", "version", kVersion);
  f.set_attr("/", "scene", scene_json);
  f.set_attr("/", "dim", int64_t{dim});
  f.set_attr("/", "frame_dt", frame_dt);
  f.create_group("/trajectories");
}

DatasetWriter::~DatasetWriter() = default;

void DatasetWriter::add(const Trajectory& t) {
  const std::string group = "/trajectories/" + trajectory_name(impl_->count);
  const std::string what =
      impl_->output.final_path() + ": trajectory " + trajectory_name(impl_->count);
  const int dim = impl_->dim;
  const auto& m = t.mesh;
  const int64_t n = m.num_nodes();
  const int cell_size = m.cell_size > 0 ? m.cell_size : dim + 1;
  if (m.dim != dim) throw InputError(what + ": mesh dimension differs from the dataset's");
  if (n == 0 || static_cast<int64_t>(m.mesh_pos.size()) != n * dim ||
      (!m.body_id.empty() && static_cast<int64_t>(m.body_id.size()) != n) || m.cells.empty() ||
      m.cells.size() % cell_size != 0)
    throw InputError(what + ": inconsistent mesh arrays");
  if (t.num_frames <= 0) throw InputError(what + ": no frames");
  check_finite(m.mesh_pos, what + " mesh_pos");
  for (int32_t c : m.cells)
    if (c < 0 || c >= n)
      throw InputError(what + ": cell index " + std::to_string(c) + " out of range");

  auto& f = impl_->file;
  f.create_group(group);
  f.set_attr(group, "seed", t.seed);
  f.set_attr(group, "parameters", t.parameters);
  if (t.solver_wall_s >= 0) f.set_attr(group, "solver_wall_s", t.solver_wall_s);
  f.write(group + "/cells", m.cells,
          {static_cast<hsize_t>(m.num_cells()), static_cast<hsize_t>(cell_size)});
  f.write(group + "/mesh_pos", m.mesh_pos, {static_cast<hsize_t>(n), static_cast<hsize_t>(dim)});
  f.write(group + "/node_type", m.node_type, {static_cast<hsize_t>(n)});
  std::vector<int32_t> body = m.body_id.empty() ? std::vector<int32_t>(n, 0) : m.body_id;
  f.write(group + "/body_id", body, {static_cast<hsize_t>(n)});
  for (const auto& [name, values] : t.fields) {
    if (kStaticFields.count(name))
      throw InputError(what + ": field name '" + name + "' is reserved");
    const int64_t per_frame = n * t.num_frames;
    if (values.empty() || values.size() % per_frame != 0)
      throw InputError(what + ": field '" + name + "' is not [T, N, width]");
    const int64_t width = static_cast<int64_t>(values.size()) / per_frame;
    check_finite(values, what + " field '" + name + "'");
    Shape shape = {static_cast<hsize_t>(t.num_frames), static_cast<hsize_t>(n)};
    if (width > 1 || name == "world_pos" || name == "velocity") shape.push_back(width);
    f.write(group + "/" + name, values, shape, /*chunk_rows=*/1);
  }
  ++impl_->count;
}

void DatasetWriter::commit() {
  impl_->file.set_attr("/", "num_trajectories", impl_->count);
  impl_->file.close();
  impl_->output.commit();
}

// ---------------------------------------------------------------------------------------------
struct Dataset::Impl {
  std::string location;
  bool public_layout = false;
  int dim = 0;
  double frame_dt = 0.0;
  std::string scene = "{}";
  // bsms layout: one file, one group per trajectory; public layout: one file per trajectory.
  std::unique_ptr<H5File> file;
  std::vector<std::string> groups;        // bsms: "/trajectories/000000"
  std::vector<std::string> public_files;  // public: paths
  std::vector<FieldInfo> fields;
  mutable std::mutex mutex;
  mutable std::map<int64_t, TrajectoryMesh> meshes;
  mutable std::map<int64_t, std::unique_ptr<H5File>> open_files;

  const H5File& file_of(int64_t t) const {
    if (!public_layout) return *file;
    auto it = open_files.find(t);
    if (it == open_files.end())
      it = open_files.emplace(t, std::make_unique<H5File>(public_files[t], H5File::Mode::kRead))
               .first;
    return *it->second;
  }
  std::string prefix(int64_t t) const { return public_layout ? "/" : groups[t] + "/"; }
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

std::vector<FieldInfo> dynamic_fields(const H5File& f, const std::string& prefix) {
  std::vector<FieldInfo> out;
  for (const auto& name : f.list(prefix == "/" ? "/" : prefix.substr(0, prefix.size() - 1))) {
    if (kStaticFields.count(name)) continue;
    const Shape dims = f.shape(prefix + name);
    if (dims.size() < 2) continue;
    out.push_back({name, dims.size() == 3 ? static_cast<int64_t>(dims[2]) : 1});
  }
  return out;
}

}  // namespace

Dataset::Dataset(const std::string& location) : impl_(std::make_unique<Impl>()) {
  auto& d = *impl_;
  d.location = location;
  std::error_code ec;
  if (fs::is_directory(location, ec)) {
    d.public_layout = true;
    std::vector<std::pair<long long, std::string>> files;
    for (const auto& entry : fs::directory_iterator(location)) {
      if (entry.path().extension() != ".h5") continue;
      const std::string stem = entry.path().stem().string();
      char* end = nullptr;
      const long long index = std::strtoll(stem.c_str(), &end, 10);
      if (stem.empty() || *end != '\0')
        throw InputError(entry.path().string() + ": public-layout files must be named {i}.h5");
      files.emplace_back(index, entry.path().string());
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) throw InputError(location + ": folder holds no {i}.h5 trajectory files");
    for (auto& [index, path] : files) d.public_files.push_back(path);
    const H5File& first = d.file_of(0);
    if (!first.exists("/mesh_pos") || !first.exists("/cells") || !first.exists("/node_type"))
      throw InputError(d.public_files[0] + ": expected datasets mesh_pos, cells and node_type");
    d.fields = dynamic_fields(first, "/");
    const Shape pos = first.shape("/mesh_pos");
    d.dim = static_cast<int>(pos.back());
    for (const auto& field : d.fields)
      if (field.name == "world_pos") d.dim = static_cast<int>(field.width);
  } else {
    d.file = std::make_unique<H5File>(location, H5File::Mode::kRead);
    if (!d.file->has_attr("/", "format") || d.file->attr_string("/", "format") != kFormat)
      throw InputError(location + ": not a bsms dataset (root attribute format must be \"" +
                       kFormat + "\")");
    const int64_t version = d.file->attr_int("/", "version");
    if (version != kVersion)
      throw InputError(location + ": dataset version " + std::to_string(version) +
                       " is not supported (expected 1)");
    d.dim = static_cast<int>(d.file->attr_int("/", "dim"));
    d.frame_dt = d.file->attr_double("/", "frame_dt");
    d.scene = d.file->attr_string("/", "scene");
    for (const auto& name : d.file->list("/trajectories"))
      d.groups.push_back("/trajectories/" + name);
    if (d.groups.empty()) throw InputError(location + ": dataset holds no trajectories");
    d.fields = dynamic_fields(*d.file, d.groups[0] + "/");
  }
  if (d.fields.empty()) throw InputError(location + ": no dynamic fields ([T, N, ...] datasets)");
}

Dataset Dataset::open_split(const std::string& dir, const std::string& split) {
  const fs::path file = fs::path(dir) / (split + ".h5");
  if (fs::exists(file)) return Dataset(file.string());
  const fs::path folder = fs::path(dir) / split;
  if (fs::is_directory(folder)) return Dataset(folder.string());
  throw InputError(dir + ": no split '" + split + "' (expected " + file.string() + " or " +
                   folder.string() + "/)");
}

bool Dataset::has_split(const std::string& dir, const std::string& split) {
  return fs::exists(fs::path(dir) / (split + ".h5")) || fs::is_directory(fs::path(dir) / split);
}

Dataset::~Dataset() = default;
Dataset::Dataset(Dataset&&) noexcept = default;
Dataset& Dataset::operator=(Dataset&&) noexcept = default;

const std::string& Dataset::location() const {
  return impl_->location;
}
bool Dataset::is_public_layout() const {
  return impl_->public_layout;
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
int64_t Dataset::num_trajectories() const {
  return static_cast<int64_t>(impl_->public_layout ? impl_->public_files.size()
                                                   : impl_->groups.size());
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
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const H5File& f = impl_->file_of(t);
  return static_cast<int64_t>(f.shape(impl_->prefix(t) + impl_->fields[0].name)[0]);
}

const TrajectoryMesh& Dataset::mesh(int64_t t) const {
  check_index(*this, t);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto it = impl_->meshes.find(t);
  if (it != impl_->meshes.end()) return it->second;
  const H5File& f = impl_->file_of(t);
  const std::string p = impl_->prefix(t);
  TrajectoryMesh m;
  Shape pos_shape, cell_shape, type_shape;
  m.mesh_pos = read_static<float>(f, p + "mesh_pos", 2, &pos_shape);
  m.cells = read_static<int32_t>(f, p + "cells", 2, &cell_shape);
  Shape raw_type = f.shape(p + "node_type");
  // node_type: [N], [N, 1], [1, N, 1] or [T, N, 1].
  const size_t base = (raw_type.size() >= 2 && raw_type.back() == 1) ? 2 : 1;
  m.node_type = read_static<int32_t>(f, p + "node_type", base, &type_shape);
  if (pos_shape.size() != 2 || cell_shape.size() != 2)
    throw InputError(f.path() + ": mesh_pos must be [N, dim] and cells [C, k]");
  m.dim = static_cast<int>(pos_shape[1]);
  m.cell_size = static_cast<int>(cell_shape[1]);
  const int64_t n = static_cast<int64_t>(pos_shape[0]);
  if (m.num_nodes() != n)
    throw InputError(f.path() + ": node_type has " + std::to_string(m.num_nodes()) +
                     " entries, mesh_pos " + std::to_string(n) + " nodes");
  if (f.exists(p + "body_id")) {
    Shape body_shape;
    m.body_id = read_static<int32_t>(f, p + "body_id", 1, &body_shape);
  } else {
    m.body_id.assign(n, 0);
  }
  for (int32_t c : m.cells)
    if (c < 0 || c >= n)
      throw InputError(f.path() + ": cell index " + std::to_string(c) + " out of range");
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

std::vector<float> Dataset::read(int64_t t, const std::string& field, int64_t t0,
                                 int64_t count) const {
  check_index(*this, t);
  if (!has_field(field)) throw InputError(impl_->location + ": no field '" + field + "'");
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const H5File& f = impl_->file_of(t);
  const std::string name = impl_->prefix(t) + field;
  const Shape dims = f.shape(name);
  if (t0 < 0 || count < 0 || static_cast<hsize_t>(t0 + count) > dims[0])
    throw InputError(f.path() + ": frames " + std::to_string(t0) + ".." +
                     std::to_string(t0 + count - 1) + " of '" + field +
                     "' out of range (T=" + std::to_string(dims[0]) + ")");
  Shape offset(dims.size(), 0), extent = dims;
  offset[0] = static_cast<hsize_t>(t0);
  extent[0] = static_cast<hsize_t>(count);
  return f.read_slab<float>(name, offset, extent);
}

}  // namespace bsms
