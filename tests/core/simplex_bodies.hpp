// Bodies of simplices for the physical-validity and projection tests: unit squares and cubes
// split into triangles and tetrahedra.
#pragma once

#include <cstdint>
#include <vector>

namespace bsms::simplex_bodies {

struct Body {
  std::vector<double> points;
  std::vector<int32_t> cells;
  void shift(const std::vector<double>& by) {
    const size_t d = by.size();
    for (size_t i = 0; i < points.size(); ++i) points[i] += by[i % d];
  }
};

// [0, 1]^2 split into n x n squares of two triangles each.
inline Body square(int n) {
  Body b;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) b.points.insert(b.points.end(), {1.0 * i / n, 1.0 * j / n});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int32_t a = j * (n + 1) + i, c = a + 1, e = a + n + 1, f = e + 1;
      b.cells.insert(b.cells.end(), {a, c, f, a, f, e});
    }
  return b;
}

// [0, 1]^3 split into n^3 cubes of 6 tetrahedra each (around the main diagonal).
inline Body cube(int n) {
  Body b;
  auto index = [n](int i, int j, int k) {
    return static_cast<int32_t>((k * (n + 1) + j) * (n + 1) + i);
  };
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i)
        b.points.insert(b.points.end(), {1.0 * i / n, 1.0 * j / n, 1.0 * k / n});
  const int axes[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& order : axes) {
          int at[3] = {i, j, k};
          b.cells.push_back(index(at[0], at[1], at[2]));
          for (int s = 0; s < 3; ++s) {
            ++at[order[s]];
            b.cells.push_back(index(at[0], at[1], at[2]));
          }
        }
  return b;
}

}  // namespace bsms::simplex_bodies
