// Three-component points and the few vector operations the geometric kernels of core need
// (physical validity and projection); 2-D points use a zero third component.
#pragma once

#include <array>

namespace bsms::point3 {

using P3 = std::array<double, 3>;

inline P3 sub(const P3& a, const P3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
inline P3 cross(const P3& a, const P3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double dot(const P3& a, const P3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

}  // namespace bsms::point3
