#include "data/generate/family.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "data/mpm/scene.hpp"

namespace bsms::generate {

namespace {

constexpr double kPi = 3.14159265358979323846;

// ---- strict readers for ranges -----------------------------------------------------------------

// A number (fixed) or [min, max]. `positive`: both ends must be > 0 (sizes, moduli, densities);
// `non_negative`: ≥ 0 (speeds, gaps).
enum class Sign { kAny, kNonNegative, kPositive };

Range range_from(const Json& j, const JsonContext& ctx, Sign sign) {
  Range r;
  if (j.is_number()) {
    r.min = r.max = j.get<double>();
  } else if (j.is_array() && j.size() == 2 && j[0].is_number() && j[1].is_number()) {
    r.min = j[0].get<double>();
    r.max = j[1].get<double>();
  } else {
    throw InputError(ctx.where() + " must be a number or [min, max], got " + j.dump());
  }
  require(std::isfinite(r.min) && std::isfinite(r.max), ctx, "finite");
  if (r.min > r.max) {
    std::ostringstream s;
    s << ctx.where() << ": min " << r.min << " > max " << r.max;
    throw InputError(s.str());
  }
  if (sign == Sign::kPositive) require(r.min > 0.0, ctx, "positive (a size, modulus or density)");
  if (sign == Sign::kNonNegative) require(r.min >= 0.0, ctx, "non-negative");
  return r;
}

Range read_range(JsonObjectReader& r, const std::string& key, Sign sign) {
  return range_from(r.raw(key), r.context(key), sign);
}

struct IntRange {
  int64_t min = 0, max = 0;
};

IntRange read_int_range(JsonObjectReader& r, const std::string& key, int64_t lowest) {
  const Json& j = r.raw(key);
  const JsonContext ctx = r.context(key);
  IntRange out;
  if (j.is_number_integer()) {
    out.min = out.max = j.get<int64_t>();
  } else if (j.is_array() && j.size() == 2 && j[0].is_number_integer() &&
             j[1].is_number_integer()) {
    out.min = j[0].get<int64_t>();
    out.max = j[1].get<int64_t>();
  } else {
    throw InputError(ctx.where() + " must be an integer or [min, max] of integers, got " +
                     j.dump());
  }
  if (out.min > out.max)
    throw InputError(ctx.where() + ": min " + std::to_string(out.min) + " > max " +
                     std::to_string(out.max));
  require(out.min >= lowest, ctx, "at least " + std::to_string(lowest));
  return out;
}

// Per-component ranges of a vector, e.g. gravity [[0, 0], [-9.81, -1]].
std::vector<Range> read_vector_range(JsonObjectReader& r, const std::string& key, int dim) {
  const Json& j = r.raw(key);
  const JsonContext ctx = r.context(key);
  if (!j.is_array() || static_cast<int>(j.size()) != dim)
    throw InputError(ctx.where() + " must hold " + std::to_string(dim) +
                     " components, each a number or [min, max]");
  std::vector<Range> out;
  for (int a = 0; a < dim; ++a)
    out.push_back(range_from(j[a], ctx.child(std::to_string(a)), Sign::kAny));
  return out;
}

std::vector<double> sample_vector(const std::vector<Range>& ranges, Rng& rng) {
  std::vector<double> v;
  for (const Range& r : ranges) v.push_back(r.sample(rng));
  return v;
}

// A material with a range per numeric parameter; string parameters (the model) are copied.
struct MaterialRange {
  std::vector<std::pair<std::string, std::string>> strings;
  std::vector<std::pair<std::string, Range>> numbers;
  Json sample(Rng& rng) const {
    Json m = Json::object();
    for (const auto& [k, v] : strings) m[k] = v;
    for (const auto& [k, v] : numbers) m[k] = v.sample(rng);
    return m;
  }
};

MaterialRange read_material(JsonObjectReader& r, const std::string& key) {
  const Json& j = r.raw(key);
  const JsonContext ctx = r.context(key);
  if (!j.is_object()) throw InputError(ctx.where() + " must be an object");
  if (!j.contains("model"))
    throw InputError(ctx.file + ": missing required key '" + ctx.child("model").path + "'");
  MaterialRange m;
  for (const auto& [k, v] : j.items()) {
    if (v.is_string()) {
      m.strings.emplace_back(k, v.get<std::string>());
      continue;
    }
    const bool positive = k == "youngs_modulus" || k == "density";
    m.numbers.emplace_back(k, range_from(v, ctx.child(k), positive ? Sign::kPositive : Sign::kAny));
  }
  return m;
}

// The background box of the base scene, m [dim] each.
void background_box(const Json& scene, const std::string& file, int dim, std::vector<double>& lo,
                    std::vector<double>& hi) {
  const JsonContext ctx{file, "scene.background"};
  if (!scene.contains("background") || !scene["background"].is_object() ||
      scene["background"].value("type", "") != "box")
    throw InputError(ctx.where() + " must be a box background (the samplers place bodies in it)");
  try {
    lo = scene["background"].at("min").get<std::vector<double>>();
    hi = scene["background"].at("max").get<std::vector<double>>();
  } catch (const nlohmann::json::exception&) {
    throw InputError(ctx.where() + " needs numeric 'min' and 'max' corners");
  }
  // The samplers index the corners by axis: a short corner must not be read past its end.
  if (static_cast<int>(lo.size()) != dim || static_cast<int>(hi.size()) != dim)
    throw InputError(ctx.where() + ": 'min' and 'max' must hold " + std::to_string(dim) +
                     " numbers (scene.dim)");
}

Json uniform_velocity(const std::vector<double>& v) {
  return {{"type", "uniform"}, {"value", v}};
}

// Shared parts of a sampler: the base scene and the timing/output settings.
struct FamilyBase {
  Json base;
  std::string file;
  int dim = 2;
  int frames = 0;
  double frame_dt = 0.0;
  std::vector<std::string> fields;

  Json finish(Json bodies, Json boundaries, const std::vector<double>& gravity) const {
    Json s = base;
    s["bodies"] = std::move(bodies);
    if (!boundaries.empty()) {
      Json all = s.contains("boundaries") ? s["boundaries"] : Json::array();
      for (auto& b : boundaries) all.push_back(b);
      s["boundaries"] = all;
    }
    if (!gravity.empty()) s["gravity"] = gravity;
    s["solver"]["end_time"] = frame_dt * (frames - 1);
    s["output"] = {{"frames", frames}, {"fields", fields}};
    return s;
  }
};

// ---- disks: 2–4 elastic disks of random size and velocity colliding in a box ----------------

class DisksSampler : public SceneSampler {
 public:
  DisksSampler(FamilyBase base, JsonObjectReader& r) : base_(std::move(base)) {
    count_ = read_int_range(r, "count", 1);
    radius_ = read_range(r, "radius", Sign::kPositive);
    spacing_ = read_range(r, "spacing", Sign::kPositive);
    speed_ = read_range(r, "speed", Sign::kNonNegative);
    gap_ = r.opt<double>("gap", 0.01);
    require(gap_ >= 0.0, r.context("gap"), "non-negative");
    aim_jitter_deg_ = r.opt<double>("aim_jitter_deg", 45.0);
    require(aim_jitter_deg_ >= 0.0 && aim_jitter_deg_ <= 180.0, r.context("aim_jitter_deg"),
            "in [0, 180]");
    material_ = read_material(r, "material");
    if (r.has("gravity")) gravity_ = read_vector_range(r, "gravity", base_.dim);
    background_box(base_.base, base_.file, base_.dim, lo_, hi_);
    require(base_.dim == 2, JsonContext{base_.file, "scene.dim"}, "2 (disks are 2D)");
    for (int a = 0; a < 2; ++a)
      if (lo_[a] + 2.0 * (radius_.max + gap_) > hi_[a])
        throw InputError(r.context("radius").where() + ": a disk of radius " +
                         std::to_string(radius_.max) + " does not fit in the background box");
  }

  SampledScene sample(Rng& rng, const std::string&) const override {
    const int64_t n = rng.integer(count_.min, count_.max);
    std::vector<std::array<double, 3>> disks;  // x, y, r
    // Seeded rejection sampling: whole sets are redrawn when one disk finds no free place.
    for (int set = 0; set < 200 && static_cast<int64_t>(disks.size()) < n; ++set) {
      disks.clear();
      for (int64_t i = 0; i < n; ++i) {
        const double r = radius_.sample(rng);
        bool placed = false;
        for (int attempt = 0; attempt < 200 && !placed; ++attempt) {
          const double x = rng.uniform(lo_[0] + r + gap_, hi_[0] - r - gap_);
          const double y = rng.uniform(lo_[1] + r + gap_, hi_[1] - r - gap_);
          placed = std::all_of(disks.begin(), disks.end(), [&](const auto& d) {
            return std::hypot(d[0] - x, d[1] - y) >= d[2] + r + gap_;
          });
          if (placed) disks.push_back({x, y, r});
        }
        if (!placed) break;
      }
    }
    if (static_cast<int64_t>(disks.size()) < n)
      throw InputError(base_.file + ": key 'sample.count': cannot place " + std::to_string(n) +
                       " disks without overlap in the background box (reduce count or radius)");
    const double cx = 0.5 * (lo_[0] + hi_[0]), cy = 0.5 * (lo_[1] + hi_[1]);
    Json bodies = Json::array(), params = Json::array();
    for (size_t i = 0; i < disks.size(); ++i) {
      const auto& [x, y, r] = disks[i];
      // Aim at the box centre (give or take the jitter) so that disks meet: contact-rich data.
      const double jitter = aim_jitter_deg_ * kPi / 180.0 * (2.0 * rng.uniform() - 1.0);
      const double aim = std::atan2(cy - y, cx - x) + jitter;
      const double speed = speed_.sample(rng);
      const std::vector<double> v = {speed * std::cos(aim), speed * std::sin(aim)};
      const double spacing = spacing_.sample(rng);
      const Json material = material_.sample(rng);
      bodies.push_back({{"name", "disk" + std::to_string(i)},
                        {"shape", {{"type", "disk"}, {"center", {x, y}}, {"radius", r}}},
                        {"spacing", spacing},
                        {"material", material},
                        {"velocity", uniform_velocity(v)}});
      params.push_back({{"center", {x, y}},
                        {"radius", r},
                        {"velocity", v},
                        {"spacing", spacing},
                        {"material", material}});
    }
    SampledScene out;
    const std::vector<double> g = sample_vector(gravity_, rng);
    out.scene = base_.finish(bodies, Json::array(), g);
    out.parameters = {{"disks", params}};
    if (!g.empty()) out.parameters["gravity"] = g;
    return out;
  }

 private:
  FamilyBase base_;
  IntRange count_;
  Range radius_, spacing_, speed_;
  double gap_ = 0.0, aim_jitter_deg_ = 0.0;
  MaterialRange material_;
  std::vector<Range> gravity_;
  std::vector<double> lo_, hi_;
};

// ---- press: a stiff, heavy actuator pressing into an elastic plate clamped at y = 0 ----------
// The solver has no prescribed-velocity bodies, so the actuator is a disk 100s of times heavier
// and stiffer than the plate: its velocity stays nearly constant while it indents the plate.

class PressSampler : public SceneSampler {
 public:
  PressSampler(FamilyBase base, JsonObjectReader& r) : base_(std::move(base)) {
    require(base_.dim == 2, JsonContext{base_.file, "scene.dim"}, "2");
    plate_width_ = read_range(r, "plate_width", Sign::kPositive);
    plate_thickness_ = read_range(r, "plate_thickness", Sign::kPositive);
    plate_spacing_ = read_range(r, "plate_spacing", Sign::kPositive);
    plate_material_ = read_material(r, "plate_material");
    radius_ = read_range(r, "actuator_radius", Sign::kPositive);
    actuator_spacing_ = read_range(r, "actuator_spacing", Sign::kPositive);
    speed_ = read_range(r, "actuator_speed", Sign::kNonNegative);
    offset_ = read_range(r, "actuator_offset", Sign::kAny);
    gap_ = r.opt<double>("actuator_gap", 0.01);
    require(gap_ >= 0.0, r.context("actuator_gap"), "non-negative");
    actuator_material_ = read_material(r, "actuator_material");
    background_box(base_.base, base_.file, base_.dim, lo_, hi_);
    require(lo_[1] < 0.0, JsonContext{base_.file, "scene.background.min"},
            "below y = 0 (the plate is clamped at y = 0)");
  }

  SampledScene sample(Rng& rng, const std::string&) const override {
    const double w = plate_width_.sample(rng), t = plate_thickness_.sample(rng);
    const double cx = 0.5 * (lo_[0] + hi_[0]);
    const double r = radius_.sample(rng), offset = offset_.sample(rng);
    const double ax = cx + offset * 0.5 * w, ay = t + gap_ + r;
    const double speed = speed_.sample(rng);
    const double plate_spacing = plate_spacing_.sample(rng);
    const double actuator_spacing = actuator_spacing_.sample(rng);
    const Json plate_mat = plate_material_.sample(rng), act_mat = actuator_material_.sample(rng);
    Json bodies = Json::array();
    bodies.push_back(
        {{"name", "plate"},
         {"shape", {{"type", "box"}, {"min", {cx - 0.5 * w, 0.0}}, {"max", {cx + 0.5 * w, t}}}},
         {"spacing", plate_spacing},
         {"material", plate_mat}});
    bodies.push_back({{"name", "actuator"},
                      {"shape", {{"type", "disk"}, {"center", {ax, ay}}, {"radius", r}}},
                      {"spacing", actuator_spacing},
                      {"material", act_mat},
                      {"velocity", uniform_velocity({0.0, -speed})}});
    Json clamp = Json::array({{{"point", {0.0, 0.0}}, {"normal", {0.0, -1.0}}, {"type", "fixed"}}});
    SampledScene out;
    out.scene = base_.finish(bodies, clamp, {});
    out.parameters = {
        {"plate",
         {{"width", w}, {"thickness", t}, {"spacing", plate_spacing}, {"material", plate_mat}}},
        {"actuator",
         {{"center", {ax, ay}},
          {"radius", r},
          {"speed", speed},
          {"spacing", actuator_spacing},
          {"material", act_mat}}}};
    out.fixed.push_back({{0.0, 0.0}, {0.0, -1.0}, 1e-9});
    out.actuator_bodies.push_back(1);
    return out;
  }

 private:
  FamilyBase base_;
  Range plate_width_, plate_thickness_, plate_spacing_, radius_, actuator_spacing_, speed_, offset_;
  double gap_ = 0.0;
  MaterialRange plate_material_, actuator_material_;
  std::vector<double> lo_, hi_;
};

// ---- cantilever: a beam clamped at x = 0 under a random load (body force) and material ------

class CantileverSampler : public SceneSampler {
 public:
  CantileverSampler(FamilyBase base, JsonObjectReader& r) : base_(std::move(base)) {
    require(base_.dim == 2, JsonContext{base_.file, "scene.dim"}, "2");
    length_ = read_range(r, "length", Sign::kPositive);
    thickness_ = read_range(r, "thickness", Sign::kPositive);
    spacing_ = read_range(r, "spacing", Sign::kPositive);
    material_ = read_material(r, "material");
    load_ = read_range(r, "load", Sign::kNonNegative);
    angle_ = read_range(r, "load_angle_deg", Sign::kAny);
    background_box(base_.base, base_.file, base_.dim, lo_, hi_);
    require(lo_[0] < 0.0, JsonContext{base_.file, "scene.background.min"},
            "left of x = 0 (the beam is clamped at x = 0)");
  }

  SampledScene sample(Rng& rng, const std::string&) const override {
    const double length = length_.sample(rng), t = thickness_.sample(rng);
    const double spacing = spacing_.sample(rng);
    const Json material = material_.sample(rng);
    const double load = load_.sample(rng), angle = angle_.sample(rng);
    // Load as a body force (m/s²): angle 0 points down (−y), positive angles turn towards +x.
    const std::vector<double> g = {load * std::sin(angle * kPi / 180.0),
                                   -load * std::cos(angle * kPi / 180.0)};
    Json bodies = Json::array();
    bodies.push_back(
        {{"name", "beam"},
         {"shape", {{"type", "box"}, {"min", {0.0, -0.5 * t}}, {"max", {length, 0.5 * t}}}},
         {"spacing", spacing},
         {"material", material}});
    Json clamp = Json::array({{{"point", {0.0, 0.0}}, {"normal", {-1.0, 0.0}}, {"type", "fixed"}}});
    SampledScene out;
    out.scene = base_.finish(bodies, clamp, g);
    out.parameters = {{"length", length},     {"thickness", t}, {"spacing", spacing},
                      {"material", material}, {"load", load},   {"load_angle_deg", angle},
                      {"gravity", g}};
    out.fixed.push_back({{0.0, 0.0}, {-1.0, 0.0}, 1e-9});
    return out;
  }

 private:
  FamilyBase base_;
  Range length_, thickness_, spacing_, load_, angle_;
  MaterialRange material_;
  std::vector<double> lo_, hi_;
};

// ---- union: a gmsh boolean union of random shapes dropped onto the floor ---------------------
// A U of two arms separated by a narrow gap, with random disks fused to the arms' outer sides and
// a random rotation: nodes across the gap are close in space but far along the mesh.

class UnionSampler : public SceneSampler {
 public:
  UnionSampler(FamilyBase base, JsonObjectReader& r) : base_(std::move(base)) {
    require(base_.dim == 2, JsonContext{base_.file, "scene.dim"}, "2");
    arm_length_ = read_range(r, "arm_length", Sign::kPositive);
    arm_width_ = read_range(r, "arm_width", Sign::kPositive);
    gap_ = read_range(r, "gap", Sign::kPositive);
    base_height_ = read_range(r, "base_height", Sign::kPositive);
    disks_ = read_int_range(r, "disks", 0);
    disk_radius_ = read_range(r, "disk_radius", Sign::kPositive);
    rotation_ = read_range(r, "rotation_deg", Sign::kAny);
    spacing_ = read_range(r, "spacing", Sign::kPositive);
    speed_ = read_range(r, "speed", Sign::kNonNegative);
    clearance_ = r.opt<double>("clearance", 0.02);
    require(clearance_ >= 0.0, r.context("clearance"), "non-negative");
    material_ = read_material(r, "material");
    if (r.has("gravity")) gravity_ = read_vector_range(r, "gravity", base_.dim);
    background_box(base_.base, base_.file, base_.dim, lo_, hi_);
  }

  SampledScene sample(Rng& rng, const std::string& work_prefix) const override {
    const double a = arm_width_.sample(rng), g = gap_.sample(rng), len = arm_length_.sample(rng);
    const double b = base_height_.sample(rng), s = spacing_.sample(rng);
    struct Shape {
      bool disk;
      double x, y, w, h;  // rectangle corner and size, or disk centre and radius (w)
    };
    std::vector<Shape> shapes = {{false, 0.0, 0.0, 2.0 * a + g, b},
                                 {false, 0.0, b * 0.5, a, 0.5 * b + len},
                                 {false, a + g, b * 0.5, a, 0.5 * b + len}};
    const int64_t n = rng.integer(disks_.min, disks_.max);
    for (int64_t i = 0; i < n; ++i) {
      const bool right = rng.uniform() < 0.5;
      const double r = disk_radius_.sample(rng);
      const double y = rng.uniform(b, b + len);
      shapes.push_back({true, right ? 2.0 * a + g : 0.0, y, r, 0.0});
    }
    const double angle = rotation_.sample(rng);
    // Bounding box of the rotated shape (rotation about the local origin), from shape corners.
    const double c = std::cos(angle * kPi / 180.0), sn = std::sin(angle * kPi / 180.0);
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const Shape& sh : shapes) {
      const double lx = sh.disk ? sh.x - sh.w : sh.x, hx = sh.disk ? sh.x + sh.w : sh.x + sh.w;
      const double ly = sh.disk ? sh.y - sh.w : sh.y, hy = sh.disk ? sh.y + sh.w : sh.y + sh.h;
      for (double px : {lx, hx})
        for (double py : {ly, hy}) {
          const double rx = c * px - sn * py, ry = sn * px + c * py;
          x0 = std::min(x0, rx), x1 = std::max(x1, rx), y0 = std::min(y0, ry),
          y1 = std::max(y1, ry);
        }
    }
    const double room_x = (hi_[0] - lo_[0]) - (x1 - x0) - 2.0 * clearance_;
    const double room_y = (hi_[1] - lo_[1]) - (y1 - y0) - 2.0 * clearance_;
    if (room_x < 0.0 || room_y < 0.0)
      throw InputError(base_.file +
                       ": key 'sample.arm_length': the union shape does not fit in "
                       "the background box");
    const double dx = lo_[0] + clearance_ + rng.uniform(0.0, room_x) - x0;
    const double dy = lo_[1] + clearance_ + rng.uniform(0.0, room_y) - y0;
    std::ostringstream geo;
    geo.precision(17);
    geo << "SetFactory(\"OpenCASCADE\");\n"
        << "Mesh.MeshSizeMin = " << s << ";\nMesh.MeshSizeMax = " << s << ";\n"
        << "Mesh.MeshSizeFromPoints = 0;\nMesh.MeshSizeFromCurvature = 0;\n"
        << "Mesh.MeshSizeExtendFromBoundary = 0;\nMesh.Algorithm = 5;\nMesh.RandomSeed = 1;\n";
    for (size_t i = 0; i < shapes.size(); ++i) {
      const Shape& sh = shapes[i];
      if (sh.disk)
        geo << "Disk(" << i + 1 << ") = {" << sh.x << ", " << sh.y << ", 0, " << sh.w << ", "
            << sh.w << "};\n";
      else
        geo << "Rectangle(" << i + 1 << ") = {" << sh.x << ", " << sh.y << ", 0, " << sh.w << ", "
            << sh.h << "};\n";
    }
    geo << "BooleanUnion(100) = { Surface{1}; Delete; }{ Surface{2:" << shapes.size()
        << "}; Delete; };\n"
        << "Rotate {{0, 0, 1}, {0, 0, 0}, " << angle * kPi / 180.0 << "} { Surface{100}; }\n"
        << "Translate {" << dx << ", " << dy << ", 0} { Surface{100}; }\n";
    const std::string path = work_prefix + ".geo";
    {
      std::ofstream f(path);
      f << geo.str();
      if (!f) throw IoError(path + ": cannot write the union geometry");
    }
    const double speed = speed_.sample(rng);
    const double dir = rng.uniform(0.0, 2.0 * kPi);
    const std::vector<double> v = {speed * std::cos(dir), speed * std::sin(dir)};
    const Json material = material_.sample(rng);
    const std::vector<double> gravity = sample_vector(gravity_, rng);
    Json bodies = Json::array();
    bodies.push_back({{"name", "union"},
                      {"shape", {{"type", "mesh"}, {"path", path}}},
                      {"spacing", s},
                      {"material", material},
                      {"velocity", uniform_velocity(v)}});
    SampledScene out;
    out.scene = base_.finish(bodies, Json::array(), gravity);
    out.parameters = {{"geometry_geo", geo.str()}, {"arm_width", a},   {"gap", g},
                      {"arm_length", len},         {"base_height", b}, {"disks", n},
                      {"rotation_deg", angle},     {"spacing", s},     {"velocity", v},
                      {"material", material}};
    if (!gravity.empty()) out.parameters["gravity"] = gravity;
    out.work_files.push_back(path);
    return out;
  }

 private:
  FamilyBase base_;
  Range arm_length_, arm_width_, gap_, base_height_, disk_radius_, rotation_, spacing_, speed_;
  IntRange disks_;
  double clearance_ = 0.0;
  MaterialRange material_;
  std::vector<Range> gravity_;
  std::vector<double> lo_, hi_;
};

}  // namespace

uint64_t Rng::next() {
  const uint64_t out = splitmix64(state_);  // the SplitMix64 sequence of core/hash.hpp
  state_ += kSplitMix64Increment;
  return out;
}

double Rng::uniform() {
  return static_cast<double>(next() >> 11) * 0x1.0p-53;
}

double Rng::uniform(double lo, double hi) {
  return lo == hi ? lo : lo + (hi - lo) * uniform();
}

int64_t Rng::integer(int64_t lo, int64_t hi) {
  const uint64_t span = static_cast<uint64_t>(hi - lo) + 1;
  return lo + static_cast<int64_t>(next() % span);  // bias is negligible for small spans
}

int64_t trajectory_seed(int64_t seed, int64_t index, int attempt) {
  uint64_t h = splitmix64(static_cast<uint64_t>(seed));
  h = splitmix64(h ^ static_cast<uint64_t>(index));
  h = splitmix64(h ^ static_cast<uint64_t>(attempt));
  return static_cast<int64_t>(h >> 1);
}

FamilyConfig parse_family(const Json& json, const std::string& file) {
  if (!json.is_object()) throw InputError(file + ": a family config must be a JSON object");
  FamilyConfig config;
  config.file = file;
  config.source = json;
  JsonObjectReader r(json, JsonContext{file, ""});
  config.family = r.get<std::string>("family");
  r.opt<std::string>("description", "");
  FamilyBase common;
  common.file = file;
  common.base = r.raw("scene");
  if (!common.base.is_object()) throw InputError(r.context("scene").where() + " must be an object");
  if (!common.base.contains("bodies")) common.base["bodies"] = Json::array();
  if (!common.base.contains("dim") || !common.base["dim"].is_number_integer())
    throw InputError(file + ": missing required key 'scene.dim'");
  config.dim = common.dim = common.base["dim"].get<int>();
  config.frames = common.frames = r.get<int>("frames");
  require(config.frames >= 2, r.context("frames"), "at least 2");
  config.frame_dt = common.frame_dt = r.get<double>("frame_dt");
  require(config.frame_dt > 0.0, r.context("frame_dt"), "positive (seconds)");
  config.fields = common.fields = r.opt<std::vector<std::string>>("fields", {"velocity"});
  for (const auto& f : config.fields)
    require(f == "velocity" || f == "stress", r.context("fields"),
            "a list of 'velocity' and 'stress' (world_pos is always stored), got '" + f + "'");
  JsonObjectReader s(r.raw("sample"), r.context("sample"));
  if (config.family == "disks") {
    config.sampler = std::make_shared<DisksSampler>(common, s);
  } else if (config.family == "press") {
    config.sampler = std::make_shared<PressSampler>(common, s);
  } else if (config.family == "cantilever") {
    config.sampler = std::make_shared<CantileverSampler>(common, s);
  } else if (config.family == "union") {
    config.sampler = std::make_shared<UnionSampler>(common, s);
  } else {
    throw InputError(r.context("family").where() + ": unknown family '" + config.family +
                     "' (allowed: disks, press, cantilever, union)");
  }
  s.finish();
  r.finish();
  // Check the base scene and the materials: the scene parser sees one draw (no meshing).
  if (config.family != "union") {
    Rng rng(static_cast<uint64_t>(trajectory_seed(0, 0, 0)));
    const SampledScene draw = config.sampler->sample(rng, "");
    mpm::parse_scene(draw.scene, file + " (scene drawn from 'sample')");
  }
  return config;
}

FamilyConfig load_family(const std::string& path, const std::vector<std::string>& overrides) {
  Json json = load_json_file(path);
  for (const auto& o : overrides) apply_override(json, o, path);
  return parse_family(json, path);
}

}  // namespace bsms::generate
