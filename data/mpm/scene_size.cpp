#include "data/mpm/scene_size.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/error.hpp"

namespace bsms::mpm {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Nodes per unit measure of a Delaunay mesh of edge length h: 2 / (sqrt(3) h^2) in 2D (equilateral
// triangles), sqrt(2) / h^3 in 3D (the regular tetrahedral packing).
double node_density(int dim, double h) {
  return dim == 2 ? 1.1547 / (h * h) : 1.4142 / (h * h * h);
}

double ball_measure(int dim, double radius) {
  return dim == 2 ? kPi * radius * radius : 4.0 / 3.0 * kPi * radius * radius * radius;
}

double box_measure(const std::vector<double>& lo, const std::vector<double>& hi) {
  double m = 1.0;
  for (size_t a = 0; a < lo.size(); ++a) m *= hi[a] - lo[a];
  return m;
}

double body_particles(const BodySpec& body, int dim) {
  const ShapeSpec& s = body.shape;
  if (s.type == "mesh") return 0.0;  // the file bounds it
  if (s.type == "box" && (body.sampling == "cell_centres" || body.structured)) {
    double n = 1.0;
    for (int a = 0; a < dim; ++a) {
      const double cells = std::max(1.0, std::round((s.max[a] - s.min[a]) / body.spacing));
      n *= body.sampling == "cell_centres" ? cells : cells + 1.0;
    }
    return n;
  }
  double measure = 0.0;
  if (s.type == "box") {
    measure = box_measure(s.min, s.max);
  } else if (s.type == "polygon") {
    for (size_t i = 0; i < s.points.size(); ++i) {
      const auto& a = s.points[i];
      const auto& b = s.points[(i + 1) % s.points.size()];
      measure += 0.5 * (a[0] * b[1] - b[0] * a[1]);
    }
    measure = std::abs(measure);
  } else {
    measure = ball_measure(dim, s.radius);
  }
  return measure * node_density(dim, body.spacing);
}

double max_initial_speed(const VelocitySpec& v) {
  auto norm = [](const std::vector<double>& x) {
    double sum = 0.0;
    for (double c : x) sum += c * c;
    return std::sqrt(sum);
  };
  if (v.type == "uniform") return norm(v.value);
  if (v.type == "halves") return std::max(norm(v.below), norm(v.above));
  if (v.type == "sine") return norm(v.amplitude);
  return 0.0;  // rotation: depends on the extent; the wave speed dominates elastic scenes
}

std::string sci(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2g", x);
  return buf;
}

}  // namespace

SceneEstimate estimate_scene(const Scene& scene) {
  SceneEstimate e;
  const int dim = scene.dim;
  const BackgroundSpec& bg = scene.background;
  double element = 0.0;
  if (scene.solver.kernel == KernelType::kBspline) {
    e.nodes = 1.0;
    for (int a = 0; a < dim; ++a)
      e.nodes *= std::ceil((bg.max[a] - bg.min[a]) / bg.element_size) + 5.0;
    element = bg.element_size;
  } else if (bg.type == "box") {
    if (bg.structured) {
      e.nodes = 1.0;
      for (int a = 0; a < dim; ++a)
        e.nodes *= std::round((bg.max[a] - bg.min[a]) / bg.element_size) + 1.0;
    } else {
      e.nodes = box_measure(bg.min, bg.max) * node_density(dim, bg.element_size);
    }
    element = bg.element_size;
  } else if (bg.type == "ball") {
    e.nodes = ball_measure(dim, bg.radius) * node_density(dim, bg.element_size);
    element = bg.element_size;
  }
  double wave_speed = 0.0, speed = 0.0, largest = -1.0;
  for (size_t b = 0; b < scene.bodies.size(); ++b) {
    const double n = body_particles(scene.bodies[b], dim);
    e.particles += n;
    if (n > largest) largest = n, e.largest_body = static_cast<int>(b);
    wave_speed = std::max(wave_speed, scene.bodies[b].material.wave_speed());
    speed = std::max(speed, max_initial_speed(scene.bodies[b].velocity));
  }
  if (scene.solver.dt > 0.0) {
    e.steps = std::ceil(scene.solver.end_time / scene.solver.dt);
  } else if (element > 0.0) {
    // The linear FEM kernel's CFL spacing is the smallest simplex height (~0.5 h).
    const double spacing = scene.solver.kernel == KernelType::kLinearFem ? 0.5 * element : element;
    e.steps =
        std::ceil(scene.solver.end_time * (wave_speed + speed) / (scene.solver.cfl * spacing));
  }
  // Bytes per particle: state (~0.2 KB) plus kernel slots (ring-1 stencil of ~30 nodes in 2D,
  // ~100 in 3D, 8 + 8 (dim + 1) bytes each) and gmsh's body mesh while it is built; per node:
  // points, cells, stencils, hash, grid arrays, 2 threads' scatter buffers and gmsh's mesh;
  // frames: position, velocity, stress, plastic strain as float32 (vectors grow up to 2x).
  const double per_particle = dim == 2 ? 1.5e3 : 6e3;
  const double per_node = dim == 2 ? 1.5e3 : 6e3;
  const double per_frame_particle = 4.0 * (2 * dim + 2) * 2.0;
  e.bytes =
      e.particles * (per_particle + per_frame_particle * scene.output.frames) + e.nodes * per_node;
  return e;
}

void check_scene_size(const Scene& scene, double memory_limit_bytes) {
  const SceneEstimate e = estimate_scene(scene);
  const std::string body_key = "bodies." + std::to_string(e.largest_body) + ".spacing";
  const std::string where = scene.file + ": key '";
  if (e.particles > kMaxParticles)
    throw InputError(where + body_key + "': about " + sci(e.particles) +
                     " particles estimated (spacing " + sci(scene.bodies[e.largest_body].spacing) +
                     " m), limit " + sci(kMaxParticles) + " (a unit typo?)");
  if (e.nodes > kMaxBackgroundNodes)
    throw InputError(where + "background.element_size': about " + sci(e.nodes) +
                     " background nodes estimated (element size " +
                     sci(scene.background.element_size) + " m), limit " + sci(kMaxBackgroundNodes) +
                     " (a unit typo?)");
  const std::string step_key = scene.solver.dt > 0.0 ? "solver.dt" : "solver.end_time";
  if (e.steps > kMaxSteps)
    throw InputError(where + step_key + "': about " + sci(e.steps) +
                     " time steps estimated (end_time " + sci(scene.solver.end_time) +
                     " s), limit " + sci(kMaxSteps));
  const double node_steps = (e.particles + e.nodes) * e.steps;
  if (node_steps > kMaxNodeSteps)
    throw InputError(where + step_key + "': about " + sci(e.steps) + " steps over " +
                     sci(e.particles) + " particles and " + sci(e.nodes) +
                     " nodes = " + sci(node_steps) + " particle-and-node steps estimated, limit " +
                     sci(kMaxNodeSteps) + " (days of stepping)");
  double limit = memory_limit_bytes;
  if (!(limit > 0.0))
    limit =
        static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGE_SIZE));
  if (limit > 0.0 && e.bytes > limit) {
    const bool particles = e.particles * 1.5e3 >= e.nodes * 1.5e3;
    throw InputError(where + (particles ? body_key : std::string("background.element_size")) +
                     "': about " + sci(e.bytes / 1e9) + " GB of memory estimated (" +
                     sci(e.particles) + " particles, " + sci(e.nodes) + " nodes, " +
                     std::to_string(scene.output.frames) + " frames), limit " + sci(limit / 1e9) +
                     " GB of physical memory");
  }
}

}  // namespace bsms::mpm
