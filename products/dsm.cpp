#include "products/dsm.h"

#include <gdal.h>
#include <Eigen/Geometry>
#include <ogr_srs_api.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"
#include "splat/rasterizer.h"
#include "ingest/dfc2019.h"
#include "ingest/geo.h"
#include "ingest/raster.h"
#include "ingest/vertical_datum.h"

namespace skyfall {
namespace {

constexpr float kNoData = std::numeric_limits<float>::quiet_NaN();
constexpr int kWaterClass = 9;

// 2x downsampling that averages the finite values of each 2x2 block.
DsmGrid Downsample(const DsmGrid& g) {
  DsmGrid out = g;
  out.width_px = std::max(1, g.width_px / 2);
  out.height_px = std::max(1, g.height_px / 2);
  out.gsd_m = 2 * g.gsd_m;
  out.height_m.assign(static_cast<size_t>(out.width_px) * out.height_px, kNoData);
  for (int r = 0; r < out.height_px; ++r)
    for (int c = 0; c < out.width_px; ++c) {
      double sum = 0;
      int n = 0;
      for (int dr = 0; dr < 2; ++dr)
        for (int dc = 0; dc < 2; ++dc) {
          const int cc = 2 * c + dc, rr = 2 * r + dr;
          if (cc >= g.width_px || rr >= g.height_px) continue;
          const float v = g.At(cc, rr);
          if (std::isfinite(v)) {
            sum += v;
            ++n;
          }
        }
      if (n) out.height_m[static_cast<size_t>(r) * out.width_px + c] = static_cast<float>(sum / n);
    }
  return out;
}

// NCC of truth(c, r) against prediction(c + dx, r + dy) over pixels valid in both.
double Ncc(const DsmGrid& pred, const DsmGrid& truth, int dx, int dy, int* overlap) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  int n = 0;
  for (int r = 0; r < truth.height_px; ++r) {
    const int pr = r + dy;
    if (pr < 0 || pr >= pred.height_px) continue;
    for (int c = 0; c < truth.width_px; ++c) {
      const int pc = c + dx;
      if (pc < 0 || pc >= pred.width_px) continue;
      const double a = truth.At(c, r), b = pred.At(pc, pr);
      if (!std::isfinite(a) || !std::isfinite(b)) continue;
      sa += a;
      sb += b;
      saa += a * a;
      sbb += b * b;
      sab += a * b;
      ++n;
    }
  }
  *overlap = n;
  if (n < 16) return -2.0;
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n, cov = sab - sa * sb / n;
  if (va <= 0 || vb <= 0) return -2.0;
  return cov / std::sqrt(va * vb);
}

}  // namespace

DsmGrid GridOfTruth(const TruthGrid& t) {
  DsmGrid g;
  g.width_px = t.width_px;
  g.height_px = t.height_px;
  g.upper_left_easting_m = t.lower_left_easting_m;
  g.upper_left_northing_m = t.UpperLeftNorthing();
  g.gsd_m = t.gsd_m;
  g.epsg = t.epsg;
  g.height_m.assign(static_cast<size_t>(g.width_px) * g.height_px, kNoData);
  return g;
}

DsmGrid GridOfDsmTxt(const DsmTxt& t, int epsg) {
  DsmGrid g;
  g.width_px = g.height_px = t.size_px;
  g.gsd_m = t.gsd_m;
  g.upper_left_easting_m = t.easting_m;
  g.upper_left_northing_m = t.northing_m + t.size_px * t.gsd_m;
  g.epsg = epsg;
  g.height_m.assign(static_cast<size_t>(g.width_px) * g.height_px, kNoData);
  return g;
}

DsmGrid ReadDsm(const std::string& path, const std::string& grid_txt, int epsg) {
  const FloatBand band = ReadFloatBand(path);
  DsmGrid g;
  g.width_px = band.width_px;
  g.height_px = band.height_px;
  g.height_m = band.values;
  if (band.has_nodata)
    for (float& v : g.height_m)
      if (v == static_cast<float>(band.nodata)) v = kNoData;
  if (!grid_txt.empty()) {
    const DsmTxt txt = ParseDsmTxt(ReadTextFile(grid_txt), grid_txt);
    if (txt.size_px != g.width_px || txt.size_px != g.height_px) {
      throw Error("dsm", grid_txt + ": size", "is " + std::to_string(txt.size_px) + " but " + path + " is " +
                                                  std::to_string(g.width_px) + "x" + std::to_string(g.height_px));
    }
    DsmGrid grid = GridOfDsmTxt(txt, epsg);
    grid.height_m = std::move(g.height_m);
    return grid;
  }
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  double gt[6];
  const bool georeferenced = ds && GDALGetGeoTransform(ds, gt) == CE_None && !(gt[1] == 1 && gt[5] == 1);
  if (georeferenced) {
    g.upper_left_easting_m = gt[0];
    g.upper_left_northing_m = gt[3];
    g.gsd_m = gt[1];
    if (std::abs(gt[5] + gt[1]) > 1e-9 || gt[2] != 0 || gt[4] != 0) {
      GDALClose(ds);
      throw Error("dsm", path, "is not a north-up grid with square pixels");
    }
    OGRSpatialReferenceH srs = GDALGetSpatialRef(ds);
    // A compound CRS (UTM + EGM96 height) has its zone's code on the PROJCS node.
    const char* code = srs ? OSRGetAuthorityCode(srs, OSRIsCompound(srs) ? "PROJCS" : nullptr) : nullptr;
    g.epsg = code ? std::atoi(code) : epsg;
  }
  if (ds) GDALClose(ds);
  if (!georeferenced) throw Error("dsm", path, "has no georeferencing; give its _DSM.txt grid file");
  g.reference = HeightReferenceOfRaster(path).value_or(HeightReference::kEllipsoid);
  return g;
}

void WriteDsm(const std::string& path, const DsmGrid& g) {
  WriteFloatCog(path, g.width_px, g.height_px, g.height_m.data(),
                {g.upper_left_easting_m, g.upper_left_northing_m, g.gsd_m, g.epsg, g.reference});
}

namespace {

// The nadir camera whose pixels are a grid's pixels.
struct NadirCamera {
  PinholeCamera cam;
  Eigen::Vector3d eye;
};

NadirCamera NadirCameraOfGrid(const DsmGrid& grid, const EnuFrame& frame, const GeodeticPoint& enu_origin,
                              const DsmExportOptions& o) {
  const UtmZone zone = UtmZoneFromEpsg(grid.epsg);
  const int W = grid.width_px, H = grid.height_px;
  // ENU position of a grid pixel centre at the frame's height.
  auto enu_of_pixel = [&](double col, double row) {
    const Eigen::Vector2d ll = GeodeticFromUtm(zone, grid.upper_left_easting_m + (col + 0.5) * grid.gsd_m,
                                               grid.upper_left_northing_m - (row + 0.5) * grid.gsd_m);
    return frame.EnuFromGeodetic({ll.x(), ll.y(), enu_origin.height_m});
  };
  // Image axes: one grid pixel along each, measured in ENU (UTM's scale
  // factor and grid convergence make them differ from gsd and from east/north).
  const Eigen::Vector3d centre = enu_of_pixel(0.5 * (W - 1), 0.5 * (H - 1));
  const Eigen::Vector3d du = (enu_of_pixel(W - 1, 0.5 * (H - 1)) - enu_of_pixel(0, 0.5 * (H - 1))) / std::max(1, W - 1);
  const Eigen::Vector3d dv = (enu_of_pixel(0.5 * (W - 1), H - 1) - enu_of_pixel(0.5 * (W - 1), 0)) / std::max(1, H - 1);
  NadirCamera n;
  PinholeCamera& cam = n.cam;
  const Eigen::Vector3d right = du.normalized();
  const Eigen::Vector3d forward = -Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d down = forward.cross(right).normalized();
  const Eigen::Vector3d right_orth = down.cross(forward).normalized();
  cam.cam_from_world_rotation.row(0) = right_orth.transpose();
  cam.cam_from_world_rotation.row(1) = down.transpose();
  cam.cam_from_world_rotation.row(2) = forward.transpose();
  n.eye = centre + o.camera_height_m * Eigen::Vector3d::UnitZ();
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * n.eye;
  // Focal lengths so that one pixel spans |du| and |dv| at the ground; the
  // small skew absorbs a non-orthogonal grid.
  const double depth = o.camera_height_m;
  cam.fx = depth / du.dot(right_orth);
  cam.fy = depth / dv.dot(down);
  cam.skew = -cam.fx * dv.dot(right_orth) / dv.dot(down);
  cam.cx = 0.5 * (W - 1);
  cam.cy = 0.5 * (H - 1);
  cam.width_px = W;
  cam.height_px = H;
  return n;
}

// The DSM's settings (the render's anti-aliasing dilation of 0.3 px^2, the
// opacity level) were all chosen on grids of 0.5 m or finer. On a coarser
// grid the same dilation in pixels blurs each roof's edge by metres (1.15 m
// sigma at 2.1 m), and a cell beside a wall reads the roof: the comparison
// with a truth sampled at cell centres then charges the render, not the
// reconstruction. Such a grid is rendered at `k` x `k` samples per cell (k
// odd, samples at most kDsmSampleM apart, the centre sample at the cell's
// centre), and a cell takes the median height of its samples that reach
// `min_alpha`, when at least half do: a point sample at the centre that
// one pinhole between Gaussians cannot sink to the ground.
constexpr double kDsmSampleM = 0.5;

int SamplesPerCellSide(double gsd_m) {
  const int k = std::max(1, static_cast<int>(std::ceil(gsd_m / kDsmSampleM - 1e-9)));
  return k % 2 == 0 ? k + 1 : k;
}

// Coarse rows rendered at once on a supersampled grid: about 1 M samples
// (a render holds some 40 bytes per sample besides its Gaussians).
int StripRows(int width_px, int k) {
  return std::max(1, static_cast<int>(1'000'000 / (static_cast<long long>(width_px) * k * k)));
}

// The ellipsoidal height where the ray of `cam`'s pixel (col, row) meets
// camera depth `z_cam` (the nadir camera's eye at `eye`).
double HitHeightM(const PinholeCamera& cam, const Eigen::Vector3d& eye, const EnuFrame& frame, double col, double row,
                  double z_cam) {
  const double yn = (row - cam.cy) / cam.fy;
  const Eigen::Vector3d dir =
      cam.cam_from_world_rotation.transpose() * Eigen::Vector3d((col - cam.cx - cam.skew * yn) / cam.fx, yn, 1.0);
  return frame.GeodeticFromEnu(eye + z_cam * dir).height_m;
}

// Renders the window of `nadir`'s image at (col0, row0) of `width_px` x
// `height_px` cells into the whole grid's heights (and `rgb`): the same
// camera, its principal point moved (and its pixels divided k x k on a
// coarse grid), so a window's cells are the whole image's.
void RenderWindow(const GaussianCloud& scene, const NadirCamera& nadir, const EnuFrame& frame,
                  const DsmExportOptions& o, int col0, int row0, int width_px, int height_px, DsmGrid* grid,
                  std::vector<float>* rgb) {
  const int k = SamplesPerCellSide(grid->gsd_m);
  RasterOptions ro;
  ro.median_depth = o.median_depth;
  const int strip = k == 1 ? height_px : StripRows(width_px, k);
  std::vector<float> heights;
  for (int s0 = 0; s0 < height_px; s0 += strip) {
    const int rows = std::min(strip, height_px - s0);
    // Sample (a, b) of a cell: fine pixel (k col + a, k row + b), whose
    // centre sample (a = b = (k - 1) / 2) lies on the cell's own centre.
    PinholeCamera cam = nadir.cam;
    const double half = 0.5 * (k - 1);
    cam.fx *= k;
    cam.fy *= k;
    cam.skew *= k;
    cam.cx = k * (nadir.cam.cx - col0) + half;
    cam.cy = k * (nadir.cam.cy - row0 - s0) + half;
    cam.width_px = k * width_px;
    cam.height_px = k * rows;
    const RenderOutput<float> r = RenderGaussians(scene, cam, ro);
    for (int row = 0; row < rows; ++row)
      for (int col = 0; col < width_px; ++col) {
        heights.clear();
        double premultiplied[3] = {0, 0, 0}, alpha_sum = 0;
        for (int b = 0; b < k; ++b)
          for (int a = 0; a < k; ++a) {
            const int fc = k * col + a, fr = k * row + b;
            const size_t q = static_cast<size_t>(fr) * cam.width_px + fc;
            for (int c = 0; c < 3; ++c) premultiplied[c] += r.rgb[3 * q + c];
            alpha_sum += r.alpha[q];
            if (r.alpha[q] < o.min_alpha) continue;
            const float rel_depth = o.median_depth ? r.median_depth[q] : r.depth[q];
            if (!std::isfinite(rel_depth)) continue;
            heights.push_back(static_cast<float>(
                HitHeightM(cam, nadir.eye, frame, fc, fr, rel_depth + r.reference_depth_m)));
          }
        if (2 * heights.size() < static_cast<size_t>(k * k)) continue;  // also: no sample at all
        const size_t p = static_cast<size_t>(row0 + s0 + row) * grid->width_px + col0 + col;
        // One sample (grids of 0.5 m and finer) is its own median: no copy per cell.
        grid->height_m[p] = k == 1 ? heights[0] : Median(heights);
        if (rgb)
          for (int c = 0; c < 3; ++c)
            (*rgb)[3 * p + c] = static_cast<float>(std::clamp(premultiplied[c] / alpha_sum, 0.0, 1.0));
      }
  }
}

void ClearRaster(DsmGrid* grid, std::vector<float>* rgb) {
  grid->height_m.assign(static_cast<size_t>(grid->width_px) * grid->height_px, kNoData);
  grid->reference = HeightReference::kEllipsoid;  // what GeodeticFromEnu gives
  if (rgb) rgb->assign(3 * grid->height_m.size(), kNoData);
}

}  // namespace

void RasterizeDsm(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const DsmExportOptions& o,
                  DsmGrid* grid, std::vector<float>* rgb) {
  const EnuFrame frame(enu_origin);
  const NadirCamera nadir = NadirCameraOfGrid(*grid, frame, enu_origin, o);
  ClearRaster(grid, rgb);
  RenderWindow(scene, nadir, frame, o, 0, 0, grid->width_px, grid->height_px, grid, rgb);
}

GroundBox EnuBoxOfGrid(const DsmGrid& grid, const GeodeticPoint& enu_origin) {
  const EnuFrame frame(enu_origin);
  const UtmZone zone = UtmZoneFromEpsg(grid.epsg);
  GroundBox box{Eigen::Vector2d(1e300, 1e300), Eigen::Vector2d(-1e300, -1e300)};
  // Corners and edge midpoints: the map from UTM to ENU bends a box's edges
  // by millimetres over kilometres, far inside the filter's metre of slack.
  for (int i = 0; i <= 2; ++i)
    for (int j = 0; j <= 2; ++j) {
      const double e = grid.upper_left_easting_m + 0.5 * i * grid.width_px * grid.gsd_m;
      const double n = grid.upper_left_northing_m - 0.5 * j * grid.height_px * grid.gsd_m;
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, e, n);
      const Eigen::Vector3d p = frame.EnuFromGeodetic({ll.x(), ll.y(), enu_origin.height_m});
      box.min_m = box.min_m.cwiseMin(p.head<2>());
      box.max_m = box.max_m.cwiseMax(p.head<2>());
    }
  return box;
}

GaussianFilter MeetsGrid(const GroundBox& box, double gsd_m) {
  constexpr double kSigmas = 3.0;          // RasterOptions::sigma_extent
  const double slack_m = 2.0 * gsd_m + 1.0;  // anti-aliasing dilation, parallax
  return [box, slack_m](const Eigen::Vector3f& mean, const Eigen::Vector3f& log_scale) {
    const double reach_m = kSigmas * std::exp(static_cast<double>(log_scale.maxCoeff())) + slack_m;
    return mean.x() >= box.min_m.x() - reach_m && mean.x() <= box.max_m.x() + reach_m &&
           mean.y() >= box.min_m.y() - reach_m && mean.y() <= box.max_m.y() + reach_m;
  };
}

GaussianCloud CropCloud(const GaussianCloud& cloud, const GaussianFilter& keep) {
  GaussianCloud out;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (keep(cloud.means[i], cloud.log_scales[i])) out.Append(cloud, i);
  return out;
}

DsmGrid SubGrid(const DsmGrid& grid, int col0, int row0, int width_px, int height_px) {
  // The grid's figures, not its pixels: a copy cleared would keep the whole
  // grid's capacity in every block (a city's raster once per block).
  DsmGrid part;
  part.gsd_m = grid.gsd_m;
  part.epsg = grid.epsg;
  part.reference = grid.reference;
  part.width_px = width_px;
  part.height_px = height_px;
  part.upper_left_easting_m = grid.upper_left_easting_m + col0 * grid.gsd_m;
  part.upper_left_northing_m = grid.upper_left_northing_m - row0 * grid.gsd_m;
  return part;
}

void PasteBlock(const std::vector<float>& part, const DsmGrid& part_grid, int col0, int row0, int channels,
                const DsmGrid& whole_grid, std::vector<float>* whole) {
  const std::size_t row_values = static_cast<std::size_t>(part_grid.width_px) * channels;
  for (int r = 0; r < part_grid.height_px; ++r)
    std::copy_n(part.begin() + static_cast<std::ptrdiff_t>(r * row_values), row_values,
                whole->begin() + static_cast<std::ptrdiff_t>(
                                     (static_cast<std::size_t>(row0 + r) * whole_grid.width_px + col0) * channels));
}

std::vector<GridBlock> GridBlocks(const DsmGrid& grid, int block_px) {
  if (block_px < 1) throw Error("dsm", "block_px", "must be >= 1, got " + std::to_string(block_px));
  std::vector<GridBlock> blocks;
  for (int row0 = 0; row0 < grid.height_px; row0 += block_px)
    for (int col0 = 0; col0 < grid.width_px; col0 += block_px) {
      const int w = std::min(block_px, grid.width_px - col0), h = std::min(block_px, grid.height_px - row0);
      blocks.push_back({col0, row0, SubGrid(grid, col0, row0, w, h)});
    }
  return blocks;
}

void RasterizeDsmInBlocks(const GaussiansMeeting& source, const GeodeticPoint& enu_origin,
                          const DsmExportOptions& options, DsmGrid* grid, std::vector<float>* rgb,
                          const BlockVisitor& visit, int block_px) {
  const EnuFrame frame(enu_origin);
  const NadirCamera nadir = NadirCameraOfGrid(*grid, frame, enu_origin, options);
  ClearRaster(grid, rgb);
  for (const GridBlock& b : GridBlocks(*grid, block_px)) {
    const GaussianCloud part = source(MeetsGrid(EnuBoxOfGrid(b.grid, enu_origin), grid->gsd_m));
    RenderWindow(part, nadir, frame, options, b.col0, b.row0, b.grid.width_px, b.grid.height_px, grid, rgb);
    if (visit) visit(b, part);
  }
}

namespace {

// The truth with water cells (by class) set to no-data, when asked.
DsmGrid TruthForComparison(const DsmGrid& truth_in, const std::vector<float>* cls, const DsmCompareOptions& o) {
  DsmGrid truth = truth_in;
  if (cls && o.mask_water) {
    if (cls->size() != truth.height_m.size()) throw Error("dsm", "compare", "CLS raster size differs from the truth");
    for (size_t p = 0; p < truth.height_m.size(); ++p)
      if (ClassCodeOf((*cls)[p]) == kWaterClass) truth.height_m[p] = kNoData;
  }
  return truth;
}

// Coarse-to-fine integer shift search maximizing NCC: sets the shift and its NCC.
void FindBestShift(const DsmGrid& pred, const DsmGrid& truth, const DsmCompareOptions& o, DsmComparison* out) {
  std::vector<DsmGrid> pp{pred}, tp{truth};
  for (int l = 1; l < o.pyramid_levels; ++l) {
    pp.push_back(Downsample(pp.back()));
    tp.push_back(Downsample(tp.back()));
  }
  int bx = 0, by = 0;
  for (int l = o.pyramid_levels - 1; l >= 0; --l) {
    const int cx = 2 * bx * (l < o.pyramid_levels - 1), cy = 2 * by * (l < o.pyramid_levels - 1);
    double best = -3;
    for (int dy = cy - o.max_shift_px; dy <= cy + o.max_shift_px; ++dy)
      for (int dx = cx - o.max_shift_px; dx <= cx + o.max_shift_px; ++dx) {
        int overlap = 0;
        const double ncc = Ncc(pp[l], tp[l], dx, dy, &overlap);
        if (ncc > best) {
          best = ncc;
          bx = dx;
          by = dy;
        }
      }
    out->ncc = best;
  }
  out->shift_col_px = bx;
  out->shift_row_px = by;
}

// Prediction minus truth (shifted) over cells valid in both: fills the error
// map and completeness, and returns the differences.
std::vector<double> ShiftedDifferences(const DsmGrid& pred, const DsmGrid& truth, DsmComparison* out) {
  const int W = truth.width_px, H = truth.height_px;
  out->error_m.assign(static_cast<size_t>(W) * H, kNoData);
  std::vector<double> diff;
  int valid_truth = 0;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const float t = truth.At(c, r);
      if (!std::isfinite(t)) continue;
      ++valid_truth;
      const int pc = c + out->shift_col_px, pr = r + out->shift_row_px;
      if (pc < 0 || pr < 0 || pc >= W || pr >= H) continue;
      const float v = pred.At(pc, pr);
      if (!std::isfinite(v)) continue;
      diff.push_back(static_cast<double>(v) - t);
      out->error_m[static_cast<size_t>(r) * W + c] = v - t;
    }
  out->valid_pixels = static_cast<int>(diff.size());
  out->completeness = valid_truth ? static_cast<double>(diff.size()) / valid_truth : 0.0;
  return diff;
}

// Removes the vertical offset from the differences and the error map, then
// the metrics. `diff` is not empty.
void ErrorStatistics(const std::vector<double>& diff, const DsmCompareOptions& o, DsmComparison* out) {
  double sum = 0;
  for (double d : diff) sum += d;
  out->bias_m = sum / diff.size();
  // The vertical offset removed is the median difference, as in the DFC2019
  // alignment (align3d): a mean would let a few large errors (a roof missed
  // by 30 m) shift every correct pixel and count those errors twice.
  out->z_offset_m = Median(diff);
  double abs_sum = 0, sq_sum = 0;
  int within = 0;
  std::vector<double> abs_err(diff.size());
  for (size_t k = 0; k < diff.size(); ++k) {
    const double e = diff[k] - out->z_offset_m;
    abs_err[k] = std::abs(e);
    abs_sum += abs_err[k];
    sq_sum += e * e;
    within += abs_err[k] <= o.within_m;
  }
  for (float& e : out->error_m)
    if (std::isfinite(e)) e = static_cast<float>(e - out->z_offset_m);
  out->mae_m = abs_sum / diff.size();
  out->rmse_m = std::sqrt(sq_sum / diff.size());
  out->median_abs_m = Median(abs_err);
  // The errors are centred on their own median (z_offset_m is a sample of
  // diff, so the centred median is exactly 0): NMAD is the scaled median
  // absolute error.
  out->nmad_m = 1.4826 * out->median_abs_m;
  out->within_fraction = static_cast<double>(within) / diff.size();
}

}  // namespace

DsmComparison CompareDsm(const DsmGrid& pred, const DsmGrid& truth_in, const std::vector<float>* cls,
                         const DsmCompareOptions& o) {
  if (pred.width_px != truth_in.width_px || pred.height_px != truth_in.height_px) {
    throw Error("dsm", "compare", "prediction is " + std::to_string(pred.width_px) + "x" + std::to_string(pred.height_px) +
                                      " px, truth is " + std::to_string(truth_in.width_px) + "x" +
                                      std::to_string(truth_in.height_px) + ": resample the prediction to the truth grid");
  }
  const DsmGrid truth = TruthForComparison(truth_in, cls, o);
  DsmComparison out;
  FindBestShift(pred, truth, o, &out);
  const std::vector<double> diff = ShiftedDifferences(pred, truth, &out);
  if (!diff.empty()) ErrorStatistics(diff, o, &out);
  out.mae_at_zero_shift_m = out.mae_m;
  if (out.shift_col_px != 0 || out.shift_row_px != 0) {
    DsmComparison unshifted;
    const std::vector<double> unshifted_diff = ShiftedDifferences(pred, truth, &unshifted);
    if (!unshifted_diff.empty()) ErrorStatistics(unshifted_diff, o, &unshifted);
    out.mae_at_zero_shift_m = unshifted.mae_m;
  }
  // With classes, the errors' breakdown, on the final (offset-free) error map.
  if (cls) {
    out.breakdown = BreakDownDsmError(out.error_m, *cls, truth.width_px, truth.height_px, truth.gsd_m, o.breakdown);
    out.has_breakdown = true;
  }
  return out;
}

TruthDsm ReadTruthDsm(const TruthGrid& truth) {
  TruthDsm t;
  t.dsm = ReadDsm(truth.dsm_path, truth.dsm_txt_path, truth.epsg);
  // A raster with a grid file is DFC2019's LiDAR, ellipsoidal by its
  // README; any other states its reference or is taken as ellipsoidal.
  t.stated_reference = truth.dsm_txt_path.empty() ? HeightReferenceOfRaster(truth.dsm_path)
                                                  : std::optional<HeightReference>(HeightReference::kEllipsoid);
  // Compared in the frame of the geometry: heights above the ellipsoid.
  ConvertHeightReference(&t.dsm, HeightReference::kEllipsoid, truth.dsm_path);
  if (!truth.cls_path.empty()) t.cls = ReadClassRaster(truth.cls_path, t.dsm);
  return t;
}

std::vector<float> ReadClassRaster(const std::string& path, const DsmGrid& truth) {
  FloatBand band = ReadFloatBand(path);
  if (band.width_px != truth.width_px || band.height_px != truth.height_px) {
    throw Error("dsm", path, "classes are " + std::to_string(band.width_px) + "x" + std::to_string(band.height_px) +
                                 " px, the truth " + std::to_string(truth.width_px) + "x" +
                                 std::to_string(truth.height_px) + " px: give the truth's own _CLS raster");
  }
  // Nodata cells have no class (ClassCodeOf maps NaN to -1).
  if (band.has_nodata)
    for (float& v : band.values)
      if (v == static_cast<float>(band.nodata)) v = std::numeric_limits<float>::quiet_NaN();
  return std::move(band.values);
}

DsmComparison CompareSceneWithTruth(const GaussianCloud& scene, const GeodeticPoint& enu_origin, const TruthGrid& grid,
                                    const TruthDsm& truth, const DsmCompareOptions& options, DsmGrid* prediction,
                                    const DsmExportOptions& export_options) {
  *prediction = GridOfTruth(grid);
  RasterizeDsm(scene, enu_origin, export_options, prediction);
  return CompareDsm(*prediction, truth.dsm, truth.cls.empty() ? nullptr : &truth.cls, options);
}

DsmGrid GridOfBounds(double min_easting_m, double min_northing_m, double max_easting_m, double max_northing_m,
                     double gsd_m, int epsg, const std::string& subject) {
  if (!(max_easting_m > min_easting_m && max_northing_m > min_northing_m) || !(gsd_m > 0)) {
    throw Error("dsm", subject, "needs min < max on both axes and a GSD > 0");
  }
  DsmGrid grid;
  grid.epsg = epsg;
  grid.gsd_m = gsd_m;
  grid.width_px = static_cast<int>(std::ceil((max_easting_m - min_easting_m) / gsd_m));
  grid.height_px = static_cast<int>(std::ceil((max_northing_m - min_northing_m) / gsd_m));
  grid.upper_left_easting_m = min_easting_m;
  grid.upper_left_northing_m = max_northing_m;
  grid.height_m.assign(static_cast<std::size_t>(grid.width_px) * grid.height_px, NAN);
  return grid;
}

DsmGrid SampleOnGrid(const DsmGrid& source, const DsmGrid& target, const std::string& source_name) {
  if (std::abs(source.gsd_m - target.gsd_m) > 1e-6) {
    throw Error("dsm", source_name, "GSD " + FormatDouble(source.gsd_m) + " differs from the target grid's " +
                                        FormatDouble(target.gsd_m) + "; export on the target grid");
  }
  DsmGrid out = target;
  for (int r = 0; r < target.height_px; ++r)
    for (int c = 0; c < target.width_px; ++c) {
      const double e = target.upper_left_easting_m + (c + 0.5) * target.gsd_m;
      const double n = target.upper_left_northing_m - (r + 0.5) * target.gsd_m;
      const int sc = static_cast<int>(std::floor((e - source.upper_left_easting_m) / source.gsd_m));
      const int sr = static_cast<int>(std::floor((source.upper_left_northing_m - n) / source.gsd_m));
      out.height_m[static_cast<std::size_t>(r) * target.width_px + c] =
          sc >= 0 && sr >= 0 && sc < source.width_px && sr < source.height_px ? source.At(sc, sr) : NAN;
    }
  return out;
}

void DsmExportOptions::Check() const { CheckOptionRanges(*this, "dsm"); }

// The breakdown's options are visited under the comparison's keys, so its
// ranges are checked here too.
void DsmCompareOptions::Check() const { CheckOptionRanges(*this, "dsm"); }

}  // namespace skyfall
