// Building a parsed scene into solver input: the background (gmsh, a mesh file or a B-spline
// lattice), particles seeded at the nodes of each body's mesh with lumped volumes, boundary
// constraints with their ghost mirrors, and the solver settings. The meshing itself is in
// scene_meshing.hpp.
#pragma once

#include <vector>

#include "core/mesh.hpp"
#include "data/mpm/scene_config.hpp"
#include "data/mpm/solver.hpp"

namespace bsms::mpm {

template <int Dim>
struct BuiltScene {
  BackgroundMesh<Dim> background;
  std::vector<Material> materials;  // one per body
  Particles<Dim> particles;
  std::vector<Mesh> body_meshes;  // particles of body b are the nodes of body_meshes[b], in order
  std::vector<NodeConstraint<Dim>> constraints;
  SolverSettings<Dim> settings;
};

// Checks the scene's size (check_scene_size), meshes the background and the bodies with gmsh and
// seeds particles at body mesh nodes with lumped volumes. InputError if a body lies outside the
// background or a group is unknown.
template <int Dim>
BuiltScene<Dim> build_scene(const Scene& scene);

}  // namespace bsms::mpm
