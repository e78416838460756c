#include "ingest/dfc2019.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <regex>
#include <sstream>

#include "catalogs/aoi_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "ingest/geo.h"
#include "ingest/height_probe.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"
#include "ingest/vendor_rpc.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

constexpr double kEarthRadiusM = 6371000.0;  // spherical Earth for the off-nadir estimate
constexpr double kRadToDeg = 180.0 / M_PI;

// What the scan found for one AOI, before anything is read.
struct AoiFiles {
  std::map<std::string, std::string> images;  // image stem -> raster path
  std::string truth_dir;
  std::string satnerf_dir;  // may not exist
  // A plain folder's truth: a georeferenced DSM raster (and classes), any
  // GDAL format; empty for DFC2019 trees (their truth is in truth_dir).
  std::string truth_dsm_path, truth_cls_path;
  std::vector<Skipped> skipped;  // files of the folder that are neither images nor truth
  std::string empty_folder;      // set when the AOI is a folder holding no image at all
};

bool HasRasterExtension(const fs::path& p) {
  const std::string ext = ToLower(p.extension().string());
  for (const char* e : {".tif", ".tiff", ".ntf", ".nitf", ".jp2", ".img", ".vrt"})
    if (ext == e) return true;
  const std::string name = p.filename().string();  // DIMAP products open through DIM_*.XML
  return name.rfind("DIM_", 0) == 0 && ext == ".xml";
}

// A plain folder of images with RPCs (GeoTIFF tags, .RPB, _RPC.TXT, DIMAP
// RPC XML: whatever GDAL reads into its RPC domain, or an RPC_<stem>.XML-like
// sidecar our own readers know, FindOwnRpcSidecar) is one AOI named after the
// folder. A raster without an RPC whose name contains "dsm" is the truth DSM,
// one containing "cls" its classes.
std::map<std::string, AoiFiles> ScanPlainFolder(const fs::path& root) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(root))
    if (entry.is_regular_file() && HasRasterExtension(entry.path())) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  std::string aoi;
  for (char c : root.filename().string()) aoi += std::isalnum(static_cast<unsigned char>(c)) || c == '-' ? c : '_';
  if (aoi.empty()) aoi = "AOI";
  AoiFiles found;
  for (const fs::path& file : files) {
    RasterInfo info;
    try {
      info = ReadRasterInfo(file.string());
    } catch (const Error& e) {
      found.skipped.push_back({file.string(), e.what()});
      continue;
    }
    const std::string name = ToLower(file.filename().string());
    if (!info.rpc_metadata.empty() || !FindOwnRpcSidecar(file.string()).empty()) {
      found.images.emplace(file.stem().string(), file.string());
    } else if (name.find("dsm") != std::string::npos && found.truth_dsm_path.empty()) {
      found.truth_dsm_path = file.string();
    } else if (name.find("cls") != std::string::npos && found.truth_cls_path.empty()) {
      found.truth_cls_path = file.string();
    } else {
      found.skipped.push_back({file.string(), "ingest: " + file.string() +
                                                  ": no RPC (not an image) and no 'dsm' or 'cls' in its name (not truth)"});
    }
  }
  if (found.images.empty()) {
    throw Error("ingest", root.string(),
                "holds no Track3-RGB or Track3-RGB-crops folder, and no raster with an RPC (a plain folder of "
                "images needs RPC tags, .RPB, _RPC.TXT or DIMAP RPC files)");
  }
  return {{aoi, found}};
}

// DFC2019 image names: <AOI>_<NNN>_RGB.tif, e.g. JAX_068_001_RGB.tif (a GDAL
// VRT under the same name, e.g. a window of a large scene, is read as well).
const std::regex kImageName(R"(^(.+)_(\d+)_RGB\.(tiff?|vrt)$)", std::regex::icase);

std::vector<fs::path> ImageFolders(const fs::path& root) {
  // Crops first: when an image is in both layouts, the crop wins (it is what
  // Sat-NeRF-style pipelines and their truth grids use).
  std::vector<fs::path> out;
  if (fs::is_directory(root / "Track3-RGB-crops")) out.push_back(root / "Track3-RGB-crops");
  for (const auto& entry : fs::directory_iterator(root)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_directory() && name.rfind("Track3-RGB", 0) == 0 && name != "Track3-RGB-crops") {
      out.push_back(entry.path());
    }
  }
  return out;
}

std::map<std::string, AoiFiles> ScanRoot(const fs::path& root) {
  if (!fs::is_directory(root)) throw Error("ingest", root.string(), "is not a folder");
  const auto folders = ImageFolders(root);
  if (folders.empty()) return ScanPlainFolder(root);
  std::map<std::string, AoiFiles> aois;
  for (const auto& folder : folders) {
    std::vector<fs::path> files;
    for (const auto& entry : fs::recursive_directory_iterator(folder)) {
      if (entry.is_regular_file()) files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    for (const auto& file : files) {
      std::smatch m;
      const std::string name = file.filename().string();
      if (!std::regex_match(name, m, kImageName)) continue;
      AoiFiles& aoi = aois[m[1].str()];
      aoi.images.emplace(file.stem().string(), file.string());  // first wins
    }
    // An AOI folder without a single image is named as such, not passed over
    // in silence (a cron job would never notice the missing AOI).
    for (const auto& entry : fs::directory_iterator(folder)) {
      if (!entry.is_directory()) continue;
      const std::string name = entry.path().filename().string();
      bool any_image = false;
      for (const auto& f : fs::recursive_directory_iterator(entry.path())) {
        any_image = any_image || std::regex_match(f.path().filename().string(), kImageName);
      }
      if (!any_image && !aois.count(name)) aois[name].empty_folder = entry.path().string();
    }
  }
  for (auto& [name, files] : aois) {
    files.truth_dir = (root / "Track3-Truth").string();
    files.satnerf_dir = (root / "satnerf-rpcs" / name).string();
  }
  return aois;
}

std::vector<std::string> ReadNameList(const fs::path& path) {
  std::vector<std::string> names;
  if (!fs::exists(path)) return names;
  std::istringstream in(ReadTextFile(path.string()));
  std::string line;
  while (std::getline(in, line)) {
    line.erase(std::remove_if(line.begin(), line.end(), ::isspace), line.end());
    if (line.empty()) continue;
    names.push_back(fs::path(line).stem().string());  // "x.tif" and "x" both name image x
  }
  return names;
}

// Below this many pixels a side an image holds too few features to match or
// a matching window to score: refused (a 1x1 "image" is a broken export).
constexpr int kMinImageSidePx = 16;

// One image's raster facts, RPC, date and sun angles. Throws on bad input.
ImageRecord ReadImage(const std::string& stem, const std::string& path, const AoiFiles& files,
                      const IngestOptions& options, std::optional<SatNerfCamera>* satnerf) {
  const RasterInfo info = ReadRasterInfo(path);
  if (info.width_px < kMinImageSidePx || info.height_px < kMinImageSidePx) {
    throw Error("ingest", path,
                "image is " + std::to_string(info.width_px) + "x" + std::to_string(info.height_px) +
                    " px; at least " + std::to_string(kMinImageSidePx) + " px a side are needed");
  }
  if (options.verify_pixels) VerifyRasterPixels(path);
  ImageRecord im;
  im.name = stem;
  im.path = path;
  im.width_px = info.width_px;
  im.height_px = info.height_px;
  im.bands = info.bands;
  im.dtype = info.dtype;
  im.radiometry = MeasureRadiometry(path, options.radiometry);

  // A plain folder has no Sat-NeRF folder: an empty one would look for the
  // JSON in the working directory.
  const fs::path json_path = fs::path(files.satnerf_dir) / (stem + ".json");
  if (!files.satnerf_dir.empty() && fs::exists(json_path)) *satnerf = ReadSatNerfCamera(json_path.string());

  const std::string own_sidecar = info.rpc_metadata.empty() ? FindOwnRpcSidecar(path) : "";
  if (!info.rpc_metadata.empty()) {
    try {
      im.rpc = RpcFromGdalRpcDomain(info.rpc_metadata);
    } catch (const Error& e) {
      throw e.Within(path);
    }
    im.rpc_source = "gdal_metadata";
  } else if (!own_sidecar.empty()) {
    im.rpc = ReadRpcAny(own_sidecar, &im.rpc_source);
  } else if (*satnerf) {
    im.rpc = (*satnerf)->rpc;
    im.rpc_source = "satnerf_json";
  } else {
    throw Error("rpc", path,
                "no RPC metadata (no GeoTIFF RPC tag, NITF RPC00B, sidecar GDAL reads (.RPB, "
                "_RPC.TXT, DigitalGlobe .XML, DIMAP), RPC_<image>.XML or Sat-NeRF JSON)");
  }
  const auto idatim = info.metadata.find("NITF_IDATIM");
  const auto imagery = info.imagery_metadata.find("ACQUISITIONDATETIME");
  if (idatim != info.metadata.end()) {
    im.acquisition_time = IsoTimeFromCompact(idatim->second);
  } else if (imagery != info.imagery_metadata.end() && imagery->second.size() >= 19) {
    im.acquisition_time = imagery->second.substr(0, 10) + "T" + imagery->second.substr(11, 8) + "Z";
  }
  if (*satnerf) {
    if (im.acquisition_time.empty()) im.acquisition_time = (*satnerf)->acquisition_time;
    im.sun_elevation_deg = (*satnerf)->sun_elevation_deg;
    im.sun_azimuth_deg = (*satnerf)->sun_azimuth_deg;
  }
  return im;
}

// Finite height range of a DSM band (nodata and NaN left out).
void SetHeightRange(const FloatBand& dsm, const std::string& path, TruthGrid* t) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (float v : dsm.values) {
    if (!std::isfinite(v) || (dsm.has_nodata && v == dsm.nodata)) continue;
    lo = std::min<double>(lo, v);
    hi = std::max<double>(hi, v);
  }
  if (!(lo <= hi)) throw Error("ingest", path, "holds no finite height");
  t->min_height_m = lo;
  t->max_height_m = hi;
}

TruthGrid ReadTruth(const std::string& aoi, const AoiFiles& files) {
  const fs::path dir(files.truth_dir);
  TruthGrid t;
  t.dsm_path = (dir / (aoi + "_DSM.tif")).string();
  t.dsm_txt_path = (dir / (aoi + "_DSM.txt")).string();
  const fs::path cls = dir / (aoi + "_CLS.tif");
  if (fs::exists(cls)) t.cls_path = cls.string();
  const fs::path ortho = dir / (aoi + "_ORTHO.tif");
  if (fs::exists(ortho)) t.ortho_path = ortho.string();
  if (!fs::exists(t.dsm_txt_path)) {
    throw Error("ingest", t.dsm_txt_path, "is missing (the DSM grid cannot be georeferenced)");
  }
  const DsmTxt grid = ParseDsmTxt(ReadTextFile(t.dsm_txt_path), t.dsm_txt_path);
  const FloatBand dsm = ReadFloatBand(t.dsm_path);
  if (dsm.width_px != grid.size_px || dsm.height_px != grid.size_px) {
    throw Error("ingest", t.dsm_txt_path + ": size",
                "is " + std::to_string(grid.size_px) + " but " + t.dsm_path + " is " +
                    std::to_string(dsm.width_px) + "x" + std::to_string(dsm.height_px) + " px");
  }
  if (!t.cls_path.empty()) {
    const RasterInfo cls_info = ReadRasterInfo(t.cls_path);
    if (cls_info.width_px != dsm.width_px || cls_info.height_px != dsm.height_px) {
      throw Error("ingest", t.cls_path,
                  "is " + std::to_string(cls_info.width_px) + "x" +
                      std::to_string(cls_info.height_px) + " px, the DSM is " +
                      std::to_string(dsm.width_px) + "x" + std::to_string(dsm.height_px));
    }
  }
  t.lower_left_easting_m = grid.easting_m;
  t.lower_left_northing_m = grid.northing_m;
  t.width_px = t.height_px = grid.size_px;
  t.gsd_m = grid.gsd_m;
  SetHeightRange(dsm, t.dsm_path, &t);
  return t;
}

// A truth DSM that carries its own grid and CRS (any GDAL raster): north-up,
// square pixels, in a WGS84 UTM zone (the frame DSMs are exported in).
TruthGrid ReadGeoreferencedTruth(const AoiFiles& files) {
  TruthGrid t;
  t.dsm_path = files.truth_dsm_path;
  const GeoGrid grid = ReadGeoGrid(t.dsm_path);
  if (!(grid.epsg >= 32601 && grid.epsg <= 32660) && !(grid.epsg >= 32701 && grid.epsg <= 32760)) {
    throw Error("ingest", t.dsm_path,
                "CRS is " + (grid.epsg ? "EPSG:" + std::to_string(grid.epsg) : std::string("unknown")) +
                    ", not a WGS84 UTM zone; reproject it, e.g. gdalwarp -t_srs EPSG:326NN");
  }
  t.epsg = grid.epsg;
  t.width_px = grid.width_px;
  t.height_px = grid.height_px;
  t.gsd_m = grid.pixel_size;
  t.lower_left_easting_m = grid.upper_left_x;
  t.lower_left_northing_m = grid.upper_left_y - grid.height_px * grid.pixel_size;
  if (!files.truth_cls_path.empty()) {
    const RasterInfo cls = ReadRasterInfo(files.truth_cls_path);
    if (cls.width_px != t.width_px || cls.height_px != t.height_px)
      throw Error("ingest", files.truth_cls_path, "is " + std::to_string(cls.width_px) + "x" +
                                                      std::to_string(cls.height_px) + " px, the DSM is " +
                                                      std::to_string(t.width_px) + "x" + std::to_string(t.height_px));
    t.cls_path = files.truth_cls_path;
  }
  SetHeightRange(ReadFloatBand(t.dsm_path), t.dsm_path, &t);
  return t;
}

// Of `standard` and its two neighbours (same hemisphere), the UTM zone in
// which the centre of the truth grid falls nearest to `images_lonlat`.
UtmZone ZoneThatPlacesGridOver(const TruthGrid& t, const UtmZone& standard, const Eigen::Vector2d& images_lonlat) {
  const double e = t.lower_left_easting_m + 0.5 * t.width_px * t.gsd_m;
  const double n = t.lower_left_northing_m + 0.5 * t.height_px * t.gsd_m;
  UtmZone best = standard;
  double best_deg = INFINITY;
  for (int step : {0, -1, 1}) {
    UtmZone z = standard;
    z.zone = (standard.zone - 1 + step + 60) % 60 + 1;
    const Eigen::Vector2d ll = GeodeticFromUtm(z, e, n);
    const double d = std::hypot(std::remainder(ll.x() - images_lonlat.x(), 360.0), ll.y() - images_lonlat.y());
    if (d < best_deg) best_deg = d, best = z;
  }
  return best;
}

double WrapDegrees360(double deg) {
  deg = std::fmod(deg, 360.0);
  return deg < 0 ? deg + 360.0 : deg;
}

// Viewing geometry at the image centre: two points of the same pixel's ray at
// different heights give the ray direction in the local ENU frame.
void SetViewGeometry(const EnuFrame& frame, double mid_height_m, const IngestOptions& options,
                     ImageRecord* im) {
  const double col = 0.5 * (im->width_px - 1), row = 0.5 * (im->height_px - 1);
  const double h_lo = mid_height_m - 0.5 * options.view_ray_height_step_m;
  const double h_hi = mid_height_m + 0.5 * options.view_ray_height_step_m;
  const Eigen::Vector2d lo = Localize(im->rpc, col, row, h_lo);
  const Eigen::Vector2d hi = Localize(im->rpc, col, row, h_hi);
  const Eigen::Vector3d ray =
      (frame.EnuFromGeodetic({hi.x(), hi.y(), h_hi}) - frame.EnuFromGeodetic({lo.x(), lo.y(), h_lo}))
          .normalized();  // from the ground towards the satellite
  im->view_zenith_deg = std::acos(std::clamp(ray.z(), -1.0, 1.0)) * kRadToDeg;
  im->view_azimuth_deg = WrapDegrees360(std::atan2(ray.x(), ray.y()) * kRadToDeg);
  const double ratio = kEarthRadiusM / (kEarthRadiusM + options.nominal_orbit_height_m);
  im->off_nadir_deg = std::asin(ratio * std::sin(im->view_zenith_deg / kRadToDeg)) * kRadToDeg;
}

std::vector<Eigen::Vector2d> ImageFootprint(const ImageRecord& im, double height_m) {
  // Outer pixel corners, in image order (top-left, top-right, bottom-right, bottom-left).
  const double w = im.width_px - 0.5, h = im.height_px - 0.5;
  const Eigen::Vector2d corners[4] = {{-0.5, -0.5}, {w, -0.5}, {w, h}, {-0.5, h}};
  std::vector<Eigen::Vector2d> out;
  for (const auto& c : corners) out.push_back(Localize(im.rpc, c.x(), c.y(), height_m));
  return out;
}

struct HeightRange {
  double min_m, max_m;
  std::string source;
};

HeightRange ChooseHeightRange(const std::optional<TruthGrid>& truth,
                              const std::vector<std::optional<SatNerfCamera>>& satnerf,
                              const std::vector<ImageRecord>& images, const IngestOptions& o) {
  if (truth) {
    return {truth->min_height_m - o.height_margin_m, truth->max_height_m + o.height_margin_m,
            "truth_dsm"};
  }
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& cam : satnerf) {
    if (cam && cam->min_alt_m && cam->max_alt_m) {
      lo = std::min(lo, *cam->min_alt_m);
      hi = std::max(hi, *cam->max_alt_m);
    }
  }
  if (lo <= hi) return {lo - o.height_margin_m, hi + o.height_margin_m, "satnerf_json"};
  std::vector<double> offsets;
  double half = o.rpc_height_half_range_m;
  for (const auto& im : images) {
    offsets.push_back(im.rpc.height_off);
    half = std::min(half, std::abs(im.rpc.height_scale));
  }
  std::nth_element(offsets.begin(), offsets.begin() + offsets.size() / 2, offsets.end());
  const double mid = offsets[offsets.size() / 2];
  // HEIGHT_OFF is the middle of the vendor's whole scene, which may be a
  // kilometre from this AOI's ground: where the views agree decides instead
  // when it falls outside the range around HEIGHT_OFF.
  if (const auto probe = ProbeSceneHeight(images)) {
    if (std::abs(probe->height_m - mid) > half - o.height_margin_m) {
      return {probe->height_m - half, probe->height_m + half, "rpc_height_probe"};
    }
  }
  return {mid - half, mid + half, "rpc"};
}

// Each image's ground footprint at `height_m`. An image whose corners its own
// RPC cannot place (a raster far larger than the RPC's validity, say) is
// left out with the reason, instead of sinking its AOI.
void LocateFootprints(double height_m, std::vector<ImageRecord>* images, std::vector<Skipped>* skipped,
                      Progress& progress) {
  std::vector<ImageRecord> kept;
  for (ImageRecord& im : *images) {
    try {
      im.footprint_lonlat = ImageFootprint(im, height_m);
      kept.push_back(std::move(im));
    } catch (const Error& e) {
      const std::string why = std::string("image corners lie outside its RPC's reach (") + e.what() + ")";
      skipped->push_back({im.path, Error("ingest", im.path, why).what()});
      progress.Warn("skipping image: " + skipped->back().reason);
    }
  }
  *images = std::move(kept);
}

bool SameView(const ImageRecord& a, const ImageRecord& b) {
  const RpcModel &p = a.rpc, &q = b.rpc;
  return a.width_px == b.width_px && a.height_px == b.height_px && p.line_off == q.line_off &&
         p.samp_off == q.samp_off && p.lat_off == q.lat_off && p.lon_off == q.lon_off &&
         p.height_off == q.height_off && p.line_scale == q.line_scale && p.samp_scale == q.samp_scale &&
         p.lat_scale == q.lat_scale && p.lon_scale == q.lon_scale && p.height_scale == q.height_scale &&
         p.line_num == q.line_num && p.line_den == q.line_den && p.samp_num == q.samp_num &&
         p.samp_den == q.samp_den;
}

// Two rasters of one size with the same RPC are the same view (a copied
// file): kept twice, it would be a zero-baseline pair that SfM matches
// perfectly and triangulates nowhere. The first in name order stays.
void SkipDuplicateViews(std::vector<ImageRecord>* images, std::vector<Skipped>* skipped, Progress& progress) {
  std::vector<ImageRecord> kept;
  for (ImageRecord& im : *images) {
    const auto first = std::find_if(kept.begin(), kept.end(), [&](const ImageRecord& k) { return SameView(k, im); });
    if (first == kept.end()) {
      kept.push_back(std::move(im));
      continue;
    }
    skipped->push_back({im.path, Error("ingest", im.path, "duplicate of " + first->path + " (same size and RPC)").what()});
    progress.Warn("skipping image: " + skipped->back().reason);
  }
  *images = std::move(kept);
}

// The lon/lat box common to all image footprints, counter-clockwise.
std::vector<Eigen::Vector2d> FootprintOverlap(const std::vector<ImageRecord>& images,
                                              const std::string& aoi) {
  Eigen::Vector2d lo(-1e9, -1e9), hi(1e9, 1e9);
  // Longitudes unwrapped around the first corner: each image's RPC keeps its
  // own branch, and an AOI astride the antimeridian has corners at 179.9 and -179.9.
  const double lon_ref = images.front().footprint_lonlat.front().x();
  for (const auto& im : images) {
    Eigen::Vector2d a(1e9, 1e9), b(-1e9, -1e9);
    for (Eigen::Vector2d p : im.footprint_lonlat) {
      p.x() = lon_ref + LongitudeDeltaDeg(p.x(), lon_ref);
      a = a.cwiseMin(p);
      b = b.cwiseMax(p);
    }
    lo = lo.cwiseMax(a);
    hi = hi.cwiseMin(b);
  }
  if (!(lo.x() < hi.x() && lo.y() < hi.y())) {
    throw Error("ingest", aoi, "the image footprints have no common area (empty AOI)");
  }
  return {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
}

// Reads every image of the AOI into the catalog; an unreadable one is
// skipped with its reason. Returns each kept image's Sat-NeRF camera, if any.
std::vector<std::optional<SatNerfCamera>> ReadImages(const AoiFiles& files, const IngestOptions& options,
                                                     AoiIngestResult* result, Progress& progress) {
  for (const Skipped& s : files.skipped) {
    result->skipped_images.push_back(s);
    progress.Warn("skipping file: " + s.reason);
  }
  progress.Begin("ingest " + result->aoi, files.images.size());
  std::vector<std::optional<SatNerfCamera>> satnerf;
  std::size_t done = 0;
  for (const auto& [stem, path] : files.images) {
    std::optional<SatNerfCamera> cam;
    try {
      result->catalog.images.push_back(ReadImage(stem, path, files, options, &cam));
      satnerf.push_back(cam);
    } catch (const Error& e) {
      result->skipped_images.push_back({path, e.what()});
      progress.Warn(std::string("skipping image: ") + e.what());
    }
    progress.Advance(++done, stem);
  }
  progress.End();
  if (!files.empty_folder.empty()) throw Error("ingest", files.empty_folder, "AOI folder holds no image (*_NNN_RGB.tif)");
  if (result->catalog.images.empty()) throw Error("ingest", result->aoi, "no usable image (all were skipped)");
  return satnerf;
}

std::optional<TruthGrid> ReadAnyTruth(const std::string& aoi, const AoiFiles& files) {
  if (!files.truth_dsm_path.empty()) return ReadGeoreferencedTruth(files);
  const bool has_truth = fs::exists(fs::path(files.truth_dir) / (aoi + "_DSM.tif")) ||
                         fs::exists(fs::path(files.truth_dir) / (aoi + "_DSM.txt"));
  if (has_truth) return ReadTruth(aoi, files);
  return std::nullopt;
}

// The AOI's UTM zone, footprint and ENU origin (at `mid_height_m`,
// ellipsoidal): the truth's grid where there is one, else the images' common
// footprint.
void PlaceAoi(double mid_height_m, AoiCatalog* catalog) {
  AoiCatalog& c = *catalog;
  const std::vector<Eigen::Vector2d> overlap = FootprintOverlap(c.images, c.aoi);
  Eigen::Vector2d centre = 0.25 * (overlap[0] + overlap[1] + overlap[2] + overlap[3]);
  centre.x() = WrapLongitudeDeg(centre.x());
  UtmZone zone = StandardUtmZone(centre.x(), centre.y());
  if (c.truth) {
    // A georeferenced truth names its zone. A DFC2019 _DSM.txt does not: it
    // is in the standard zone of the AOI, which for an AOI on a zone
    // boundary may be the neighbour of the images' centre's zone; take the
    // zone that puts the grid over the images.
    if (c.truth->epsg) {
      zone = UtmZoneFromEpsg(c.truth->epsg);
    } else {
      zone = ZoneThatPlacesGridOver(*c.truth, zone, centre);
    }
    c.truth->epsg = zone.Epsg();
    const TruthGrid& t = *c.truth;
    const double e0 = t.lower_left_easting_m, n0 = t.lower_left_northing_m;
    const double e1 = e0 + t.width_px * t.gsd_m, n1 = n0 + t.height_px * t.gsd_m;
    c.footprint_lonlat = {GeodeticFromUtm(zone, e0, n0), GeodeticFromUtm(zone, e1, n0),
                          GeodeticFromUtm(zone, e1, n1), GeodeticFromUtm(zone, e0, n1)};
    c.footprint_source = "truth_grid";
    centre = GeodeticFromUtm(zone, 0.5 * (e0 + e1), 0.5 * (n0 + n1));
  } else {
    c.footprint_lonlat = overlap;
    c.footprint_source = "image_overlap";
  }
  c.utm_zone = zone.zone;
  c.utm_north = zone.north;
  c.epsg = zone.Epsg();
  c.enu_origin = {centre.x(), centre.y(), mid_height_m};
}

AoiIngestResult IngestAoi(const std::string& aoi, const AoiFiles& files, const std::string& root,
                          const std::string& out_dir, const IngestOptions& options,
                          Progress& progress) {
  Stopwatch clock;
  AoiIngestResult result;
  result.aoi = aoi;
  result.report.stage = "ingest";
  AoiCatalog& c = result.catalog;
  c.aoi = aoi;
  c.source_root = root;

  const std::vector<std::optional<SatNerfCamera>> satnerf = ReadImages(files, options, &result, progress);
  c.truth = ReadAnyTruth(aoi, files);
  const HeightRange range = ChooseHeightRange(c.truth, satnerf, c.images, options);
  c.min_ellipsoid_height_m = range.min_m;
  c.max_ellipsoid_height_m = range.max_m;
  c.height_range_source = range.source;
  const double mid_height_m = 0.5 * (c.min_ellipsoid_height_m + c.max_ellipsoid_height_m);

  LocateFootprints(mid_height_m, &c.images, &result.skipped_images, progress);
  SkipDuplicateViews(&c.images, &result.skipped_images, progress);
  if (c.images.empty()) throw Error("ingest", aoi, "no usable image (all were skipped)");
  PlaceAoi(mid_height_m, &c);
  const EnuFrame frame(c.enu_origin);
  for (auto& im : c.images) SetViewGeometry(frame, mid_height_m, options, &im);

  const fs::path split_dir(files.satnerf_dir);
  c.train_images = ReadNameList(split_dir / "train.txt");
  c.test_images = ReadNameList(split_dir / "test.txt");

  result.catalog_path = (fs::path(out_dir) / aoi / "aoi.json").string();
  WriteAoiCatalog(result.catalog_path, c);

  result.report.metrics["images"] = static_cast<double>(c.images.size());
  result.report.metrics["images_skipped"] = static_cast<double>(result.skipped_images.size());
  for (const auto& s : result.skipped_images) result.report.warnings.push_back(s.reason);
  result.report.seconds = clock.Seconds();
  return result;
}

AoiIngestResult FailedAoi(const std::string& aoi, const std::string& message) {
  AoiIngestResult r;
  r.aoi = aoi;
  r.report.stage = "ingest";
  r.report.status = StageStatus::kFailed;
  r.report.message = message;
  return r;
}

double ParseDsmField(const std::string& token, const std::string& path, const char* field) {
  char* end = nullptr;
  const double v = std::strtod(token.c_str(), &end);
  if (token.empty() || *end != '\0' || !std::isfinite(v)) {
    throw Error("ingest", path + ": " + field, "is not a finite number: '" + token + "'");
  }
  return v;
}

}  // namespace

void IngestOptions::Check() const { CheckOptionRanges(*this, "ingest"); }

int IngestResult::NumIngested() const {
  int n = 0;
  for (const auto& a : aois) n += a.report.status == StageStatus::kOk;
  return n;
}

DsmTxt ParseDsmTxt(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::vector<std::string> tokens;
  std::string token;
  while (in >> token) tokens.push_back(token);
  static const char* kFields[] = {"easting", "northing", "size", "gsd"};
  if (tokens.size() != 4) {
    const std::string missing = tokens.size() < 4 ? kFields[tokens.size()] : "extra value";
    throw Error("ingest", path,
                "expected 4 numbers (easting northing size gsd), found " +
                    std::to_string(tokens.size()) + " (first problem: " + missing + ")");
  }
  DsmTxt d;
  d.easting_m = ParseDsmField(tokens[0], path, "easting");
  d.northing_m = ParseDsmField(tokens[1], path, "northing");
  const double size = ParseDsmField(tokens[2], path, "size");
  d.gsd_m = ParseDsmField(tokens[3], path, "gsd");
  // UTM: eastings lie within (0, 1e6) m, northings within [0, 1e7] m.
  if (d.easting_m <= 0 || d.easting_m >= 1e6) {
    throw Error("ingest", path + ": easting", FormatDouble(d.easting_m) + " is not a UTM easting");
  }
  if (d.northing_m < 0 || d.northing_m > 1e7) {
    throw Error("ingest", path + ": northing",
                FormatDouble(d.northing_m) + " is not a UTM northing");
  }
  if (size < 1 || size != std::floor(size) || size > 1e6) {
    throw Error("ingest", path + ": size", FormatDouble(size) + " is not a positive pixel count");
  }
  d.size_px = static_cast<int>(size);
  if (d.gsd_m <= 0) throw Error("ingest", path + ": gsd", FormatDouble(d.gsd_m) + " must be > 0");
  return d;
}

IngestResult RunIngest(const IngestOptions& options, const std::string& root,
                       const std::string& out_dir, Progress& progress) {
  options.Check();
  // Catalogs hold absolute, normalized paths so they stay valid from any
  // working directory.
  const std::string root_abs = fs::weakly_canonical(fs::absolute(root)).string();
  std::map<std::string, AoiFiles> found = ScanRoot(root_abs);
  IngestResult result;
  for (const std::string& wanted : options.aois) {
    if (!found.count(wanted)) {
      result.aois.push_back(FailedAoi(wanted, "ingest: " + wanted + ": no images of this AOI under " + root));
    }
  }
  for (const auto& [aoi, files] : found) {
    if (!options.aois.empty() &&
        std::find(options.aois.begin(), options.aois.end(), aoi) == options.aois.end()) {
      continue;
    }
    try {
      result.aois.push_back(IngestAoi(aoi, files, root_abs, out_dir, options, progress));
    } catch (const Error& e) {
      progress.Warn(std::string("skipping AOI: ") + e.what());
      result.aois.push_back(FailedAoi(aoi, e.what()));
    }
  }
  return result;
}

}  // namespace skyfall
