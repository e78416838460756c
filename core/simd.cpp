#include "core/simd.h"

#include <atomic>
#include <cstdlib>

#include "core/error.h"

namespace skyfall {
namespace {

bool Supported(SimdPath path) {
  switch (path) {
    case SimdPath::kBaseline:
      return true;
    case SimdPath::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case SimdPath::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
             __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
  }
  return false;
}

SimdPath Best() {
  for (SimdPath p : {SimdPath::kAvx512, SimdPath::kAvx2})
    if (Supported(p)) return p;
  return SimdPath::kBaseline;
}

// -1 until the first use.
std::atomic<int> g_active{-1};

SimdPath Initial() {
  const char* env = std::getenv("SKYFALL_SIMD");
  if (env == nullptr || *env == '\0') return Best();
  const SimdPath wanted = ParseSimdPath(env);
  if (!Supported(wanted)) {
    throw Error("simd", "SKYFALL_SIMD", std::string("'") + env + "' is not supported by this CPU (best: " +
                                            SimdPathName(Best()) + ")");
  }
  return wanted;
}

}  // namespace

const char* SimdPathName(SimdPath path) {
  switch (path) {
    case SimdPath::kBaseline:
      return "baseline";
    case SimdPath::kAvx2:
      return "avx2";
    case SimdPath::kAvx512:
      return "avx512";
  }
  return "unknown";
}

SimdPath ParseSimdPath(const std::string& name) {
  for (SimdPath p : {SimdPath::kBaseline, SimdPath::kAvx2, SimdPath::kAvx512})
    if (name == SimdPathName(p)) return p;
  throw Error("simd", "path", "'" + name + "' is not baseline, avx2 or avx512");
}

std::vector<SimdPath> SupportedSimdPaths() {
  std::vector<SimdPath> out;
  for (SimdPath p : {SimdPath::kBaseline, SimdPath::kAvx2, SimdPath::kAvx512})
    if (Supported(p)) out.push_back(p);
  return out;
}

SimdPath ActiveSimdPath() {
  int v = g_active.load(std::memory_order_relaxed);
  if (v < 0) {
    v = static_cast<int>(Initial());
    g_active.store(v, std::memory_order_relaxed);
  }
  return static_cast<SimdPath>(v);
}

void SetSimdPath(SimdPath path) {
  if (!Supported(path)) throw Error("simd", "path", std::string(SimdPathName(path)) + " is not supported by this CPU");
  g_active.store(static_cast<int>(path), std::memory_order_relaxed);
}

}  // namespace skyfall
