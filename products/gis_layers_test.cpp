#include "products/gis_layers.h"

#include <gdal.h>
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "ingest/geo.h"
#include "ingest/vertical_datum.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// Jacksonville, near sea level: the frame of the DFC2019 truth.
const GeodeticPoint kOrigin{-81.6636, 30.3577, 5.0};
constexpr int kUtm17N = 32617;

// A grid of `n` x `n` pixels of 0.5 m centred on the ENU origin.
DsmGrid GridAroundOrigin(int n) {
  const Eigen::Vector2d utm = UtmFromGeodetic(UtmZoneFromEpsg(kUtm17N), kOrigin.lon_deg, kOrigin.lat_deg);
  DsmGrid g;
  g.width_px = g.height_px = n;
  g.gsd_m = 0.5;
  g.epsg = kUtm17N;
  g.upper_left_easting_m = utm.x() - 0.25 * n;
  g.upper_left_northing_m = utm.y() + 0.25 * n;
  g.height_m.assign(static_cast<std::size_t>(n) * n, NAN);
  return g;
}

// Cells of 0.5 m over [x0, x1) x [-10, 10) ENU with the given layers.
DenseCells Cells(double x0, double x1, float terrain_m, std::uint8_t views, FillRule rule) {
  DenseCells c;
  c.cell_m = 0.5;
  for (double y = -10; y < 10; y += 0.5)
    for (double x = x0; x < x1; x += 0.5) {
      c.points.emplace_back(x, y, terrain_m + 3.0f);
      c.colours.emplace_back(0.5f, 0.5f, 0.5f);
      c.filled.push_back(rule != FillRule::kMatched);
      c.cost.push_back(0.25f);
      c.fill_rule.push_back(rule);
      c.views.push_back(views);
      c.terrain_m.push_back(terrain_m);
    }
  return c;
}

TileSpec Spec(int col) {
  TileSpec s;
  s.col = col;
  s.grid.origin_m = {-20, -10};
  s.grid.tile_m = 20;  // tile 0 owns east < 0, tile 1 east >= 0
  s.grid.cols = 2;
  s.grid.rows = 1;
  return s;
}

// Two tiles overlap by 4 m around east = 0; each pixel takes the cell of the
// tile whose core owns it, and the terrain goes from ENU up to the ellipsoid.
TEST(GisLayers, DenseLayersComeFromTheOwningTile) {
  std::vector<DenseTileCells> tiles = {{Cells(-10, 2, 1.0f, 4, FillRule::kMatched), Spec(0)},
                                       {Cells(-2, 10, 2.0f, 7, FillRule::kSeenHole), Spec(1)}};
  const DsmGrid grid = GridAroundOrigin(24);  // 12 m: east -6 .. 6
  const DenseLayers layers = SampleDenseLayers(tiles, kOrigin, grid);
  const EnuFrame frame(kOrigin);
  const UtmZone zone = UtmZoneFromEpsg(kUtm17N);
  for (int row = 0; row < grid.height_px; row += 5)
    for (int col = 0; col < grid.width_px; ++col) {
      const std::size_t p = static_cast<std::size_t>(row) * grid.width_px + col;
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, grid.upper_left_easting_m + (col + 0.5) * 0.5,
                                                 grid.upper_left_northing_m - (row + 0.5) * 0.5);
      const Eigen::Vector3d enu = frame.EnuFromGeodetic({ll.x(), ll.y(), kOrigin.height_m});
      const bool east = enu.x() >= 0;
      EXPECT_EQ(layers.views[p], east ? 7.0f : 4.0f) << enu.x();
      EXPECT_EQ(layers.fill_rule[p], east ? 4.0f : 0.0f);
      EXPECT_FLOAT_EQ(layers.cost[p], 0.25f);
      const double expected = frame.GeodeticFromEnu({enu.x(), enu.y(), east ? 2.0 : 1.0}).height_m;
      EXPECT_NEAR(layers.dtm.height_m[p], expected, 1e-3);
      // Within 6 m of the origin the ENU plane and the ellipsoid part by < 3 mm.
      EXPECT_NEAR(layers.dtm.height_m[p], kOrigin.height_m + (east ? 2.0 : 1.0), 0.003);
    }
  EXPECT_EQ(layers.dtm.reference, HeightReference::kEllipsoid);
  // A tile whose dense.ply predates the layers gives NaN, not zeros.
  tiles[1].cells.terrain_m.clear();
  tiles[1].cells.views.clear();
  const DenseLayers older = SampleDenseLayers(tiles, kOrigin, grid);
  EXPECT_TRUE(std::isnan(older.views.back()));
  EXPECT_TRUE(std::isnan(older.dtm.height_m.back()));
}

GaussianCloud Gaussians(const std::vector<Eigen::Vector3f>& means, float log_scale_z) {
  GaussianCloud c;
  for (const Eigen::Vector3f& m : means) {
    c.means.push_back(m);
    c.log_scales.emplace_back(std::log(0.1f), std::log(0.1f), log_scale_z);
    c.rotations.emplace_back(1.0f, 0.0f, 0.0f, 0.0f);
    c.opacity_logits.push_back(4.0f);
    c.sh.push_back({});
  }
  return c;
}

// Two thin Gaussians 2 m apart in one pixel spread 1 m; one Gaussian alone
// spreads its own vertical extent, also when it is rotated to stand upright.
TEST(GisLayers, HeightSpreadIsTheMixtureStandardDeviation) {
  const DsmGrid grid = GridAroundOrigin(8);
  const std::vector<float> two =
      GaussianHeightSpreadM(Gaussians({{0.1f, 0.1f, 0.0f}, {0.1f, 0.1f, 2.0f}}, std::log(1e-4f)), kOrigin, grid, 0.5);
  const std::vector<float> one = GaussianHeightSpreadM(Gaussians({{0.1f, 0.1f, 0.0f}}, std::log(0.3f)), kOrigin, grid, 0.5);
  GaussianCloud standing = Gaussians({{0.1f, 0.1f, 0.0f}}, std::log(0.01f));
  standing.log_scales[0].y() = std::log(0.7f);
  standing.rotations[0] = Eigen::Vector4f(std::cos(M_PI / 4), std::sin(M_PI / 4), 0, 0);  // 90 deg about east
  const std::vector<float> upright = GaussianHeightSpreadM(standing, kOrigin, grid, 0.5);
  int found = 0;
  for (std::size_t p = 0; p < two.size(); ++p) {
    if (!std::isfinite(two[p])) continue;
    ++found;
    EXPECT_NEAR(two[p], 1.0f, 1e-3f);
    EXPECT_NEAR(one[p], 0.3f, 1e-3f);
    EXPECT_NEAR(upright[p], 0.7f, 1e-3f);
  }
  EXPECT_EQ(found, 1);
  // Too transparent to count: no spread anywhere.
  GaussianCloud faint = Gaussians({{0.1f, 0.1f, 0.0f}}, 0.0f);
  faint.opacity_logits[0] = -4.0f;
  for (float v : GaussianHeightSpreadM(faint, kOrigin, grid, 0.5)) EXPECT_TRUE(std::isnan(v));
}

TEST(GisLayers, AnNdsmIsTheDsmAboveTheDtmOnOneGrid) {
  DsmGrid dsm = GridAroundOrigin(4), dtm = GridAroundOrigin(4);
  std::fill(dsm.height_m.begin(), dsm.height_m.end(), 30.0f);
  std::fill(dtm.height_m.begin(), dtm.height_m.end(), 25.5f);
  dtm.height_m[3] = NAN;
  const DsmGrid ndsm = HeightAboveTerrain(dsm, dtm);
  EXPECT_EQ(ndsm.reference, HeightReference::kAboveTerrain);
  EXPECT_FLOAT_EQ(ndsm.height_m[0], 4.5f);
  EXPECT_TRUE(std::isnan(ndsm.height_m[3]));
  dtm.reference = HeightReference::kEgm96;
  EXPECT_THROW(HeightAboveTerrain(dsm, dtm), Error);
}

// A truth of flat ground at 10 m with an 8 m building (class 6): a DTM 0.3 m
// high on the ground and an nDSM 0.5 m low on the roof give those errors.
TEST(GisLayers, TerrainIsComparedOnGroundAndTheNdsmOnBuildings) {
  constexpr int kN = 60;
  DsmGrid truth = GridAroundOrigin(kN), dtm = GridAroundOrigin(kN), ndsm = GridAroundOrigin(kN);
  std::vector<float> cls(static_cast<std::size_t>(kN) * kN, 2.0f);
  for (int r = 0; r < kN; ++r)
    for (int c = 0; c < kN; ++c) {
      const std::size_t p = static_cast<std::size_t>(r) * kN + c;
      const bool building = r >= 20 && r < 40 && c >= 20 && c < 40;
      cls[p] = building ? 6.0f : 2.0f;
      truth.height_m[p] = building ? 18.0f : 10.0f;
      dtm.height_m[p] = 10.3f;
      ndsm.height_m[p] = building ? 7.5f : 0.0f;
    }
  const TerrainComparison t = CompareTerrain(dtm, ndsm, truth, cls, 0, 0, 0.0);
  EXPECT_NEAR(t.dtm_mae_ground_m, 0.3, 1e-5);
  EXPECT_NEAR(t.dtm_bias_ground_m, 0.3, 1e-5);
  EXPECT_NEAR(t.ndsm_mae_building_m, 0.5, 1e-5);
  EXPECT_NEAR(t.ndsm_bias_building_m, -0.5, 1e-5);
  EXPECT_EQ(t.building_cells, 400);
  EXPECT_EQ(t.ground_cells, kN * kN - 400);
  // The DSM comparison's vertical offset is the DTM's too.
  EXPECT_NEAR(CompareTerrain(dtm, ndsm, truth, cls, 0, 0, 0.3).dtm_mae_ground_m, 0.0, 1e-5);
}

// Texture with a 5 m wavelength, a function of longitude and latitude.
double Texture(double lon, double lat) {
  return 0.5 + 0.3 * std::sin(lon * 2 * M_PI / 5e-5) * std::cos(lat * 2 * M_PI / 4.5e-5);
}

// An image of 0.5 m pixels north up around the origin, with an affine RPC.
struct RpcImage {
  RpcModel rpc;
  NormalizedImage image;
};
RpcImage AffineRpcImage(int size_px) {
  RpcImage out;
  RpcModel& r = out.rpc;
  r.lon_off = kOrigin.lon_deg;
  r.lat_off = kOrigin.lat_deg;
  r.lon_scale = r.lat_scale = 0.01;
  r.samp_off = r.line_off = 0.5 * (size_px - 1);
  r.samp_scale = 0.01 / 5.2e-6;  // about 0.5 m per pixel east at 30 deg north
  r.line_scale = 0.01 / 4.5e-6;
  r.samp_num[1] = 1;   // col = L
  r.line_num[2] = -1;  // row = -P: rows go south
  r.samp_den[0] = r.line_den[0] = 1;
  out.image.width_px = out.image.height_px = size_px;
  out.image.rgb.resize(3 * static_cast<std::size_t>(size_px) * size_px);
  out.image.valid.assign(static_cast<std::size_t>(size_px) * size_px, 1);
  for (int row = 0; row < size_px; ++row)
    for (int col = 0; col < size_px; ++col) {
      const double lon = r.lon_off + (col - r.samp_off) / r.samp_scale * r.lon_scale;
      const double lat = r.lat_off - (row - r.line_off) / r.line_scale * r.lat_scale;
      for (int b = 0; b < 3; ++b)
        out.image.rgb[3 * (static_cast<std::size_t>(row) * size_px + col) + b] = static_cast<float>(Texture(lon, lat));
    }
  return out;
}

// The orthophoto of the texture agrees with the image on ground cells; the
// same ortho two pixels east is found at that shift, and noise does not agree.
TEST(GisLayers, TheOrthoIsComparedWithTheImageOnGroundCells) {
  constexpr int kN = 80;
  const RpcImage shot = AffineRpcImage(300);
  DsmGrid truth = GridAroundOrigin(kN);
  std::fill(truth.height_m.begin(), truth.height_m.end(), 0.0f);
  std::vector<float> cls(static_cast<std::size_t>(kN) * kN, 2.0f);
  for (int r = 30; r < 50; ++r)
    for (int c = 30; c < 50; ++c) cls[static_cast<std::size_t>(r) * kN + c] = 6.0f;
  const UtmZone zone = UtmZoneFromEpsg(kUtm17N);
  auto ortho_shifted = [&](int shift_cols) {
    std::vector<float> rgb(3 * static_cast<std::size_t>(kN) * kN);
    for (int r = 0; r < kN; ++r)
      for (int c = 0; c < kN; ++c) {
        const Eigen::Vector2d ll = GeodeticFromUtm(zone, truth.upper_left_easting_m + (c - shift_cols + 0.5) * 0.5,
                                                   truth.upper_left_northing_m - (r + 0.5) * 0.5);
        for (int b = 0; b < 3; ++b) rgb[3 * (static_cast<std::size_t>(r) * kN + c) + b] = static_cast<float>(Texture(ll.x(), ll.y()));
      }
    return rgb;
  };
  const OrthoAgreement same = CompareOrthoWithImage(ortho_shifted(0), truth, cls, shot.image, shot.rpc, 0, 0);
  EXPECT_GT(same.psnr_db, 35.0);  // bilinear resampling of a 5 m texture at 0.5 m
  EXPECT_GT(same.ssim, 0.98);
  EXPECT_EQ(same.shift_col_px, 0);
  EXPECT_EQ(same.shift_row_px, 0);
  EXPECT_LE(same.cells, kN * kN - 400);  // the building's cells are left out
  const OrthoAgreement moved = CompareOrthoWithImage(ortho_shifted(2), truth, cls, shot.image, shot.rpc, 0, 0);
  EXPECT_EQ(moved.shift_col_px, 2);
  EXPECT_NEAR(moved.psnr_db, same.psnr_db, 1.0);
  std::vector<float> noise(3 * static_cast<std::size_t>(kN) * kN);
  for (std::size_t k = 0; k < noise.size(); ++k) noise[k] = static_cast<float>((k * 7919 % 1000) / 1000.0);
  const OrthoAgreement wrong = CompareOrthoWithImage(noise, truth, cls, shot.image, shot.rpc, 0, 0);
  EXPECT_LT(wrong.psnr_db, 15.0);
  EXPECT_LT(wrong.ssim, 0.3);
  // A 20 m block (class 6) seen from 30 deg off nadir in the east hides the
  // ground west of it up to 20 m * tan(30 deg) = 11.5 m (23 cells) away.
  for (int r = 30; r < 50; ++r)
    for (int c = 30; c < 50; ++c) truth.height_m[static_cast<std::size_t>(r) * kN + c] = 20.0f;
  const OrthoAgreement oblique = CompareOrthoWithImage(ortho_shifted(0), truth, cls, shot.image, shot.rpc, 30, 90);
  EXPECT_NEAR(same.cells - oblique.cells, 20 * 23, 20 * 2) << same.cells << " " << oblique.cells;
}

// An orthophoto at half the contrast and a tint of the image it is matched
// to gets that image's colours back: gain 2 and offset -0.2 per band.
TEST(GisLayers, ColoursAreMatchedToTheChosenImage) {
  constexpr int kN = 80;
  const RpcImage shot = AffineRpcImage(300);
  DsmGrid dsm = GridAroundOrigin(kN);
  std::fill(dsm.height_m.begin(), dsm.height_m.end(), 0.0f);
  const UtmZone zone = UtmZoneFromEpsg(kUtm17N);
  std::vector<float> rgb(3 * static_cast<std::size_t>(kN) * kN), exact(rgb.size());
  for (int r = 0; r < kN; ++r)
    for (int c = 0; c < kN; ++c) {
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, dsm.upper_left_easting_m + (c + 0.5) * 0.5,
                                                 dsm.upper_left_northing_m - (r + 0.5) * 0.5);
      for (int b = 0; b < 3; ++b) {
        const std::size_t k = 3 * (static_cast<std::size_t>(r) * kN + c) + b;
        exact[k] = static_cast<float>(Texture(ll.x(), ll.y()));
        rgb[k] = 0.5f * exact[k] + 0.1f;
      }
    }
  rgb[0] = rgb[1] = rgb[2] = NAN;  // an empty pixel stays empty
  const ColourMatch match = MatchColoursToImage(rgb, dsm, shot.image, shot.rpc, 0, 0);
  EXPECT_GT(match.cells, kN * kN / 2);
  // The image resamples the texture bilinearly at 10 pixels per wavelength,
  // which lowers its contrast by 4%: the fitted gain comes out 1.92.
  constexpr double kResamplingGainTol = 0.1, kResamplingOffsetTol = 0.05;
  for (int b = 0; b < 3; ++b) {
    EXPECT_NEAR(match.gain[b], 2.0, kResamplingGainTol);
    EXPECT_NEAR(match.offset[b], -0.2, kResamplingOffsetTol);
  }
  ApplyColourMatch(match, &rgb);
  EXPECT_TRUE(std::isnan(rgb[0]));
  double worst = 0;
  for (std::size_t k = 3; k < rgb.size(); ++k) worst = std::max(worst, std::abs(static_cast<double>(rgb[k] - exact[k])));
  EXPECT_LT(worst, 0.05);
  // Too few cells to fit: the colours stay.
  DsmGrid outside = dsm;
  std::fill(outside.height_m.begin(), outside.height_m.end(), NAN);
  const ColourMatch none = MatchColoursToImage(rgb, outside, shot.image, shot.rpc, 0, 0);
  EXPECT_EQ(none.cells, 0);
  EXPECT_EQ(none.gain[0], 1.0);
}

// Each written layer is a valid COG with named bands; the orthophoto has an
// alpha band where the scene is empty.
TEST(GisLayers, QualityAndOrthoAreNamedCogs) {
  const fs::path dir = ScratchDir("gis_layers");
  const DsmGrid grid = GridAroundOrigin(300);
  const std::size_t n = static_cast<std::size_t>(300) * 300;
  DenseLayers dense;
  dense.views.assign(n, 3.0f);
  dense.fill_rule.assign(n, 2.0f);
  dense.cost.assign(n, 0.5f);
  WriteQualityCog((dir / "quality.tif").string(), grid, dense, std::vector<float>(n, 0.1f));
  std::vector<float> rgb(3 * n, 0.25f);
  rgb[0] = rgb[1] = rgb[2] = NAN;
  WriteOrthoCog((dir / "ortho.tif").string(), grid, rgb, {false, 8}, {{"APPEARANCE", "test"}});
  WriteOrthoCog((dir / "ortho16.tif").string(), grid, rgb, {true, 16}, {});
  GDALAllRegister();
  GDALDatasetH quality = GDALOpen((dir / "quality.tif").c_str(), GA_ReadOnly);
  ASSERT_NE(quality, nullptr);
  ASSERT_EQ(GDALGetRasterCount(quality), 4);
  const char* names[] = {"views", "fill_rule", "matching_cost", "height_spread_m"};
  for (int b = 0; b < 4; ++b) EXPECT_STREQ(GDALGetDescription(GDALGetRasterBand(quality, b + 1)), names[b]);
  GDALClose(quality);
  GDALDatasetH ortho = GDALOpen((dir / "ortho.tif").c_str(), GA_ReadOnly);
  ASSERT_EQ(GDALGetRasterCount(ortho), 4);
  EXPECT_EQ(GDALGetRasterColorInterpretation(GDALGetRasterBand(ortho, 4)), GCI_AlphaBand);
  std::uint8_t px[4];
  for (int b = 0; b < 4; ++b)
    ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ortho, b + 1), GF_Read, 0, 0, 1, 1, &px[b], 1, 1, GDT_Byte, 0, 0), CE_None);
  EXPECT_EQ(px[3], 0);  // empty
  ASSERT_EQ(GDALRasterIO(GDALGetRasterBand(ortho, 1), GF_Read, 1, 0, 1, 1, &px[0], 1, 1, GDT_Byte, 0, 0), CE_None);
  EXPECT_EQ(px[0], 64);  // 0.25 * 255, rounded
  GDALClose(ortho);
  GDALDatasetH grey = GDALOpen((dir / "ortho16.tif").c_str(), GA_ReadOnly);
  EXPECT_EQ(GDALGetRasterCount(grey), 2);
  EXPECT_EQ(GDALGetRasterDataType(GDALGetRasterBand(grey, 1)), GDT_UInt16);
  GDALClose(grey);
  for (const char* name : {"quality.tif", "ortho.tif", "ortho16.tif"}) {
    const CommandResult v = RunCommand(
        "/usr/bin/python3 /usr/lib/python3/dist-packages/osgeo_utils/samples/validate_cloud_optimized_geotiff.py " +
            (dir / name).string(),
        dir);
    EXPECT_EQ(v.exit_code, 0) << v.out << v.err;
  }
}

// Ground points lie within the tolerance of the DTM; EGM96 heights are the
// ellipsoidal ones less the undulation.
TEST(GisLayers, ScenePointsAreClassifiedAgainstTheDtm) {
  DsmGrid dtm = GridAroundOrigin(40);
  std::fill(dtm.height_m.begin(), dtm.height_m.end(), static_cast<float>(kOrigin.height_m));
  const GaussianCloud scene = Gaussians({{0, 0, 0.2f}, {1, 1, 6.0f}, {-2, 3, 0.0f}}, std::log(0.1f));
  const std::vector<LasPoint> ell = ScenePoints(scene, kOrigin, dtm, HeightReference::kEllipsoid, 0.5, 1.0);
  ASSERT_EQ(ell.size(), 3u);
  EXPECT_EQ(ell[0].classification, 2);
  EXPECT_EQ(ell[1].classification, 1);
  EXPECT_EQ(ell[2].classification, 2);
  EXPECT_NEAR(ell[1].height_m, kOrigin.height_m + 6.0, 0.01);
  const std::vector<LasPoint> egm = ScenePoints(scene, kOrigin, dtm, HeightReference::kEgm96, 0.5, 1.0);
  const double n = Egm96UndulationsM({{kOrigin.lon_deg, kOrigin.lat_deg}}).at(0);
  EXPECT_NEAR(egm[1].height_m - ell[1].height_m, -n, 0.01);
  EXPECT_THROW(ScenePoints(scene, kOrigin, dtm, HeightReference::kAboveTerrain, 0.5, 1.0), Error);
}

// Above ground, a point takes its cell's class when the land cover names
// an object (building 6, high vegetation 5); ground stays ground whatever
// the cell says, and a cell "above ground, untold" (1) gives class 1.
TEST(GisLayers, ScenePointsTakeTheirCellsLandCover) {
  DsmGrid dtm = GridAroundOrigin(40);
  std::fill(dtm.height_m.begin(), dtm.height_m.end(), static_cast<float>(kOrigin.height_m));
  const GaussianCloud scene =
      Gaussians({{1.25f, 1.25f, 6.0f}, {-3.25f, -3.25f, 8.0f}, {4.25f, -4.25f, 5.0f}, {-1.25f, 2.25f, 0.1f}},
                std::log(0.1f));
  std::vector<std::uint8_t> cover(dtm.height_m.size(), 2);
  // The pixel of a point at ENU (east, north): the grid's upper left corner
  // is 10 m west and north of the origin, pixels 0.5 m (points sit at pixel
  // centres, clear of the UTM grid's 0.3 degree convergence here).
  auto cell = [&](double east_m, double north_m) -> std::uint8_t& {
    const int col = static_cast<int>(std::floor((east_m + 10) / 0.5)), row = static_cast<int>(std::floor((10 - north_m) / 0.5));
    return cover[static_cast<std::size_t>(row) * 40 + col];
  };
  cell(1.25, 1.25) = 6;
  cell(-3.25, -3.25) = 5;
  cell(4.25, -4.25) = 1;
  cell(-1.25, 2.25) = 6;
  const std::vector<LasPoint> p = ScenePoints(scene, kOrigin, dtm, HeightReference::kEllipsoid, 0.5, 1.0, cover);
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0].classification, 6);
  EXPECT_EQ(p[1].classification, 5);
  EXPECT_EQ(p[2].classification, 1);
  EXPECT_EQ(p[3].classification, 2);  // on the ground, under a roof's edge cell
  EXPECT_THROW(ScenePoints(scene, kOrigin, dtm, HeightReference::kEllipsoid, 0.5, 1.0, {6, 6}), Error);
}

}  // namespace
}  // namespace skyfall
