// Small portable hashes: the same value on every platform and standard library, so seeded draws
// (random seeding, training samples, generated scenes) are reproducible everywhere.
#pragma once

#include <cstdint>

namespace bsms {

// SplitMix64's state increment (the golden ratio in 64 bits).
constexpr uint64_t kSplitMix64Increment = 0x9e3779b97f4a7c15ull;

// SplitMix64 (Steele, Lea, Flood 2014): the output for state `x`, a bijective 64-bit mix. The
// generator's next state is x + kSplitMix64Increment.
inline uint64_t splitmix64(uint64_t x) {
  x += kSplitMix64Increment;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace bsms
