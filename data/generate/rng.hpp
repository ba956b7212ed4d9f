// The generator's random stream: a splitmix64 sequence (core/hash.hpp), portable, so a draw is
// identical on every platform and standard library and a stored seed redraws its trajectory.
#pragma once

#include <cstdint>

namespace bsms::generate {

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t next();
  double uniform();                         // [0, 1)
  double uniform(double lo, double hi);     // [lo, hi); lo when lo == hi
  int64_t integer(int64_t lo, int64_t hi);  // [lo, hi], inclusive
 private:
  uint64_t state_;
};

// Seed of global trajectory `index` at draw `attempt` (0 first, +1 per unstable redraw) of a run
// with seed `seed`. Non-negative, stored in the dataset; Rng(trajectory_seed(...)) redraws it.
int64_t trajectory_seed(int64_t seed, int64_t index, int attempt);

}  // namespace bsms::generate
