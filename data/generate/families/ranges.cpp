#include "data/generate/families/ranges.hpp"

#include <cmath>
#include <sstream>

#include "core/error.hpp"

namespace bsms::generate::families {

Range range_from(const Json& j, const JsonContext& ctx, Sign sign) {
  if (j.is_object()) {
    JsonObjectReader o(j, ctx);
    const Json& ends = o.raw("log_uniform");
    o.finish();
    Range r = range_from(ends, ctx.child("log_uniform"), Sign::kAny);
    require(r.min > 0.0, ctx.child("log_uniform"), "positive ends (a log-uniform range)");
    r.log = true;
    return r;
  }
  Range r;
  if (j.is_number()) {
    r.min = r.max = j.get<double>();
  } else if (j.is_array() && j.size() == 2 && j[0].is_number() && j[1].is_number()) {
    r.min = j[0].get<double>();
    r.max = j[1].get<double>();
  } else {
    throw InputError(ctx.where() +
                     " must be a number, [min, max] or {\"log_uniform\": [min, max]}, got " +
                     describe_json(j));
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
                     describe_json(j));
  }
  if (out.min > out.max)
    throw InputError(ctx.where() + ": min " + std::to_string(out.min) + " > max " +
                     std::to_string(out.max));
  require(out.min >= lowest, ctx, "at least " + std::to_string(lowest));
  return out;
}

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

Json MaterialRange::sample(Rng& rng) const {
  Json m = Json::object();
  for (const auto& [k, v] : strings) m[k] = v;
  for (const auto& [k, v] : numbers) m[k] = v.sample(rng);
  return m;
}

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

}  // namespace bsms::generate::families
