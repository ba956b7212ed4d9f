// Numbers in reports, tables and messages: one formatter for the whole pipeline.
#pragma once

#include <string>

#include "core/config.hpp"

namespace bsms {

enum class Notation {
  kGeneral,     // %g-like: 3 significant digits by default ("0.0123", "1.5e+03")
  kFixed,       // `precision` digits after the point ("0.012")
  kScientific,  // `precision` digits after the point, with exponent ("1.23e-02")
};

// `v` in the notation; "–" for NaN or an infinity, so a table never shows "nan".
std::string format_number(double v, int precision = 3, Notation notation = Notation::kGeneral);
// The same for a JSON value; "–" when it is null or not a number.
std::string format_number(const Json& v, int precision = 3, Notation notation = Notation::kGeneral);

}  // namespace bsms
