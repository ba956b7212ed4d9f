// bsms._torch: trained runs (bsms.Run). Loaded only when a run is opened, since LibTorch takes
// a good part of a second to load.
#include <torch/torch.h>

#include <filesystem>
#include <limits>
#include <string>

#include "common.hpp"
#include "core/physical_projection.hpp"
#include "core/runtime.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/rollout/rollout_model.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms::python {
namespace {

// ThreadScope for LibTorch: its intra-op count and OpenBLAS's (configure_threads makes OpenBLAS
// single-threaded) restored after the call, so the caller's own torch keeps its settings.
class TorchThreadScope {
 public:
  explicit TorchThreadScope(int threads)
      : torch_before_(torch::get_num_threads()), blas_before_(blas_threads()), omp_(threads) {
    configure_threads(omp_.threads());
  }
  ~TorchThreadScope() {
    torch::set_num_threads(torch_before_);
    set_blas_threads(blas_before_);
  }
  TorchThreadScope(const TorchThreadScope&) = delete;
  TorchThreadScope& operator=(const TorchThreadScope&) = delete;

 private:
  int torch_before_, blas_before_;
  ThreadScope omp_;
};

// A Lagrangian run opened on a dataset (its training data unless told otherwise).
struct PyRun {
  RunFolder folder;
  std::string data_dir;
  std::unique_ptr<Dataset> data;
  RolloutModel model;
};

torch::Tensor positions_tensor(const py::handle& value, const std::string& what, int64_t n,
                               int dim) {
  const py::array a = checked_array(value, what, 'f', 2, 2);
  if (a.shape(0) != n || a.shape(1) != dim)
    throw InputError(what + ": expected shape (" + std::to_string(n) + ", " + std::to_string(dim) +
                     "), got " + shape_text(a));
  const auto f = as_contiguous<float>(a);
  auto t = torch::from_blob(const_cast<float*>(f.data()), {n, dim}, torch::kFloat32).clone();
  if (!torch::isfinite(t).all().item<bool>()) throw InputError(what + ": NaN or infinite value");
  return t;
}

template <class T>
std::vector<T> int_vector(const py::handle& value, const std::string& what, int ndim,
                          py::ssize_t rows, py::ssize_t cols, py::array* shape_out = nullptr) {
  const py::array a = checked_array(value, what, 'i', ndim, ndim);
  if ((rows >= 0 && a.shape(0) != rows) || (ndim == 2 && cols >= 0 && a.shape(1) != cols))
    throw InputError(what + ": expected " + std::to_string(rows >= 0 ? rows : 0) + " rows" +
                     (ndim == 2 && cols >= 0 ? " of " + std::to_string(cols) : "") + ", got " +
                     shape_text(a));
  if (shape_out) *shape_out = a;
  const auto c = as_contiguous<int64_t>(a);
  std::vector<T> out(static_cast<size_t>(c.size()));
  for (size_t i = 0; i < out.size(); ++i) {
    const int64_t v = c.data()[i];
    if (v < std::numeric_limits<T>::min() || v > std::numeric_limits<T>::max())
      throw InputError(what + ": value " + std::to_string(v) + " out of range");
    out[i] = static_cast<T>(v);
  }
  return out;
}

// The mesh of a predicted state, as bsms.Dataset.mesh() gives it, checked as a dataset's mesh is
// (check_trajectory_mesh) with the node types of the run's data.
TrajectoryMesh mesh_from_dict(const py::dict& mesh, const LagrangianSpec& spec,
                              const Dataset& data) {
  for (const char* key : {"cells", "mesh_pos", "node_type"})
    if (!mesh.contains(key))
      throw InputError(std::string("mesh: missing ") + key +
                       " (expected the dict bsms.Dataset.mesh() returns)");
  TrajectoryMesh m;
  const py::array pos = checked_array(mesh["mesh_pos"], "mesh_pos", 'f', 2, 2);
  if (pos.shape(1) != spec.mesh_dimension())
    throw InputError("mesh_pos: expected " + std::to_string(spec.mesh_dimension()) +
                     " columns (the run's mesh dimension), got " + shape_text(pos));
  const int64_t n = pos.shape(0);
  m.dim = static_cast<int>(pos.shape(1));
  const auto pf = as_contiguous<float>(pos);
  m.mesh_pos.assign(pf.data(), pf.data() + pf.size());
  py::array cells;
  m.cells = int_vector<int32_t>(mesh["cells"], "cells", 2, -1, -1, &cells);
  m.cell_size = static_cast<int>(cells.shape(1));
  m.node_type = int_vector<int32_t>(mesh["node_type"], "node_type", 1, n, -1);
  m.body_id = mesh.contains("body_id") ? int_vector<int32_t>(mesh["body_id"], "body_id", 1, n, -1)
                                       : std::vector<int32_t>(static_cast<size_t>(n), 0);
  check_trajectory_mesh(m, "mesh", data.has_simulated_node_types());
  return m;
}

}  // namespace

void bind_torch(py::module_& m) {
  py::class_<PyRun>(m, "_Run")
      .def(py::init([](const std::string& run, const std::string& data, const std::string& split,
                       const std::string& seeding) {
             return run_unlocked([&] {
               auto r = std::make_unique<PyRun>();
               r->folder = RunFolder::open(run);
               const Json& features = r->folder.features_resolved;
               if (features.is_object() && features.value("kind", std::string()) == "eulerian")
                 throw InputError(r->folder.config_path +
                                  ": an Eulerian run; predict() steps Lagrangian runs (rollout() "
                                  "takes both)");
               r->data_dir = data.empty() ? r->folder.config.data : data;
               r->data = std::make_unique<Dataset>(Dataset::open_split(r->data_dir, split));
               r->model = open_rollout_model(r->folder, *r->data, r->data_dir, seeding);
               return r;
             });
           }),
           py::arg("run"), py::arg("data"), py::arg("split"), py::arg("seeding"))
      .def_property_readonly("model_type", [](const PyRun& r) { return r.model.model_type; })
      .def_property_readonly("levels", [](const PyRun& r) { return r.folder.levels; })
      .def_property_readonly("checkpoint", [](const PyRun& r) { return r.model.checkpoint; })
      .def_property_readonly("dim", [](const PyRun& r) { return r.model.spec.dim; })
      .def_property_readonly("history", [](const PyRun& r) { return r.model.spec.history; })
      .def_property_readonly("config_path", [](const PyRun& r) { return r.folder.config_path; })
      .def_property_readonly("data", [](const PyRun& r) { return r.data->location(); })
      .def(
          "predict",
          [](PyRun& r, const py::dict& mesh_arrays, const py::list& frames,
             const py::object& prescribed, int threads) {
            const LagrangianSpec& spec = r.model.spec;
            const TrajectoryMesh mesh = mesh_from_dict(mesh_arrays, spec, *r.data);
            const int64_t n = mesh.num_nodes();
            if (frames.size() < 2)
              throw InputError(
                  "positions: expected the world positions of at least 2 frames "
                  "(oldest first), got " +
                  std::to_string(frames.size()));
            std::vector<torch::Tensor> x;
            for (size_t k = 0; k < frames.size(); ++k)
              x.push_back(
                  positions_tensor(frames[k], "positions[" + std::to_string(k) + "]", n, spec.dim));
            // Nodes the model does not move keep their last position unless told.
            const torch::Tensor driven =
                prescribed.is_none() ? x.back().clone()
                                     : positions_tensor(prescribed, "prescribed", n, spec.dim);
            const torch::Tensor next = run_unlocked([&] {
              const TorchThreadScope scope(threads);
              torch::InferenceMode inference;
              return predict_step(r.model, mesh, x, driven).contiguous();
            });
            std::vector<float> out(next.data_ptr<float>(), next.data_ptr<float>() + next.numel());
            return to_numpy(std::move(out), {n, spec.dim});
          },
          py::arg("mesh"), py::arg("positions"), py::arg("prescribed"), py::arg("threads"));

  m.def(
      "_rollout",
      [](const std::string& run, const std::string& split, const std::string& data,
         const std::string& seeding, const std::string& out, int64_t trajectories, int64_t steps,
         bool one_step, const std::string& project, int threads) {
        RolloutRequest request;
        request.run = run;
        request.split = split;
        request.data = data;
        request.seeding = seeding;
        request.out = out;
        request.max_trajectories = trajectories;
        request.max_steps = steps;
        request.one_step = one_step;
        request.threads = threads;
        request.quiet = true;
        if (!project.empty()) request.projection = parse_projection(project);
        return run_unlocked([&] {
          const TorchThreadScope scope(threads);
          return to_json(rollout(request)).dump();
        });
      },
      py::arg("run"), py::arg("split"), py::arg("data"), py::arg("seeding"), py::arg("out"),
      py::arg("trajectories"), py::arg("steps"), py::arg("one_step"), py::arg("project"),
      py::arg("threads"));
}

}  // namespace bsms::python

PYBIND11_MODULE(_torch, m) {
  namespace bp = bsms::python;
  m.doc() = "bsms with LibTorch: trained runs";
  bp::share_library_mutex(m);
  bp::register_errors(m);
  bp::bind_torch(m);
}
