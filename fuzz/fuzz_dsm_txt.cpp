// DFC2019 <AOI>_DSM.txt: easting, northing, size, GSD.
#include "fuzz/fuzz_target.h"
#include "ingest/dfc2019.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  skyfall::fuzz::Expect([&] { skyfall::ParseDsmTxt(skyfall::fuzz::Text(data, size), "fuzz_DSM.txt"); });
  return 0;
}
