#include "data/mpm/scene.hpp"

#include <gmsh.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/error.hpp"
#include "core/gmsh_session.hpp"

namespace bsms::mpm {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::vector<double> read_vector(JsonObjectReader& r, const std::string& key, int dim) {
  auto v = r.get<std::vector<double>>(key);
  require(static_cast<int>(v.size()) == dim, r.context(key),
          "a list of " + std::to_string(dim) + " numbers");
  for (double x : v) require(std::isfinite(x), r.context(key), "finite");
  return v;
}

std::vector<double> opt_vector(JsonObjectReader& r, const std::string& key, int dim) {
  if (!r.has(key)) {
    r.opt<Json>(key, Json());
    return {};
  }
  return read_vector(r, key, dim);
}

Material parse_material(const Json& j, const JsonContext& ctx) {
  JsonObjectReader r(j, ctx);
  Material m;
  m.model = parse_material_model(r.get<std::string>("model"), r.context("model").where());
  m.youngs_modulus = r.get<double>("youngs_modulus");
  require(m.youngs_modulus > 0.0, r.context("youngs_modulus"), "> 0 (Pa)");
  m.poisson_ratio = r.get<double>("poisson_ratio");
  require(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5, r.context("poisson_ratio"),
          "in (-1, 0.5)");
  m.density = r.get<double>("density");
  require(m.density > 0.0, r.context("density"), "> 0 (kg/m^3)");
  if (m.model == MaterialModel::kHenckyJ2) {
    // Plasticity keys exist only for hencky_j2 (elsewhere finish() rejects them as unknown).
    m.yield_stress = r.get<double>("yield_stress");
    require(std::isfinite(m.yield_stress) && m.yield_stress > 0.0, r.context("yield_stress"),
            "> 0 (Pa)");
    m.residual_yield_stress = r.opt<double>("residual_yield_stress", m.yield_stress);
    require(m.residual_yield_stress > 0.0 && m.residual_yield_stress <= m.yield_stress,
            r.context("residual_yield_stress"), "in (0, yield_stress] (Pa)");
    m.softening = r.opt<double>("softening", 0.0);
    require(std::isfinite(m.softening) && m.softening >= 0.0, r.context("softening"), ">= 0");
  }
  r.finish();
  return m;
}

ShapeSpec parse_shape(const Json& j, const JsonContext& ctx, int dim, const std::string& base_dir) {
  JsonObjectReader r(j, ctx);
  ShapeSpec s;
  s.type = r.get<std::string>("type");
  if (s.type == "box") {
    s.min = read_vector(r, "min", dim);
    s.max = read_vector(r, "max", dim);
    for (int a = 0; a < dim; ++a)
      require(s.max[a] > s.min[a], r.context("max"), "greater than min in every axis");
  } else if ((s.type == "disk" && dim == 2) || (s.type == "sphere" && dim == 3)) {
    s.center = read_vector(r, "center", dim);
    s.radius = r.get<double>("radius");
    require(s.radius > 0.0, r.context("radius"), "> 0 (m)");
  } else if (s.type == "polygon" && dim == 2) {
    s.points = r.get<std::vector<std::vector<double>>>("points");
    require(s.points.size() >= 3, r.context("points"), "at least 3 [x, y] vertices");
    double area2 = 0.0;  // twice the signed area (shoelace)
    for (size_t i = 0; i < s.points.size(); ++i) {
      const auto& a = s.points[i];
      require(a.size() == 2 && std::isfinite(a[0]) && std::isfinite(a[1]), r.context("points"),
              "a list of finite [x, y] vertices");
      const auto& b = s.points[(i + 1) % s.points.size()];
      if (b.size() == 2) area2 += a[0] * b[1] - b[0] * a[1];
    }
    require(std::abs(area2) > 0.0, r.context("points"), "a polygon of non-zero area");
  } else if (s.type == "mesh") {
    s.path = r.get<std::string>("path");
    if (std::filesystem::path(s.path).is_relative())
      s.path = (std::filesystem::path(base_dir) / s.path).string();
  } else {
    throw InputError(r.context("type").where() + ": unknown shape '" + s.type + "' for dim " +
                     std::to_string(dim) + " (allowed: box, " +
                     (dim == 2 ? "disk, polygon" : "sphere") + ", mesh)");
  }
  r.finish();
  return s;
}

VelocitySpec parse_velocity(const Json& j, const JsonContext& ctx, int dim) {
  JsonObjectReader r(j, ctx);
  VelocitySpec v;
  v.type = r.get<std::string>("type");
  if (v.type == "uniform") {
    v.value = read_vector(r, "value", dim);
  } else if (v.type == "halves") {
    v.axis = r.get<int>("axis");
    require(v.axis >= 0 && v.axis < dim, r.context("axis"), "a coordinate axis index");
    v.split = r.get<double>("split");
    v.below = read_vector(r, "below", dim);
    v.above = read_vector(r, "above", dim);
  } else if (v.type == "sine") {
    v.axis = r.get<int>("axis");
    require(v.axis >= 0 && v.axis < dim, r.context("axis"), "a coordinate axis index");
    v.amplitude = read_vector(r, "amplitude", dim);
    v.wavenumber = r.get<double>("wavenumber");
    v.origin = r.opt<double>("origin", 0.0);
  } else if (v.type == "rotation") {
    v.center = read_vector(r, "center", dim);
    v.angular_velocity = r.get<double>("angular_velocity");
  } else {
    throw InputError(r.context("type").where() + ": unknown velocity '" + v.type +
                     "' (allowed: uniform, halves, sine, rotation)");
  }
  r.finish();
  return v;
}

}  // namespace

Scene parse_scene(const Json& json, const std::string& file) {
  Scene scene;
  scene.file = file;
  scene.source = json;
  const std::string base_dir = std::filesystem::path(file).parent_path().string();
  JsonObjectReader r(json, JsonContext{file, ""});
  scene.dim = r.get<int>("dim");
  require(scene.dim == 2 || scene.dim == 3, r.context("dim"), "2 or 3");
  const int dim = scene.dim;

  {
    JsonObjectReader b(r.raw("background"), r.context("background"));
    BackgroundSpec& bg = scene.background;
    bg.type = b.get<std::string>("type");
    if (bg.type == "mesh") {
      bg.path = b.get<std::string>("path");
      require(!bg.path.empty(), b.context("path"), "a mesh file path");
      if (std::filesystem::path(bg.path).is_relative())
        bg.path = (std::filesystem::path(base_dir) / bg.path).string();
    } else if (bg.type == "box") {
      bg.min = read_vector(b, "min", dim);
      bg.max = read_vector(b, "max", dim);
      for (int a = 0; a < dim; ++a)
        require(bg.max[a] > bg.min[a], b.context("max"), "greater than min in every axis");
      bg.element_size = b.get<double>("element_size");
      require(bg.element_size > 0.0, b.context("element_size"), "> 0 (m)");
      bg.structured = b.opt<bool>("structured", false);
      bg.rotation_deg = b.opt<double>("rotation_deg", 0.0);
      bg.rotation_center = opt_vector(b, "rotation_center", dim);
      bg.embedded_lines = b.opt<std::vector<std::vector<double>>>("embedded_lines", {});
      for (const auto& line : bg.embedded_lines)
        require(dim == 2 && line.size() == 4, b.context("embedded_lines"),
                "a list of [x0, y0, x1, y1] (2D)");
      require(bg.embedded_lines.empty() || !bg.structured, b.context("embedded_lines"),
              "empty for a structured background");
    } else if (bg.type == "ball") {
      bg.center = read_vector(b, "center", dim);
      bg.radius = b.get<double>("radius");
      require(bg.radius > 0.0, b.context("radius"), "> 0 (m)");
      bg.element_size = b.get<double>("element_size");
      require(bg.element_size > 0.0, b.context("element_size"), "> 0 (m)");
    } else {
      throw InputError(b.context("type").where() + ": unknown background '" + bg.type +
                       "' (allowed: box, ball, mesh)");
    }
    bg.extra_layer = b.opt<bool>("extra_layer", true);
    bg.kernel_width = b.opt<double>("kernel_width", 0.0);
    require(std::isfinite(bg.kernel_width) && bg.kernel_width >= 0.0, b.context("kernel_width"),
            ">= 0 (m; 0: from the mesh)");
    b.finish();
  }

  const Json& bodies = r.raw("bodies");
  if (!bodies.is_array() || bodies.empty())
    throw InputError(r.context("bodies").where() + " must be a non-empty list");
  for (size_t i = 0; i < bodies.size(); ++i) {
    const JsonContext ctx = r.context("bodies").child(std::to_string(i));
    JsonObjectReader b(bodies[i], ctx);
    BodySpec body;
    body.name = b.opt<std::string>("name", "body" + std::to_string(i));
    body.shape = parse_shape(b.raw("shape"), b.context("shape"), dim, base_dir);
    body.spacing =
        body.shape.type == "mesh" ? b.opt<double>("spacing", 1.0) : b.get<double>("spacing");
    require(body.spacing > 0.0, b.context("spacing"), "> 0 (m)");
    body.structured = b.opt<bool>("structured", true);
    body.sampling = b.opt<std::string>("sampling", "nodes");
    require(
        body.sampling == "nodes" || (body.sampling == "cell_centres" && body.shape.type == "box"),
        b.context("sampling"), "nodes, or cell_centres for a box shape");
    body.material = parse_material(b.raw("material"), b.context("material"));
    if (b.has("velocity")) {
      body.velocity = parse_velocity(b.raw("velocity"), b.context("velocity"), dim);
    } else {
      b.opt<Json>("velocity", Json());
      body.velocity.value.assign(dim, 0.0);
    }
    body.initial_stretch = b.opt<double>("initial_stretch", 1.0);
    require(body.initial_stretch > 0.0, b.context("initial_stretch"), "> 0");
    b.finish();
    scene.bodies.push_back(body);
  }

  if (r.has("boundaries")) {
    const Json& list = r.raw("boundaries");
    if (!list.is_array()) throw InputError(r.context("boundaries").where() + " must be a list");
    for (size_t i = 0; i < list.size(); ++i) {
      JsonObjectReader b(list[i], r.context("boundaries").child(std::to_string(i)));
      BoundarySpec s;
      s.type = parse_boundary_type(b.get<std::string>("type"), b.context("type").where());
      if (b.has("group")) {
        s.group = b.get<std::string>("group");
        b.opt<Json>("point", Json());
        b.opt<Json>("normal", Json());
      } else {
        b.opt<Json>("group", Json());
        s.point = read_vector(b, "point", dim);
        s.normal = read_vector(b, "normal", dim);
        double len = 0.0;
        for (double x : s.normal) len += x * x;
        require(len > 0.0, b.context("normal"), "a non-zero vector");
      }
      b.finish();
      scene.boundaries.push_back(s);
    }
  } else {
    r.opt<Json>("boundaries", Json());
  }

  scene.gravity = r.has("gravity") ? read_vector(r, "gravity", dim) : std::vector<double>(dim, 0.0);
  if (!r.has("gravity")) r.opt<Json>("gravity", Json());

  {
    JsonObjectReader s(r.raw("solver"), r.context("solver"));
    SolverSpec& sv = scene.solver;
    sv.kernel = parse_kernel(s.opt<std::string>("kernel", "umls"), s.context("kernel").where());
    sv.transfer =
        parse_transfer(s.opt<std::string>("transfer", "apic"), s.context("transfer").where());
    sv.cfl = s.opt<double>("cfl", 0.3);
    require(sv.cfl > 0.0 && sv.cfl <= 1.0, s.context("cfl"), "in (0, 1]");
    sv.dt = s.opt<double>("dt", 0.0);
    require(sv.dt >= 0.0, s.context("dt"), ">= 0 (s; 0 = CFL)");
    sv.flip_ratio = s.opt<double>("flip_ratio", 1.0);
    require(sv.flip_ratio >= 0.0 && sv.flip_ratio <= 1.0, s.context("flip_ratio"), "in [0, 1]");
    sv.end_time = s.get<double>("end_time");
    require(sv.end_time > 0.0, s.context("end_time"), "> 0 (s)");
    s.finish();
    if (sv.kernel == KernelType::kBspline && scene.background.type != "box")
      throw InputError(file + ": key 'solver.kernel': bspline needs a box background");
    if (sv.kernel == KernelType::kBspline && scene.background.rotation_deg != 0.0)
      throw InputError(file + ": key 'solver.kernel': bspline needs an unrotated box background");
    if (sv.kernel == KernelType::kBspline && scene.background.kernel_width > 0.0)
      throw InputError(file + ": key 'background.kernel_width': bspline's lattice spacing is " +
                       "background.element_size; kernel_width is for simplicial backgrounds");
  }

  if (r.has("output")) {
    JsonObjectReader o(r.raw("output"), r.context("output"));
    scene.output.frames = o.opt<int>("frames", 101);
    require(scene.output.frames >= 2, o.context("frames"), ">= 2");
    scene.output.fields = o.opt<std::vector<std::string>>("fields", scene.output.fields);
    for (const auto& f : scene.output.fields)
      require(f == "velocity" || f == "stress" || f == "plastic_strain", o.context("fields"),
              "a list of velocity, stress, plastic_strain (got '" + f + "')");
    o.finish();
  } else {
    r.opt<Json>("output", Json());
  }
  r.finish();
  return scene;
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  Json json = load_json_file(path);
  for (const auto& o : overrides) apply_override(json, o, path);
  return parse_scene(json, path);
}

namespace {

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

namespace {

void set_mesh_options(double size) {
  gmsh::option::setNumber("Mesh.MeshSizeMin", size);
  gmsh::option::setNumber("Mesh.MeshSizeMax", size);
  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
  gmsh::option::setNumber("Mesh.Algorithm", 5);    // Delaunay, as in the paper
  gmsh::option::setNumber("Mesh.Algorithm3D", 1);  // Delaunay
  gmsh::option::setNumber("Mesh.RandomSeed", 1);
}

// Transfinite constraints on every curve/surface/volume: a regular lattice of nodes.
void make_structured(double size) {
  gmsh::vectorpair curves;
  gmsh::model::getEntities(curves, 1);
  for (const auto& [dim, tag] : curves) {
    double x0, y0, z0, x1, y1, z1;
    gmsh::model::getBoundingBox(dim, tag, x0, y0, z0, x1, y1, z1);
    const double len =
        std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
    gmsh::model::mesh::setTransfiniteCurve(
        tag, std::max(2, static_cast<int>(std::lround(len / size)) + 1));
  }
  gmsh::vectorpair surfaces, volumes;
  gmsh::model::getEntities(surfaces, 2);
  for (const auto& s : surfaces)
    gmsh::model::mesh::setTransfiniteSurface(s.second, "AlternateLeft");
  gmsh::model::getEntities(volumes, 3);
  for (const auto& v : volumes) gmsh::model::mesh::setTransfiniteVolume(v.second);
}

Mesh mesh_box_background(const BackgroundSpec& spec, int dim, const std::string& context) {
  GmshSession session;
  set_mesh_options(spec.element_size);
  const std::vector<double>& lo = spec.min;
  const std::vector<double>& hi = spec.max;
  int tag;
  if (dim == 2) {
    tag = gmsh::model::occ::addRectangle(lo[0], lo[1], 0.0, hi[0] - lo[0], hi[1] - lo[1]);
  } else {
    tag =
        gmsh::model::occ::addBox(lo[0], lo[1], lo[2], hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  }
  gmsh::model::occ::synchronize();
  // Classify the sides before any rotation (tags survive the rotation).
  const char* names[3][2] = {{"left", "right"}, {"bottom", "top"}, {"back", "front"}};
  std::vector<int> sides[3][2];
  gmsh::vectorpair faces;
  gmsh::model::getEntities(faces, dim - 1);
  const double tol = 1e-4 * spec.element_size;  // OCC pads bounding boxes
  for (const auto& f : faces) {
    double b[6];
    gmsh::model::getBoundingBox(f.first, f.second, b[0], b[1], b[2], b[3], b[4], b[5]);
    for (int a = 0; a < dim; ++a) {
      if (b[3 + a] - b[a] > tol) continue;
      if (std::abs(b[a] - lo[a]) < tol) sides[a][0].push_back(f.second);
      if (std::abs(b[a] - hi[a]) < tol) sides[a][1].push_back(f.second);
    }
  }
  if (spec.rotation_deg != 0.0) {
    std::vector<double> c = spec.rotation_center;
    if (c.empty())
      for (int a = 0; a < dim; ++a) c.push_back(0.5 * (lo[a] + hi[a]));
    gmsh::model::occ::rotate({{dim, tag}}, c[0], c[1], dim == 3 ? c[2] : 0.0, 0, 0, 1,
                             spec.rotation_deg * kPi / 180.0);
    gmsh::model::occ::synchronize();
  }
  for (int a = 0; a < dim; ++a)
    for (int s = 0; s < 2; ++s) {
      const int group = gmsh::model::addPhysicalGroup(dim - 1, sides[a][s]);
      gmsh::model::setPhysicalName(dim - 1, group, names[a][s]);
    }
  for (const auto& line : spec.embedded_lines) {
    const int a = gmsh::model::occ::addPoint(line[0], line[1], 0.0);
    const int b = gmsh::model::occ::addPoint(line[2], line[3], 0.0);
    const int segment = gmsh::model::occ::addLine(a, b);
    gmsh::model::occ::synchronize();
    gmsh::model::mesh::embed(1, {segment}, 2, tag);
  }
  const int domain = gmsh::model::addPhysicalGroup(dim, {tag});
  gmsh::model::setPhysicalName(dim, domain, "domain");
  if (spec.structured) make_structured(spec.element_size);
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

Mesh mesh_ball_background(const BackgroundSpec& spec, int dim, const std::string& context) {
  GmshSession session;
  set_mesh_options(spec.element_size);
  const std::vector<double>& c = spec.center;
  const int tag = dim == 2 ? gmsh::model::occ::addDisk(c[0], c[1], 0.0, spec.radius, spec.radius)
                           : gmsh::model::occ::addSphere(c[0], c[1], c[2], spec.radius);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair boundary;
  gmsh::model::getBoundary({{dim, tag}}, boundary, false, false, false);
  std::vector<int> faces;
  for (const auto& b : boundary) faces.push_back(std::abs(b.second));
  gmsh::model::setPhysicalName(dim - 1, gmsh::model::addPhysicalGroup(dim - 1, faces), "wall");
  gmsh::model::setPhysicalName(dim, gmsh::model::addPhysicalGroup(dim, {tag}), "domain");
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

Mesh mesh_body(const BodySpec& body, int dim, const std::string& context) {
  if (body.shape.type == "mesh") return read_mesh(body.shape.path);
  GmshSession session;
  set_mesh_options(body.spacing);
  ShapeSpec s = body.shape;
  const bool centres = body.sampling == "cell_centres";
  if (centres)
    for (int a = 0; a < dim; ++a) {
      // Whole cells of size `spacing` (the box is assumed to hold an integer number of them).
      const double cells = std::max(1.0, std::round((s.max[a] - s.min[a]) / body.spacing));
      const double step = (s.max[a] - s.min[a]) / cells;
      s.min[a] += 0.5 * step;
      s.max[a] -= 0.5 * step;
      if (cells < 2.0)
        throw InputError(context + ": cell_centres sampling needs at least 2 cells per axis");
    }
  if (s.type == "box") {
    if (dim == 2) {
      gmsh::model::occ::addRectangle(s.min[0], s.min[1], 0.0, s.max[0] - s.min[0],
                                     s.max[1] - s.min[1]);
    } else {
      gmsh::model::occ::addBox(s.min[0], s.min[1], s.min[2], s.max[0] - s.min[0],
                               s.max[1] - s.min[1], s.max[2] - s.min[2]);
    }
  } else if (s.type == "disk") {
    gmsh::model::occ::addDisk(s.center[0], s.center[1], 0.0, s.radius, s.radius);
  } else if (s.type == "polygon") {
    std::vector<int> points, lines;
    for (const auto& p : s.points) points.push_back(gmsh::model::occ::addPoint(p[0], p[1], 0.0));
    for (size_t i = 0; i < points.size(); ++i)
      lines.push_back(gmsh::model::occ::addLine(points[i], points[(i + 1) % points.size()]));
    gmsh::model::occ::addPlaneSurface({gmsh::model::occ::addCurveLoop(lines)});
  } else {
    gmsh::model::occ::addSphere(s.center[0], s.center[1], s.center[2], s.radius);
  }
  gmsh::model::occ::synchronize();
  if (s.type == "box" && (body.structured || centres)) make_structured(body.spacing);
  gmsh::model::mesh::generate(dim);
  return session.extract_mesh(context);
}

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

}  // namespace

template <int Dim>
BuiltScene<Dim> build_scene(const Scene& scene) {
  if (scene.dim != Dim)
    throw InputError(scene.file + ": scene is " + std::to_string(scene.dim) + "D");
  check_scene_size(scene);
  BuiltScene<Dim> built;
  const BackgroundSpec& bs = scene.background;
  const std::string bg_context = scene.file + ": background";
  if (scene.solver.kernel == KernelType::kBspline) {
    built.background =
        make_lattice<Dim>(Eigen::Map<const Vec<Dim>>(bs.min.data()),
                          Eigen::Map<const Vec<Dim>>(bs.max.data()), bs.element_size, 2);
  } else {
    const Mesh mesh = bs.type == "mesh"   ? read_mesh(bs.path)
                      : bs.type == "ball" ? mesh_ball_background(bs, Dim, bg_context)
                                          : mesh_box_background(bs, Dim, bg_context);
    // Zero-volume or inverted cells break the kernel and the cell walk: refused, not warned.
    if (bs.type == "mesh") refuse_bad_cells(mesh, bs.path, scene.file + ": key 'background.path'");
    built.background = make_background<Dim>(mesh, bs.extra_layer, bg_context, bs.kernel_width);
  }
  const BackgroundMesh<Dim>& bg = built.background;

  for (size_t b = 0; b < scene.bodies.size(); ++b) {
    const BodySpec& body = scene.bodies[b];
    const std::string context = scene.file + ": body '" + body.name + "'";
    Mesh mesh = mesh_body(body, Dim, context);
    if (body.shape.type == "mesh")
      refuse_bad_cells(mesh, body.shape.path,
                       scene.file + ": key 'bodies." + std::to_string(b) + ".shape.path'");
    if (mesh.dim > Dim || mesh.cell_dim != Dim)
      throw InputError(context + ": body mesh must have " + std::to_string(Dim) + "D simplices");
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
    built.body_meshes.push_back(std::move(mesh));
  }

  const double tol = 1e-9 * bg.h;
  // A constraint on `node`; a ghost (node beyond the wall) when its mirror point differs.
  auto constrain = [&](int32_t node, BoundaryType type, const Vec<Dim>& normal,
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
    built.constraints.push_back(c);
  };
  for (size_t i = 0; i < scene.boundaries.size(); ++i) {
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
        constrain(group.nodes[k], s.type, group.normals[k], group.mirrors[k]);
    } else {
      const Vec<Dim> point = Eigen::Map<const Vec<Dim>>(s.point.data());
      const Vec<Dim> normal = Eigen::Map<const Vec<Dim>>(s.normal.data()).normalized();
      for (int32_t v = 0; v < bg.num_nodes(); ++v) {
        const double depth = (bg.points[v] - point).dot(normal);
        // A half-space need not follow mesh faces: its nodes are constrained directly.
        if (depth >= -tol) constrain(v, s.type, normal, bg.points[v]);
      }
    }
  }

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
