// Runtime choice of the SIMD path. One binary carries kernels for the x86-64
// baseline (SSE2), AVX2 + FMA and AVX-512 (F, VL, BW, DQ); at the first use
// the best one the CPU supports is chosen. The environment variable
// SKYFALL_SIMD (baseline, avx2 or avx512) asks for a lower one, e.g. to
// compare paths; SetSimdPath does the same from code (tests).
//
// Kernels that have per-path versions: the rasterizer's forward and backward
// passes (splat/rasterizer.cpp), the appearance MLP's layers and weight
// gradients (splat/appearance.cpp) and the dense sweep's warp, window
// statistics, pair cost and SGM step (dense/dense.cpp). Each path gives the
// baseline's results within the tolerances their tests name. How a kernel
// source is compiled once per path: core/simd_target.h.
#pragma once

#include <string>
#include <vector>

namespace skyfall {

enum class SimdPath { kBaseline = 0, kAvx2 = 1, kAvx512 = 2 };

const char* SimdPathName(SimdPath path);
// Parses "baseline", "avx2" or "avx512"; throws Error("simd", ...) otherwise.
SimdPath ParseSimdPath(const std::string& name);
// The paths this CPU can run, baseline first.
std::vector<SimdPath> SupportedSimdPaths();
// The path the kernels use now: the best supported one, or SKYFALL_SIMD's.
SimdPath ActiveSimdPath();
// Switches the kernels to `path`; throws Error("simd", ...) when the CPU
// cannot run it.
void SetSimdPath(SimdPath path);

// Of three per-path values (a file's table of kernels for each path), the
// one for the active path.
template <typename T>
const T& ForActivePath(const T& baseline, const T& avx2, const T& avx512) {
  switch (ActiveSimdPath()) {
    case SimdPath::kAvx512:
      return avx512;
    case SimdPath::kAvx2:
      return avx2;
    case SimdPath::kBaseline:
      break;
  }
  return baseline;
}

}  // namespace skyfall
