// RPC metadata as it comes from outside: RPB text, GDAL "KEY=VALUE" metadata,
// "KEY: value" _RPC.TXT text, Sat-NeRF camera JSON.
#include <map>
#include <sstream>

#include "core/rpc.h"
#include "fuzz/fuzz_target.h"
#include "ingest/rpc_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace skyfall;
  const std::string text = fuzz::Text(data, size);
  fuzz::Expect([&] { RpcFromRpbText(text); });
  fuzz::Expect([&] { RpcFromKeyValueText(text); });
  fuzz::Expect([&] {
    std::map<std::string, std::string> keys;
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);) {
      const auto eq = line.find('=');
      if (eq != std::string::npos) keys[line.substr(0, eq)] = line.substr(eq + 1);
    }
    RpcFromGdalMetadata(keys);
  });
  fuzz::Expect([&] { ParseSatNerfCamera(text, "fuzz.json"); });
  return 0;
}
