// The test city's hashes: deterministic draws keyed by seeds, positions,
// views and pixels (not a public header).
#pragma once

#include <cstdint>

namespace skyfall::synth {

// SplitMix64's finalizer: every input bit reaches every output bit, so
// keys that differ by one (neighbouring lattice points, views, pixels) give
// independent draws.
inline std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// The top 24 bits of `x` as a float in [0, 1).
inline float Unit01(std::uint64_t x) { return static_cast<float>((x >> 40) * (1.0 / 16777216.0)); }

}  // namespace skyfall::synth
