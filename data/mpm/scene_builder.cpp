#include "data/mpm/scene_builder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/error.hpp"
#include "data/mpm/scene_meshing.hpp"
#include "data/mpm/scene_size.hpp"

namespace bsms::mpm {

namespace {

void refuse_bad_cells(const Mesh& mesh, const std::string& path, const std::string& where) {
  const BadCells bad = find_bad_cells(mesh);
  if (bad.count() > 0)
    throw InputError(where + ": mesh " + path + " has " + bad.describe() +
                     "; the solver needs cells of non-zero volume that do not overlap");
}

template <int Dim>
Vec<Dim> initial_velocity(const VelocitySpec& v, const Vec<Dim>& x) {
  auto vec = [](const std::vector<double>& a) {
    return Vec<Dim>(Eigen::Map<const Vec<Dim>>(a.data()));
  };
  if (v.type == "uniform") return vec(v.value);
  if (v.type == "halves") return x[v.axis] < v.split ? vec(v.below) : vec(v.above);
  if (v.type == "sine") return vec(v.amplitude) * std::sin(v.wavenumber * (x[v.axis] - v.origin));
  const Vec<Dim> r = x - vec(v.center);
  Vec<Dim> out = Vec<Dim>::Zero();
  out[0] = -v.angular_velocity * r[1];
  out[1] = v.angular_velocity * r[0];
  return out;
}

// The background of the scene: a B-spline lattice, or a mesh (gmsh or a file) without bad cells.
template <int Dim>
BackgroundMesh<Dim> build_background(const Scene& scene) {
  const BackgroundSpec& bs = scene.background;
  const std::string bg_context = scene.file + ": background";
  if (scene.solver.kernel == KernelType::kBspline)
    return make_lattice<Dim>(Eigen::Map<const Vec<Dim>>(bs.min.data()),
                             Eigen::Map<const Vec<Dim>>(bs.max.data()), bs.element_size, 2);
  const Mesh mesh = mesh_background(bs, Dim, bg_context);
  // Zero-volume or inverted cells break the kernel and the cell walk: refused, not warned.
  if (bs.type == "mesh") refuse_bad_cells(mesh, bs.path, scene.file + ": key 'background.path'");
  return make_background<Dim>(mesh, bs.extra_layer, bg_context, bs.kernel_width);
}

// Volume (m³) lumped to each node of a body's mesh: the box split evenly over its nodes for
// "cell_centres" sampling, each cell's volume shared by its nodes for "nodes".
template <int Dim>
std::vector<double> lumped_volumes(const BodySpec& body, const Mesh& mesh) {
  std::vector<double> volume(mesh.num_nodes(), 0.0);
  if (body.sampling == "cell_centres") {
    double cell_volume = 1.0;
    for (int a = 0; a < Dim; ++a) cell_volume *= body.shape.max[a] - body.shape.min[a];
    std::fill(volume.begin(), volume.end(), cell_volume / static_cast<double>(mesh.num_nodes()));
  }
  for (int64_t c = 0; c < mesh.num_cells() && body.sampling == "nodes"; ++c) {
    Mat<Dim> jac;
    for (int k = 0; k < Dim; ++k)
      jac.col(k) = (mesh.points.row(mesh.cells(c, k + 1)) - mesh.points.row(mesh.cells(c, 0)))
                       .transpose()
                       .template head<Dim>();
    const double vol = std::abs(jac.determinant()) / (Dim == 2 ? 2.0 : 6.0);
    for (int k = 0; k <= Dim; ++k) volume[mesh.cells(c, k)] += vol / (Dim + 1);
  }
  return volume;
}

// InputError unless a particle at x (body mesh node i) lies where the background can carry it.
template <int Dim>
void check_inside_background(const BackgroundMesh<Dim>& bg, const Vec<Dim>& x, int64_t i,
                             const std::string& context) {
  if (bg.grid) {
    const RegularGrid<Dim>& g = *bg.grid;
    for (int a = 0; a < Dim; ++a) {
      const double xi = (x[a] - g.origin[a]) / g.dx - 0.5;
      if (!(xi >= 0.0 && xi + 2.0 < g.counts[a]))
        throw InputError(context + ": particle at node " + std::to_string(i) +
                         " lies outside the background");
    }
  } else {
    Eigen::Matrix<double, Dim + 1, 1> bary;
    if (bg.locate(x, -1, bary) < 0)
      throw InputError(context + ": particle at node " + std::to_string(i) +
                       " lies outside the background");
  }
}

// Meshes body b and appends its material, its particles (one per mesh node) and its mesh.
template <int Dim>
void add_body(const Scene& scene, size_t b, BuiltScene<Dim>& built) {
  const BodySpec& body = scene.bodies[b];
  const std::string context = scene.file + ": body '" + body.name + "'";
  Mesh mesh = mesh_body(body, Dim, context);
  if (body.shape.type == "mesh")
    refuse_bad_cells(mesh, body.shape.path,
                     scene.file + ": key 'bodies." + std::to_string(b) + ".shape.path'");
  if (mesh.dim > Dim || mesh.cell_dim != Dim)
    throw InputError(context + ": body mesh must have " + std::to_string(Dim) + "D simplices");
  const std::vector<double> volume = lumped_volumes<Dim>(body, mesh);
  built.materials.push_back(body.material);
  const int32_t first = built.particles.size();
  built.particles.resize(first + static_cast<int32_t>(mesh.num_nodes()));
  const double J0 = std::pow(body.initial_stretch, Dim);
  for (int64_t i = 0; i < mesh.num_nodes(); ++i) {
    const int32_t p = first + static_cast<int32_t>(i);
    const Vec<Dim> x = mesh.points.row(i).transpose().template head<Dim>();
    built.particles.x[p] = x;
    built.particles.v[p] = initial_velocity<Dim>(body.velocity, x);
    built.particles.F[p] = body.initial_stretch * Mat<Dim>::Identity();
    built.particles.volume0[p] = volume[i] / J0;
    built.particles.mass[p] = body.material.density * volume[i] / J0;
    built.particles.material[p] = static_cast<int32_t>(b);
    built.particles.body[p] = static_cast<int32_t>(b);
    check_inside_background<Dim>(built.background, x, i, context);
  }
  built.body_meshes.push_back(std::move(mesh));
}

// A constraint on `node`; a ghost (node beyond the wall) when its mirror point differs from the
// node by more than tol (m).
template <int Dim>
NodeConstraint<Dim> make_constraint(const BackgroundMesh<Dim>& bg, double tol, int32_t node,
                                    BoundaryType type, const Vec<Dim>& normal,
                                    const Vec<Dim>& mirror) {
  NodeConstraint<Dim> c;
  c.node = node;
  c.type = type;
  c.normal = normal;
  if ((mirror - bg.points[node]).norm() > tol) {
    if (bg.grid) {
      const RegularGrid<Dim>& g = *bg.grid;
      std::array<int32_t, Dim> ijk;
      bool inside = true;
      for (int a = 0; a < Dim; ++a) {
        ijk[a] = static_cast<int32_t>(std::lround((mirror[a] - g.origin[a]) / g.dx));
        inside = inside && ijk[a] >= 0 && ijk[a] < g.counts[a];
      }
      if (inside) {
        c.mirror_count = 1;
        c.mirror_nodes[0] = g.index(ijk);
        c.mirror_weights[0] = 1.0;
      }
    } else {
      Eigen::Matrix<double, Dim + 1, 1> bary;
      const int32_t cell = bg.locate(mirror, -1, bary);
      if (cell >= 0) {
        c.mirror_count = Dim + 1;
        for (int k = 0; k <= Dim; ++k) {
          c.mirror_nodes[k] = bg.cells[cell][k];
          c.mirror_weights[k] = bary[k];
        }
      }
    }
  }
  return c;
}

// Appends the constraints of boundary i: a background node group, or the half-space beyond a
// plane.
template <int Dim>
void add_boundary(const Scene& scene, size_t i, BuiltScene<Dim>& built) {
  const BackgroundMesh<Dim>& bg = built.background;
  const double tol = 1e-9 * bg.h;
  const BoundarySpec& s = scene.boundaries[i];
  if (!s.group.empty()) {
    auto it = bg.groups.find(s.group);
    if (it == bg.groups.end()) {
      std::string names;
      for (const auto& g : bg.groups) names += (names.empty() ? "" : ", ") + g.first;
      throw InputError(scene.file + ": key 'boundaries." + std::to_string(i) +
                       ".group': unknown group '" + s.group + "' (background groups: " + names +
                       ")");
    }
    const NodeGroup<Dim>& group = it->second;
    for (size_t k = 0; k < group.nodes.size(); ++k)
      built.constraints.push_back(make_constraint<Dim>(bg, tol, group.nodes[k], s.type,
                                                       group.normals[k], group.mirrors[k]));
  } else {
    const Vec<Dim> point = Eigen::Map<const Vec<Dim>>(s.point.data());
    const Vec<Dim> normal = Eigen::Map<const Vec<Dim>>(s.normal.data()).normalized();
    for (int32_t v = 0; v < bg.num_nodes(); ++v) {
      const double depth = (bg.points[v] - point).dot(normal);
      // A half-space need not follow mesh faces: its nodes are constrained directly.
      if (depth >= -tol)
        built.constraints.push_back(make_constraint<Dim>(bg, tol, v, s.type, normal, bg.points[v]));
    }
  }
}

}  // namespace

template <int Dim>
BuiltScene<Dim> build_scene(const Scene& scene) {
  if (scene.dim != Dim)
    throw InputError(scene.file + ": scene is " + std::to_string(scene.dim) + "D");
  check_scene_size(scene);
  BuiltScene<Dim> built;
  built.background = build_background<Dim>(scene);
  for (size_t b = 0; b < scene.bodies.size(); ++b) add_body<Dim>(scene, b, built);
  for (size_t i = 0; i < scene.boundaries.size(); ++i) add_boundary<Dim>(scene, i, built);

  SolverSettings<Dim>& st = built.settings;
  st.kernel = scene.solver.kernel;
  st.transfer = scene.solver.transfer;
  st.cfl = scene.solver.cfl;
  st.fixed_dt = scene.solver.dt;
  st.flip_ratio = scene.solver.flip_ratio;
  st.gravity = Eigen::Map<const Vec<Dim>>(scene.gravity.data());
  return built;
}

template BuiltScene<2> build_scene<2>(const Scene&);
template BuiltScene<3> build_scene<3>(const Scene&);

}  // namespace bsms::mpm