// Disks: 2–4 elastic disks of random size and velocity colliding in a box.
#include "data/generate/families/samplers.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <utility>

#include "core/error.hpp"
#include "data/generate/families/ranges.hpp"

namespace bsms::generate::families {

namespace {

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

}  // namespace

std::shared_ptr<const SceneSampler> make_disks_sampler(FamilyBase base, JsonObjectReader& r) {
  return std::make_shared<DisksSampler>(std::move(base), r);
}

}  // namespace bsms::generate::families
