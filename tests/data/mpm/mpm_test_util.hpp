// Shared helpers of the data/ tests: background meshes built with gmsh and random points.
#pragma once

#include <gmsh.h>

#include <random>
#include <string>

#include "core/gmsh_session.hpp"
#include "data/mpm/background.hpp"
#include "data/mpm/kernel.hpp"
#include "data/mpm/scene_builder.hpp"
#include "data/mpm/solver.hpp"

namespace bsms::mpm::testing {

// Path of a shipped scene file.
inline std::string scene_path(const std::string& name) {
  return std::string(BSMS_SOURCE_DIR) + "/configs/scenes/" + name;
}

// A 2D solver for a parsed scene (background, bodies, constraints as the scene builds them).
inline MpmSolver<2> make_solver(const Scene& scene) {
  BuiltScene<2> b = build_scene<2>(scene);
  return MpmSolver<2>(std::move(b.background), std::move(b.materials), std::move(b.particles),
                      std::move(b.constraints), b.settings);
}

// Delaunay mesh of the box [0, size]^Dim with target edge length `element`; `graded` refines it
// towards the origin so that h (the maximum edge) exceeds the local element size there.
template <int Dim>
Mesh box_mesh(double size, double element, bool graded = false) {
  GmshSession session;
  gmsh::option::setNumber("Mesh.MeshSizeMin", graded ? 0.25 * element : element);
  gmsh::option::setNumber("Mesh.MeshSizeMax", element);
  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", graded ? 1 : 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", graded ? 1 : 0);
  gmsh::option::setNumber("Mesh.Algorithm", 5);
  gmsh::option::setNumber("Mesh.Algorithm3D", 1);
  if (Dim == 2) {
    gmsh::model::occ::addRectangle(0, 0, 0, size, size);
  } else {
    gmsh::model::occ::addBox(0, 0, 0, size, size, size);
  }
  gmsh::model::occ::synchronize();
  if (graded) {
    gmsh::vectorpair points;
    gmsh::model::getEntities(points, 0);
    gmsh::model::mesh::setSize(points, element);
    gmsh::model::mesh::setSize({{0, 1}}, 0.25 * element);
  }
  gmsh::model::mesh::generate(Dim);
  return session.extract_mesh("test box");
}

// A uniformly random point inside a random cell of the input (non-layer) part of the mesh.
template <int Dim>
Vec<Dim> random_point(const BackgroundMesh<Dim>& bg, int32_t domain_cells, std::mt19937& rng) {
  std::uniform_int_distribution<int32_t> pick(0, domain_cells - 1);
  std::exponential_distribution<double> e(1.0);
  const auto& cell = bg.cells[pick(rng)];
  double b[Dim + 1], sum = 0.0;
  for (int k = 0; k <= Dim; ++k) sum += (b[k] = e(rng));
  Vec<Dim> x = Vec<Dim>::Zero();
  for (int k = 0; k <= Dim; ++k) x += b[k] / sum * bg.points[cell[k]];
  return x;
}

}  // namespace bsms::mpm::testing
