// gmsh meshing of a scene's geometry (scene_config.hpp) with the paper's settings: Delaunay,
// one target edge length, fixed random seed; structured boxes get transfinite (lattice) meshes.
#pragma once

#include <string>

#include "core/mesh.hpp"
#include "data/mpm/scene_config.hpp"

namespace bsms::mpm {

// The background mesh of a simplicial background: "box" (physical groups left/right, bottom/top,
// back/front for its sides, domain; rotated and with embedded lines as the spec says) and "ball"
// (groups wall, domain) meshed with gmsh at spec.element_size; "mesh" read from spec.path.
// `context` prefixes error messages.
Mesh mesh_background(const BackgroundSpec& spec, int dim, const std::string& context);

// A body's mesh, whose nodes become its particles: box, disk, polygon or sphere meshed with gmsh
// at body.spacing (a lattice for structured boxes and cell_centres sampling), or a mesh file.
// InputError when cell_centres sampling has fewer than 2 cells per axis.
Mesh mesh_body(const BodySpec& body, int dim, const std::string& context);

}  // namespace bsms::mpm
