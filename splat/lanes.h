// Fixed-width vectors for the rasterizer's per-pixel loops (GCC/Clang vector
// extensions): a block of pixels is blended at once (rasterizer_kernels.inc,
// TileLayout), with lane masks instead of branches. Four floats fill one SSE
// register, which every x86-64 CPU has; vectors wider than the target's
// registers are slower (GCC lowers them through memory), so the width is not
// raised without a matching target: the rasterizer compiles its own copy at
// 8 lanes for AVX2 and 16 for AVX-512 (core/simd.h).
//
// Masks follow the vector-extension convention: a comparison gives -1 (all
// bits) in lanes where it holds and 0 elsewhere, and `Select(m, a, b)` picks
// a where m is set. Lanes a mask excludes may hold inf or NaN: they are only
// ever passed through Select, never multiplied by a 0/1 mask.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#if defined(__x86_64__)
#include <immintrin.h>  // lanes_body.inc: one-instruction mask tests
#endif

namespace skyfall::lanes {

constexpr int kLanes = 4;
#include "splat/lanes_body.inc"

}  // namespace skyfall::lanes
