// bsms.multilevel, bsms.read_multilevel, bsms.read_mesh: the preprocessor on NumPy arrays.
#include <filesystem>
#include <string>

#include "common.hpp"
#include "core/mesh.hpp"
#include "core/runtime.hpp"
#include "preprocess/contact_enhancement.hpp"
#include "preprocess/multilevel_file.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace bsms::python {
namespace {

// A built or read multilevel graph; levels are handed out as dicts of arrays.
struct PyMultilevel {
  MultilevelGraph graph;
  std::vector<LevelReport> report;  // empty when read from a file
};

// (2, E) int64 in PyTorch Geometric's edge_index layout: senders, then receivers (CSR order).
py::array_t<int64_t> edge_index(const CsrGraph& graph) {
  const int64_t e = graph.num_edges();
  std::vector<int64_t> out(static_cast<size_t>(2 * e));
  for (int64_t i = 0; i < graph.num_nodes; ++i)
    for (int64_t k = graph.offsets[i]; k < graph.offsets[i + 1]; ++k) {
      out[static_cast<size_t>(k)] = i;
      out[static_cast<size_t>(e + k)] = graph.targets[static_cast<size_t>(k)];
    }
  return to_numpy(std::move(out), {2, e});
}

py::array_t<int64_t> edge_index(const EdgeList& edges) {
  const int64_t e = edges.size();
  std::vector<int64_t> out(static_cast<size_t>(2 * e));
  for (int64_t k = 0; k < e; ++k) {
    out[static_cast<size_t>(k)] = edges.sender(k);
    out[static_cast<size_t>(e + k)] = edges.receiver(k);
  }
  return to_numpy(std::move(out), {2, e});
}

py::dict level_dict(const py::object& self, int k) {
  const PyMultilevel& m = self.cast<const PyMultilevel&>();
  const GraphLevel& level = m.graph.levels[static_cast<size_t>(k)];
  py::dict d;
  d["num_nodes"] = level.num_nodes();
  d["edges"] = edge_index(level.graph);
  if (k > 0) {
    d["pooled"] =
        view_numpy(level.pooled.data(), {static_cast<py::ssize_t>(level.pooled.size())}, self);
    d["down_weight"] = view_numpy(level.down_weight.data(),
                                  {static_cast<py::ssize_t>(level.down_weight.size())}, self);
  }
  return d;
}

int parse_levels(const py::object& levels) {
  if (py::isinstance<py::str>(levels) && levels.cast<std::string>() == "auto") return 0;
  if (py::isinstance<py::int_>(levels) && !py::isinstance<py::bool_>(levels)) {
    const long value = levels.cast<long>();
    if (value >= 1 && value <= kAutoMaxLevels) return static_cast<int>(value);
  }
  throw InputError("levels " + truncate(py::repr(levels)) + ": expected auto or an integer in 1.." +
                   std::to_string(kAutoMaxLevels));
}

// The mesh of (positions [N, dim], cells [C, k]), checked as a mesh file is (finite positions,
// indices in range, no repeated node in a cell).
Mesh mesh_from_arrays(const py::handle& positions, const py::handle& cells) {
  const py::array p = checked_array(positions, "positions", 'f', 2, 2);
  const py::array c = checked_array(cells, "cells", 'i', 2, 2);
  if (p.shape(1) < 1 || p.shape(1) > 3)
    throw InputError("positions: expected shape (N, 1), (N, 2) or (N, 3), got " + shape_text(p));
  if (c.shape(1) < 2 || c.shape(1) > 4)
    throw InputError("cells: expected lines (C, 2), triangles (C, 3) or tetrahedra (C, 4), got " +
                     shape_text(c));
  const auto pd = as_contiguous<double>(p);
  const auto ci = as_contiguous<int64_t>(c);
  return make_mesh(static_cast<int>(p.shape(1)),
                   Eigen::Map<const RowMatrixXd>(pd.data(), p.shape(0), p.shape(1)),
                   Eigen::Map<const RowMatrixXi64>(ci.data(), c.shape(0), c.shape(1)),
                   "positions/cells");
}

void check_output_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path + ": output is a folder, expected a file");
}

// Multilevel.contact_enhance: contact edges (2, E) carried to every level.
py::list contact_enhance(const PyMultilevel& g, const py::handle& pairs) {
  const py::array a = checked_array(pairs, "contact", 'i', 2, 2);
  if (a.shape(0) != 2)
    throw InputError("contact: expected shape (2, E) (senders, receivers), got " + shape_text(a));
  const auto c = as_contiguous<int64_t>(a);
  EdgeList edges;
  const int64_t e = a.shape(1);
  edges.data.resize(static_cast<size_t>(2 * e));
  for (int64_t k = 0; k < e; ++k) {
    edges.data[static_cast<size_t>(2 * k)] = c.data()[k];
    edges.data[static_cast<size_t>(2 * k + 1)] = c.data()[e + k];
  }
  const std::vector<EdgeList> levels =
      run_unlocked([&] { return enhance_contact_edges_all_levels(g.graph, edges); });
  py::list out;
  for (const EdgeList& l : levels) out.append(edge_index(l));
  return out;
}

// The Multilevel class: levels as dicts, the build report, save, contact enhancement.
void bind_multilevel_class(py::module_& m) {
  py::class_<PyMultilevel>(m, "Multilevel",
                           "A bi-stride multilevel graph: a sequence of levels, level 0 the mesh "
                           "graph. Each level is a dict: num_nodes, edges (2 x E int64, "
                           "senders then receivers), and for k >= 1 pooled (indices into level "
                           "k-1 kept at level k) and down_weight (float32, one per level k-1 "
                           "edge).")
      .def("__len__", [](const PyMultilevel& g) { return g.graph.num_levels(); })
      .def("__getitem__",
           [](const py::object& self, int k) {
             const int n = self.cast<const PyMultilevel&>().graph.num_levels();
             if (k < 0) k += n;
             if (k < 0 || k >= n) throw py::index_error("level index out of range");
             return level_dict(self, k);
           })
      .def_property_readonly("seeding",
                             [](const PyMultilevel& g) { return to_string(g.graph.seeding); })
      .def_property_readonly("thinned", [](const PyMultilevel& g) { return g.graph.thinned; })
      .def_property_readonly(
          "report",
          [](const PyMultilevel& g) {
            py::list rows;
            for (const LevelReport& r : g.report)
              rows.append(py::dict(py::arg("level") = r.level, py::arg("nodes") = r.nodes,
                                   py::arg("edges") = r.edges, py::arg("clusters") = r.clusters,
                                   py::arg("mean_degree") = r.mean_degree,
                                   py::arg("ms") = r.milliseconds));
            return rows;
          },
          "per level: nodes, edges, clusters, mean_degree and the build time in ms (the table "
          "bsms preprocess prints); empty for a graph read from a file")
      .def(
          "save",
          [](const PyMultilevel& g, const Path& path) {
            check_output_file(path.string());
            run_unlocked([&] { write_multilevel_graph(g.graph, path.string()); });
          },
          py::arg("path"),
          "write the multilevel graph file bsms preprocess writes (HDF5, written atomically)")
      .def("contact_enhance", &contact_enhance, py::arg("contact"),
           "contact edges (2 x E, level-0 node indices) carried to every level, thesis eq. 4.1: "
           "a list of 2 x E_k arrays, level 0 sorted and unique");
}

// multilevel (build from arrays) and read_multilevel (from a file).
void bind_multilevel_builders(py::module_& m) {
  m.def(
      "multilevel",
      [](const py::handle& positions, const py::handle& cells, const py::object& levels,
         const std::string& seeding, const std::string& thinning, uint64_t seed, int threads) {
        BuildOptions options;
        options.num_levels = parse_levels(levels);
        options.seeding = parse_seeding(seeding);
        options.thinning = parse_thinning(thinning);
        options.rng_seed = seed;
        Mesh mesh = mesh_from_arrays(positions, cells);
        auto result = std::make_unique<PyMultilevel>();
        run_unlocked([&] {
          const ThreadScope scope(threads);
          result->graph = build_multilevel_graph(mesh, options, &result->report);
        });
        return result;
      },
      py::arg("positions"), py::arg("cells"), py::arg("levels") = "auto",
      py::arg("seeding") = "minave", py::arg("thinning") = "auto", py::arg("seed") = 0,
      py::arg("threads") = 0,
      "Builds the bi-stride multilevel graph of a mesh, as bsms preprocess --mesh does.\n"
      "positions: (N, dim) floats; cells: (C, dim + 1) node indices; levels: 'auto' or the\n"
      "level count including the mesh; seeding: 'minave', 'closecenter' or 'random' (seed);\n"
      "thinning: 'auto', 'on' or 'off'; threads: 0 for every core. Releases the GIL.");

  m.def(
      "read_multilevel",
      [](const Path& path) {
        auto result = std::make_unique<PyMultilevel>();
        result->graph = run_unlocked([&] { return read_multilevel_graph(path.string()); });
        return result;
      },
      py::arg("path"), "reads and checks a multilevel graph file (bsms preprocess's output)");
}

void bind_read_mesh(py::module_& m) {
  m.def(
      "read_mesh",
      [](const Path& path) {
        Mesh mesh = run_unlocked([&] { return read_mesh(path.string()); });
        py::dict d;
        std::vector<double> points(mesh.points.data(), mesh.points.data() + mesh.points.size());
        std::vector<int64_t> cells(mesh.cells.data(), mesh.cells.data() + mesh.cells.size());
        d["positions"] = to_numpy(std::move(points), {mesh.num_nodes(), mesh.dim});
        d["cells"] = to_numpy(std::move(cells), {mesh.num_cells(), mesh.nodes_per_cell()});
        py::dict groups;
        for (auto& [name, nodes] : mesh.node_groups)
          groups[py::str(name)] =
              to_numpy(std::move(nodes), {static_cast<py::ssize_t>(nodes.size())});
        d["node_groups"] = groups;
        return d;
      },
      py::arg("path"),
      "reads a mesh as bsms preprocess --mesh does (.msh 2.2/4.1 directly, other formats and .geo "
      "through gmsh in a child process): positions (N, dim), cells (C, k), node_groups");
}

}  // namespace

void bind_preprocess(py::module_& m) {
  bind_multilevel_class(m);
  bind_multilevel_builders(m);
  bind_read_mesh(m);
}

}  // namespace bsms::python
