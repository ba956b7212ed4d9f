#include "pipeline/report/number_format.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

namespace bsms {

std::string format_number(double v, int precision, Notation notation) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream s;
  if (notation == Notation::kFixed) s << std::fixed;
  if (notation == Notation::kScientific) s << std::scientific;
  s << std::setprecision(precision) << v;
  return s.str();
}

std::string format_number(const Json& v, int precision, Notation notation) {
  if (!v.is_number()) return "–";
  return format_number(v.get<double>(), precision, notation);
}

}  // namespace bsms
