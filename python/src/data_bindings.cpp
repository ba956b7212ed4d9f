// bsms.Dataset's C++ side: random access to any dataset layout bsms reads, as NumPy arrays.
#include <string>

#include "common.hpp"
#include "data/dataset/dataset.hpp"

namespace bsms::python {
namespace {

void check_trajectory(const Dataset& d, int64_t t) {
  if (t < 0 || t >= d.num_trajectories())
    throw py::index_error("trajectory " + std::to_string(t) + " out of range: " + d.location() +
                          " holds " + std::to_string(d.num_trajectories()));
}

}  // namespace

void bind_data(py::module_& m) {
  py::class_<Dataset>(m, "_Dataset")
      .def(py::init([](const std::string& location) {
             return run_unlocked([&] { return std::make_unique<Dataset>(location); });
           }),
           py::arg("location"))
      .def_static(
          "open_split",
          [](const std::string& dir, const std::string& split) {
            return run_unlocked(
                [&] { return std::make_unique<Dataset>(Dataset::open_split(dir, split)); });
          },
          py::arg("dir"), py::arg("split"))
      .def_static("has_split", &Dataset::has_split, py::arg("dir"), py::arg("split"))
      .def_property_readonly("location", &Dataset::location)
      .def_property_readonly("layout", [](const Dataset& d) { return layout_name(d.layout()); })
      .def_property_readonly("dim", &Dataset::dim)
      .def_property_readonly("frame_dt", &Dataset::frame_dt)
      .def_property_readonly("collision_radius", &Dataset::collision_radius)
      .def_property_readonly("simulator", &Dataset::simulator)
      .def_property_readonly("scene", &Dataset::scene)
      .def_property_readonly("num_trajectories", &Dataset::num_trajectories)
      .def_property_readonly("fields",
                             [](const Dataset& d) {
                               py::dict out;
                               for (const FieldInfo& f : d.fields()) out[py::str(f.name)] = f.width;
                               return out;
                             })
      .def("num_frames",
           [](const Dataset& d, int64_t t) {
             check_trajectory(d, t);
             return run_unlocked([&] { return d.num_frames(t); });
           })
      .def("seed",
           [](const Dataset& d, int64_t t) {
             check_trajectory(d, t);
             return run_unlocked([&] { return d.seed(t); });
           })
      .def("parameters",
           [](const Dataset& d, int64_t t) {
             check_trajectory(d, t);
             return run_unlocked([&] { return d.parameters(t); });
           })
      .def("solver_wall_s",
           [](const Dataset& d, int64_t t) {
             check_trajectory(d, t);
             return run_unlocked([&] { return d.solver_wall_s(t); });
           })
      // Views of the mesh the dataset caches (no copy; read-only, alive with the dataset).
      .def("mesh",
           [](const py::object& self, int64_t t) {
             const Dataset& d = self.cast<const Dataset&>();
             check_trajectory(d, t);
             const TrajectoryMesh& mesh =
                 run_unlocked([&]() -> const TrajectoryMesh& { return d.mesh(t); });
             const py::ssize_t n = mesh.num_nodes();
             py::dict out;
             out["cells"] = view_numpy(mesh.cells.data(), {mesh.num_cells(), mesh.cell_size}, self);
             out["mesh_pos"] = view_numpy(mesh.mesh_pos.data(), {n, mesh.dim}, self);
             out["node_type"] = view_numpy(mesh.node_type.data(), {n}, self);
             out["body_id"] = view_numpy(mesh.body_id.data(), {n}, self);
             return out;
           })
      .def(
          "read",
          [](const Dataset& d, int64_t t, const std::string& field, int64_t start, int64_t count) {
            check_trajectory(d, t);
            int64_t width = 0;
            for (const FieldInfo& f : d.fields())
              if (f.name == field) width = f.width;
            if (width == 0)
              throw InputError(d.location() + ": no field " + truncate(py::str(field)) +
                               " (it has " + std::to_string(d.fields().size()) + " fields)");
            int64_t frames = 0, nodes = 0;
            std::vector<float> values = run_unlocked([&] {
              frames = d.num_frames(t);
              nodes = d.mesh(t).num_nodes();
              if (start < 0 || start >= frames || count < 0 || start + count > frames)
                throw InputError(d.describe(t) + ": frames " + std::to_string(start) + ".." +
                                 std::to_string(start + count - 1) + " out of range 0.." +
                                 std::to_string(frames - 1));
              return d.read(t, field, start, count);
            });
            return to_numpy(std::move(values), {count, nodes, width});
          },
          py::arg("trajectory"), py::arg("field"), py::arg("start"), py::arg("count"));
}

}  // namespace bsms::python
