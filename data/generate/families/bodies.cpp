// Bodies: 2–4 elastic spheres and boxes (disks and rectangles in 2D) thrown at each other in a box.
// The first two bodies are thrown so that they meet: their centres' closest approach under the
// relative velocity lies within half the smaller body's inner radius, before `contact_within` of
// the horizon. Gravity and a common velocity do not change the relative motion, so every draw has
// at least one collision unless a wall gets in between (the placement keeps the pair apart by at
// most the box). The other bodies are aimed at the box centre, give or take the jitter.
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <utility>

#include "core/error.hpp"
#include "data/generate/families/ranges.hpp"
#include "data/generate/families/samplers.hpp"

namespace bsms::generate::families {

namespace {

using Point = std::array<double, 3>;

struct Placed {
  bool box = false;
  Point centre{}, half{};  // half extents (box) or radius in half[0] (ball)
  double bound = 0.0;      // radius of the enclosing ball
  double inner = 0.0;      // radius of the largest ball inside
};

double dot(const Point& a, const Point& b, int dim) {
  double s = 0.0;
  for (int i = 0; i < dim; ++i) s += a[i] * b[i];
  return s;
}

// `d` (unit) turned by `angle` (rad) towards a random direction perpendicular to it.
Point turned(const Point& d, double angle, Rng& rng, int dim) {
  Point p{};
  if (dim == 2) {
    p = {-d[1], d[0], 0.0};
  } else {
    // A random unit vector perpendicular to d: Gram–Schmidt on a random axis (retried when it is
    // nearly parallel to d).
    for (int attempt = 0; attempt < 16; ++attempt) {
      const double z = rng.uniform(-1.0, 1.0), phi = rng.uniform(0.0, 2.0 * kPi);
      const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
      Point u{s * std::cos(phi), s * std::sin(phi), z};
      const double along = dot(u, d, 3);
      for (int i = 0; i < 3; ++i) u[i] -= along * d[i];
      const double n = std::sqrt(dot(u, u, 3));
      if (n > 1e-3) {
        for (int i = 0; i < 3; ++i) p[i] = u[i] / n;
        break;
      }
    }
  }
  Point out{};
  for (int i = 0; i < dim; ++i) out[i] = std::cos(angle) * d[i] + std::sin(angle) * p[i];
  return out;
}

class BodiesSampler : public SceneSampler {
 public:
  BodiesSampler(FamilyBase base, JsonObjectReader& r) : base_(std::move(base)) {
    const int dim = base_.dim;
    require(dim == 2 || dim == 3, JsonContext{base_.file, "scene.dim"}, "2 or 3");
    count_ = read_int_range(r, "count", 2);
    shapes_ = r.opt<std::vector<std::string>>("shapes", {dim == 2 ? "disk" : "sphere", "box"});
    require(!shapes_.empty(), r.context("shapes"), "a non-empty list");
    for (const auto& s : shapes_)
      require(s == "box" || s == (dim == 2 ? "disk" : "sphere"), r.context("shapes"),
              dim == 2 ? "a list of 'disk' and 'box'" : "a list of 'sphere' and 'box'");
    size_ = read_range(r, "size", Sign::kPositive);
    aspect_ = r.has("box_aspect") ? read_range(r, "box_aspect", Sign::kPositive) : Range{1.0, 1.0};
    spacing_ = read_range(r, "spacing", Sign::kPositive);
    speed_ = read_range(r, "speed", Sign::kPositive);
    gap_ = r.opt<double>("gap", 0.02);
    require(gap_ >= 0.0, r.context("gap"), "non-negative");
    aim_jitter_deg_ = r.opt<double>("aim_jitter_deg", 30.0);
    require(aim_jitter_deg_ >= 0.0 && aim_jitter_deg_ <= 180.0, r.context("aim_jitter_deg"),
            "in [0, 180]");
    if (r.has("nodes")) {
      nodes_ = read_range(r, "nodes", Sign::kPositive);
    } else {
      nodes_ = {0.0, 1e300};
    }
    contact_within_ = r.opt<double>("contact_within", 0.5);
    require(contact_within_ > 0.0 && contact_within_ <= 1.0, r.context("contact_within"),
            "in (0, 1] (a share of the trajectory's duration)");
    material_ = read_material(r, "material");
    if (r.has("gravity")) gravity_ = read_vector_range(r, "gravity", dim);
    background_box(base_.base, base_.file, dim, lo_, hi_);
    const double largest = size_.max * std::max(1.0, aspect_.max) * std::sqrt(double(dim));
    for (int a = 0; a < dim; ++a)
      if (lo_[a] + 2.0 * (largest + gap_) > hi_[a])
        throw InputError(r.context("size").where() + ": a body of size " +
                         std::to_string(size_.max) + " does not fit in the background box");
  }

  SampledScene sample(Rng& rng, const std::string&) const override {
    const int dim = base_.dim;
    const int64_t n = rng.integer(count_.min, count_.max);
    const double horizon = base_.frame_dt * (base_.frames - 1);
    const double spacing = spacing_.sample(rng);
    // Seeded rejection sampling: whole sets are redrawn when a body finds no free place or the
    // first pair cannot be thrown to meet in time.
    std::vector<Placed> placed;
    std::vector<Point> velocity;
    for (int set = 0; set < 200; ++set) {
      placed.clear();
      for (int64_t i = 0; i < n; ++i) {
        Placed b = draw_shape(rng);
        bool free = false;
        for (int attempt = 0; attempt < 200 && !free; ++attempt) {
          for (int a = 0; a < dim; ++a)
            b.centre[a] = rng.uniform(lo_[a] + b.bound + gap_, hi_[a] - b.bound - gap_);
          free = std::all_of(placed.begin(), placed.end(), [&](const Placed& o) {
            Point d{};
            for (int a = 0; a < dim; ++a) d[a] = b.centre[a] - o.centre[a];
            return std::sqrt(dot(d, d, dim)) >= b.bound + o.bound + gap_;
          });
        }
        if (!free) break;
        placed.push_back(b);
      }
      if (static_cast<int64_t>(placed.size()) < n) continue;
      double nodes = 0.0;
      for (const Placed& b : placed) nodes += node_estimate(b, spacing);
      if (nodes < nodes_.min || nodes > nodes_.max) {
        placed.clear();
        continue;
      }
      if (throw_bodies(placed, horizon, rng, velocity)) break;
      placed.clear();
    }
    if (static_cast<int64_t>(placed.size()) < n)
      throw InputError(base_.file + ": key 'sample.count': cannot place " + std::to_string(n) +
                       " bodies without overlap, within the 'nodes' range, the first two meeting "
                       "within " +
                       std::to_string(contact_within_) +
                       " of the duration (widen the ranges, or raise speed)");

    Json bodies = Json::array(), params = Json::array();
    for (size_t i = 0; i < placed.size(); ++i) {
      const Placed& b = placed[i];
      std::vector<double> c(b.centre.begin(), b.centre.begin() + dim);
      std::vector<double> v(velocity[i].begin(), velocity[i].begin() + dim);
      Json shape;
      if (b.box) {
        std::vector<double> mn(dim), mx(dim);
        for (int a = 0; a < dim; ++a) {
          mn[a] = b.centre[a] - b.half[a];
          mx[a] = b.centre[a] + b.half[a];
        }
        shape = {{"type", "box"}, {"min", mn}, {"max", mx}};
      } else {
        shape = {{"type", dim == 2 ? "disk" : "sphere"}, {"center", c}, {"radius", b.half[0]}};
      }
      const Json material = material_.sample(rng);
      bodies.push_back({{"name", "body" + std::to_string(i)},
                        {"shape", shape},
                        {"spacing", spacing},
                        {"material", material},
                        {"velocity", uniform_velocity(v)}});
      params.push_back(
          {{"shape", shape}, {"velocity", v}, {"spacing", spacing}, {"material", material}});
    }
    SampledScene out;
    const std::vector<double> g = sample_vector(gravity_, rng);
    out.scene = base_.finish(bodies, Json::array(), g);
    out.parameters = {{"bodies", params}};
    if (!g.empty()) out.parameters["gravity"] = g;
    return out;
  }

 private:
  Placed draw_shape(Rng& rng) const {
    const int dim = base_.dim;
    Placed b;
    const auto k = rng.integer(0, static_cast<int64_t>(shapes_.size()) - 1);
    b.box = shapes_[static_cast<size_t>(k)] == "box";
    const double size = size_.sample(rng);
    if (b.box) {
      double sq = 0.0;
      b.inner = 1e300;
      for (int a = 0; a < dim; ++a) {
        b.half[a] = size * aspect_.sample(rng);
        sq += b.half[a] * b.half[a];
        b.inner = std::min(b.inner, b.half[a]);
      }
      b.bound = std::sqrt(sq);
    } else {
      b.half[0] = b.bound = b.inner = size;
    }
    return b;
  }

  // The mesh nodes a body will have, roughly: a structured box has (edge / spacing + 1) nodes per
  // axis; gmsh fills a ball with about 1.5 nodes per spacing³ in 3D (1.2 per spacing² in 2D).
  double node_estimate(const Placed& b, double spacing) const {
    const int dim = base_.dim;
    double n = 1.0;
    if (b.box) {
      for (int a = 0; a < dim; ++a) n *= std::round(2.0 * b.half[a] / spacing) + 1.0;
      return n;
    }
    const double r = b.half[0] / spacing;
    return dim == 2 ? 1.2 * kPi * r * r : 1.5 * 4.0 / 3.0 * kPi * r * r * r;
  }

  // Velocities: the first two bodies towards each other (jittered, accepted only when they meet in
  // time), the rest towards the box centre. False when 100 throws of the pair all miss.
  bool throw_bodies(const std::vector<Placed>& placed, double horizon, Rng& rng,
                    std::vector<Point>& velocity) const {
    const int dim = base_.dim;
    const double jitter = aim_jitter_deg_ * kPi / 180.0;
    velocity.assign(placed.size(), Point{});
    Point centre{};
    for (int a = 0; a < dim; ++a) centre[a] = 0.5 * (lo_[a] + hi_[a]);
    auto aim = [&](const Point& from, const Point& to) {
      Point d{};
      for (int a = 0; a < dim; ++a) d[a] = to[a] - from[a];
      const double len = std::sqrt(dot(d, d, dim));
      for (int a = 0; a < dim; ++a) d[a] = len > 0.0 ? d[a] / len : (a == 0 ? 1.0 : 0.0);
      const Point t = turned(d, jitter * rng.uniform(-1.0, 1.0), rng, dim);
      const double speed = speed_.sample(rng);
      Point v{};
      for (int a = 0; a < dim; ++a) v[a] = speed * t[a];
      return v;
    };
    bool met = false;
    for (int attempt = 0; attempt < 100 && !met; ++attempt) {
      velocity[0] = aim(placed[0].centre, placed[1].centre);
      velocity[1] = aim(placed[1].centre, placed[0].centre);
      Point d{}, w{};
      for (int a = 0; a < dim; ++a) {
        d[a] = placed[1].centre[a] - placed[0].centre[a];
        w[a] = velocity[1][a] - velocity[0][a];
      }
      const double ww = dot(w, w, dim);
      const double t = ww > 0.0 ? std::max(0.0, -dot(d, w, dim) / ww) : 0.0;
      Point closest{};
      for (int a = 0; a < dim; ++a) closest[a] = d[a] + t * w[a];
      const double miss = std::sqrt(dot(closest, closest, dim));
      // The surfaces touch before the centres reach their closest approach: the time at which the
      // centres come within the sum of the enclosing radii bounds the contact time from above
      // only loosely, so the bound asked for is the closest-approach time itself.
      met = miss <= 0.5 * std::min(placed[0].inner, placed[1].inner) &&
            t <= contact_within_ * horizon;
    }
    if (!met) return false;
    for (size_t i = 2; i < placed.size(); ++i) velocity[i] = aim(placed[i].centre, centre);
    return true;
  }

  FamilyBase base_;
  IntRange count_;
  std::vector<std::string> shapes_;
  Range size_, aspect_, spacing_, speed_, nodes_;
  double gap_ = 0.0, aim_jitter_deg_ = 0.0, contact_within_ = 0.5;
  MaterialRange material_;
  std::vector<Range> gravity_;
  std::vector<double> lo_, hi_;
};

}  // namespace

std::shared_ptr<const SceneSampler> make_bodies_sampler(FamilyBase base, JsonObjectReader& r) {
  return std::make_shared<BodiesSampler>(std::move(base), r);
}

}  // namespace bsms::generate::families
