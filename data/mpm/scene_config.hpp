// Scene files (configs/scenes/*.json): one typed struct per concern (background mesh, bodies,
// boundaries, solver, output), read strictly from JSON (unknown or missing keys and impossible
// values are an InputError naming the file and key). No meshing here: scene_size.hpp estimates a
// scene's work from these structs, scene_builder.hpp turns them into solver input. A dataset
// generator samples parameters by editing the JSON (e.g. through apply_override) and calling
// parse_scene again.
#pragma once

#include <string>
#include <vector>

#include "core/config.hpp"
#include "data/mpm/solver.hpp"

namespace bsms::mpm {

struct BackgroundSpec {
  std::string type;              // "box" | "ball" (disk/sphere; group "wall"), built with gmsh,
                                 // or "mesh" (read from `path`; groups = its physical groups)
  std::string path;              // mesh: .msh (relative to the scene file)
  std::vector<double> min, max;  // box corners, m [dim]
  double element_size = 0.0;     // box: target edge length, m
  bool structured = false;       // box: transfinite (regular) triangulation
  double rotation_deg = 0.0;     // box: rotation about `rotation_center` (about z in 3D)
  std::vector<double> rotation_center;  // default: box centre
  // box (2D, unstructured): segments [x0, y0, x1, y1] (m, after rotation) the mesh must conform
  // to, e.g. a clamped face that should carry nodes whatever the mesh rotation.
  std::vector<std::vector<double>> embedded_lines;
  std::vector<double> center;  // ball centre, m [dim]
  double radius = 0.0;         // ball radius, m
  bool extra_layer = true;     // extrude one outer element layer (needed by UMLS at walls)
  // Simplicial backgrounds: the kernel unit h (m) held fixed instead of derived from the mesh's
  // edges (0: derived, see make_background), e.g. to compare meshes that differ only in their
  // tessellation. At least the longest edge / 1.5.
  double kernel_width = 0.0;
};

struct ShapeSpec {
  std::string type;              // "box" | "disk" (2D) | "polygon" (2D) | "sphere" (3D) | "mesh"
  std::vector<double> min, max;  // box
  std::vector<double> center;    // disk, sphere
  double radius = 0.0;           // disk, sphere
  std::string path;              // mesh
  std::vector<std::vector<double>> points;  // polygon: [x, y] vertices in order, m (unstructured)
};

// Initial velocity field v(x), m/s.
struct VelocitySpec {
  std::string type = "uniform";  // "uniform" | "halves" | "sine" | "rotation"
  std::vector<double> value;     // uniform
  int axis = 0;                  // halves, sine: coordinate axis
  double split = 0.0;            // halves: x[axis] < split gets `below`, else `above`
  std::vector<double> below, above;
  std::vector<double> amplitude;  // sine: amplitude * sin(wavenumber * (x[axis] - origin))
  double wavenumber = 0.0, origin = 0.0;
  std::vector<double> center;     // rotation: rigid rotation about center (z axis in 3D)
  double angular_velocity = 0.0;  // rad/s
};

struct BodySpec {
  std::string name;
  ShapeSpec shape;
  double spacing = 0.0;    // particle spacing (body mesh edge length), m
  bool structured = true;  // box bodies: regular particle lattice
  // "nodes": particles at the body mesh nodes with lumped volumes (half volumes on faces);
  // "cell_centres" (box only): particles at the centres of a lattice of cells of size `spacing`,
  // each with volume spacing^dim; the body mesh is the structured mesh through those centres.
  std::string sampling = "nodes";
  Material material;
  VelocitySpec velocity;
  double initial_stretch = 1.0;  // initial F = stretch * I (stored elastic energy)
};

struct BoundarySpec {
  std::string group;  // physical group of the background (box: left/right/bottom/top/back/front)
  // or a half-space: nodes with (x - point)·normal >= 0, all constrained directly (no ghosts)
  std::vector<double> point, normal;
  BoundaryType type = BoundaryType::kFixed;
};

struct SolverSpec {
  KernelType kernel = KernelType::kUmls;
  Transfer transfer = Transfer::kApic;
  double cfl = 0.3;
  double dt = 0.0;  // > 0: fixed time step, s
  double flip_ratio = 1.0;
  double end_time = 1.0;  // s
};

struct OutputSpec {
  int frames = 101;  // frames written, t = 0 and end_time included
  // Optional fields besides position: "velocity", "stress" (von Mises, Pa), "plastic_strain"
  // (equivalent plastic strain α of hencky_j2, dimensionless).
  std::vector<std::string> fields{"velocity", "stress"};
};

struct Scene {
  std::string file;  // for messages and relative paths
  Json source;       // the resolved JSON (written next to outputs)
  int dim = 2;
  BackgroundSpec background;
  std::vector<BodySpec> bodies;
  std::vector<BoundarySpec> boundaries;
  std::vector<double> gravity;  // m/s² [dim]
  SolverSpec solver;
  OutputSpec output;
};

Scene parse_scene(const Json& json, const std::string& file);
// A family's base scene (the "scene" of configs/families/*.json, which every draw completes): read
// as parse_scene reads a scene, except that "bodies" may be absent or empty (the draws bring them;
// absent reads as none). `where`: the file and the scene's key path in it, for messages.
Scene parse_base_scene(const Json& json, const JsonContext& where);
// Loads a scene file and applies `--set key.path=value` overrides before parsing.
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});

}  // namespace bsms::mpm
