// Cantilever: a beam clamped at x = 0 under a random load (body force) and material.
#include "data/generate/families/samplers.hpp"

#include <cmath>
#include <memory>
#include <utility>

#include "core/error.hpp"
#include "data/generate/families/ranges.hpp"

namespace bsms::generate::families {

namespace {

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

}  // namespace

std::shared_ptr<const SceneSampler> make_cantilever_sampler(FamilyBase base, JsonObjectReader& r) {
  return std::make_shared<CantileverSampler>(std::move(base), r);
}

}  // namespace bsms::generate::families
