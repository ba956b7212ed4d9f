// Small portable hashes: the same value on every platform and standard library, so seeded draws
// (random seeding, training samples, generated scenes) are reproducible everywhere.
#pragma once

#include <cstdint>

namespace bsms {

// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
inline uint64_t splitmix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace bsms
