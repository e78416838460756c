#include "tiling/tiling.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "catalogs/aoi_catalog.h"
#include "catalogs/tile_catalog.h"
#include "tests/test_support.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

AoiCatalog IngestJax(const fs::path& dir) {
  IngestOptions o;
  o.aois = {"JAX_068"};
  o.verify_pixels = false;
  NullProgress progress;
  RunIngest(o, Dfc2019Root().string(), (dir / "catalogs").string(), progress);
  return ReadAoiCatalog((dir / "catalogs" / "JAX_068" / "aoi.json").string());
}

// 2 x 2 tiles over JAX_068's 256 m truth grid.
TilingOptions QuarterTiles() {
  TilingOptions o;
  o.tile_m = 128;
  o.overlap_m = 16;
  return o;
}

TEST(Tiling, CoresPartitionTheAoiAndExtentsOverlapByTheMargin) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("tiles");
  const AoiCatalog jax = IngestJax(dir);
  const TilingOptions o = QuarterTiles();
  const TilePlan plan = PlanTiles(o, {jax});
  EXPECT_EQ(plan.city, "JAX_068");
  // The truth grid is 256 m x 256 m: two by two tiles of 128 m.
  EXPECT_NEAR(plan.bounds.Width(), 256.0, 2.0);  // + grid convergence
  ASSERT_EQ(plan.grid.cols, 2);
  ASSERT_EQ(plan.grid.rows, 2);
  ASSERT_EQ(plan.tiles.size(), 4u);
  // Every ground point of the bounds has exactly one owning core, and the
  // owner found by the grid is the core that contains it.
  // Beyond the outer cores (the AOI's rotated corners) the edge tile owns.
  const Eigen::Vector2d span_max = plan.grid.origin_m + plan.grid.tile_m * Eigen::Vector2d(2, 2);
  for (double e = plan.bounds.min_m.x() + 0.3; e < plan.bounds.max_m.x(); e += 7.1) {
    for (double n = plan.bounds.min_m.y() + 0.3; n < plan.bounds.max_m.y(); n += 7.3) {
      const Eigen::Vector2i owner = plan.grid.Owner(e, n);
      const Eigen::Vector2d clamped = Eigen::Vector2d(e, n).cwiseMax(plan.grid.origin_m).cwiseMin(span_max - Eigen::Vector2d::Constant(1e-9));
      int owners = 0;
      for (const TileSpec& t : plan.tiles) owners += t.core.Contains(clamped.x(), clamped.y());
      ASSERT_EQ(owners, 1) << e << " " << n;
      EXPECT_TRUE(plan.grid.Core(owner.x(), owner.y()).Contains(clamped.x(), clamped.y()));
    }
  }
  for (const TileSpec& t : plan.tiles) {
    // Margin: the extent reaches overlap_m beyond the core towards the
    // neighbouring tile, and overlap_m beyond the AOI's bounds at its edge
    // (what stands just outside the AOI is reconstructed too).
    const double m = o.overlap_m;
    constexpr double kTol = 1e-9;  // [m] the same sums in another order
    EXPECT_NEAR(t.extent.min_m.x(), t.col == 0 ? plan.bounds.min_m.x() - m : t.core.min_m.x() - m, kTol) << t.id;
    EXPECT_NEAR(t.extent.max_m.x(), t.col == 1 ? plan.bounds.max_m.x() + m : t.core.max_m.x() + m, kTol) << t.id;
    EXPECT_NEAR(t.extent.min_m.y(), t.row == 0 ? plan.bounds.min_m.y() - m : t.core.min_m.y() - m, kTol) << t.id;
    EXPECT_NEAR(t.extent.max_m.y(), t.row == 1 ? plan.bounds.max_m.y() + m : t.core.max_m.y() + m, kTol) << t.id;
    // (2 m: the AOI's bounding box in the ENU frame is ~1.5 m wider than its
    // 256 m UTM square, rotated by the grid convergence.)
    EXPECT_NEAR(t.extent.Width(), 128.0 + 2 * m, 2.0) << t.id;
    EXPECT_NEAR(t.extent.Height(), 128.0 + 2 * m, 2.0) << t.id;
    // Every JAX_068 crop covers the whole AOI, so every image sees every tile.
    EXPECT_EQ(t.images.size(), jax.images.size()) << t.id;
  }
}

TEST(Tiling, CropsAreVrtWindowsWithShiftedRpcs) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("tiles");
  const AoiCatalog jax = IngestJax(dir);
  const TilingOptions o = QuarterTiles();
  NullProgress progress;
  const TilingResult r = WriteTiles(PlanTiles(o, {jax}), (dir / "tiles").string(), progress);
  ASSERT_EQ(r.tile_dirs.size(), 4u);
  const TileSpec tile = ReadTileSpec(r.tile_dirs[3] + "/tile.json");
  const AoiCatalog catalog = ReadAoiCatalog(r.tile_dirs[3] + "/aoi.json");
  ASSERT_EQ(catalog.images.size(), tile.images.size());
  const EnuFrame frame(tile.enu_origin);
  const TileImage& im = tile.images[0];
  // The crop is a VRT of a few kB, not a copy of the pixels.
  EXPECT_LT(fs::file_size(im.crop_path), 16000u);
  EXPECT_LT(im.width_px, 2048);
  // Its pixels are the source window's.
  const FloatImage src = ReadFloatImage(im.source_path), crop = ReadFloatImage(im.crop_path);
  ASSERT_EQ(crop.width_px, im.width_px);
  ASSERT_EQ(crop.height_px, im.height_px);
  for (int y = 0; y < crop.height_px; y += 37) {
    for (int x = 0; x < crop.width_px; x += 41) {
      const std::size_t a = 3 * (static_cast<std::size_t>(y) * crop.width_px + x);
      const std::size_t b = 3 * (static_cast<std::size_t>(y + im.row0_px) * src.width_px + x + im.col0_px);
      ASSERT_EQ(crop.values[a], src.values[b]);
    }
  }
  // The RPC GDAL wrote into the VRT, the catalog's RPC and the source RPC
  // shifted by the window agree at the tile's corners (1e-6 px: round-off).
  const RpcModel from_vrt = ReadRpcFromRaster(im.crop_path);
  const RpcModel& source = jax.images[0].rpc;
  for (double h : {tile.min_ellipsoid_height_m, tile.max_ellipsoid_height_m}) {
    for (const Eigen::Vector2d& en : {tile.extent.min_m, tile.extent.max_m}) {
      const GeodeticPoint g = frame.GeodeticFromEnu({en.x(), en.y(), 0.0});
      const Eigen::Vector2d full = source.Project(g.lon_deg, g.lat_deg, h);
      const Eigen::Vector2d shifted = full - Eigen::Vector2d(im.col0_px, im.row0_px);
      EXPECT_NEAR((from_vrt.Project(g.lon_deg, g.lat_deg, h) - shifted).norm(), 0.0, 1e-6);
      EXPECT_NEAR((catalog.images[0].rpc.Project(g.lon_deg, g.lat_deg, h) - shifted).norm(), 0.0, 1e-6);
      // ...and a corner the source image sees lies inside the crop.
      const int source_width = ReadRasterInfo(im.source_path).width_px;
      if (full.x() >= 0 && full.x() < source_width) {
        EXPECT_GE(shifted.x(), 0.0);
        EXPECT_LT(shifted.x(), im.width_px);
      }
    }
  }
  // Re-tiling leaves identical files untouched (finished runs keep their inputs).
  const auto before = fs::last_write_time(r.tile_dirs[3] + "/tile.json");
  WriteTiles(PlanTiles(o, {jax}), (dir / "tiles").string(), progress);
  EXPECT_EQ(fs::last_write_time(r.tile_dirs[3] + "/tile.json"), before);
}

// The tiles' bundle adjustments share a frame only through the acquisitions
// they all hold: those go into every tile's catalog when the tiles differ.
TEST(Tiling, TilesHoldingDifferentPassesAreGivenTheAcquisitionsAllHold) {
  auto plan_of = [](const std::vector<std::vector<std::string>>& tiles) {
    TilePlan plan;
    for (const auto& times : tiles) {
      AoiCatalog c;
      for (const std::string& t : times) {
        ImageRecord im;
        im.name = "image_" + t;
        im.acquisition_time = t;
        c.images.push_back(im);
      }
      plan.catalogs.push_back(c);
    }
    AssignGaugeAcquisitions(&plan);
    return plan;
  };
  const TilePlan differ = plan_of({{"a", "b", "c", "d"}, {"a", "b", "c", "e"}, {}, {"b", "c", "d", "e"}});
  EXPECT_TRUE(differ.gauge_shared);
  EXPECT_EQ(differ.catalogs[0].gauge_acquisitions, (std::vector<std::string>{"b", "c"}));
  EXPECT_EQ(differ.catalogs[3].gauge_acquisitions, (std::vector<std::string>{"b", "c"}));
  EXPECT_TRUE(differ.catalogs[2].gauge_acquisitions.empty());  // no images, nothing to fix
  EXPECT_NE(differ.gauge.find("2 acquisitions all 3 tiles hold"), std::string::npos) << differ.gauge;
  // The same passes everywhere: every tile's average is already the same one.
  const TilePlan same = plan_of({{"a", "b"}, {"a", "b"}});
  EXPECT_TRUE(same.gauge_shared);
  EXPECT_TRUE(same.catalogs[0].gauge_acquisitions.empty());
  // One pass in common fixes no height: said, and left to each tile.
  const TilePlan one = plan_of({{"a", "b"}, {"b", "c"}});
  EXPECT_FALSE(one.gauge_shared);
  EXPECT_TRUE(one.catalogs[0].gauge_acquisitions.empty());
  EXPECT_NE(one.gauge.find("may step at tile borders"), std::string::npos) << one.gauge;
  // Without acquisition times the shared passes are unknown.
  const TilePlan unknown = plan_of({{"a", ""}, {"a", "b"}});
  EXPECT_FALSE(unknown.gauge_shared);
  EXPECT_TRUE(unknown.catalogs[1].gauge_acquisitions.empty());
  // The catalog keeps the list, and writes nothing when there is none.
  AoiCatalog listed;  // no images: the round trip is about the list
  listed.gauge_acquisitions = differ.catalogs[0].gauge_acquisitions;
  EXPECT_EQ(AoiCatalogFromJson(AoiCatalogToJson(listed), "test").gauge_acquisitions, listed.gauge_acquisitions);
  EXPECT_EQ(AoiCatalogToJson(AoiCatalog()).find("gauge_acquisitions"), std::string::npos);
}

TEST(Tiling, EmptyOrInconsistentInputIsAClearError) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("tiles");
  AoiCatalog jax = IngestJax(dir);
  TilingOptions o;
  EXPECT_NE(ErrorText([&] { PlanTiles(o, {}); }).find("no AOI"), std::string::npos);
  AoiCatalog other = jax;
  other.aoi = "OTHER";
  other.epsg = 32618;
  EXPECT_NE(ErrorText([&] { PlanTiles(o, {jax, other}); }).find("OTHER: UTM EPSG 32618"), std::string::npos);
  AoiCatalog empty = jax;
  empty.images.clear();
  EXPECT_NE(ErrorText([&] { PlanTiles(o, {empty}); }).find("JAX_068: the AOI has no images"), std::string::npos);
  o.overlap_m = 300;
  EXPECT_NE(ErrorText([&] { PlanTiles(o, {jax}); }).find("overlap_m"), std::string::npos);
  // A tile that no image sees is kept, empty, rather than failing the city.
  TilingOptions strict;
  strict.min_coverage = 0.5;
  strict.tile_m = 64;
  strict.overlap_m = 8;
  AoiCatalog narrow = jax;
  narrow.images.resize(2);
  for (auto& im : narrow.images) im.width_px = im.width_px / 2;  // sees only part of the AOI
  const TilePlan plan = PlanTiles(strict, {narrow});
  int empty_tiles = 0;
  for (const TileSpec& t : plan.tiles) empty_tiles += t.images.empty();
  EXPECT_GT(empty_tiles, 0);
  EXPECT_LT(empty_tiles, static_cast<int>(plan.tiles.size()));
}

}  // namespace
}  // namespace skyfall
