// The Inria 3DGS PLY reader (scenes, LOD levels, checkpoints of others).
#include "fuzz/fuzz_target.h"
#include "splat/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  skyfall::fuzz::Expect([&] { skyfall::ParseGaussiansPly(skyfall::fuzz::Text(data, size), "scene.ply"); });
  return 0;
}
