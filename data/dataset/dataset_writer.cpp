#include "data/dataset/dataset.hpp"

#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "core/hdf5_file.hpp"

namespace bsms {

namespace {

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

struct DatasetWriter::Impl {
  AtomicOutput output;
  H5File file;
  int dim;
  int64_t count = 0;
  bool finished = false;
  Impl(const std::string& path, int d)
      : output(path), file(output.temp_path(), H5File::Mode::kTruncate), dim(d) {}
};

DatasetWriter::DatasetWriter(const std::string& path, const std::string& scene_json, int dim,
                             double frame_dt) {
  if (dim < 1 || dim > 3) throw InputError(path + ": dataset dimension must be 1, 2 or 3");
  impl_ = std::make_unique<Impl>(path, dim);
  auto& f = impl_->file;
  f.set_attr("/", "format", std::string(kDatasetFormat));
  f.set_attr("/", "version", kDatasetVersion);
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
  // The mesh may have fewer dimensions than the world (cloth: 2-D mesh_pos, 3-D world_pos).
  if (m.dim < 1 || m.dim > dim)
    throw InputError(what + ": mesh dimension " + std::to_string(m.dim) + " is not in 1.." +
                     std::to_string(dim) + " (the dataset's dimension)");
  if (n == 0 || static_cast<int64_t>(m.mesh_pos.size()) != n * m.dim ||
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
  f.write(group + "/mesh_pos", m.mesh_pos, {static_cast<hsize_t>(n), static_cast<hsize_t>(m.dim)});
  f.write(group + "/node_type", m.node_type, {static_cast<hsize_t>(n)});
  std::vector<int32_t> body = m.body_id.empty() ? std::vector<int32_t>(n, 0) : m.body_id;
  f.write(group + "/body_id", body, {static_cast<hsize_t>(n)});
  for (const auto& [name, values] : t.fields) {
    if (is_static_field(name)) throw InputError(what + ": field name '" + name + "' is reserved");
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

void DatasetWriter::finish() {
  if (impl_->finished) return;
  impl_->file.set_attr("/", "num_trajectories", impl_->count);
  impl_->file.close();
  impl_->output.sync();
  impl_->finished = true;
}

void DatasetWriter::commit() {
  finish();
  impl_->output.commit();
}

}  // namespace bsms
