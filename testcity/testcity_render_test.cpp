// The test city's renderer: RPCs that reproduce its cameras, occlusion,
// shadows, smooth roofs and terrain, pixel integration.
#include "testcity/testcity.h"

#include <gtest/gtest.h>

#include <functional>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <regex>
#include <nlohmann/json.hpp>
#include <set>

#include "catalogs/aoi_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/test_support.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "ingest/height_probe.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"
#include "tiling/tiling.h"
#include "testcity/test_scene.h"

namespace skyfall::synth {
namespace {

using namespace skyfall::testing;
using namespace skyfall::synth::testing_scene;


// Ground-to-image through the RPC written into a TIFF.
Eigen::Vector2d ProjectScenePoint(const RpcModel& rpc, const SynthResult& r, const Eigen::Vector3d& s) {
  const UtmZone zone = UtmZoneFromEpsg(r.epsg);
  const Eigen::Vector2d ll = GeodeticFromUtm(zone, r.utm_easting0_m + s.x(), r.utm_northing0_m + s.y());
  return rpc.Project(ll.x(), ll.y(), s.z());
}

// The tallest flat-roofed building inside the AOI [0, aoi_m]^2 (the city
// also fills the margin around it).
int TallestFlatBuilding(const City& city, double aoi_m = 128.0) {
  int best = -1;
  for (int b = 0; b < static_cast<int>(city.buildings.size()); ++b) {
    const Building& bld = city.buildings[b];
    const bool inside = bld.x0_m > 8 && bld.y0_m > 8 && bld.x1_m < aoi_m - 8 && bld.y1_m < aoi_m - 8;
    if (inside && !bld.gable && (best < 0 || bld.eave_m > city.buildings[best].eave_m)) best = b;
  }
  return best;
}

// The view with the largest (or smallest) off-nadir angle.
const SynthView& ExtremeView(const SynthResult& r, bool most_oblique) {
  const auto& views = r.aois.at(0).views;
  return *std::max_element(views.begin(), views.end(), [&](const SynthView& a, const SynthView& b) {
    return most_oblique ? a.off_nadir_deg < b.off_nadir_deg : a.off_nadir_deg > b.off_nadir_deg;
  });
}

// `v` rendered under its own lighting as `change` alters it.
RenderedView RenderUnder(const SynthResult& r, const SynthView& v, const std::function<void(Lighting&)>& change) {
  Lighting light = v.lighting;
  change(light);
  return RenderView(r.city, v.camera, r.scene_from_enu, light);
}

// SynthOptions::Check refuses the options as `set` changes them.
void ExpectCheckRefuses(const std::function<void(SynthOptions&)>& set) {
  SynthOptions o;
  set(o);
  EXPECT_THROW(o.Check(), Error);
}

// A view rendered without and with cast shadows.
struct ShadowPair {
  RenderedView lit, shaded;
  Eigen::Vector3d sun;  // unit, towards the sun
};
ShadowPair RenderWithAndWithoutShadows(const Scene& s, const SynthView& v) {
  Lighting no_shadows = v.lighting;
  no_shadows.cast_shadows = false;
  return {RenderView(s.result.city, v.camera, s.result.scene_from_enu, no_shadows),
          RenderView(s.result.city, v.camera, s.result.scene_from_enu, v.lighting), v.lighting.sun_scene.normalized()};
}
// Whether the shadows darken pixel k: by more than 15 DN over the three
// bands, well above the +-1 DN noise per band.
bool DarkenedByShadow(const ShadowPair& p, std::size_t k) {
  const int lit = p.lit.rgb[3 * k] + p.lit.rgb[3 * k + 1] + p.lit.rgb[3 * k + 2];
  const int shaded = p.shaded.rgb[3 * k] + p.shaded.rgb[3 * k + 1] + p.shaded.rgb[3 * k + 2];
  return shaded < lit - 15;
}

TEST(Synth, WrittenRpcsReproduceTheTrueCamerasWithinAHundredthOfAPixel) {
  const Scene s = MakeScene(SynthOptions{});  // the default scene: 256 m, 12 views
  const EnuFrame frame(s.result.enu_origin);
  double worst = 0;
  for (const SynthView& v : s.result.aois.at(0).views) {
    EXPECT_LE(v.rpc_fit_max_px, kRpcFitTolPx) << v.name;
    // Independently of the fit's own check grid: read the TIFF's RPC back
    // and compare with the camera at scene points over the whole AOI.
    const RpcModel rpc = ReadRpcFromRaster(v.path);
    for (double fx : {0.03, 0.5, 0.97})
      for (double fy : {0.1, 0.62})
        for (double z : {-21.0, 0.0, 45.0}) {
          const Eigen::Vector3d p(fx * 256.0, fy * 256.0, z);
          const UtmZone zone = UtmZoneFromEpsg(s.result.epsg);
          const Eigen::Vector2d ll = GeodeticFromUtm(zone, s.result.utm_easting0_m + p.x(),
                                                     s.result.utm_northing0_m + p.y());
          const Eigen::Vector2d truth = v.camera.Project(frame.EnuFromGeodetic({ll.x(), ll.y(), z}));
          const double e = (rpc.Project(ll.x(), ll.y(), z) - truth).norm();
          worst = std::max(worst, e);
          EXPECT_LT(e, kRpcFitTolPx) << v.name;
        }
    // Like WorldView-3: 5-35 deg off nadir, hundreds of km away.
    EXPECT_GE(v.off_nadir_deg, 5.0);
    EXPECT_LE(v.off_nadir_deg, 35.0);
    EXPECT_GT(v.range_km, 600.0);
    EXPECT_LT(v.range_km, 800.0);
  }
  std::printf("[figures] default scene: worst RPC-vs-camera error %.3g px over 12 views; affine "
              "ENU->scene error %.3g m\n", worst, s.result.scene_from_enu.max_error_m);
  EXPECT_LT(s.result.scene_from_enu.max_error_m, 0.01);
}

TEST(Synth, RoofCornerProjectsThroughTheRpcToWhereTheRendererDrewIt) {
  const Scene s = MakeScene(SmallScene());
  const City& city = s.result.city;
  const int b = TallestFlatBuilding(city);
  ASSERT_GE(b, 0);
  const Building& bld = city.buildings[b];
  for (const SynthView& v : s.result.aois.at(0).views) {
    const RpcModel rpc = ReadRpcFromRaster(v.path);
    // The roof corner as built: the footprint rasterized to whole columns
    // (cells whose centre lies inside it). The tallest roof is never hidden
    // by another building.
    Eigen::Vector2i cell = city.CellOf(bld.x1_m, bld.y1_m);
    if (city.CellCentre(cell.x(), cell.y()).x() > bld.x1_m) --cell.x();
    if (city.CellCentre(cell.x(), cell.y()).y() > bld.y1_m) --cell.y();
    const Eigen::Vector2d corner_xy =
        city.CellCentre(cell.x(), cell.y()) + Eigen::Vector2d::Constant(0.5 * city.options.cell_m);
    const Eigen::Vector3d corner(corner_xy.x(), corner_xy.y(), bld.eave_m);
    const Eigen::Vector2d px = ProjectScenePoint(rpc, s.result, corner);
    ASSERT_TRUE(px.x() > 3 && px.y() > 3 && px.x() < v.camera.width_px - 4 && px.y() < v.camera.height_px - 4);
    const RenderedView img = RenderView(city, v.camera, s.result.scene_from_enu, v.lighting);
    int roof_pixels = 0;
    const int c0 = static_cast<int>(std::round(px.x())), r0 = static_cast<int>(std::round(px.y()));
    for (int r = r0 - 3; r <= r0 + 3; ++r)
      for (int c = c0 - 3; c <= c0 + 3; ++c) {
        const size_t k = static_cast<size_t>(r) * img.width_px + c;
        ASSERT_TRUE(img.hit_scene[k].allFinite());
        // Whatever the renderer drew at this pixel projects back onto it.
        const Eigen::Vector2d back = ProjectScenePoint(rpc, s.result, img.hit_scene[k].cast<double>());
        EXPECT_LT((back - Eigen::Vector2d(c, r)).norm(), kRenderVsRpcTolPx) << v.name;
        if (img.hit_object[k] == b && std::abs(img.hit_scene[k].z() - bld.eave_m) < 1e-3) {
          ++roof_pixels;
          // Roof pixels lie inside the footprint: on the corner's inner side.
          EXPECT_LE(img.hit_scene[k].x(), corner.x() + 1e-3);
          EXPECT_LE(img.hit_scene[k].y(), corner.y() + 1e-3);
        }
      }
    // Around a corner, roughly a quarter of the window is roof.
    EXPECT_GT(roof_pixels, 5) << v.name;
    EXPECT_LT(roof_pixels, 40) << v.name;
  }
}

TEST(Synth, BuildingsHideWhatIsBehindThemInObliqueViews) {
  const Scene s = MakeScene(SmallScene());
  const City& city = s.result.city;
  const int b = TallestFlatBuilding(city);
  const Building& bld = city.buildings[b];
  const SynthView* v = &ExtremeView(s.result, /*most_oblique=*/true);
  const RpcModel rpc = ReadRpcFromRaster(v->path);
  const RenderedView img = RenderView(city, v->camera, s.result.scene_from_enu, v->lighting);
  // A ground point just behind the building, seen from the satellite.
  const double az = v->view_azimuth_deg * M_PI / 180.0;
  const Eigen::Vector2d away(-std::sin(az), -std::cos(az));  // from the satellite over the building
  const Eigen::Vector2d centre(0.5 * (bld.x0_m + bld.x1_m), 0.5 * (bld.y0_m + bld.y1_m));
  const double half_diag = 0.5 * std::hypot(bld.x1_m - bld.x0_m, bld.y1_m - bld.y0_m);
  const double lean = (bld.eave_m - bld.base_m) * std::tan(v->view_zenith_deg * M_PI / 180.0);
  ASSERT_GT(lean, 4.0);  // tall and oblique enough to hide something
  const Eigen::Vector2d behind = centre + away * (half_diag + 0.5 * lean);
  const Eigen::Vector3d ground(behind.x(), behind.y(), city.TerrainAt(behind.x(), behind.y()));
  const Eigen::Vector2d px = ProjectScenePoint(rpc, s.result, ground);
  ASSERT_TRUE(px.x() >= 0 && px.y() >= 0 && px.x() < img.width_px - 1 && px.y() < img.height_px - 1);
  const size_t k = static_cast<size_t>(std::lround(px.y())) * img.width_px + std::lround(px.x());
  EXPECT_EQ(img.hit_object[k], b) << "the ground behind the building is visible in " << v->name;
  EXPECT_GT(img.hit_scene[k].z(), ground.z() + 2.0);
}

TEST(Synth, ShadowsDarkenGroundOnTheAntiSunSide) {
  const Scene s = MakeScene(SmallScene());
  const City& city = s.result.city;
  const int b = TallestFlatBuilding(city);
  const Building& bld = city.buildings[b];
  // The most nadir view sees the ground around the building best.
  const SynthView* v = &ExtremeView(s.result, /*most_oblique=*/false);
  const ShadowPair pair = RenderWithAndWithoutShadows(s, *v);
  const RenderedView& shaded = pair.shaded;
  // Count pixels whose hit is ground within the building's shadow length on
  // the anti-sun side, and compare their brightness with and without shadows.
  const Eigen::Vector2d to_sun = v->lighting.sun_scene.head<2>().normalized();
  int darker = 0, counted = 0;
  for (size_t k = 0; k < shaded.hit_scene.size(); ++k) {
    const Eigen::Vector3f h = shaded.hit_scene[k];
    if (!h.allFinite() || shaded.hit_object[k] >= 0) continue;
    // Just outside the footprint, opposite the sun, within 3 m.
    const Eigen::Vector2d centre(0.5 * (bld.x0_m + bld.x1_m), 0.5 * (bld.y0_m + bld.y1_m));
    const Eigen::Vector2d d = h.head<2>().cast<double>() - centre;
    const double half_x = 0.5 * (bld.x1_m - bld.x0_m), half_y = 0.5 * (bld.y1_m - bld.y0_m);
    const bool just_outside = std::abs(d.x()) < half_x + 3 && std::abs(d.y()) < half_y + 3 &&
                              (std::abs(d.x()) > half_x + 0.5 || std::abs(d.y()) > half_y + 0.5);
    if (!just_outside || d.dot(to_sun) > 0) continue;
    ++counted;
    darker += DarkenedByShadow(pair, k);
  }
  ASSERT_GT(counted, 20);
  EXPECT_GT(darker, counted * 8 / 10) << darker << " of " << counted;
}

TEST(Synth, GableRoofsAndTreeCrownsAreSmoothWithoutRisersOrStripesOfShadow) {
  // As flat-topped 0.25 m columns a gable's slope and a crown's dome would
  // be stairs whose risers, lit as walls, and their shadows stripe them
  // differently in every view and at every sun position.
  const Scene s = MakeScene(SmallScene());
  const City& city = s.result.city;
  const ShadowPair pair = RenderWithAndWithoutShadows(s, ExtremeView(s.result, /*most_oblique=*/true));
  // The smooth object a cell belongs to: a gable building (its index) or a
  // tree (-2 - its index); -1 otherwise.
  auto smooth_object = [&](const Eigen::Vector2i& c) {
    if (!city.Inside(c.x(), c.y())) return -1;
    const std::size_t k = city.Index(c.x(), c.y());
    if (city.material[k] == Material::kGableRoof) return city.object[k];
    if (city.material[k] == Material::kTree) return -2 - city.tree[k];
    return -1;
  };
  auto surface_at = [&](int object, double x, double y) {
    return object >= 0 ? RoofAt(city.buildings[object], x, y) : city.trees[-2 - object].CrownAt(x, y);
  };
  auto normal_at = [&](int object, double x, double y) {
    return object >= 0 ? RoofNormal(city.buildings[object], x, y) : city.trees[-2 - object].CrownNormal(x, y);
  };
  // Per kind (0 gable, 1 crown): pixels inside, those whose surface faces
  // the sun, and those of them shadows darken.
  int inside_pixels[2] = {0, 0}, sunlit[2] = {0, 0}, striped[2] = {0, 0};
  double worst_m = 0;
  for (std::size_t k = 0; k < pair.shaded.hit_scene.size(); ++k) {
    const Eigen::Vector3d h = pair.shaded.hit_scene[k].cast<double>();
    if (!h.allFinite()) continue;
    // Inside the object (a wall's hit lies on the boundary of its cell).
    const Eigen::Vector2i c = city.CellOf(h.x(), h.y());
    const int object = smooth_object(c);
    if (object == -1) continue;
    bool inside = true;
    for (int dj = -2; dj <= 2; ++dj)
      for (int di = -2; di <= 2; ++di) inside &= smooth_object(c + Eigen::Vector2i(di, dj)) == object;
    if (!inside) continue;
    const int kind = object >= 0 ? 0 : 1;
    ++inside_pixels[kind];
    const double off_m = std::abs(h.z() - surface_at(object, h.x(), h.y()));
    ASSERT_TRUE(std::isfinite(off_m));
    worst_m = std::max(worst_m, off_m);
    // A gable's half or a crown's part that faces the sun: nothing of its
    // own roof or crown can shade it, so only a taller neighbour could.
    if (normal_at(object, h.x(), h.y()).dot(pair.sun) < 0.05) continue;
    ++sunlit[kind];
    striped[kind] += DarkenedByShadow(pair, k);
  }
  ASSERT_GT(inside_pixels[0], 500);
  ASSERT_GT(inside_pixels[1], 200);
  ASSERT_GT(sunlit[0], 200);
  ASSERT_GT(sunlit[1], 100);
  // Hits lie on the roof or crown itself (bisection to well under a mm;
  // float storage of the hit: < 0.1 mm).
  EXPECT_LT(worst_m, 1e-3);
  // Taller neighbours (buildings, trees of a park) may shade a few of them.
  EXPECT_LT(striped[0], sunlit[0] / 20) << "of " << sunlit[0] << " pixels of gables facing the sun";
  EXPECT_LT(striped[1], sunlit[1] / 10) << "of " << sunlit[1] << " pixels of crowns facing the sun";
  std::printf("[figures] %d gable and %d crown pixels, farthest from their surface %.2e m; shadows darken %d of %d "
              "sunlit gable and %d of %d sunlit crown pixels\n",
              inside_pixels[0], inside_pixels[1], worst_m, striped[0], sunlit[0], striped[1], sunlit[1]);
}

// Median over view pairs and points of the normalized cross-correlation,
// in windows of 5 x 5 points 0.5 m apart (the dense matcher's), of the grey
// values two views show at the gable roofs' points (those inside a roof that
// both views see), each view rendered with `subpixels`.
double GableRoofNccBetweenViews(const Scene& s, int subpixels) {
  const City& city = s.result.city;
  // Points every second cell (0.5 m) of the AOI; -1 where not inside a gable.
  const int step = 2, n = static_cast<int>(128.0 / city.options.cell_m) / step;
  std::vector<Eigen::Vector3d> points;
  std::vector<int> grid(static_cast<std::size_t>(n) * n, -1);
  for (int gj = 0; gj < n; ++gj)
    for (int gi = 0; gi < n; ++gi) {
      const Eigen::Vector2i cell = city.CellOf(gi * step * city.options.cell_m + 0.1, gj * step * city.options.cell_m + 0.1);
      const std::size_t k = city.Index(cell.x(), cell.y());
      if (city.material[k] != Material::kGableRoof) continue;
      bool inside = true;
      for (int dj = -2; dj <= 2; ++dj)
        for (int di = -2; di <= 2; ++di) inside &= city.object[city.Index(cell.x() + di, cell.y() + dj)] == city.object[k];
      if (!inside) continue;
      const Eigen::Vector2d c = city.CellCentre(cell.x(), cell.y());
      grid[static_cast<std::size_t>(gj) * n + gi] = static_cast<int>(points.size());
      points.emplace_back(c.x(), c.y(), RoofAt(city.buildings[city.object[k]], c.x(), c.y()));
    }
  const auto& views = s.result.aois.at(0).views;
  // Per view, the grey value at each point it sees (NaN where it does not).
  std::vector<std::vector<double>> grey(views.size(), std::vector<double>(points.size(), NAN));
  for (std::size_t v = 0; v < views.size(); ++v) {
    Lighting lighting = views[v].lighting;
    lighting.subpixels = subpixels;
    const RenderedView img = RenderView(city, views[v].camera, s.result.scene_from_enu, lighting);
    const RpcModel rpc = ReadRpcFromRaster(views[v].path);
    for (std::size_t p = 0; p < points.size(); ++p) {
      const Eigen::Vector2d px = ProjectScenePoint(rpc, s.result, points[p]);
      const int c = static_cast<int>(std::floor(px.x())), r = static_cast<int>(std::floor(px.y()));
      if (c < 0 || r < 0 || c + 1 >= img.width_px || r + 1 >= img.height_px) continue;
      const std::size_t k = static_cast<std::size_t>(std::lround(px.y())) * img.width_px + std::lround(px.x());
      if (!((img.hit_scene[k].cast<double>() - points[p]).norm() < 0.5)) continue;  // hidden
      const double fx = px.x() - c, fy = px.y() - r;
      auto at = [&](int cc, int rr) {
        const std::size_t q = 3 * (static_cast<std::size_t>(rr) * img.width_px + cc);
        return (img.rgb[q] + img.rgb[q + 1] + img.rgb[q + 2]) / 3.0;
      };
      grey[v][p] = (1 - fy) * ((1 - fx) * at(c, r) + fx * at(c + 1, r)) + fy * ((1 - fx) * at(c, r + 1) + fx * at(c + 1, r + 1));
    }
  }
  std::vector<double> nccs;
  for (std::size_t a = 0; a < views.size(); ++a)
    for (std::size_t b = a + 1; b < views.size(); ++b)
      for (int gj = 2; gj + 2 < n; ++gj)
        for (int gi = 2; gi + 2 < n; ++gi) {
          double m = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
          for (int dj = -2; dj <= 2; ++dj)
            for (int di = -2; di <= 2; ++di) {
              const int p = grid[static_cast<std::size_t>(gj + dj) * n + gi + di];
              if (p < 0 || !std::isfinite(grey[a][p]) || !std::isfinite(grey[b][p])) continue;
              const double x = grey[a][p], y = grey[b][p];
              m += 1, sa += x, sb += y, saa += x * x, sbb += y * y, sab += x * y;
            }
          if (m < 25) continue;
          const double va = saa / m - sa * sa / (m * m), vb = sbb / m - sb * sb / (m * m);
          if (!(va > 1.0 && vb > 1.0)) continue;  // under 1 DN of texture: no correlation to speak of
          nccs.push_back((sab / m - sa * sb / (m * m)) / std::sqrt(va * vb));
        }
  if (nccs.size() < 100) return NAN;
  std::nth_element(nccs.begin(), nccs.begin() + nccs.size() / 2, nccs.end());
  return nccs[nccs.size() / 2];
}

TEST(Synth, PixelsAverageOverTheirAreaSoRoofTilesDoNotAliasBetweenViews) {
  // A gable's tile courses (0.6 m) are finer than two pixels. Point-sampled,
  // they alias into a moire of another period and direction in every view.
  const Scene s = MakeScene(SmallScene());
  const double point_sampled = GableRoofNccBetweenViews(s, 1);
  const double integrated = GableRoofNccBetweenViews(s, Lighting{}.subpixels);
  std::printf("[figures] gable roofs between views, median NCC (5 x 5 points, 2.5 m): %.2f point-sampled, %.2f integrated over the pixel\n",
              point_sampled, integrated);
  // Textured ground correlates at about 0.9 in such windows; point-sampled
  // roofs measured 0.21, integrated over 4 x 4 points 0.78.
  constexpr double kMinRoofNcc = 0.6;
  EXPECT_GT(integrated, kMinRoofNcc);
  EXPECT_LT(point_sampled, integrated - 0.3) << "point sampling no longer aliases: is the test still testing?";
}

// Haze adds the same path radiance to every pixel: the crowns' excess
// green falls towards a hazy WorldView-3 crop's (DFC2019's trees: about
// 0.04), and the image's contrast falls by the clear share of the light.
TEST(Synth, HazePullsColoursTowardsGreyAndLowersContrast) {
  CityOptions co;
  co.margin_m = 8;
  const City city = GenerateCity(co);
  constexpr double kGsdM = 0.5;
  constexpr int kPx = 512;  // the city's 256 m
  auto render = [&](float haze) {
    Lighting light;
    light.haze = haze;
    return RenderOrtho(city, light, 0.0, co.height_m, kGsdM, kPx, kPx);
  };
  const std::vector<std::uint8_t> clear = render(0.0f), hazy = render(0.7f);
  auto tree_green = [&](const std::vector<std::uint8_t>& rgb) {
    double sum = 0;
    int n = 0;
    for (int row = 0; row < kPx; ++row)
      for (int col = 0; col < kPx; ++col) {
        const Eigen::Vector2i c = city.CellOf((col + 0.5) * kGsdM, co.height_m - (row + 0.5) * kGsdM);
        if (!city.Inside(c.x(), c.y()) || city.material[city.Index(c.x(), c.y())] != Material::kTree) continue;
        const std::size_t p = 3 * (static_cast<std::size_t>(row) * kPx + col);
        const double r = rgb[p], g = rgb[p + 1], b = rgb[p + 2];
        if (r + g + b > 0) sum += (2 * g - r - b) / (r + g + b), ++n;
      }
    EXPECT_GT(n, 50);
    return sum / n;
  };
  auto spread = [](const std::vector<std::uint8_t>& rgb) {  // of the pixels' grey levels
    double s = 0, s2 = 0;
    const std::size_t n = rgb.size() / 3;
    for (std::size_t p = 0; p < n; ++p) {
      const double grey = rgb[3 * p] + rgb[3 * p + 1] + rgb[3 * p + 2];
      s += grey, s2 += grey * grey;
    }
    return std::sqrt(s2 / n - (s / n) * (s / n));
  };
  const double green_clear = tree_green(clear), green_hazy = tree_green(hazy);
  EXPECT_GT(green_clear, 0.3);
  EXPECT_LT(green_hazy, 0.12);
  EXPECT_GT(green_hazy, 0.0);
  // Path radiance is an offset: the spread scales by the clear share, 0.3,
  // up to the 8-bit rounding.
  EXPECT_NEAR(spread(hazy) / spread(clear), 0.3, 0.02);
  ExpectCheckRefuses([](SynthOptions& o) { o.haze = 0.95; });
}

// Sensor noise (`--noise-dn`): each view gains Gaussian noise of the asked
// standard deviation per band and pixel, independent between views; 0 keeps
// the images as they were.
TEST(Synth, SensorNoiseHasTheAskedSpreadAndIsIndependentBetweenViews) {
  const Scene s = MakeScene(SmallScene());
  const SynthView& v = s.result.aois.at(0).views.at(0);
  const SynthView& w = s.result.aois.at(0).views.at(1);
  constexpr float kNoiseDn = 4.0f;
  auto render = [&](const SynthView& view, float noise_dn) {
    return RenderUnder(s.result, view, [&](Lighting& light) { light.noise_dn = noise_dn; }).rgb;
  };
  const std::vector<std::uint8_t> clean = render(v, 0.0f), noisy = render(v, kNoiseDn);
  const std::vector<std::uint8_t> clean_w = render(w, 0.0f), noisy_w = render(w, kNoiseDn);
  EXPECT_EQ(clean, RenderView(s.result.city, v.camera, s.result.scene_from_enu, v.lighting).rgb);
  // The added noise's spread, away from 0 and 255 where clipping cuts it, and
  // its correlation between the two views at the same pixel index.
  double sum = 0, sum2 = 0, cross = 0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < clean.size() && p < clean_w.size(); ++p) {
    if (clean[p] < 30 || clean[p] > 225 || clean_w[p] < 30 || clean_w[p] > 225) continue;
    const double d = static_cast<double>(noisy[p]) - clean[p], e = static_cast<double>(noisy_w[p]) - clean_w[p];
    sum += d, sum2 += d * d, cross += d * e, ++n;
  }
  ASSERT_GT(n, 10000u);
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  std::printf("[figures] --noise-dn %.0f: added noise %.3f DN (mean %+.3f), correlation between two views %+.4f\n",
              kNoiseDn, sd, mean, cross / n / (sd * sd));
  // Rounding to whole DN adds 1/12 DN^2 of variance: 4.01 DN expected.
  EXPECT_NEAR(sd, kNoiseDn, 0.15);
  EXPECT_NEAR(mean, 0.0, 0.1);
  EXPECT_LT(std::abs(cross / n) / (sd * sd), 0.02);
  ExpectCheckRefuses([](SynthOptions& o) { o.noise_dn = 25; });
}

// Sensor blur (`--blur-px`): the optics' point-spread function softens the
// texture at the pixel's scale (what a 3 x 3 Laplacian responds to) and
// keeps the image's mean; 0 leaves the view as it was.
TEST(Synth, SensorBlurSoftensPixelScaleTextureAndKeepsTheMean) {
  const Scene s = MakeScene(SmallScene());
  const SynthView& v = s.result.aois.at(0).views.at(0);
  auto render = [&](float blur_px) {
    return RenderUnder(s.result, v, [&](Lighting& light) { light.blur_px = blur_px; });
  };
  const RenderedView sharp = render(0.0f), soft = render(1.0f);
  EXPECT_EQ(sharp.rgb, RenderView(s.result.city, v.camera, s.result.scene_from_enu, v.lighting).rgb);
  // Mean absolute 3 x 3 Laplacian response of the grey image, and its mean.
  auto texture = [](const RenderedView& img, double* mean) {
    const int w = img.width_px, h = img.height_px;
    auto grey = [&](int c, int r) {
      const std::size_t p = 3 * (static_cast<std::size_t>(r) * w + c);
      return (img.rgb[p] + img.rgb[p + 1] + img.rgb[p + 2]) / 3.0;
    };
    double response = 0, sum = 0;
    for (int r = 1; r + 1 < h; ++r)
      for (int c = 1; c + 1 < w; ++c) {
        response += std::abs(4 * grey(c, r) - grey(c - 1, r) - grey(c + 1, r) - grey(c, r - 1) - grey(c, r + 1));
        sum += grey(c, r);
      }
    *mean = sum / ((w - 2.0) * (h - 2.0));
    return response / ((w - 2.0) * (h - 2.0));
  };
  double mean_sharp = 0, mean_soft = 0;
  const double t_sharp = texture(sharp, &mean_sharp), t_soft = texture(soft, &mean_soft);
  std::printf("[figures] --blur-px 1: pixel-scale texture %.2f -> %.2f DN, mean %.2f -> %.2f DN\n", t_sharp, t_soft,
              mean_sharp, mean_soft);
  // A Gaussian of 1 px passes about a fifth of a Laplacian's response to
  // texture at the pixel's scale; the +-1 DN noise added after it stays.
  EXPECT_LT(t_soft, 0.5 * t_sharp);
  EXPECT_NEAR(mean_soft, mean_sharp, 0.5);
  ExpectCheckRefuses([](SynthOptions& o) { o.blur_px = 4; });
}

// Clouds: a puff on the view's ray through the AOI's centre hides the
// ground there (cloud-white pixels), a puff on the sun's ray from it shades
// the ground around it (lit pixels lose most of their direct light), and
// `--clouds` puts puffs on every second date only, recording each image's
// covered share.
TEST(Synth, CloudsHideTheGroundFromTheViewAndShadeItFromTheSun) {
  SynthOptions o = SmallScene();
  o.clouds = 0.4;
  const Scene s = MakeScene(o);
  const SynthResult& r = s.result;
  const auto& views = r.aois.at(0).views;
  ASSERT_EQ(views.size(), 4u);  // two dates of two images
  EXPECT_EQ(views[0].cloud_covered_fraction, 0.0);  // date 0: clear
  EXPECT_EQ(views[1].cloud_covered_fraction, 0.0);
  // Puffs opaque beyond 0.5 over 0.29 of their area, 0.4 of the sky: about
  // a tenth of the pixels; a layer that missed the images would give 0.
  EXPECT_GT(views[2].cloud_covered_fraction, 0.03);
  EXPECT_GT(views[3].cloud_covered_fraction, 0.03);

  const SynthView& v = views[0];
  const Eigen::Vector3d sun = v.lighting.sun_scene.normalized();
  const Eigen::Vector3d ground(0.5 * o.size_m, 0.5 * o.size_m, r.city.TerrainAt(0.5 * o.size_m, 0.5 * o.size_m));
  const Eigen::Vector3d to_camera = (r.scene_from_enu.Apply(v.camera.centre_enu_m) - ground).normalized();
  CloudLayer layer;
  layer.height_m = r.city.max_height_m + 1000.0;
  auto crossing = [&](const Eigen::Vector3d& dir) {
    const double t = (layer.height_m - ground.z()) / dir.z();
    return Eigen::Vector2d((ground + t * dir).head<2>());
  };
  constexpr double kRadiusM = 100.0;
  // The two crossings lie far apart: each puff acts on one ray only.
  ASSERT_GT((crossing(to_camera) - crossing(sun)).norm(), 2.5 * kRadiusM);
  auto render = [&](const std::vector<CloudPuff>& puffs) {
    return RenderUnder(r, v, [&](Lighting& light) {
      light.clouds = layer;
      light.clouds.puffs = puffs;
    });
  };
  const RenderedView clear = render({}), hidden = render({{crossing(to_camera), kRadiusM}}),
                     shaded = render({{crossing(sun), kRadiusM}});
  EXPECT_EQ(clear.cloud_covered_fraction, 0.0);
  EXPECT_GT(hidden.cloud_covered_fraction, 0.0);
  const Eigen::Vector2d centre_px = v.camera.Project(r.scene_from_enu.linear.inverse() *
                                                     (ground - r.scene_from_enu.offset_m));
  const std::size_t k = static_cast<std::size_t>(std::lround(centre_px.y())) * clear.width_px +
                        static_cast<std::size_t>(std::lround(centre_px.x()));
  // Cloud white (0.93-0.96) through the date's gain (at least 0.88) and tint.
  for (int ch = 0; ch < 3; ++ch) EXPECT_GT(hidden.rgb[3 * k + ch], 190) << "band " << ch;
  EXPECT_GT(hidden.rgb[3 * k] + hidden.rgb[3 * k + 1] + hidden.rgb[3 * k + 2],
            clear.rgb[3 * k] + clear.rgb[3 * k + 1] + clear.rgb[3 * k + 2] + 60);  // the ground there is darker
  // Within 20 m of the ground point the shadow's puff is at least 0.92
  // opaque: a lit pixel keeps its ambient share (0.28-0.40) and
  // 1 - 0.85 * 0.92 of its direct light, so the pixels there that no
  // building shades lose a third or more.
  Lighting no_cast_shadows = v.lighting;
  no_cast_shadows.cast_shadows = false;
  const RenderedView unshadowed = RenderView(r.city, v.camera, r.scene_from_enu, no_cast_shadows);
  auto grey = [](const RenderedView& view, std::size_t p) {
    return view.rgb[3 * p] + view.rgb[3 * p + 1] + view.rgb[3 * p + 2];
  };
  double sum_clear = 0, sum_shaded = 0;
  int pixels = 0;
  for (std::size_t p = 0; p < clear.hit_scene.size(); ++p) {
    const Eigen::Vector3f& hit = clear.hit_scene[p];
    if (!hit.allFinite() || (hit.cast<double>().head<2>() - ground.head<2>()).norm() > 20.0) continue;
    if (grey(clear, p) < grey(unshadowed, p) - 15) continue;  // in a building's shadow
    sum_clear += grey(clear, p), sum_shaded += grey(shaded, p), ++pixels;
  }
  ASSERT_GT(pixels, 100);
  EXPECT_LT(sum_shaded / sum_clear, 0.67);
  EXPECT_THROW(
      [] {
        SynthOptions bad;
        bad.clouds = 0.9;
        bad.Check();
      }(),
      Error);
}

TEST(Synth, HillsAreSmoothTerrainWithoutStairsOrStripesOfShadow) {
  // 100 m of relief: slopes up to 31%. As flat-topped 0.25 m columns a
  // hill would be stairs of 7.5 cm risers whose shadows stripe the slopes.
  SynthOptions o = SmallScene();
  o.relief_m = 100.0;
  const Scene s = MakeScene(o);
  const City& city = s.result.city;
  const ShadowPair pair = RenderWithAndWithoutShadows(s, ExtremeView(s.result, /*most_oblique=*/true));
  const RenderedView& shaded = pair.shaded;
  const Eigen::Vector3d sun = pair.sun;
  const Eigen::Vector2d sun_xy = sun.head<2>();
  // The sun is above any slope of the scene, so the terrain alone shades
  // but casts no shadow: a terrain pixel is in shadow only where a column
  // that is not terrain stands in the way of the sun.
  ASSERT_GT(sun.z() / sun_xy.norm(), 0.45);
  auto terrain_cell = [&](const Eigen::Vector2i& c) {
    const Material m = city.material[city.Index(c.x(), c.y())];
    return m == Material::kGrass || m == Material::kRoad;
  };
  auto object_towards_sun = [&](const Eigen::Vector3d& p) {
    const double step_m = 0.5 * city.options.cell_m;
    for (double t = step_m;; t += step_m / sun_xy.norm()) {
      const Eigen::Vector3d q = p + t * sun;
      if (q.z() > city.max_height_m) return false;
      // The walk samples the way in steps; a 3x3 neighbourhood of cells
      // covers the corners it could step over.
      const Eigen::Vector2i c = city.CellOf(q.x(), q.y());
      if (!city.Inside(c.x() - 1, c.y() - 1) || !city.Inside(c.x() + 1, c.y() + 1)) return false;
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
          const Eigen::Vector2i n = c + Eigen::Vector2i(di, dj);
          if (!terrain_cell(n) && city.height_m[city.Index(n.x(), n.y())] > q.z() - 0.5) return true;
        }
    }
  };
  int terrain = 0, open_to_sun = 0, darker = 0;
  double worst_m = 0;
  for (std::size_t k = 0; k < shaded.hit_scene.size(); k += 5) {
    const Eigen::Vector3d h = shaded.hit_scene[k].cast<double>();
    if (!h.allFinite()) continue;
    // Terrain all round (a wall's hit lies on the boundary of its cell).
    const Eigen::Vector2i c = city.CellOf(h.x(), h.y());
    bool inside_terrain = true;
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) inside_terrain &= terrain_cell(c + Eigen::Vector2i(di, dj));
    if (!inside_terrain) continue;
    ++terrain;
    worst_m = std::max(worst_m, std::abs(h.z() - city.TerrainAt(h.x(), h.y())));
    if (object_towards_sun(h)) continue;
    ++open_to_sun;
    darker += DarkenedByShadow(pair, k);
  }
  ASSERT_GT(terrain, 2000);
  ASSERT_GT(open_to_sun, 1000);
  // Hits lie on the terrain itself (float storage of the hit: < 0.1 mm).
  EXPECT_LT(worst_m, 1e-3);
  EXPECT_EQ(darker, 0) << "of " << open_to_sun << " terrain pixels open to the sun";
}

}  // namespace
}  // namespace skyfall::synth
