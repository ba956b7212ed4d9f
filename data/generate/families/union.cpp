// Union: a gmsh boolean union of random shapes dropped onto the floor.
// A U of two arms separated by a narrow gap, with random disks fused to the arms' outer sides and
// a random rotation: nodes across the gap are close in space but far along the mesh.
#include "data/generate/families/samplers.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>
#include <utility>

#include "core/error.hpp"
#include "data/generate/families/ranges.hpp"

namespace bsms::generate::families {

namespace {

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

std::shared_ptr<const SceneSampler> make_union_sampler(FamilyBase base, JsonObjectReader& r) {
  return std::make_shared<UnionSampler>(std::move(base), r);
}

}  // namespace bsms::generate::families
