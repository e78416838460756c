// The AOI catalog (aoi.json), a tile (tile.json) and radiometry records.
#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "fuzz/fuzz_target.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace skyfall;
  const std::string text = fuzz::Text(data, size);
  fuzz::Expect([&] { AoiCatalogFromJson(text, "aoi.json"); });
  fuzz::Expect([&] { TileSpecFromJson(text, "tile.json"); });
  fuzz::Expect([&] { RadiometryFromJson(text, "radiometry"); });
  return 0;
}
