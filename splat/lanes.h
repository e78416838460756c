// Fixed-width vectors for the rasterizer's per-pixel loops (GCC/Clang vector
// extensions): four pixels of a tile row are blended at once, with lane
// masks instead of branches. Four floats fill one SSE register, which every
// x86-64 CPU has; vectors wider than the target's registers are slower (GCC
// lowers them through memory), so the width is not raised without a
// matching target.
//
// Masks follow the vector-extension convention: a comparison gives -1 (all
// bits) in lanes where it holds and 0 elsewhere, and `Select(m, a, b)` picks
// a where m is set. Lanes a mask excludes may hold inf or NaN: they are only
// ever passed through Select, never multiplied by a 0/1 mask.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace skyfall::lanes {

constexpr int kLanes = 4;

template <typename T>
struct Types;
template <>
struct Types<float> {
  typedef float V __attribute__((vector_size(kLanes * sizeof(float))));
  typedef std::int32_t M __attribute__((vector_size(kLanes * sizeof(std::int32_t))));
};
template <>
struct Types<double> {
  typedef double V __attribute__((vector_size(kLanes * sizeof(double))));
  typedef std::int64_t M __attribute__((vector_size(kLanes * sizeof(std::int64_t))));
};

template <typename T>
using Vec = typename Types<T>::V;
template <typename T>
using Mask = typename Types<T>::M;  // also the per-lane integer type

template <typename V>
inline V Load(const void* p) {
  V v;
  std::memcpy(&v, p, sizeof(V));  // unaligned load
  return v;
}
template <typename V>
inline void Store(void* p, const V& v) {
  std::memcpy(p, &v, sizeof(V));
}

template <typename V, typename S>
inline V Splat(S s) {
  V v;
  for (int i = 0; i < kLanes; ++i) v[i] = s;
  return v;
}

template <typename V>
inline V Iota() {
  V v;
  for (int i = 0; i < kLanes; ++i) v[i] = i;
  return v;
}

template <typename M, typename V>
inline V Select(const M& m, const V& a, const V& b) {
  return m ? a : b;
}

template <typename M>
inline bool Any(const M& m) {
  // OR-reduce in halves: the compiler turns this into a few vector ops.
  std::uint64_t w[sizeof(M) / 8];
  std::memcpy(w, &m, sizeof(M));
  std::uint64_t acc = 0;
  for (std::size_t i = 0; i < sizeof(M) / 8; ++i) acc |= w[i];
  return acc != 0;
}

template <typename M>
inline int Count(const M& m) {
  int n = 0;
  for (int i = 0; i < kLanes; ++i) n += m[i] != 0;
  return n;
}

template <typename V>
inline auto Sum(const V& v) {
  // Pairwise, in a fixed order: deterministic, independent of the target.
  auto acc = v[0];
  for (int i = 1; i < kLanes; ++i) acc += v[i];
  return acc;
}

// exp() per lane. Float: Cephes-style range reduction x = n ln2 + r,
// |r| <= ln2/2, and a degree-5 minimax polynomial for e^r; relative error
// < 2e-7 (about 1.5 ulp, tested against std::exp), results are flushed to 0
// below e^-87 (the blending never uses values that small: alpha < 1/255 is
// cut). Double: std::exp per lane, so the finite-difference tests that run
// in double see the exact function.
inline Vec<float> Exp(Vec<float> x) {
  using V = Vec<float>;
  using M = Mask<float>;
  const V lo = Splat<V>(-87.0f), hi = Splat<V>(88.0f);
  const M underflow = x < lo;
  x = Select(x < lo, lo, x);
  x = Select(x > hi, hi, x);
  const V fx = x * 1.44269504088896341f + 0.5f;
  M n = __builtin_convertvector(fx, M);  // truncation
  V fn = __builtin_convertvector(n, V);
  const M too_big = fn > fx;  // floor for negative values
  fn = Select(too_big, fn - 1.0f, fn);
  n = Select(too_big, n - 1, n);
  const V r = x - fn * 0.693359375f - fn * -2.12194440e-4f;
  V p = Splat<V>(1.9875691500e-4f);
  p = p * r + 1.3981999507e-3f;
  p = p * r + 8.3334519073e-3f;
  p = p * r + 4.1665795894e-2f;
  p = p * r + 1.6666665459e-1f;
  p = p * r + 5.0000001201e-1f;
  p = p * r * r + r + 1.0f;
  const M bits = (n + 127) << 23;
  V scale;
  std::memcpy(&scale, &bits, sizeof(V));
  return Select(underflow, Splat<V>(0.0f), p * scale);
}

inline Vec<double> Exp(Vec<double> x) {
  for (int i = 0; i < kLanes; ++i) x[i] = std::exp(x[i]);
  return x;
}

}  // namespace skyfall::lanes
