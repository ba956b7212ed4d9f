#include "data/mpm/scene_config.hpp"

#include <cmath>
#include <filesystem>

#include "core/error.hpp"

namespace bsms::mpm {

namespace {

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
  m.viscosity = r.opt<double>("viscosity", 0.0);
  require(std::isfinite(m.viscosity) && m.viscosity >= 0.0, r.context("viscosity"),
          ">= 0 (Pa s, Kelvin-Voigt damping)");
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

// Resolves a path relative to the scene file's folder.
std::string scene_relative(const std::string& path, const std::string& base_dir) {
  if (!std::filesystem::path(path).is_relative()) return path;
  return (std::filesystem::path(base_dir) / path).string();
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
    s.path = scene_relative(r.get<std::string>("path"), base_dir);
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

// The "box" keys of a background (all but type and the keys shared by every type).
void parse_box_background(JsonObjectReader& b, int dim, BackgroundSpec& bg) {
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
}

BackgroundSpec parse_background(const Json& j, const JsonContext& ctx, int dim,
                                const std::string& base_dir) {
  JsonObjectReader b(j, ctx);
  BackgroundSpec bg;
  bg.type = b.get<std::string>("type");
  if (bg.type == "mesh") {
    bg.path = b.get<std::string>("path");
    require(!bg.path.empty(), b.context("path"), "a mesh file path");
    bg.path = scene_relative(bg.path, base_dir);
  } else if (bg.type == "box") {
    parse_box_background(b, dim, bg);
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
  return bg;
}

// Body i of the "bodies" list.
BodySpec parse_body(const Json& j, const JsonContext& ctx, size_t i, int dim,
                    const std::string& base_dir) {
  JsonObjectReader b(j, ctx);
  BodySpec body;
  body.name = b.opt<std::string>("name", "body" + std::to_string(i));
  body.shape = parse_shape(b.raw("shape"), b.context("shape"), dim, base_dir);
  body.spacing =
      body.shape.type == "mesh" ? b.opt<double>("spacing", 1.0) : b.get<double>("spacing");
  require(body.spacing > 0.0, b.context("spacing"), "> 0 (m)");
  body.structured = b.opt<bool>("structured", true);
  body.sampling = b.opt<std::string>("sampling", "nodes");
  require(body.sampling == "nodes" || (body.sampling == "cell_centres" && body.shape.type == "box"),
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
  return body;
}

std::vector<BodySpec> parse_bodies(JsonObjectReader& r, int dim, const std::string& base_dir) {
  const Json& bodies = r.raw("bodies");
  if (!bodies.is_array() || bodies.empty())
    throw InputError(r.context("bodies").where() + " must be a non-empty list");
  std::vector<BodySpec> out;
  for (size_t i = 0; i < bodies.size(); ++i)
    out.push_back(
        parse_body(bodies[i], r.context("bodies").child(std::to_string(i)), i, dim, base_dir));
  return out;
}

// A boundary: a background node group, or a half-space given by a point and an outward normal.
BoundarySpec parse_boundary(const Json& j, const JsonContext& ctx, int dim) {
  JsonObjectReader b(j, ctx);
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
  return s;
}

std::vector<BoundarySpec> parse_boundaries(JsonObjectReader& r, int dim) {
  std::vector<BoundarySpec> out;
  if (!r.has("boundaries")) {
    r.opt<Json>("boundaries", Json());
    return out;
  }
  const Json& list = r.raw("boundaries");
  if (!list.is_array()) throw InputError(r.context("boundaries").where() + " must be a list");
  for (size_t i = 0; i < list.size(); ++i)
    out.push_back(parse_boundary(list[i], r.context("boundaries").child(std::to_string(i)), dim));
  return out;
}

// The solver settings, checked against the background they run on.
SolverSpec parse_solver(const Json& j, const JsonContext& ctx, const BackgroundSpec& background,
                        const std::string& file) {
  JsonObjectReader s(j, ctx);
  SolverSpec sv;
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
  if (sv.kernel == KernelType::kBspline && background.type != "box")
    throw InputError(file + ": key 'solver.kernel': bspline needs a box background");
  if (sv.kernel == KernelType::kBspline && background.rotation_deg != 0.0)
    throw InputError(file + ": key 'solver.kernel': bspline needs an unrotated box background");
  if (sv.kernel == KernelType::kBspline && background.kernel_width > 0.0)
    throw InputError(file + ": key 'background.kernel_width': bspline's lattice spacing is " +
                     "background.element_size; kernel_width is for simplicial backgrounds");
  return sv;
}

// The optional "output" object (defaults when absent).
OutputSpec parse_output(JsonObjectReader& r) {
  OutputSpec out;
  if (!r.has("output")) {
    r.opt<Json>("output", Json());
    return out;
  }
  JsonObjectReader o(r.raw("output"), r.context("output"));
  out.frames = o.opt<int>("frames", 101);
  require(out.frames >= 2, o.context("frames"), ">= 2");
  out.fields = o.opt<std::vector<std::string>>("fields", out.fields);
  for (const auto& f : out.fields)
    require(f == "velocity" || f == "stress" || f == "plastic_strain", o.context("fields"),
            "a list of velocity, stress, plastic_strain (got '" + f + "')");
  o.finish();
  return out;
}

// A scene; with `base`, a family's base scene (parse_base_scene). One reader for both, so that
// every key has one default.
Scene parse_scene_object(const Json& json, const JsonContext& where, bool base) {
  const std::string& file = where.file;
  Scene scene;
  scene.file = file;
  scene.source = json;
  const std::string base_dir = std::filesystem::path(file).parent_path().string();
  JsonObjectReader r(json, where);
  scene.dim = r.get<int>("dim");
  require(scene.dim == 2 || scene.dim == 3, r.context("dim"), "2 or 3");
  const int dim = scene.dim;
  scene.background = parse_background(r.raw("background"), r.context("background"), dim, base_dir);
  // A family's draws bring their own bodies (FamilyBase::finish): its base scene may have none.
  if (!base || (r.has("bodies") && r.raw("bodies") != Json::array()))
    scene.bodies = parse_bodies(r, dim, base_dir);
  scene.boundaries = parse_boundaries(r, dim);
  scene.gravity = r.has("gravity") ? read_vector(r, "gravity", dim) : std::vector<double>(dim, 0.0);
  if (!r.has("gravity")) r.opt<Json>("gravity", Json());
  scene.solver = parse_solver(r.raw("solver"), r.context("solver"), scene.background, file);
  scene.output = parse_output(r);
  r.finish();
  return scene;
}

}  // namespace

Scene parse_scene(const Json& json, const std::string& file) {
  return parse_scene_object(json, JsonContext{file, ""}, false);
}

Scene parse_base_scene(const Json& json, const JsonContext& where) {
  return parse_scene_object(json, where, true);
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  Json json = load_json_file(path);
  for (const auto& o : overrides) apply_override(json, o, path);
  return parse_scene(json, path);
}

}  // namespace bsms::mpm
