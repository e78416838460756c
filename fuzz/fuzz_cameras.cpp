// cameras.json written by SfM and read by training, rendering and orbits.
#include "fuzz/fuzz_target.h"
#include "splat/dataset.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  skyfall::fuzz::Expect([&] { skyfall::ParseCameraEntries(skyfall::fuzz::Text(data, size), "cameras.json"); });
  return 0;
}
