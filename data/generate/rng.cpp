#include "data/generate/rng.hpp"

#include "core/hash.hpp"

namespace bsms::generate {

uint64_t Rng::next() {
  // Draw k is splitmix64(seed + k·γ): splitmix64 adds γ, the golden-ratio increment, itself.
  const uint64_t out = splitmix64(state_);
  state_ += kSplitMix64Increment;
  return out;
}

double Rng::uniform() {
  return static_cast<double>(next() >> 11) * 0x1.0p-53;
}

double Rng::uniform(double lo, double hi) {
  return lo == hi ? lo : lo + (hi - lo) * uniform();
}

int64_t Rng::integer(int64_t lo, int64_t hi) {
  const uint64_t span = static_cast<uint64_t>(hi - lo) + 1;
  return lo + static_cast<int64_t>(next() % span);  // bias is negligible for small spans
}

int64_t trajectory_seed(int64_t seed, int64_t index, int attempt) {
  uint64_t h = splitmix64(static_cast<uint64_t>(seed));
  h = splitmix64(h ^ static_cast<uint64_t>(index));
  h = splitmix64(h ^ static_cast<uint64_t>(attempt));
  return static_cast<int64_t>(h >> 1);
}

}  // namespace bsms::generate
