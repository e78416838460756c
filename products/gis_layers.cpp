#include "products/gis_layers.h"

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <functional>
#include <map>

#include "core/error.h"
#include "core/stats.h"
#include "dense/hole_fill.h"
#include "ingest/geo.h"
#include "ingest/raster.h"
#include "ingest/vertical_datum.h"
#include "products/dsm_breakdown.h"
#include "products/land_cover.h"

namespace skyfall {
namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr int kGroundClass = 2, kBuildingClass = 6;  // ASPRS

std::size_t Pixels(const DsmGrid& g) { return static_cast<std::size_t>(g.width_px) * g.height_px; }

DsmGrid EmptyLike(const DsmGrid& grid) {
  DsmGrid out = grid;
  out.height_m.assign(Pixels(grid), kNan);
  return out;
}

// The UTM position of a pixel centre.
Eigen::Vector2d PixelCentreUtm(const DsmGrid& g, int col, int row) {
  return {g.upper_left_easting_m + (col + 0.5) * g.gsd_m, g.upper_left_northing_m - (row + 0.5) * g.gsd_m};
}

// A pixel's column and row holding a UTM position, or (-1, -1) outside.
Eigen::Vector2i PixelOfUtm(const DsmGrid& g, double easting_m, double northing_m) {
  if (!std::isfinite(easting_m) || !std::isfinite(northing_m)) return {-1, -1};
  const int col = static_cast<int>(std::floor((easting_m - g.upper_left_easting_m) / g.gsd_m));
  const int row = static_cast<int>(std::floor((g.upper_left_northing_m - northing_m) / g.gsd_m));
  if (col < 0 || row < 0 || col >= g.width_px || row >= g.height_px) return {-1, -1};
  return {col, row};
}

// A tile's cells indexed by their position on its regular cell lattice.
struct CellLattice {
  double x0 = 0, y0 = 0, cell = 1;
  int nx = 0, ny = 0;
  std::vector<int> index;  // nx * ny, -1 where there is no cell
  int At(double x, double y) const {
    const int i = static_cast<int>(std::lround((x - x0) / cell)), j = static_cast<int>(std::lround((y - y0) / cell));
    if (i < 0 || j < 0 || i >= nx || j >= ny) return -1;
    return index[static_cast<std::size_t>(j) * nx + i];
  }
};

CellLattice LatticeOf(const DenseCells& cells) {
  CellLattice l;
  if (cells.points.empty()) return l;
  l.cell = cells.cell_m;
  double x1 = -1e300, y1 = -1e300;
  l.x0 = l.y0 = 1e300;
  for (const Eigen::Vector3f& p : cells.points) {
    l.x0 = std::min(l.x0, static_cast<double>(p.x()));
    l.y0 = std::min(l.y0, static_cast<double>(p.y()));
    x1 = std::max(x1, static_cast<double>(p.x()));
    y1 = std::max(y1, static_cast<double>(p.y()));
  }
  l.nx = static_cast<int>(std::lround((x1 - l.x0) / l.cell)) + 1;
  l.ny = static_cast<int>(std::lround((y1 - l.y0) / l.cell)) + 1;
  l.index.assign(static_cast<std::size_t>(l.nx) * l.ny, -1);
  for (std::size_t k = 0; k < cells.points.size(); ++k) {
    const int i = static_cast<int>(std::lround((cells.points[k].x() - l.x0) / l.cell));
    const int j = static_cast<int>(std::lround((cells.points[k].y() - l.y0) / l.cell));
    l.index[static_cast<std::size_t>(j) * l.nx + i] = static_cast<int>(k);
  }
  return l;
}

// The tile that owns an ENU position: the one whose core's grid cell it is,
// or the first whose lattice has a cell there when tiles have no spec.
int OwnerTile(const std::vector<DenseTileCells>& tiles, const std::vector<CellLattice>& lattices, double x, double y) {
  for (std::size_t t = 0; t < tiles.size(); ++t) {
    const std::optional<TileSpec>& spec = tiles[t].spec;
    if (spec ? spec->grid.Owner(x, y) == Eigen::Vector2i(spec->col, spec->row) : lattices[t].At(x, y) >= 0)
      return static_cast<int>(t);
  }
  return -1;
}

float LayerAt(const std::vector<float>& layer, int k) { return layer.empty() ? kNan : layer[k]; }

// Calls visit(i, opacity, geodetic, utm, pixel) for each Gaussian of at least
// `min_opacity` whose centre lies on `grid`.
template <typename Visit>
void ForGaussiansOnGrid(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const DsmGrid& grid,
                        double min_opacity, const Visit& visit) {
  const EnuFrame frame(enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(grid.epsg);
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const double opacity = OpacityOfLogit(scene.opacity_logits[i]);
    if (opacity < min_opacity) continue;
    const GeodeticPoint g = frame.GeodeticFromEnu(scene.means[i].cast<double>());
    const Eigen::Vector2d utm = UtmFromGeodetic(zone, g.lon_deg, g.lat_deg);
    const Eigen::Vector2i px = PixelOfUtm(grid, utm.x(), utm.y());
    if (px.x() < 0) continue;  // another AOI's, or the tiles' margin beyond the city
    visit(i, opacity, g, utm, px);
  }
}

}  // namespace

DenseLayers SampleDenseLayers(const std::vector<DenseTileCells>& tiles, const GeodeticPoint& enu_origin,
                              const DsmGrid& grid) {
  DenseLayers out;
  out.dtm = EmptyLike(grid);
  out.dtm.reference = HeightReference::kEllipsoid;
  out.views.assign(Pixels(grid), kNan);
  out.fill_rule.assign(Pixels(grid), kNan);
  out.cost.assign(Pixels(grid), kNan);
  std::vector<CellLattice> lattices;
  for (const DenseTileCells& t : tiles) lattices.push_back(LatticeOf(t.cells));
  const EnuFrame frame(enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(grid.epsg);
  for (int row = 0; row < grid.height_px; ++row)
    for (int col = 0; col < grid.width_px; ++col) {
      const Eigen::Vector2d utm = PixelCentreUtm(grid, col, row);
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, utm.x(), utm.y());
      const Eigen::Vector3d enu = frame.EnuFromGeodetic({ll.x(), ll.y(), enu_origin.height_m});
      const int t = OwnerTile(tiles, lattices, enu.x(), enu.y());
      if (t < 0) continue;
      const int k = lattices[t].At(enu.x(), enu.y());
      if (k < 0) continue;
      const DenseCells& c = tiles[t].cells;
      const std::size_t p = static_cast<std::size_t>(row) * grid.width_px + col;
      const float terrain = LayerAt(c.terrain_m, k);
      if (std::isfinite(terrain))  // ENU up to the ellipsoid at this point
        out.dtm.height_m[p] = static_cast<float>(frame.GeodeticFromEnu({enu.x(), enu.y(), terrain}).height_m);
      out.views[p] = c.views.empty() ? kNan : static_cast<float>(c.views[k]);
      out.fill_rule[p] = c.fill_rule.empty() ? kNan : static_cast<float>(c.fill_rule[k]);
      out.cost[p] = LayerAt(c.cost, k);
    }
  return out;
}

std::vector<float> GaussianHeightSpreadM(const GaussianCloud& scene, const GeodeticPoint& enu_origin,
                                         const DsmGrid& grid, double min_opacity) {
  std::vector<double> weight(Pixels(grid), 0.0), mean(Pixels(grid), 0.0), second(Pixels(grid), 0.0);
  ForGaussiansOnGrid(scene, enu_origin, grid, min_opacity,
                     [&](std::size_t i, double opacity, const GeodeticPoint& g, const Eigen::Vector2d&,
                         const Eigen::Vector2i& px) {
                       // The Gaussian's own vertical variance: (R S^2 R^T)_zz.
                       const Eigen::Vector4d q = scene.rotations[i].cast<double>();  // (w, x, y, z)
                       const Eigen::Matrix3d r =
                           Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
                       const Eigen::Vector3d s2 = (2.0 * scene.log_scales[i].cast<double>()).array().exp();
                       const double var_z = (r.row(2).array().square() * s2.transpose().array()).sum();
                       const std::size_t p = static_cast<std::size_t>(px.y()) * grid.width_px + px.x();
                       weight[p] += opacity;
                       mean[p] += opacity * g.height_m;
                       second[p] += opacity * (g.height_m * g.height_m + var_z);
                     });
  std::vector<float> spread(Pixels(grid), kNan);
  for (std::size_t p = 0; p < spread.size(); ++p) {
    if (weight[p] <= 0) continue;
    const double m = mean[p] / weight[p];
    spread[p] = static_cast<float>(std::sqrt(std::max(0.0, second[p] / weight[p] - m * m)));
  }
  return spread;
}

DsmGrid HeightAboveTerrain(const DsmGrid& dsm, const DsmGrid& dtm) {
  if (dsm.width_px != dtm.width_px || dsm.height_px != dtm.height_px || dsm.reference != dtm.reference ||
      dsm.epsg != dtm.epsg || dsm.gsd_m != dtm.gsd_m || dsm.upper_left_easting_m != dtm.upper_left_easting_m ||
      dsm.upper_left_northing_m != dtm.upper_left_northing_m)
    throw Error("products", "ndsm", "the DSM and the DTM are not on one grid in one height reference");
  DsmGrid out = EmptyLike(dsm);
  out.reference = HeightReference::kAboveTerrain;
  for (std::size_t p = 0; p < out.height_m.size(); ++p) out.height_m[p] = dsm.height_m[p] - dtm.height_m[p];
  return out;
}

void WriteQualityCog(const std::string& path, const DsmGrid& grid, const DenseLayers& dense,
                     const std::vector<float>& spread_m) {
  const std::size_t n = Pixels(grid);
  const std::vector<const std::vector<float>*> layers = {&dense.views, &dense.fill_rule, &dense.cost, &spread_m};
  std::vector<float> pixels(layers.size() * n);
  for (std::size_t p = 0; p < n; ++p)
    for (std::size_t b = 0; b < layers.size(); ++b) pixels[p * layers.size() + b] = (*layers[b])[p];
  CogBands bands;
  bands.count = static_cast<int>(layers.size());
  bands.descriptions = {"views", "fill_rule", "matching_cost", "height_spread_m"};
  bands.metadata = {{"FILL_RULE_CODES",
                     "0 matched, 1 coarse sweep, 2 occluded ground (terrain), 3 roof hole (roof), 4 seen hole "
                     "(lowest in reach above the ground), 5 seen ground (terrain), 6 far raised (ground), 7 side "
                     "decided by the views"}};
  WriteCog(path, grid.width_px, grid.height_px, SampleType::kFloat32, pixels.data(),
           {grid.upper_left_easting_m, grid.upper_left_northing_m, grid.gsd_m, grid.epsg, std::nullopt}, bands);
}

void WriteOrthoCog(const std::string& path, const DsmGrid& grid, const std::vector<float>& rgb,
                   const OrthoFormat& format, const std::map<std::string, std::string>& metadata) {
  if (format.bits != 8 && format.bits != 16)
    throw Error("products", "ortho_bits", std::to_string(format.bits) + " must be 8 or 16");
  const std::size_t n = Pixels(grid);
  const int colours = format.grey ? 1 : 3, count = colours + 1;
  const double full = format.bits == 8 ? 255.0 : 65535.0;
  std::vector<std::uint16_t> wide(format.bits == 16 ? n * count : 0);
  std::vector<std::uint8_t> narrow(format.bits == 8 ? n * count : 0);
  for (std::size_t p = 0; p < n; ++p) {
    const bool empty = !std::isfinite(rgb[3 * p]);
    for (int b = 0; b < count; ++b) {
      double v = 0;
      if (!empty && b < colours)
        v = format.grey ? (rgb[3 * p] + rgb[3 * p + 1] + rgb[3 * p + 2]) / 3.0 : rgb[3 * p + b];
      if (b == colours) v = empty ? 0.0 : 1.0;  // alpha
      const double level = std::round(std::clamp(v, 0.0, 1.0) * full);
      if (format.bits == 8) narrow[p * count + b] = static_cast<std::uint8_t>(level);
      else wide[p * count + b] = static_cast<std::uint16_t>(level);
    }
  }
  CogBands bands;
  bands.count = count;
  bands.descriptions = format.grey ? std::vector<std::string>{"grey", "alpha"}
                                   : std::vector<std::string>{"red", "green", "blue", "alpha"};
  bands.colour = !format.grey;
  bands.last_is_alpha = true;
  bands.metadata = metadata;
  const NorthUpGrid where{grid.upper_left_easting_m, grid.upper_left_northing_m, grid.gsd_m, grid.epsg, std::nullopt};
  if (format.bits == 8) WriteCog(path, grid.width_px, grid.height_px, SampleType::kByte, narrow.data(), where, bands);
  else WriteCog(path, grid.width_px, grid.height_px, SampleType::kUInt16, wide.data(), where, bands);
}

namespace {

// The colours of fill_rule.png, by code (docs/outputs.md's table).
constexpr std::uint8_t kRuleColours[8][3] = {{200, 200, 200}, {120, 160, 230}, {150, 90, 40}, {230, 60, 60},
                                             {240, 170, 40}, {90, 180, 90}, {160, 90, 200}, {40, 200, 200}};

// Writes `bands` x 8-bit samples per preview pixel from `sample(pixel)`,
// every step-th pixel of the grid along both axes.
void WritePreview(const std::string& path, const DsmGrid& g, int bands,
                  const std::function<void(std::size_t, std::uint8_t*)>& sample) {
  const int step = std::max(1, (std::max(g.width_px, g.height_px) + kPreviewPx - 1) / kPreviewPx);
  const int w = (g.width_px + step - 1) / step, h = (g.height_px + step - 1) / step;
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(w) * h * bands, 0);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      sample(static_cast<std::size_t>(r) * step * g.width_px + static_cast<std::size_t>(c) * step,
             &pixels[(static_cast<std::size_t>(r) * w + c) * bands]);
  WriteBytePng(path, w, h, bands, pixels.data());
}

// A grey ramp of `values` between `lo` and `hi` (black where NaN).
std::uint8_t Ramp(float v, double lo, double hi) {
  if (!std::isfinite(v)) return 0;
  return static_cast<std::uint8_t>(std::lround(30 + 225 * std::clamp((v - lo) / std::max(hi - lo, 1e-6), 0.0, 1.0)));
}

}  // namespace

void WriteProductPreviews(const std::string& dir, const DsmGrid& dsm, const PreviewLayers& layers) {
  const std::vector<float>&rgb = layers.rgb, &views = layers.views, &fill_rule = layers.fill_rule;
  std::vector<double> finite;
  for (float v : dsm.height_m)
    if (std::isfinite(v)) finite.push_back(v);
  const double lo = Quantile(finite, 0.02), hi = finite.empty() ? 1.0 : Quantile(finite, 0.98);
  WritePreview(dir + "/dsm.png", dsm, 1, [&](std::size_t p, std::uint8_t* out) { out[0] = Ramp(dsm.height_m[p], lo, hi); });
  if (!rgb.empty())
    WritePreview(dir + "/ortho.png", dsm, 3, [&](std::size_t p, std::uint8_t* out) {
      for (int b = 0; b < 3; ++b)
        out[b] = std::isfinite(rgb[3 * p + b]) ? static_cast<std::uint8_t>(std::lround(255 * rgb[3 * p + b])) : 0;
    });
  if (!views.empty()) {
    float most = 1;
    for (float v : views)
      if (std::isfinite(v)) most = std::max(most, v);
    WritePreview(dir + "/views.png", dsm, 1, [&](std::size_t p, std::uint8_t* out) { out[0] = Ramp(views[p], 0, most); });
  }
  if (!fill_rule.empty())
    WritePreview(dir + "/fill_rule.png", dsm, 3, [&](std::size_t p, std::uint8_t* out) {
      const float code = fill_rule[p];
      if (!std::isfinite(code) || code < 0 || code > 7) return;
      for (int b = 0; b < 3; ++b) out[b] = kRuleColours[static_cast<int>(code)][b];
    });
  if (!layers.classes.empty())
    WritePreview(dir + "/classes.png", dsm, 3, [&](std::size_t p, std::uint8_t* out) {
      const auto it = LandCoverColours().find(layers.classes[p]);
      if (it != LandCoverColours().end()) std::copy(it->second.begin(), it->second.end(), out);
    });
}

TerrainComparison CompareTerrain(const DsmGrid& dtm, const DsmGrid& ndsm, const DsmGrid& truth,
                                 const std::vector<float>& cls, int shift_col_px, int shift_row_px,
                                 double z_offset_m) {
  TerrainComparison out;
  if (cls.size() != Pixels(truth) || dtm.width_px != truth.width_px || dtm.height_px != truth.height_px) return out;
  const int nx = truth.width_px, ny = truth.height_px;
  // The truth's bare earth: its ground cells, and the terrain model through
  // them under everything else.
  std::vector<float> ground(Pixels(truth), kNan);
  for (std::size_t p = 0; p < ground.size(); ++p)
    if (ClassCodeOf(cls[p]) == kGroundClass) ground[p] = truth.height_m[p];
  HoleFillGrid terrain_options = HoleFillOptions{}.OnGrid(truth.gsd_m);
  const std::vector<float> truth_terrain = TerrainModel(ground, ground, nx, ny, terrain_options);
  std::vector<double> dtm_error, ndsm_error;
  for (int row = 0; row < ny; ++row)
    for (int col = 0; col < nx; ++col) {
      const int c = col + shift_col_px, r = row + shift_row_px;
      if (c < 0 || r < 0 || c >= nx || r >= ny) continue;
      const std::size_t p = static_cast<std::size_t>(row) * nx + col, q = static_cast<std::size_t>(r) * nx + c;
      const int code = ClassCodeOf(cls[p]);
      if (code == kGroundClass && std::isfinite(dtm.height_m[q]) && std::isfinite(truth.height_m[p]))
        dtm_error.push_back(dtm.height_m[q] - z_offset_m - truth.height_m[p]);
      if (code == kBuildingClass && std::isfinite(ndsm.height_m[q]) && std::isfinite(truth.height_m[p]) &&
          std::isfinite(truth_terrain[p]))
        ndsm_error.push_back(ndsm.height_m[q] - (truth.height_m[p] - truth_terrain[p]));
    }
  auto mae = [](const std::vector<double>& e) {
    double s = 0;
    for (double v : e) s += std::abs(v);
    return e.empty() ? NAN : s / e.size();
  };
  auto mean = [](const std::vector<double>& e) {
    double s = 0;
    for (double v : e) s += v;
    return e.empty() ? NAN : s / e.size();
  };
  out.ground_cells = static_cast<int>(dtm_error.size());
  out.building_cells = static_cast<int>(ndsm_error.size());
  out.dtm_mae_ground_m = mae(dtm_error);
  out.dtm_bias_ground_m = mean(dtm_error);
  out.ndsm_mae_building_m = mae(ndsm_error);
  out.ndsm_bias_building_m = mean(ndsm_error);
  return out;
}

namespace {

// The image's colours sampled (bilinearly) where the RPC projects each cell
// of `heights` at its height, 3 per cell; NaN outside the image, where it
// has no data or where the grid has no height.
std::vector<float> ImageOnGrid(const DsmGrid& heights, const NormalizedImage& image, const RpcModel& rpc) {
  std::vector<float> out(3 * Pixels(heights), kNan);
  const UtmZone zone = UtmZoneFromEpsg(heights.epsg);
  auto at = [&](int c, int r, int b) {
    const std::size_t p = static_cast<std::size_t>(r) * image.width_px + c;
    return image.valid[p] ? image.rgb[3 * p + b] : kNan;
  };
  for (int row = 0; row < heights.height_px; ++row)
    for (int col = 0; col < heights.width_px; ++col) {
      const float h = heights.At(col, row);
      if (!std::isfinite(h)) continue;
      const Eigen::Vector2d utm = PixelCentreUtm(heights, col, row);
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, utm.x(), utm.y());
      const Eigen::Vector2d px = rpc.Project(ll.x(), ll.y(), h);  // pixel centres at integers
      const int c = static_cast<int>(std::floor(px.x())), r = static_cast<int>(std::floor(px.y()));
      if (c < 0 || r < 0 || c + 1 >= image.width_px || r + 1 >= image.height_px) continue;
      const float fc = static_cast<float>(px.x() - c), fr = static_cast<float>(px.y() - r);
      const std::size_t p = static_cast<std::size_t>(row) * heights.width_px + col;
      for (int b = 0; b < 3; ++b)
        out[3 * p + b] = (1 - fr) * ((1 - fc) * at(c, r, b) + fc * at(c + 1, r, b)) +
                         fr * ((1 - fc) * at(c, r + 1, b) + fc * at(c + 1, r + 1, b));
    }
  return out;
}

// Grey levels of an interleaved RGB raster (NaN stays NaN).
cv::Mat GreyOf(const std::vector<float>& rgb, int nx, int ny) {
  cv::Mat grey(ny, nx, CV_32F);
  for (int r = 0; r < ny; ++r)
    for (int c = 0; c < nx; ++c) {
      const std::size_t p = static_cast<std::size_t>(r) * nx + c;
      grey.at<float>(r, c) = (rgb[3 * p] + rgb[3 * p + 1] + rgb[3 * p + 2]) / 3.0f;
    }
  return grey;
}

// Per truth cell, 1 where a ray from it towards the satellite passes below
// the truth's surface (by more than kSeenToleranceM): hidden in the image.
constexpr double kSeenToleranceM = 0.5;  // the LiDAR's own noise on flat roofs
std::vector<std::uint8_t> HiddenFromView(const DsmGrid& truth, double zenith_deg, double azimuth_deg) {
  std::vector<std::uint8_t> hidden(Pixels(truth), 0);
  const double tan_zenith = std::tan(zenith_deg * M_PI / 180);
  if (tan_zenith < 1e-6) return hidden;
  float highest = -std::numeric_limits<float>::infinity();
  for (float h : truth.height_m)
    if (std::isfinite(h)) highest = std::max(highest, h);
  const double az = azimuth_deg * M_PI / 180;
  const double step_col = std::sin(az), step_row = -std::cos(az);  // half-pixel steps towards the satellite
  for (int row = 0; row < truth.height_px; ++row)
    for (int col = 0; col < truth.width_px; ++col) {
      const float h0 = truth.At(col, row);
      if (!std::isfinite(h0)) continue;
      for (double t = 0.5;; t += 0.5) {
        const double rise_m = t * truth.gsd_m / tan_zenith;
        if (h0 + rise_m > highest) break;
        const int c = static_cast<int>(std::lround(col + t * step_col)), r = static_cast<int>(std::lround(row + t * step_row));
        if (c < 0 || r < 0 || c >= truth.width_px || r >= truth.height_px) break;
        const float h = truth.At(c, r);
        if (std::isfinite(h) && h > h0 + rise_m + kSeenToleranceM) {
          hidden[static_cast<std::size_t>(row) * truth.width_px + col] = 1;
          break;
        }
      }
    }
  return hidden;
}

// Mean SSIM (7 x 7 box windows, the usual constants for a [0, 1] range) over
// the pixels of `mask` whose whole window lies in it.
double MaskedSsim(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;
  const cv::Size window(7, 7);
  cv::Mat a0 = a.clone(), b0 = b.clone();
  a0.setTo(0, ~mask);
  b0.setTo(0, ~mask);
  cv::Mat mu_a, mu_b, aa, bb, ab;
  cv::boxFilter(a0, mu_a, CV_64F, window);
  cv::boxFilter(b0, mu_b, CV_64F, window);
  cv::boxFilter(a0.mul(a0), aa, CV_64F, window);
  cv::boxFilter(b0.mul(b0), bb, CV_64F, window);
  cv::boxFilter(a0.mul(b0), ab, CV_64F, window);
  cv::Mat inside;
  // Beyond the grid is outside the mask: a window crossing the edge does not count.
  cv::erode(mask, inside, cv::getStructuringElement(cv::MORPH_RECT, window), cv::Point(-1, -1), 1,
            cv::BORDER_CONSTANT, cv::Scalar(0));
  double sum = 0;
  int n = 0;
  for (int r = 0; r < a.rows; ++r)
    for (int c = 0; c < a.cols; ++c) {
      if (!inside.at<std::uint8_t>(r, c)) continue;
      const double ma = mu_a.at<double>(r, c), mb = mu_b.at<double>(r, c);
      const double va = aa.at<double>(r, c) - ma * ma, vb = bb.at<double>(r, c) - mb * mb;
      const double cov = ab.at<double>(r, c) - ma * mb;
      sum += ((2 * ma * mb + kC1) * (2 * cov + kC2)) / ((ma * ma + mb * mb + kC1) * (va + vb + kC2));
      ++n;
    }
  return n ? sum / n : NAN;
}

}  // namespace

namespace {

// The ortho at (col + dx, row + dy) against the reference at (col, row), on
// the cells `usable` marks where both hold a value: the shift within
// `max_shift_px` of least squared error, its PSNR and SSIM.
OrthoAgreement Agreement(const cv::Mat& ortho, const cv::Mat& reference, const cv::Mat& usable, int max_shift_px) {
  OrthoAgreement out;
  const int nx = ortho.cols, ny = ortho.rows;
  auto shifted = [&](int dx, int dy, cv::Mat* moved, cv::Mat* mask) {
    *moved = cv::Mat(ny, nx, CV_32F, cv::Scalar(kNan));
    *mask = cv::Mat::zeros(ny, nx, CV_8U);
    for (int r = 0; r < ny; ++r)
      for (int c = 0; c < nx; ++c) {
        const int sc = c + dx, sr = r + dy;
        if (sc < 0 || sr < 0 || sc >= nx || sr >= ny) continue;
        const float v = ortho.at<float>(sr, sc), w = reference.at<float>(r, c);
        moved->at<float>(r, c) = v;
        if (std::isfinite(v) && std::isfinite(w) && usable.at<std::uint8_t>(r, c)) mask->at<std::uint8_t>(r, c) = 255;
      }
  };
  double best_mse = std::numeric_limits<double>::infinity();
  for (int dy = -max_shift_px; dy <= max_shift_px; ++dy)
    for (int dx = -max_shift_px; dx <= max_shift_px; ++dx) {
      cv::Mat moved, mask;
      shifted(dx, dy, &moved, &mask);
      double sum = 0;
      int n = 0;
      for (int r = 0; r < ny; ++r)
        for (int c = 0; c < nx; ++c)
          if (mask.at<std::uint8_t>(r, c)) {
            const double d = moved.at<float>(r, c) - reference.at<float>(r, c);
            sum += d * d;
            ++n;
          }
      if (n > 0 && sum / n < best_mse) {
        best_mse = sum / n;
        out.cells = n;
        out.shift_col_px = dx;
        out.shift_row_px = dy;
      }
    }
  if (out.cells == 0) return out;
  out.psnr_db = 10.0 * std::log10(1.0 / std::max(best_mse, 1e-12));
  cv::Mat moved, mask;
  shifted(out.shift_col_px, out.shift_row_px, &moved, &mask);
  cv::Mat a = moved.clone(), b = reference.clone();
  a.setTo(0, ~mask);
  b.setTo(0, ~mask);
  out.ssim = MaskedSsim(a, b, mask);
  return out;
}

}  // namespace

OrthoAgreement CompareOrthoWithImage(const std::vector<float>& ortho_rgb, const DsmGrid& truth,
                                     const std::vector<float>& cls, const NormalizedImage& image, const RpcModel& rpc,
                                     double view_zenith_deg, double view_azimuth_deg, int max_shift_px) {
  const int nx = truth.width_px, ny = truth.height_px;
  if (cls.size() != Pixels(truth) || ortho_rgb.size() != 3 * Pixels(truth)) return {};
  const cv::Mat seen = GreyOf(ImageOnGrid(truth, image, rpc), nx, ny);
  const std::vector<std::uint8_t> hidden = HiddenFromView(truth, view_zenith_deg, view_azimuth_deg);
  cv::Mat ground = cv::Mat::zeros(ny, nx, CV_8U);
  for (int r = 0; r < ny; ++r)
    for (int c = 0; c < nx; ++c) {
      const std::size_t p = static_cast<std::size_t>(r) * nx + c;
      if (!hidden[p] && ClassCodeOf(cls[p]) == kGroundClass) ground.at<std::uint8_t>(r, c) = 255;
    }
  return Agreement(GreyOf(ortho_rgb, nx, ny), seen, ground, max_shift_px);
}

ColourMatch MatchColoursToImage(const std::vector<float>& ortho_rgb, const DsmGrid& dsm, const NormalizedImage& image,
                                const RpcModel& rpc, double view_zenith_deg, double view_azimuth_deg) {
  ColourMatch match;
  if (ortho_rgb.size() != 3 * Pixels(dsm)) return match;
  const std::vector<float> seen = ImageOnGrid(dsm, image, rpc);
  const std::vector<std::uint8_t> hidden = HiddenFromView(dsm, view_zenith_deg, view_azimuth_deg);
  // Least squares per band: image = gain * ortho + offset.
  std::array<double, 3> sx{}, sy{}, sxx{}, sxy{};
  for (std::size_t p = 0; p < Pixels(dsm); ++p) {
    if (hidden[p] || !std::isfinite(ortho_rgb[3 * p]) || !std::isfinite(seen[3 * p]) ||
        !std::isfinite(seen[3 * p + 1]) || !std::isfinite(seen[3 * p + 2]))
      continue;
    ++match.cells;
    for (int b = 0; b < 3; ++b) {
      const double x = ortho_rgb[3 * p + b], y = seen[3 * p + b];
      sx[b] += x, sy[b] += y, sxx[b] += x * x, sxy[b] += x * y;
    }
  }
  if (match.cells < kMinColourMatchCells) {
    match.cells = 0;
    return match;
  }
  for (int b = 0; b < 3; ++b) {
    const double n = match.cells, var = sxx[b] - sx[b] * sx[b] / n;
    if (var <= 1e-9 * n) continue;  // a flat band: keep it
    match.gain[b] = (sxy[b] - sx[b] * sy[b] / n) / var;
    match.offset[b] = (sy[b] - match.gain[b] * sx[b]) / n;
  }
  return match;
}

void ApplyColourMatch(const ColourMatch& match, std::vector<float>* rgb) {
  for (std::size_t k = 0; k < rgb->size(); ++k) {
    float& v = (*rgb)[k];
    if (std::isfinite(v)) v = static_cast<float>(std::clamp(match.gain[k % 3] * v + match.offset[k % 3], 0.0, 1.0));
  }
}

OrthoAgreement CompareOrthoWithTruth(const std::vector<float>& ortho_rgb, const NormalizedImage& truth, int max_shift_px) {
  const int nx = truth.width_px, ny = truth.height_px;
  if (ortho_rgb.size() != 3 * static_cast<std::size_t>(nx) * ny) return {};
  cv::Mat valid(ny, nx, CV_8U);
  for (int r = 0; r < ny; ++r)
    for (int c = 0; c < nx; ++c) valid.at<std::uint8_t>(r, c) = truth.valid[static_cast<std::size_t>(r) * nx + c] ? 255 : 0;
  return Agreement(GreyOf(ortho_rgb, nx, ny), GreyOf(truth.rgb, nx, ny), valid, max_shift_px);
}

std::vector<LasPoint> ScenePoints(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const DsmGrid& dtm,
                                  HeightReference reference, double min_opacity, double ground_tolerance_m,
                                  const std::vector<std::uint8_t>& land_cover) {
  if (!land_cover.empty() && land_cover.size() != Pixels(dtm))
    throw Error("products", "points", "the land cover must be on the DTM's grid");
  constexpr std::uint8_t kUnclassified = 1, kVegetationClass = 5;
  // The class of a point above ground: its cell's, when that names an object.
  auto above_ground_class = [&](const Eigen::Vector2i& px) {
    if (land_cover.empty()) return kUnclassified;
    const std::uint8_t c = land_cover[static_cast<std::size_t>(px.y()) * dtm.width_px + px.x()];
    return c == kBuildingClass || c == kVegetationClass ? c : kUnclassified;
  };
  if (reference == HeightReference::kAboveTerrain)
    throw Error("products", "points", "a point cloud's heights need a datum (ellipsoid or egm96)");
  std::vector<LasPoint> points;
  std::vector<Eigen::Vector2d> lon_lat;
  ForGaussiansOnGrid(scene, enu_origin, dtm, min_opacity,
                     [&](std::size_t i, double, const GeodeticPoint& g, const Eigen::Vector2d& utm,
                         const Eigen::Vector2i& px) {
                       LasPoint p;
                       p.easting_m = utm.x();
                       p.northing_m = utm.y();
                       p.height_m = g.height_m;
                       auto level = [&](int c) {
                         const double colour = kShC0 * scene.sh[i][c * kShCoeffsPerChannel] + 0.5;
                         return static_cast<std::uint16_t>(std::lround(std::clamp(colour, 0.0, 1.0) * 65535.0));
                       };
                       p.red = level(0);
                       p.green = level(1);
                       p.blue = level(2);
                       const float ground = dtm.At(px.x(), px.y());
                       p.classification = std::isfinite(ground) && g.height_m - ground <= ground_tolerance_m
                                              ? kGroundClass
                                              : above_ground_class(px);
                       points.push_back(p);
                       lon_lat.emplace_back(g.lon_deg, g.lat_deg);
                     });
  if (reference == HeightReference::kEgm96) {
    const std::vector<double> n = Egm96UndulationsM(lon_lat);
    for (std::size_t k = 0; k < points.size(); ++k) points[k].height_m -= n[k];
  }
  return points;
}

}  // namespace skyfall
