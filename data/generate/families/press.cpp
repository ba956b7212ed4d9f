// Press: a stiff, heavy actuator pressing into an elastic plate clamped at y = 0.
// The solver has no prescribed-velocity bodies, so the actuator is a disk 100s of times heavier
// and stiffer than the plate: its velocity stays nearly constant while it indents the plate.
#include "data/generate/families/samplers.hpp"

#include <memory>
#include <utility>

#include "core/error.hpp"
#include "data/generate/families/ranges.hpp"

namespace bsms::generate::families {

namespace {

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

}  // namespace

std::shared_ptr<const SceneSampler> make_press_sampler(FamilyBase base, JsonObjectReader& r) {
  return std::make_shared<PressSampler>(std::move(base), r);
}

}  // namespace bsms::generate::families
