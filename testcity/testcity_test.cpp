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

namespace skyfall::synth {
namespace {

using namespace skyfall::testing;

// The issue's bound on the RPC written for each image.
constexpr double kRpcFitTolPx = 0.01;
// Rendering maps rays into the scene frame with an affine fit of the
// ENU -> UTM map (reported error ~5 mm at most for these scenes); at 0.5 m
// GSD that is 0.01 px, plus the RPC fit: 0.03 px leaves margin for both.
constexpr double kRenderVsRpcTolPx = 0.03;

SynthOptions SmallScene() {
  SynthOptions o;
  o.size_m = 128.0;
  o.views = 4;
  o.seed = 7;
  return o;
}

struct Scene {
  fs::path root;
  SynthResult result;
};

Scene MakeScene(const SynthOptions& o) {
  Scene s;
  s.root = ScratchDir("synth");
  NullProgress progress;
  s.result = RunSynth(o, s.root.string(), progress);
  return s;
}

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

TEST(Synth, IngestReadsTheSceneLikeRealData) {
  const Scene s = MakeScene(SmallScene());
  NullProgress progress;
  const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
  ASSERT_EQ(r.NumIngested(), 1);
  const AoiCatalog& c = r.aois.at(0).catalog;
  EXPECT_EQ(c.aoi, "SYN_001");
  ASSERT_EQ(c.images.size(), 4u);
  EXPECT_EQ(c.epsg, 32617);
  ASSERT_TRUE(c.truth.has_value());
  EXPECT_EQ(c.truth->width_px, 256);
  EXPECT_EQ(c.height_range_source, "truth_dsm");
  EXPECT_EQ(c.test_images.size(), 2u);
  EXPECT_EQ(c.train_images.size(), 2u);
  for (size_t i = 0; i < c.images.size(); ++i) {
    const ImageRecord& im = c.images[i];
    const SynthView& v = s.result.aois[0].views[i];
    EXPECT_EQ(im.rpc_source, "gdal_metadata");
    EXPECT_EQ(im.acquisition_time, v.acquisition_time);
    ASSERT_TRUE(im.sun_elevation_deg.has_value());
    EXPECT_NEAR(*im.sun_elevation_deg, v.sun_elevation_deg, 1e-9);
    // Ingest derives the viewing geometry from the RPC alone: it agrees
    // with the camera that made the image.
    EXPECT_NEAR(im.view_zenith_deg, v.view_zenith_deg, 0.1) << im.name;
    EXPECT_NEAR(im.off_nadir_deg, v.off_nadir_deg, 0.1) << im.name;
    const double daz = std::remainder(im.view_azimuth_deg - v.view_azimuth_deg, 360.0);
    EXPECT_LT(std::abs(daz), 0.5) << im.name;
  }
}

// Passes fall at about 10:30 local solar time at any longitude, as a
// sun-synchronous satellite's do: over a mid-latitude city far east or west
// of the default one the sun is up (at 45 S in its winter, 10:30 puts it
// about 18 deg high; 10 deg leaves room for the approximate solar position),
// and at the default longitude the times are those of before.
TEST(Synth, PassesFallInTheLocalMorningAtAnyLongitude) {
  constexpr double kMinSunElevationDeg = 10.0;
  for (const double lon_deg : {-170.0, 0.0, 100.0, 170.5}) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;
    o.views = 4;
    o.views_per_date = 1;  // four dates, January to June
    o.lat_deg = -45.0;
    o.lon_deg = lon_deg;
    const Scene s = MakeScene(o);
    for (const SynthView& v : s.result.aois[0].views)
      EXPECT_GT(v.sun_elevation_deg, kMinSunElevationDeg) << "lon " << lon_deg << " " << v.acquisition_time;
  }
  const Scene reference = MakeScene(SmallScene());
  EXPECT_EQ(reference.result.aois[0].views[0].acquisition_time, "2015-01-15T15:55:00Z");
}

// Stiff and extreme geometry (docs/reliability.md lists each case and its
// outcome): far north and south, a UTM zone boundary, steep views, a 300 m
// tower, fine and coarse GSD. In each the written RPCs reproduce the true
// cameras within kRpcFitTolPx, and ingest reads the viewing geometry back
// from the RPCs alone within 0.1 deg. The antimeridian is an open finding
// (see the docs), not a case that passes.
struct ExtremeCase {
  const char* name;
  std::function<void(SynthOptions&)> set;
};

TEST(Synth, ExtremeScenesKeepTheirRpcsAndViewGeometry) {
  const std::vector<ExtremeCase> cases = {
      {"lat 80 N", [](SynthOptions& o) { o.lat_deg = 80.0; o.lon_deg = 15.0; }},
      {"lat 79.9 S", [](SynthOptions& o) { o.lat_deg = -79.9; o.lon_deg = -57.0; }},
      // On the boundary of zones 20 and 21: the images' centre falls in one,
      // the truth grid (DSM.txt, no CRS) was written in the other.
      {"UTM zone boundary", [](SynthOptions& o) { o.lon_deg = -60.0; }},
      {"zone boundary, 60 S", [](SynthOptions& o) { o.lat_deg = -60.0; o.lon_deg = -60.0; }},
      // Astride the antimeridian: the AOI spans 179.9992 E to 179.9998 W.
      {"antimeridian", [](SynthOptions& o) { o.lon_deg = 179.9995; }},
      {"antimeridian, 60 S", [](SynthOptions& o) { o.lat_deg = -60.0; o.lon_deg = -179.9995; }},
      // HEIGHT_OFF 1500 m above and 800 m below the ground: the scene sits
      // at one face of the RPCs' validity cube.
      {"RPC HEIGHT_OFF 1500 m above", [](SynthOptions& o) { o.rpc_height_offset_m = 1500.0; }},
      {"RPC HEIGHT_OFF 800 m below", [](SynthOptions& o) { o.rpc_height_offset_m = -800.0; }},
      {"45 deg off nadir", [](SynthOptions& o) { o.min_off_nadir_deg = 40.0; o.max_off_nadir_deg = 45.0; }},
      {"300 m tower", [](SynthOptions& o) { o.max_building_m = 300.0; }},
      {"GSD 0.3 m", [](SynthOptions& o) { o.gsd_m = 0.3; o.size_m = 60.0; }},
      {"GSD 2 m", [](SynthOptions& o) { o.gsd_m = 2.0; o.size_m = 256.0; }},
      // A city 4,000 m above the ellipsoid (La Paz, El Alto).
      {"ground 4000 m", [](SynthOptions& o) { o.ground_height_m = 4000.0; }},
      // A three-line camera: forward, nadir, backward on one track (ZY-3).
      {"three-line +-22 deg", [](SynthOptions& o) { o.along_track_deg = 22.0; o.views_per_date = 3; }},
  };
  for (const ExtremeCase& c : cases) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;  // a whole number of GSDs (cases may change both)
    o.views = 3;
    c.set(o);
    const Scene s = MakeScene(o);
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << c.name << ": " << r.aois.at(0).report.message;
    const AoiCatalog& catalog = r.aois.at(0).catalog;
    for (std::size_t i = 0; i < catalog.images.size(); ++i) {
      const SynthView& v = s.result.aois[0].views[i];
      EXPECT_LE(v.rpc_fit_max_px, kRpcFitTolPx) << c.name << " " << v.name;
      EXPECT_NEAR(catalog.images[i].off_nadir_deg, v.off_nadir_deg, 0.1) << c.name << " " << v.name;
      EXPECT_NEAR(catalog.images[i].view_zenith_deg, v.view_zenith_deg, 0.1) << c.name << " " << v.name;
    }
    std::printf("[figures] %s: EPSG %d, worst RPC fit %.2g px\n", c.name, catalog.epsg,
                std::max_element(s.result.aois[0].views.begin(), s.result.aois[0].views.end(),
                                 [](const SynthView& a, const SynthView& b) { return a.rpc_fit_max_px < b.rpc_fit_max_px; })
                    ->rpc_fit_max_px);
  }
}

// Without truth or Sat-NeRF altitudes the height range comes from the RPCs.
// Their HEIGHT_OFF may lie far from the AOI's ground (the middle of a
// vendor's whole scene): ingest then finds the ground where the views agree.
// Near HEIGHT_OFF, the range stays centred on it as before.
TEST(Synth, RpcOnlyHeightRangeFindsTheGroundFarFromHeightOff) {
  for (const double offset_m : {1500.0, -800.0, 0.0}) {
    SynthOptions o = SmallScene();
    o.size_m = 64.0;
    o.views = 3;
    o.rpc_height_offset_m = offset_m;
    const Scene s = MakeScene(o);
    fs::remove_all(s.root / "Track3-Truth");
    fs::remove_all(s.root / "satnerf-rpcs");
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << "offset " << offset_m << ": " << r.aois.at(0).report.message;
    const AoiCatalog& c = r.aois.at(0).catalog;
    EXPECT_EQ(c.height_range_source, offset_m == 0.0 ? "rpc" : "rpc_height_probe") << offset_m;
    // The whole scene, ground to roofs, inside the searched range.
    EXPECT_LE(c.min_ellipsoid_height_m, s.result.city.min_height_m) << offset_m;
    EXPECT_GE(c.max_ellipsoid_height_m, s.result.city.max_height_m) << offset_m;
    std::printf("[figures] HEIGHT_OFF %+.0f m from the ground: range %.1f..%.1f m (%s), scene %.1f..%.1f m\n",
                offset_m, c.min_ellipsoid_height_m, c.max_ellipsoid_height_m, c.height_range_source.c_str(),
                static_cast<double>(s.result.city.min_height_m), static_cast<double>(s.result.city.max_height_m));
    // One view cannot place anything.
    EXPECT_FALSE(ProbeSceneHeight({c.images.front()}).has_value());
  }
  HeightProbeOptions bad;
  bad.fine_step_m = 5.0;  // coarser than the coarse step
  EXPECT_NE(ErrorText([&] { bad.Check(); }).find("fine_step_m"), std::string::npos);
}

// The options that make real sensors' defect classes: a city far above the
// ellipsoid, biased RPCs, a three-line camera.
TEST(Synth, GroundHeightLiftsTheWholeSceneAndItsRpcs) {
  SynthOptions o = SmallScene();
  o.size_m = 64.0;
  o.views = 3;
  o.ground_height_m = 2300.0;
  const Scene s = MakeScene(o);
  EXPECT_GT(s.result.city.min_height_m, 2200.0);
  EXPECT_LT(s.result.city.max_height_m, 2300.0 + o.max_building_m + 50.0);
  EXPECT_NEAR(s.result.enu_origin.height_m, 2300.0, 60.0);
  const FloatBand dsm = ReadFloatBand((s.root / "Track3-Truth" / (o.aoi + "_DSM.tif")).string());
  EXPECT_GT(*std::min_element(dsm.values.begin(), dsm.values.end()), 2200.0f);
  for (const SynthView& v : s.result.aois[0].views) {
    EXPECT_NEAR(ReadRpcFromRaster(v.path).height_off, 2300.0, 100.0) << v.name;
    EXPECT_LE(v.rpc_fit_max_px, kRpcFitTolPx) << v.name;
  }
}

TEST(Synth, BiasedRpcsPointOffTheCameraByTheRecordedBias) {
  SynthOptions o = SmallScene();
  o.size_m = 64.0;
  o.views = 4;
  o.rpc_bias_px = 4.0;
  o.rpc_bias_rotation_deg = 0.05;
  const Scene s = MakeScene(o);
  const EnuFrame frame(s.result.enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(s.result.epsg);
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile((s.root / "synth_report.json").string()));
  // What a shift v of the whole scene would do to the images: P_i v.
  const Eigen::Vector2d centre_ll = GeodeticFromUtm(zone, s.result.utm_easting0_m + 32, s.result.utm_northing0_m + 32);
  const Eigen::Vector3d centre_enu = frame.EnuFromGeodetic({centre_ll.x(), centre_ll.y(), o.ground_height_m});
  Eigen::Vector3d common = Eigen::Vector3d::Zero();  // sum P_i^T b_i: zero when no v explains any of the biases
  double largest = 0;
  for (std::size_t i = 0; i < s.result.aois[0].views.size(); ++i) {
    const SynthView& v = s.result.aois[0].views[i];
    const nlohmann::json& recorded = report.at("images").at(i);
    EXPECT_DOUBLE_EQ(recorded.at("rpc_bias_shift_px").at(0).get<double>(), v.rpc_bias_shift_px.x());
    EXPECT_DOUBLE_EQ(recorded.at("rpc_bias_rotation_deg").get<double>(), v.rpc_bias_rotation_deg);
    EXPECT_LE(v.rpc_bias_shift_px.norm(), 2 * o.rpc_bias_px);  // drawn within 4 px, less the mean
    EXPECT_LE(std::abs(v.rpc_bias_rotation_deg), o.rpc_bias_rotation_deg);
    Eigen::Matrix<double, 2, 3> jacobian;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = Eigen::Vector3d::Unit(k);
      jacobian.col(k) = 0.5 * (v.camera.Project(centre_enu + h) - v.camera.Project(centre_enu - h));
    }
    common += jacobian.transpose() * v.rpc_bias_shift_px;
    largest = std::max(largest, v.rpc_bias_shift_px.norm());
    const RpcModel rpc = ReadRpcFromRaster(v.path);
    const Eigen::Vector2d centre(0.5 * (v.camera.width_px - 1), 0.5 * (v.camera.height_px - 1));
    const double a = v.rpc_bias_rotation_deg * M_PI / 180.0;
    const Eigen::Matrix2d rot = (Eigen::Matrix2d() << std::cos(a), -std::sin(a), std::sin(a), std::cos(a)).finished();
    for (double fx : {0.1, 0.9})
      for (double fy : {0.1, 0.9}) {
        const double z = s.result.city.TerrainAt(fx * 64, fy * 64);
        const Eigen::Vector2d ll = GeodeticFromUtm(zone, s.result.utm_easting0_m + fx * 64,
                                                   s.result.utm_northing0_m + fy * 64);
        const Eigen::Vector2d truth = v.camera.Project(frame.EnuFromGeodetic({ll.x(), ll.y(), z}));
        const Eigen::Vector2d want = centre + rot * (truth - centre) + v.rpc_bias_shift_px;
        EXPECT_LT((rpc.Project(ll.x(), ll.y(), z) - want).norm(), kRpcFitTolPx) << v.name;
      }
  }
  // The truth's frame is the images' average: the biases hold no common
  // shift of the scene (1e-6: the Jacobians' differences over 1 m; a metre of
  // shift moves an image by about 2 px).
  EXPECT_LT(common.norm(), 1e-6);
  EXPECT_GT(largest, 1.0);
}

// Tiles are sized by the imagery unless a side is given: a 256 m tile of a
// 2 m sensor holds 128 px, too few to match, while 0.5 m imagery keeps the
// 256 m tiles every accuracy figure was measured with.
TEST(Tiling, AutomaticTilesHoldAboutTilePxPixelsOfTheFinestImage) {
  struct Case { double gsd_m, size_m, want_tile_m; };
  for (const Case c : {Case{0.5, 64.0, 256.0}, Case{2.0, 512.0, 1024.0}}) {
    SynthOptions o = SmallScene();
    o.gsd_m = c.gsd_m;
    o.size_m = c.size_m;
    o.views = 3;
    const Scene s = MakeScene(o);
    NullProgress progress;
    const IngestResult r = RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress);
    ASSERT_EQ(r.NumIngested(), 1) << r.aois.at(0).report.message;
    const AoiCatalog& catalog = r.aois.at(0).catalog;
    const TilePlan plan = PlanTiles(TilingOptions{}, {catalog});
    EXPECT_EQ(plan.grid.tile_m, c.want_tile_m) << c.gsd_m;
    EXPECT_TRUE(plan.tile_side_automatic);
    // The nadir-most view's ground pixel: the nominal GSD stretched by at
    // most 1/cos(zenith) along one axis (SmallScene's views reach 30 deg).
    EXPECT_GE(plan.finest_gsd_m, 0.99 * c.gsd_m) << c.gsd_m;
    EXPECT_LE(plan.finest_gsd_m, 1.08 * c.gsd_m) << c.gsd_m;
    TilingOptions given;
    given.tile_m = 128;
    const TilePlan fixed = PlanTiles(given, {catalog});
    EXPECT_EQ(fixed.grid.tile_m, 128.0);
    EXPECT_FALSE(fixed.tile_side_automatic);
    std::printf("[figures] GSD %.1f m scene: finest image %.3f m, automatic tile %.0f m (%.0f px)\n", c.gsd_m,
                plan.finest_gsd_m, plan.grid.tile_m, plan.grid.tile_m / plan.finest_gsd_m);
  }
}

TEST(Synth, TruthFilesFollowTheJax068Conventions) {
  const Scene s = MakeScene(SmallScene());
  const fs::path ours = s.root / "Track3-Truth", jax = Dfc2019Root() / "Track3-Truth";
  // _DSM.txt: four numbers printed with six decimals, one per line.
  const std::regex line(R"(^-?\d+\.\d{6}$)");
  auto txt_lines = [](const fs::path& p) {
    std::vector<std::string> lines;
    std::ifstream in(p);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    return lines;
  };
  const auto ours_txt = txt_lines(ours / "SYN_001_DSM.txt");
  ASSERT_EQ(ours_txt.size(), 4u);
  for (const auto& l : ours_txt) EXPECT_TRUE(std::regex_match(l, line)) << l;
  const std::set<int> dfc_codes = {2, 5, 6, 9, 17, 65};
  auto check_rasters = [&](const fs::path& dir, const std::string& aoi) {
    const RasterInfo dsm = ReadRasterInfo((dir / (aoi + "_DSM.tif")).string());
    const RasterInfo cls = ReadRasterInfo((dir / (aoi + "_CLS.tif")).string());
    EXPECT_EQ(dsm.dtype, "Float32");
    EXPECT_EQ(cls.dtype, "Byte");
    EXPECT_EQ(dsm.bands, 1);
    EXPECT_EQ(dsm.width_px, dsm.height_px);
    EXPECT_EQ(cls.width_px, dsm.width_px);
    const FloatBand codes = ReadFloatBand((dir / (aoi + "_CLS.tif")).string());
    std::set<int> seen;
    for (float v : codes.values) seen.insert(static_cast<int>(v));
    for (int code : seen) EXPECT_TRUE(dfc_codes.count(code)) << aoi << " class " << code;
    return seen;
  };
  const std::set<int> ours_codes = check_rasters(ours, "SYN_001");
  for (int code : {2, 5, 6, 9, 17}) EXPECT_TRUE(ours_codes.count(code)) << "class " << code << " missing";
  if (fs::exists(jax)) {
    check_rasters(jax, "JAX_068");
    const auto jax_txt = txt_lines(jax / "JAX_068_DSM.txt");
    ASSERT_EQ(jax_txt.size(), 4u);
    for (const auto& l : jax_txt) EXPECT_TRUE(std::regex_match(l, line)) << l;
  }
  // Lower-left convention: DSM row 0 is the north edge, and the txt holds the
  // south-west corner. Every DSM pixel equals the scene height there.
  const DsmTxt grid = ParseDsmTxt(ReadTextFile((ours / "SYN_001_DSM.txt").string()), "txt");
  const FloatBand dsm = ReadFloatBand((ours / "SYN_001_DSM.tif").string());
  const double ul_northing = grid.northing_m + grid.size_px * grid.gsd_m;
  int mismatches = 0;
  for (int r = 0; r < dsm.height_px; ++r)
    for (int c = 0; c < dsm.width_px; ++c) {
      const double e = grid.easting_m + (c + 0.5) * grid.gsd_m, n = ul_northing - (r + 0.5) * grid.gsd_m;
      mismatches += dsm.values[static_cast<size_t>(r) * dsm.width_px + c] !=
                    s.result.city.HeightAt(e - s.result.utm_easting0_m, n - s.result.utm_northing0_m);
    }
  EXPECT_EQ(mismatches, 0);
}

TEST(Synth, SameSeedSameBytesOtherSeedOtherCity) {
  SynthOptions o = SmallScene();
  o.views = 2;
  o.size_m = 64;
  const Scene a = MakeScene(o);
  const std::string first = ReadTextFile(a.result.aois[0].views[1].path);
  const std::string dsm_a = ReadTextFile((a.root / "Track3-Truth" / "SYN_001_DSM.tif").string());
  const Scene b = MakeScene(o);  // same scratch folder name: rewritten in place
  EXPECT_EQ(ReadTextFile(b.result.aois[0].views[1].path), first);
  EXPECT_EQ(ReadTextFile((b.root / "Track3-Truth" / "SYN_001_DSM.tif").string()), dsm_a);
  o.seed = 8;
  const Scene c = MakeScene(o);
  EXPECT_NE(ReadTextFile((c.root / "Track3-Truth" / "SYN_001_DSM.tif").string()), dsm_a);
}

TEST(Synth, AdjacentBlocksShareTheirBoundary) {
  SynthOptions o = SmallScene();
  o.size_m = 64;
  o.views = 2;
  o.blocks_x = 2;
  const Scene s = MakeScene(o);
  ASSERT_EQ(s.result.aois.size(), 2u);
  EXPECT_EQ(s.result.aois[0].name, "SYN_001_X0Y0");
  EXPECT_EQ(s.result.aois[1].name, "SYN_001_X1Y0");
  const fs::path truth = s.root / "Track3-Truth";
  const DsmTxt west = ParseDsmTxt(ReadTextFile((truth / "SYN_001_X0Y0_DSM.txt").string()), "w");
  const DsmTxt east = ParseDsmTxt(ReadTextFile((truth / "SYN_001_X1Y0_DSM.txt").string()), "e");
  EXPECT_DOUBLE_EQ(east.easting_m, west.easting_m + 64.0);
  EXPECT_DOUBLE_EQ(east.northing_m, west.northing_m);
  NullProgress progress;
  EXPECT_EQ(RunIngest(IngestOptions{}, s.root.string(), (s.root / "out").string(), progress).NumIngested(), 2);
}

// East, north and up of an ENU frame at (lon, lat) in ECEF (geodetic normal).
Eigen::Matrix3d EnuFromEcef(const GeodeticPoint& g) {
  const double l = g.lon_deg * M_PI / 180, p = g.lat_deg * M_PI / 180;
  Eigen::Matrix3d m;
  m << -std::sin(l), std::cos(l), 0, -std::sin(p) * std::cos(l), -std::sin(p) * std::sin(l), std::cos(p),
      std::cos(p) * std::cos(l), std::cos(p) * std::sin(l), std::sin(p);
  return m;
}

// Truth views of an image's own camera, given in another ENU frame 2 km
// away, reproduce that image: same frame conversion, lighting and noise;
// only the cars (absent from truth views) differ.
TEST(Synth, TruthViewOfAnImagesCameraInAnotherFrameReproducesTheImage) {
  const SynthOptions o = SmallScene();
  const Scene scene = MakeScene(o);
  const int v = 2;
  const SynthView& view = scene.result.aois[0].views[v];
  const GeodeticPoint own = scene.result.enu_origin;
  const GeodeticPoint other{own.lon_deg + 0.02, own.lat_deg - 0.01, own.height_m + 30.0};
  const EnuFrame own_frame(own), other_frame(other);
  PinholeCamera cam;
  cam.fx = cam.fy = view.camera.focal_px;
  cam.cx = view.camera.principal_px.x();
  cam.cy = view.camera.principal_px.y();
  cam.width_px = view.camera.width_px;
  cam.height_px = view.camera.height_px;
  // Rotation between the frames from their ECEF axes (independent of the
  // finite differences the renderer uses).
  cam.cam_from_world_rotation = view.camera.cam_from_enu * EnuFromEcef(own) * EnuFromEcef(other).transpose();
  const Eigen::Vector3d centre_other = other_frame.EnuFromGeodetic(own_frame.GeodeticFromEnu(view.camera.centre_enu_m));
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * centre_other;
  const fs::path out = scene.root / "truth";
  NullProgress quiet;
  ASSERT_EQ(RenderTruthViews(o, {{"again", cam}}, other, v, out.string(), quiet), 1);
  const FloatImage truth = ReadFloatImage((out / "again.png").string());
  const FloatImage image = ReadFloatImage(view.path);
  const FloatBand mask = ReadFloatBand((out / "again_mask.png").string());
  ASSERT_EQ(truth.width_px, image.width_px);
  ASSERT_EQ(truth.height_px, image.height_px);
  std::size_t same = 0, inside = 0;
  const std::size_t n = static_cast<std::size_t>(truth.width_px) * truth.height_px;
  for (std::size_t p = 0; p < n; ++p) {
    bool equal = true;
    for (int c = 0; c < 3; ++c) equal = equal && std::abs(truth.values[3 * p + c] - image.values[3 * p + c]) <= 1.0f;
    same += equal;
    inside += mask.values[p] > 127;
  }
  // Cars cover ~2 % of the ground, with their shadows a few % of the pixels.
  EXPECT_GT(static_cast<double>(same) / n, 0.9);
  // The crop bounds the AOI's footprint, turned by the orbit's heading, plus
  // a margin: at a 30 deg turn the square fills about 1 / (cos + sin)^2 =
  // 54 % of its bounding box, less with the margin and the leaning buildings.
  EXPECT_GT(static_cast<double>(inside) / n, 0.3);
  EXPECT_LT(inside, n);
  EXPECT_THROW(RenderTruthViews(o, {{"again", cam}}, other, o.views, out.string(), quiet), Error);
}

TEST(Synth, OptionsAreChecked) {
  SynthOptions o;
  o.aoi = "no-number";
  EXPECT_THROW(o.Check(), Error);
  o = SynthOptions{};
  o.size_m = 100.25;  // not a whole number of 0.5 m pixels
  EXPECT_THROW(o.Check(), Error);
  o = SynthOptions{};
  o.views = 1;
  EXPECT_THROW(o.Check(), Error);
}

// Drawn scenes must each be a valid scene, made again from the same number,
// keep what is not drawn, and over many draws reach every part of the ranges
// DrawSceneOptions documents. The share bounds are wide (400 draws: a
// binomial share of 1/3 or 1/2 lies within +-0.1 with probability > 0.999).
TEST(Synth, DrawnScenesAreValidRepeatableAndSpanTheirRanges) {
  SynthOptions base;
  base.aoi = "DRW_007";
  base.size_m = 128;
  int one_band = 0, flat = 0, south = 0, tall = 0, few_views = 0, sixteen_bits = 0, oblique = 0;
  std::set<std::uint64_t> seeds;
  const int draws = 400;
  for (int d = 1; d <= draws; ++d) {
    const SynthOptions o = DrawSceneOptions(d, base);
    const SynthOptions again = DrawSceneOptions(d, base);
    EXPECT_EQ(o.seed, again.seed);
    EXPECT_EQ(o.lat_deg, again.lat_deg);
    EXPECT_EQ(o.max_building_m, again.max_building_m);
    EXPECT_NO_THROW(o.Check());
    EXPECT_EQ(o.aoi, "DRW_007");
    EXPECT_EQ(o.size_m, 128);
    EXPECT_EQ(o.gsd_m, base.gsd_m);
    EXPECT_GE(o.seed, 1000000u) << "drawn cities never reuse the small seeds the tuning cities have";
    seeds.insert(o.seed);
    EXPECT_LE(std::abs(o.lat_deg), 60.0);
    EXPECT_GE(o.min_off_nadir_deg, 0.0);
    EXPECT_LE(o.min_off_nadir_deg, 20.0);
    EXPECT_GE(o.max_off_nadir_deg, std::min(45.0, o.min_off_nadir_deg + 10.0) - 0.05);
    EXPECT_LE(o.max_off_nadir_deg, 45.0);
    EXPECT_GE(o.views, 3);
    EXPECT_LE(o.views, 16);
    EXPECT_LE(o.views_per_date, o.views);
    EXPECT_GE(o.max_building_m, 15.0);
    EXPECT_LE(o.max_building_m, 180.0);
    EXPECT_TRUE(o.relief_m == 0.0 || (o.relief_m >= 10.0 && o.relief_m <= 100.0)) << o.relief_m;
    EXPECT_GE(o.date_contrast, 0.5);
    EXPECT_LE(o.date_contrast, 3.0);
    one_band += o.bands == 1;
    flat += o.relief_m == 0.0;
    south += o.lat_deg < 0;
    tall += o.max_building_m >= 150.0;
    few_views += o.views <= 4;
    sixteen_bits += o.bit_depth == 16;
    oblique += o.min_off_nadir_deg >= 15.0;
  }
  EXPECT_EQ(seeds.size(), static_cast<std::size_t>(draws));
  EXPECT_NEAR(one_band / double(draws), 1.0 / 3.0, 0.1);
  EXPECT_NEAR(flat / double(draws), 0.5, 0.1);
  EXPECT_NEAR(south / double(draws), 0.5, 0.1);
  for (int count : {tall, few_views, sixteen_bits, oblique}) EXPECT_GT(count, draws / 20);
  EXPECT_NE(DrawSceneOptions(1, base).seed, DrawSceneOptions(2, base).seed);
}

}  // namespace
}  // namespace skyfall::synth
