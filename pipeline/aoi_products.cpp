#include "pipeline/aoi_products.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>

#include "catalogs/tile_catalog.h"
#include "core/crash_point.h"
#include "core/error.h"
#include "ingest/geo.h"
#include "ingest/radiometry.h"
#include "ingest/vertical_datum.h"
#include "pipeline/city_entries.h"
#include "products/dsm.h"
#include "products/dsm_report.h"
#include "products/gis_layers.h"
#include "products/land_cover.h"
#include "products/point_cloud.h"
#include "splat/ply.h"

namespace skyfall {

namespace fs = std::filesystem;
using json = nlohmann::json;

UtmBox FootprintUtm(const AoiCatalog& c) {
  const UtmZone zone = UtmZoneFromEpsg(c.epsg);
  UtmBox b{Eigen::Vector2d(1e18, 1e18), Eigen::Vector2d(-1e18, -1e18)};
  for (const auto& p : c.footprint_lonlat) {
    const Eigen::Vector2d u = UtmFromGeodetic(zone, p.x(), p.y());
    b.lo = b.lo.cwiseMin(u);
    b.hi = b.hi.cwiseMax(u);
  }
  return b;
}

namespace {

constexpr float kNanF = std::numeric_limits<float>::quiet_NaN();  // nodata in the mosaics

// The AOI's image of that name, or null.
const ImageRecord* ImageNamed(const AoiCatalog& a, const std::string& name) {
  for (const ImageRecord& image : a.images)
    if (image.name == name) return &image;
  return nullptr;
}

}  // namespace

void CheckOrthoImage(const ProductOptions& o, const std::vector<AoiCatalog>& aois) {
  if (o.ortho_image.empty()) return;
  std::string names;
  for (const AoiCatalog& a : aois) {
    if (ImageNamed(a, o.ortho_image)) return;
    names += (names.empty() ? "" : ", ") + a.aoi;
  }
  throw Error("products", "ortho_image", o.ortho_image + " is not an image of " + names);
}

std::vector<std::string> AoiProductFiles(const ProductOptions& o, const AoiCatalog& aoi, const std::string& out_dir) {
  const fs::path dir = fs::path(out_dir) / aoi.aoi;
  std::vector<std::string> files = {(dir / "dsm.tif").string()};
  if (o.terrain) files.push_back((dir / "dtm.tif").string()), files.push_back((dir / "ndsm.tif").string());
  if (o.quality) files.push_back((dir / "quality.tif").string());
  if (o.ortho) files.push_back((dir / "ortho.tif").string());
  if (o.classes) files.push_back((dir / "classes.tif").string());
  if (o.points) files.push_back((dir / PointCloudFileName(o.points_format)).string());
  return files;
}

namespace {

// The dense cells, with the spec that says which it owns, of every finished
// tile whose extent meets `box` (ENU, the city's frame; every tile without
// one): the tiles that own a cell of a grid in that box.
std::vector<DenseTileCells> ReadDenseTiles(const std::vector<std::string>& tile_dirs, const GroundBox& box) {
  constexpr double kCellReachM = 2.0;  // a cell's Gaussian is half a cell wide, a cell at most a metre
  std::vector<DenseTileCells> tiles;
  for (const std::string& dir : tile_dirs) {
    const fs::path ply = fs::path(dir) / "sfm" / "dense.ply";
    if (!fs::exists(ply)) continue;
    const fs::path spec_path = fs::path(dir) / "tile.json";
    std::optional<TileSpec> spec;
    if (fs::exists(spec_path)) spec = ReadTileSpec(spec_path.string());
    if (spec && (spec->extent.max_m.x() + kCellReachM < box.min_m.x() || spec->extent.min_m.x() - kCellReachM > box.max_m.x() ||
                 spec->extent.max_m.y() + kCellReachM < box.min_m.y() || spec->extent.min_m.y() - kCellReachM > box.max_m.y()))
      continue;
    tiles.push_back({ReadDenseCells(ply.string()), spec});
  }
  return tiles;
}

// The dense heights of the tiles as opaque Gaussians (one per cell:
// half a cell wide, flat), so they go through the same DSM export as the
// trained scene and the two can be compared side by side: all cells, and the
// matched ones alone (the filled ones left out). Tiles share the city frame;
// each cell is taken from the tile whose core owns it, as the merge does with
// Gaussians: with both copies in an overlap, the export took the higher of
// two estimates, one of them from a tile's outer margin, which the views
// constrain least.
struct DenseClouds {
  GaussianCloud all, measured;
  std::size_t cells = 0, filled = 0;
};

DenseClouds DenseCellsAsGaussians(const std::vector<DenseTileCells>& tiles) {
  DenseClouds out;
  for (const DenseTileCells& tile : tiles) {
    const DenseCells& cells = tile.cells;
    const std::optional<TileSpec>& spec = tile.spec;
    const float half_cell = static_cast<float>(std::log(0.5 * cells.cell_m));
    // The cells of the margin beyond the city render too (they cover the
    // AOI's border cells) but are not counted: the figures are the city's.
    const std::optional<GroundBox> city_part =
        spec ? std::optional<GroundBox>(spec->ReconstructedCore()) : std::nullopt;
    for (std::size_t k = 0; k < cells.points.size(); ++k) {
      if (spec && spec->grid.Owner(cells.points[k].x(), cells.points[k].y()) != Eigen::Vector2i(spec->col, spec->row))
        continue;
      if (!city_part || city_part->Contains(cells.points[k].x(), cells.points[k].y())) {
        ++out.cells;
        out.filled += cells.filled[k];
      }
      std::array<float, 3 * kShCoeffsPerChannel> sh{};
      for (int c = 0; c < 3; ++c) sh[c * kShCoeffsPerChannel] = static_cast<float>(ShDcFromColour(cells.colours[k][c]));
      for (GaussianCloud* cloud : {&out.all, &out.measured}) {
        if (cloud == &out.measured && cells.filled[k]) continue;
        cloud->means.push_back(cells.points[k]);
        cloud->log_scales.emplace_back(half_cell, half_cell, std::log(0.05f));
        cloud->rotations.emplace_back(1.0f, 0.0f, 0.0f, 0.0f);
        cloud->opacity_logits.push_back(4.6f);  // opacity 0.99: opaque
        cloud->sh.push_back(sh);
      }
    }
  }
  return out;
}

json ComparisonJson(const DsmComparison& c) {
  json j = {{"mae_m", c.mae_m}, {"rmse_m", c.rmse_m}, {"median_abs_m", c.median_abs_m}, {"nmad_m", c.nmad_m},
            {"completeness", c.completeness}, {"within_1m", c.within_fraction},
            {"shift_px", {c.shift_col_px, c.shift_row_px}}, {"mae_at_zero_shift_m", c.mae_at_zero_shift_m}};
  if (c.has_breakdown) j.update(DsmBreakdownJson(c.breakdown));
  return j;
}

// The products' grid of an AOI: its truth's, else its footprint.
DsmGrid ProductGrid(const AoiCatalog& a, double gsd_m) {
  if (a.truth) return GridOfTruth(*a.truth);
  const UtmBox box = FootprintUtm(a);
  return GridOfBounds(box.lo.x(), box.lo.y(), box.hi.x(), box.hi.y(), gsd_m, a.epsg, a.aoi + " footprint");
}

// A height raster in the datum the user asked for.
void WriteHeights(const std::string& path, DsmGrid grid, HeightReference datum) {
  ConvertHeightReference(&grid, datum, path);
  WriteDsm(path, grid);
}

// The image closest to nadir: the orthophoto's reference on the ground.
const ImageRecord* NadirMostImage(const AoiCatalog& a) {
  const ImageRecord* best = nullptr;
  for (const ImageRecord& image : a.images)
    if (!best || image.view_zenith_deg < best->view_zenith_deg) best = &image;
  return best;
}

bool Panchromatic(const AoiCatalog& a) {
  return !a.images.empty() && std::all_of(a.images.begin(), a.images.end(), [](const ImageRecord& i) {
           return i.bands == 1 || (i.radiometry.bands[0] == i.radiometry.bands[1] &&
                                   i.radiometry.bands[1] == i.radiometry.bands[2]);
         });
}

// What one AOI's products share while they are written.
struct AoiScene {
  const GaussianCloud& scene;
  const GeodeticPoint& enu_origin;
  const std::vector<DenseTileCells>& dense_tiles;
};

// The comparison of the DSM (and the dense heights' DSMs) with the truth.
json CompareWithTruth(const RunOptions& options, const AoiCatalog& a, const TruthDsm& truth, const DsmGrid& pred,
                      const DenseClouds& dense, const AoiScene& s, const fs::path& aoi_dir, DsmComparison* c,
                      Progress& progress) {
  *c = CompareDsm(pred, truth.dsm, truth.cls.empty() ? nullptr : &truth.cls, options.dsm.compare);
  WriteDsmComparison(*c, truth.dsm, options.dsm.compare,
                     {(aoi_dir / "dsm.tif").string(), a.truth->dsm_path, a.truth->cls_path},
                     (aoi_dir / "dsm_compare").string());
  progress.Info(fmt::format("[{}] DSM vs truth: MAE {:.2f} m, RMSE {:.2f} m, completeness {:.1f}%", a.aoi, c->mae_m,
                            c->rmse_m, 100 * c->completeness));
  json entry = ComparisonJson(*c);
  entry["aoi"] = a.aoi;
  entry["dsm"] = (aoi_dir / "dsm.tif").string();
  entry["report"] = (aoi_dir / "dsm_compare/report.json").string();
  entry["truth_vertical_datum"] =
      truth.stated_reference ? EnumName(*truth.stated_reference) : "ellipsoid (assumed: the truth states none)";
  if (dense.all.size() == 0) return entry;
  // The dense heights' own DSM and error map sit beside the trained
  // scene's, so an analyst sees where training changed the surface.
  DsmGrid dense_pred, measured_pred;
  const DsmComparison d = CompareSceneWithTruth(dense.all, s.enu_origin, *a.truth, truth, options.dsm.compare,
                                                &dense_pred, options.dsm.export_options);
  WriteHeights((aoi_dir / "dense_dsm.tif").string(), dense_pred, options.products.vertical_datum);
  WriteDsmComparison(d, truth.dsm, options.dsm.compare,
                     {(aoi_dir / "dense_dsm.tif").string(), a.truth->dsm_path, a.truth->cls_path},
                     (aoi_dir / "dense_dsm_compare").string());
  const DsmComparison m = CompareSceneWithTruth(dense.measured, s.enu_origin, *a.truth, truth, options.dsm.compare,
                                                &measured_pred, options.dsm.export_options);
  // The matched cells alone (nodata where a cell was filled): which
  // heights a pair of views measured, and which were filled in.
  WriteHeights((aoi_dir / "dense_measured_dsm.tif").string(), measured_pred, options.products.vertical_datum);
  const double filled_fraction = dense.cells ? static_cast<double>(dense.filled) / dense.cells : 0.0;
  entry["dense"] = ComparisonJson(d);
  entry["dense"]["filled_cell_fraction"] = filled_fraction;
  entry["dense"]["cells"] = static_cast<double>(dense.cells);
  entry["dense_measured_only"] = ComparisonJson(m);
  progress.Info(fmt::format("[{}] dense heights alone: MAE {:.2f} m, completeness {:.1f}% ({:.1f}% of cells "
                            "filled; matched cells alone: MAE {:.2f} m, completeness {:.1f}%)",
                            a.aoi, d.mae_m, 100 * d.completeness, 100.0 * filled_fraction, m.mae_m,
                            100 * m.completeness));
  return entry;
}

json TerrainJson(const TerrainComparison& t) {
  return {{"dtm_mae_ground_m", FiniteOrNull(t.dtm_mae_ground_m)},     {"dtm_bias_ground_m", FiniteOrNull(t.dtm_bias_ground_m)},
          {"ground_cells", t.ground_cells},                       {"ndsm_mae_building_m", FiniteOrNull(t.ndsm_mae_building_m)},
          {"ndsm_bias_building_m", FiniteOrNull(t.ndsm_bias_building_m)}, {"building_cells", t.building_cells}};
}

// The image whose date the orthophoto's colours take: products.ortho_image
// when the AOI has it, else its image closest to nadir.
const ImageRecord* OrthoImage(const ProductOptions& o, const AoiCatalog& a) {
  const ImageRecord* named = o.ortho_image.empty() ? nullptr : ImageNamed(a, o.ortho_image);
  return named ? named : NadirMostImage(a);
}

// `cells_key` names what the cells are: "ground_cells" against an image,
// "cells" against the exact orthophoto.
json AgreementJson(const OrthoAgreement& agree, const char* cells_key) {
  return {{cells_key, agree.cells}, {"psnr_db", FiniteOrNull(agree.psnr_db)}, {"ssim", FiniteOrNull(agree.ssim)},
          {"shift_col_px", agree.shift_col_px}, {"shift_row_px", agree.shift_row_px}};
}

// ortho.tif in the appearance of the chosen image's date, and its agreement
// with the exact orthophoto (synthetic scenes) and with the image closest to
// nadir on the truth's ground cells that image sees (the product, and the
// scene's own colours before the match).
json WriteOrtho(const RunOptions& options, const AoiCatalog& a, const DsmGrid& dsm, std::vector<float>* colours,
                const TruthDsm* truth, const fs::path& aoi_dir, Progress& progress) {
  const ProductOptions& po = options.products;
  std::vector<float>& rgb = *colours;  // matched in place: the previews show the product
  const ImageRecord* nadir = NadirMostImage(a);
  const ImageRecord* styled = OrthoImage(po, a);
  const std::vector<float> scene_colours = rgb;
  std::map<std::string, std::string> metadata = {
      {"ORTHO_SOURCE", "nadir render of the trained scene (dsm.source " + std::string(EnumName(options.dsm.source)) +
                           "): a true orthophoto, no building lean"}};
  json entry = {{"path", (aoi_dir / "ortho.tif").string()}, {"grey", Panchromatic(a)}, {"bits", po.ortho_bits}};
  // The nadir image is read once: by default it is also the one matched to.
  const std::optional<NormalizedImage> nadir_image =
      nadir ? std::optional<NormalizedImage>(ReadNormalizedImage(nadir->path, nadir->radiometry)) : std::nullopt;
  if (styled) {
    const ColourMatch match = MatchColoursToImage(
        rgb, dsm, styled == nadir ? *nadir_image : ReadNormalizedImage(styled->path, styled->radiometry), styled->rpc,
        styled->view_zenith_deg, styled->view_azimuth_deg);
    ApplyColourMatch(match, &rgb);
    metadata["APPEARANCE_IMAGE"] = styled->name;
    metadata["APPEARANCE_DATE"] = styled->acquisition_time;
    metadata["APPEARANCE"] = fmt::format(
        "colours matched to {} ({}): per band gain and offset fitted on {} cells it sees; gains {:.3f} {:.3f} "
        "{:.3f}, offsets {:.3f} {:.3f} {:.3f}", styled->name, styled->acquisition_time, match.cells, match.gain[0],
        match.gain[1], match.gain[2], match.offset[0], match.offset[1], match.offset[2]);
    entry["appearance"] = {{"image", styled->name}, {"date", styled->acquisition_time}, {"cells", match.cells},
                           {"gain", match.gain}, {"offset", match.offset}};
  }
  if (nadir) {
    metadata["NADIR_IMAGE"] = nadir->name;
    metadata["NADIR_IMAGE_DATE"] = nadir->acquisition_time;
  }
  WriteOrthoCog(entry["path"].get<std::string>(), dsm, rgb, {Panchromatic(a), po.ortho_bits}, metadata);
  if (nadir && a.truth && !a.truth->ortho_path.empty()) {
    const OrthoAgreement exact = CompareOrthoWithTruth(rgb, ReadNormalizedImage(a.truth->ortho_path, nadir->radiometry));
    progress.Info(fmt::format("[{}] ortho vs the exact orthophoto on {} cells: PSNR {:.2f} dB, SSIM {:.3f}", a.aoi,
                              exact.cells, exact.psnr_db, exact.ssim));
    entry["versus_ortho_truth"] = AgreementJson(exact, "cells");
    entry["versus_ortho_truth"]["truth"] = a.truth->ortho_path;
  }
  if (!truth || truth->cls.empty() || !nadir) return entry;
  auto versus_nadir = [&](const std::vector<float>& colours) {
    return CompareOrthoWithImage(colours, truth->dsm, truth->cls, *nadir_image, nadir->rpc, nadir->view_zenith_deg,
                                 nadir->view_azimuth_deg);
  };
  const OrthoAgreement agree = versus_nadir(rgb), own = versus_nadir(scene_colours);
  progress.Info(fmt::format("[{}] ortho vs {} on {} ground cells: PSNR {:.2f} dB, SSIM {:.3f} (scene's own colours: "
                            "{:.2f} dB, {:.3f})", a.aoi, nadir->name, agree.cells, agree.psnr_db, agree.ssim,
                            own.psnr_db, own.ssim));
  entry["versus_nadir_image"] = AgreementJson(agree, "ground_cells");
  entry["versus_nadir_image"]["image"] = nadir->name;
  entry["versus_nadir_image"]["view_zenith_deg"] = nadir->view_zenith_deg;
  entry["versus_nadir_image"]["scene_colours_psnr_db"] = FiniteOrNull(own.psnr_db);
  entry["versus_nadir_image"]["scene_colours_ssim"] = FiniteOrNull(own.ssim);
  return entry;
}

json ClassJson(const ClassAgreement& a) {
  return {{"iou", FiniteOrNull(a.iou)}, {"precision", FiniteOrNull(a.precision)}, {"recall", FiniteOrNull(a.recall)},
          {"truth_cells", a.truth_cells}};
}

// classes.tif from the DSM, the DTM and the scene's own colours, and its
// agreement with the truth's classes under the DSM comparison's shift.
LandCoverMap WriteLandCover(const ProductOptions& po, const AoiCatalog& a, const DsmGrid& dsm, const DsmGrid& dtm,
                            const std::vector<float>& rgb, const TruthDsm* truth, const DsmComparison& registration,
                            const fs::path& aoi_dir, json* entry, json* comparison, Progress& progress) {
  const LandCoverMap map = ClassifyLandCover(dsm, dtm, rgb, !Panchromatic(a), po.land_cover);
  const std::string rule =
      map.colour ? fmt::format("above ground: more than {} m over the DTM; vegetation: excess green above {:.4f} "
                               "(the objects' median + {} robust sigmas) and more than {} m from a local plane, by "
                               "majority within {} m; else building",
                               po.land_cover.object_min_m, map.green_threshold, po.land_cover.green_sigmas,
                               po.land_cover.min_roughness_m, po.land_cover.vote_radius_m)
                 : fmt::format("above ground: more than {} m over the DTM; building and vegetation not told apart "
                               "(panchromatic: no colour)", po.land_cover.object_min_m);
  const std::string path = (aoi_dir / "classes.tif").string();
  WriteLandCoverCog(path, dsm, map, {{"LAND_COVER_RULE", rule}});
  *entry = {{"path", path},
            {"rule", rule},
            {"colour", map.colour},
            {"cells", {{"ground", map.ground_cells},
                       {"building", map.building_cells},
                       {"vegetation", map.vegetation_cells},
                       {"above_ground_untold", map.above_ground_cells}}}};
  if (map.colour) (*entry)["green_threshold"] = map.green_threshold;
  else (*entry)["left_out"] = "building vs vegetation (panchromatic: no colour tells a crown from a roof)";
  if (!truth || truth->cls.empty()) return map;
  const LandCoverAgreement agree = CompareLandCover(map, truth->cls, dsm.width_px, dsm.height_px,
                                                    registration.shift_col_px, registration.shift_row_px);
  (*comparison)["land_cover"] = {{"cells", agree.cells},
                                 {"overall_accuracy", FiniteOrNull(agree.overall_accuracy)},
                                 {"ground", ClassJson(agree.ground)},
                                 {"building", ClassJson(agree.building)},
                                 {"vegetation", ClassJson(agree.vegetation)}};
  progress.Info(fmt::format("[{}] classes vs the truth's on {} cells: accuracy {:.3f}; IoU building {:.3f}, "
                            "vegetation {:.3f}, ground {:.3f}", a.aoi, agree.cells, agree.overall_accuracy,
                            agree.building.iou, agree.vegetation.iou, agree.ground.iou));
  return map;
}

// A product the options now leave out goes, so that the catalog and the
// report page, which list what exists, do not offer a previous run's file.
void RemoveStale(const std::vector<fs::path>& files) {
  std::error_code ignored;
  for (const fs::path& f : files) fs::remove(f, ignored);
}

// dtm.tif and ndsm.tif, and with the truth's classes their comparison.
void WriteTerrain(const ProductOptions& po, const AoiCatalog& a, const DsmGrid& pred, const DsmGrid& dtm,
                  const TruthDsm* truth, const DsmComparison& c, const fs::path& aoi_dir, json* entry,
                  json* comparison, Progress& progress) {
  const DsmGrid ndsm = HeightAboveTerrain(pred, dtm);
  WriteHeights((aoi_dir / "dtm.tif").string(), dtm, po.vertical_datum);
  WriteDsm((aoi_dir / "ndsm.tif").string(), ndsm);
  (*entry)["dtm"] = (aoi_dir / "dtm.tif").string();
  (*entry)["ndsm"] = (aoi_dir / "ndsm.tif").string();
  if (!truth || truth->cls.empty()) return;
  const TerrainComparison t =
      CompareTerrain(dtm, ndsm, truth->dsm, truth->cls, c.shift_col_px, c.shift_row_px, c.z_offset_m);
  (*comparison)["terrain"] = TerrainJson(t);
  progress.Info(fmt::format("[{}] DTM on ground cells: MAE {:.2f} m; nDSM on buildings: MAE {:.2f} m", a.aoi,
                            t.dtm_mae_ground_m, t.ndsm_mae_building_m));
}

// The point cloud files of every encoding but `keep`: an earlier run's, in
// another encoding, would otherwise linger beside the new one.
std::vector<fs::path> OtherPointClouds(const fs::path& dir, std::optional<PointCloudEncoding> keep,
                                       const std::string& stem = "points") {
  std::vector<fs::path> paths;
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    if (encoding != keep) paths.push_back(dir / PointCloudFileName(encoding, stem));
  }
  return paths;
}

// points.laz (or .las, .copc.laz): the scene's Gaussians as classified
// points; returns its entry.
json WritePoints(const ProductOptions& po, const AoiCatalog& a, const AoiScene& s, const DsmGrid& dtm,
                 const std::vector<std::uint8_t>& classes, const fs::path& aoi_dir) {
  const std::vector<LasPoint> points =
      ScenePoints(s.scene, s.enu_origin, dtm, po.vertical_datum, po.min_opacity, po.ground_tolerance_m, classes);
  const fs::path path = aoi_dir / PointCloudFileName(po.points_format);
  WriteLas(path.string(), points, HeightCrsWkt(a.epsg, po.vertical_datum, /*wkt1=*/true), po.points_format);
  RemoveStale(OtherPointClouds(aoi_dir, po.points_format));
  return {{"path", path.string()},
          {"count", points.size()},
          {"encoding", EnumName(po.points_format)},
          {"bytes", fs::file_size(path)},
          {"format", "LAS 1.4, point format 7"}};
}

// One AOI: the products on its grid, compared with its truth when it has
// one. Returns its products entry; `comparison` receives the truth entry.
json WriteOneAoi(const RunOptions& options, const AoiCatalog& a, const AoiScene& s, const DenseClouds& dense,
                 const std::string& out_dir, json* comparison, CityOutcome* outcome, Progress& progress) {
  const ProductOptions& po = options.products;
  const fs::path aoi_dir = fs::path(out_dir) / a.aoi;
  const std::optional<TruthDsm> truth = a.truth ? std::optional<TruthDsm>(ReadTruthDsm(*a.truth)) : std::nullopt;
  DsmGrid pred = ProductGrid(a, po.gsd_m);
  std::vector<float> rgb;
  RasterizeDsm(s.scene, s.enu_origin, options.dsm.export_options, &pred, po.ortho || po.classes ? &rgb : nullptr);
  WriteHeights((aoi_dir / "dsm.tif").string(), pred, po.vertical_datum);
  CrashPoint("dsm_written");
  json entry = {{"aoi", a.aoi}, {"dsm", (aoi_dir / "dsm.tif").string()},
                {"vertical_datum", EnumName(po.vertical_datum)},
                {"vertical_datum_description", HeightReferenceDescription(po.vertical_datum)}};
  DsmComparison c;
  if (truth) *comparison = CompareWithTruth(options, a, *truth, pred, dense, s, aoi_dir, &c, progress);
  json left_out = json::array();
  const DenseLayers layers = SampleDenseLayers(s.dense_tiles, s.enu_origin, pred);
  const DsmGrid& dtm = layers.dtm;
  if (po.terrain) {
    WriteTerrain(po, a, pred, dtm, truth ? &*truth : nullptr, c, aoi_dir, &entry, comparison, progress);
  } else {
    left_out.push_back("dtm.tif and ndsm.tif (products.terrain off)");
    RemoveStale({aoi_dir / "dtm.tif", aoi_dir / "ndsm.tif"});
  }
  if (po.quality) {
    WriteQualityCog((aoi_dir / "quality.tif").string(), pred, layers,
                    GaussianHeightSpreadM(s.scene, s.enu_origin, pred, po.min_opacity));
    entry["quality"] = (aoi_dir / "quality.tif").string();
  } else {
    left_out.push_back("quality.tif (products.quality off)");
    RemoveStale({aoi_dir / "quality.tif"});
  }
  LandCoverMap land_cover;  // before the ortho's colour match: the classes take the scene's own colours
  if (po.classes) {
    land_cover = WriteLandCover(po, a, pred, dtm, rgb, truth ? &*truth : nullptr, c, aoi_dir, &entry["classes"],
                                comparison, progress);
  } else {
    left_out.push_back("classes.tif (products.classes off)");
    RemoveStale({aoi_dir / "classes.tif"});
  }
  if (po.ortho) {
    entry["ortho"] = WriteOrtho(options, a, pred, &rgb, truth ? &*truth : nullptr, aoi_dir, progress);
    if (truth && entry["ortho"].contains("versus_nadir_image"))
      (*comparison)["ortho"] = entry["ortho"]["versus_nadir_image"];
    if (truth && entry["ortho"].contains("versus_ortho_truth"))
      (*comparison)["ortho_truth"] = entry["ortho"]["versus_ortho_truth"];
  } else {
    left_out.push_back("ortho.tif (products.ortho off)");
    RemoveStale({aoi_dir / "ortho.tif"});
  }
  if (po.points) {
    entry["points"] = WritePoints(po, a, s, dtm, land_cover.classes, aoi_dir);
  } else {
    left_out.push_back("point cloud (products.points off)");
    RemoveStale(OtherPointClouds(aoi_dir, std::nullopt));
  }
  entry["left_out"] = left_out;
  // Previews for the report page (not products: PNGs without georeferencing).
  fs::create_directories(aoi_dir / "previews");
  PreviewLayers previews;
  if (po.ortho) previews.rgb = std::move(rgb);
  if (po.quality) previews.views = layers.views, previews.fill_rule = layers.fill_rule;
  previews.classes = std::move(land_cover.classes);
  WriteProductPreviews((aoi_dir / "previews").string(), pred, previews);
  entry["previews"] = (aoi_dir / "previews").string();
  if (truth) outcome->dsm_mae_m.push_back(c.mae_m);
  return entry;
}

// The city's grid: the union of its AOIs' grids, at the finest of their
// pixel sizes.
DsmGrid CityGrid(const std::vector<AoiCatalog>& aois, double gsd_m) {
  double min_e = 1e300, min_n = 1e300, max_e = -1e300, max_n = -1e300, gsd = 1e300;
  for (const AoiCatalog& a : aois) {
    const DsmGrid g = ProductGrid(a, gsd_m);
    min_e = std::min(min_e, g.upper_left_easting_m);
    max_n = std::max(max_n, g.upper_left_northing_m);
    max_e = std::max(max_e, g.upper_left_easting_m + g.width_px * g.gsd_m);
    min_n = std::min(min_n, g.upper_left_northing_m - g.height_px * g.gsd_m);
    gsd = std::min(gsd, g.gsd_m);
  }
  return GridOfBounds(min_e, min_n, max_e, max_n, gsd, aois.front().epsg, "city");
}

// A city mosaic's layers, pasted block by block.
struct MosaicLayers {
  DsmGrid dsm;
  std::vector<float> rgb;
  DenseLayers dense;
  std::vector<float> spread_m;
};

MosaicLayers EmptyMosaic(const DsmGrid& grid, const ProductOptions& po) {
  MosaicLayers m;
  m.dsm = grid;
  m.dsm.height_m.assign(static_cast<std::size_t>(grid.width_px) * grid.height_px, kNanF);
  m.dsm.reference = HeightReference::kEllipsoid;  // RasterizeDsm's and SampleDenseLayers' heights
  const std::size_t n = m.dsm.height_m.size();
  if (po.ortho || po.classes) m.rgb.assign(3 * n, kNanF);
  m.dense.dtm = m.dsm;
  m.dense.views.assign(n, kNanF);
  m.dense.fill_rule.assign(n, kNanF);
  m.dense.cost.assign(n, kNanF);
  if (po.quality) m.spread_m.assign(n, kNanF);
  return m;
}

// The city's layers in blocks of kDsmBlockPx: each block reads the
// Gaussians and dense tiles that meet it, so memory holds the mosaics'
// rasters and one block's scene, not the city's.
MosaicLayers RenderMosaic(const RunOptions& options, const DsmGrid& grid, const std::string& surface_path,
                          const GeodeticPoint& enu_origin, const std::vector<std::string>& tile_dirs) {
  const ProductOptions& po = options.products;
  MosaicLayers m = EmptyMosaic(grid, po);
  const auto read = [&](const GaussianFilter& keep) { return ReadGaussiansPly(surface_path, keep); };
  const auto layers = [&](const GridBlock& b, const GaussianCloud& part) {
    const DenseLayers dense = SampleDenseLayers(ReadDenseTiles(tile_dirs, EnuBoxOfGrid(b.grid, enu_origin)),
                                                enu_origin, b.grid);
    PasteBlock(dense.dtm.height_m, b.grid, b.col0, b.row0, 1, grid, &m.dense.dtm.height_m);
    PasteBlock(dense.views, b.grid, b.col0, b.row0, 1, grid, &m.dense.views);
    PasteBlock(dense.fill_rule, b.grid, b.col0, b.row0, 1, grid, &m.dense.fill_rule);
    PasteBlock(dense.cost, b.grid, b.col0, b.row0, 1, grid, &m.dense.cost);
    if (po.quality)
      PasteBlock(GaussianHeightSpreadM(part, enu_origin, b.grid, po.min_opacity), b.grid, b.col0, b.row0, 1, grid,
                 &m.spread_m);
  };
  RasterizeDsmInBlocks(read, enu_origin, options.dsm.export_options, &m.dsm,
                       po.ortho || po.classes ? &m.rgb : nullptr, layers);
  return m;
}

// The values of block `b` of a raster on `whole` (one value per cell).
template <class T>
std::vector<T> CropBlock(const std::vector<T>& values, const DsmGrid& whole, const GridBlock& b) {
  std::vector<T> out;
  out.reserve(static_cast<std::size_t>(b.grid.width_px) * b.grid.height_px);
  for (int r = 0; r < b.grid.height_px; ++r) {
    const auto row = values.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(b.row0 + r) * whole.width_px + b.col0);
    out.insert(out.end(), row, row + b.grid.width_px);
  }
  return out;
}

// points_city.laz: the city's Gaussians as one classified point cloud, the
// merged cloud a GIS user loads instead of one file per AOI. Read block by
// block like the mosaics; each Gaussian falls in one block (its centre's
// cell), so no point is written twice. The cloud itself is held whole:
// 32 bytes a point (about 70 MB for a 1 km city at 0.5 m).
json WriteCityPoints(const ProductOptions& po, int epsg, const MosaicLayers& m, const std::vector<std::uint8_t>& classes,
                     const std::string& surface_path, const GeodeticPoint& enu_origin, const fs::path& city_dir) {
  std::vector<LasPoint> points;
  for (const GridBlock& b : GridBlocks(m.dsm, kDsmBlockPx)) {
    const GaussianCloud part = ReadGaussiansPly(surface_path, MeetsGrid(EnuBoxOfGrid(b.grid, enu_origin), m.dsm.gsd_m));
    DsmGrid dtm = b.grid;
    dtm.height_m = CropBlock(m.dense.dtm.height_m, m.dsm, b);
    dtm.reference = HeightReference::kEllipsoid;
    const std::vector<std::uint8_t> block_classes = classes.empty() ? classes : CropBlock(classes, m.dsm, b);
    const std::vector<LasPoint> block = ScenePoints(part, enu_origin, dtm, po.vertical_datum, po.min_opacity,
                                                    po.ground_tolerance_m, block_classes);
    points.insert(points.end(), block.begin(), block.end());
  }
  const fs::path path = city_dir / PointCloudFileName(po.points_format, "points_city");
  WriteLas(path.string(), points, HeightCrsWkt(epsg, po.vertical_datum, /*wkt1=*/true), po.points_format);
  RemoveStale(OtherPointClouds(city_dir, po.points_format, "points_city"));
  return {{"path", path.string()}, {"count", points.size()}, {"encoding", EnumName(po.points_format)},
          {"bytes", fs::file_size(path)}};
}

// ortho_city.tif, dtm_city.tif, quality_city.tif, classes_city.tif and
// points_city.laz over all of a city's AOIs, like scene/dsm_city.tif; a
// city of one AOI has its AOI's.
json WriteCityMosaics(const RunOptions& options, const std::vector<AoiCatalog>& aois, const std::string& surface_path,
                      const GeodeticPoint& enu_origin, const std::vector<std::string>& tile_dirs,
                      const fs::path& city_dir) {
  if (aois.size() < 2) return {{"left_out", "one AOI: its own products are the city's"}};
  const ProductOptions& po = options.products;
  const MosaicLayers m = RenderMosaic(options, CityGrid(aois, po.gsd_m), surface_path, enu_origin, tile_dirs);
  json files = json::object();
  if (po.ortho) {
    const std::string path = (city_dir / "ortho_city.tif").string();
    WriteOrthoCog(path, m.dsm, m.rgb, {Panchromatic(aois.front()), po.ortho_bits},
                  {{"ORTHO_SOURCE", "nadir render of the city's trained scene"},
                   {"APPEARANCE", "the scene's own colours (each AOI's ortho.tif takes one image's date)"}});
    files["ortho"] = path;
  }
  if (po.terrain) {
    const std::string path = (city_dir / "dtm_city.tif").string();
    WriteHeights(path, m.dense.dtm, po.vertical_datum);
    files["dtm"] = path;
  }
  if (po.quality) {
    const std::string path = (city_dir / "quality_city.tif").string();
    WriteQualityCog(path, m.dsm, m.dense, m.spread_m);
    files["quality"] = path;
  }
  LandCoverMap map;
  if (po.classes) {
    // One threshold for the whole city: its objects' median colour.
    const std::string path = (city_dir / "classes_city.tif").string();
    map = ClassifyLandCover(m.dsm, m.dense.dtm, m.rgb, !Panchromatic(aois.front()), po.land_cover);
    WriteLandCoverCog(path, m.dsm, map, {{"LAND_COVER_RULE", "as each AOI's classes.tif, with the city's threshold"}});
    files["classes"] = path;
  }
  if (po.points) {
    files["points"] = WriteCityPoints(po, aois.front().epsg, m, map.classes, surface_path, enu_origin, city_dir);
  } else {
    RemoveStale(OtherPointClouds(city_dir, std::nullopt, "points_city"));
  }
  return files;
}

}  // namespace

AoiProducts WriteAoiProducts(const RunOptions& options, const std::vector<AoiCatalog>& aois,
                             const MergeSummary& merged, const std::vector<std::string>& tile_dirs,
                             const std::string& out_dir, json* stages, CityOutcome* outcome, Progress& progress) {
  AoiProducts out;
  for (const AoiCatalog& a : aois) {
    Stopwatch clock;
    // Only what meets the AOI's grid is read: memory follows the AOI, not
    // the city, and the products are those of the whole scene.
    const DsmGrid grid = ProductGrid(a, options.products.gsd_m);
    const GroundBox box = EnuBoxOfGrid(grid, merged.enu_origin);
    const GaussianCloud scene = ReadGaussiansPly(merged.surface_path, MeetsGrid(box, grid.gsd_m));
    const std::vector<DenseTileCells> dense_tiles = ReadDenseTiles(tile_dirs, box);
    const DenseClouds dense = DenseCellsAsGaussians(dense_tiles);
    const AoiScene s{scene, merged.enu_origin, dense_tiles};
    json comparison;
    out.products.push_back(WriteOneAoi(options, a, s, dense, out_dir, &comparison, outcome, progress));
    if (!comparison.is_null()) {
      out.comparisons.push_back(comparison);
      Emit(progress, "info", "dsm", a.aoi, "", "DSM compared with the truth",
           {{"mae_m", comparison.at("mae_m")},
            {"rmse_m", comparison.at("rmse_m")},
            {"median_abs_m", comparison.at("median_abs_m")},
            {"nmad_m", comparison.at("nmad_m")},
            {"completeness", comparison.at("completeness")},
            {"within_1m", comparison.at("within_1m")},
            {"seconds", clock.Seconds()}});
    }
    stages->push_back(StageEntry("products " + a.aoi, "ok", clock.Seconds()));
  }
  Stopwatch clock;
  out.city = WriteCityMosaics(options, aois, merged.surface_path, merged.enu_origin, tile_dirs,
                              fs::path(out_dir) / outcome->city);
  stages->push_back(StageEntry("products city", "ok", clock.Seconds()));
  return out;
}

}  // namespace skyfall
