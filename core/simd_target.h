// Compiling one kernel source once per SIMD path (core/simd.h): a file
// includes its kernels three times, each inside its own namespace and its
// own target region, so no code of one path can end up in another:
//
//   namespace foo_baseline { #include "foo_kernels.inc" }
//   SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX2)
//   namespace foo_avx2 { #include "foo_kernels.inc" }
//   SKYFALL_TARGET_END
//
// Headers must all be included before the first region: only the kernels
// themselves are compiled for the wider targets.
#pragma once

// _Pragma takes one string literal, so the target is stringified into it.
#define SKYFALL_STRINGIFY(x) #x
#if defined(__clang__)
#define SKYFALL_TARGET_BEGIN(t) \
  _Pragma(SKYFALL_STRINGIFY(clang attribute push(__attribute__((target(t))), apply_to = function)))
#define SKYFALL_TARGET_END _Pragma("clang attribute pop")
#else
#define SKYFALL_TARGET_BEGIN(t) _Pragma("GCC push_options") _Pragma(SKYFALL_STRINGIFY(GCC target(t)))
#define SKYFALL_TARGET_END _Pragma("GCC pop_options")
#endif

#define SKYFALL_TARGET_AVX2 "avx2,fma"
#define SKYFALL_TARGET_AVX512 "avx512f,avx512vl,avx512bw,avx512dq,avx2,fma"

// `return prefix_<path>::call` for the active path, where a file compiled its
// kernels into the namespaces prefix_baseline, prefix_avx2 and
// prefix_avx512 as above (the caller includes core/simd.h).
#if defined(__x86_64__)
#define SKYFALL_RETURN_FOR_ACTIVE_PATH(prefix, call) \
  switch (ActiveSimdPath()) {                       \
    case SimdPath::kAvx512:                         \
      return prefix##_avx512::call;                 \
    case SimdPath::kAvx2:                           \
      return prefix##_avx2::call;                   \
    case SimdPath::kBaseline:                       \
      break;                                        \
  }                                                 \
  return prefix##_baseline::call
#else
#define SKYFALL_RETURN_FOR_ACTIVE_PATH(prefix, call) return prefix##_baseline::call
#endif
