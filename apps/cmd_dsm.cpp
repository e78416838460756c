// skyfall dsm export | compare
#include <spdlog/spdlog.h>

#include <filesystem>

#include "apps/commands.h"
#include "catalogs/aoi_catalog.h"
#include "core/error.h"
#include "products/dsm.h"
#include "products/dsm_report.h"
#include "splat/ply.h"
#include "ingest/dfc2019.h"
#include "ingest/raster.h"
#include "core/atomic_file.h"

namespace skyfall::cli {
namespace {

struct ExportArgs {
  std::string scene, frame, out, grid_txt;
  std::vector<double> bounds;  // min_easting min_northing max_easting max_northing
  double gsd_m = 0.5;
  int epsg = 0;
  std::string depth = DsmExportOptions{}.median_depth ? "median" : "expected";
};

void AddExport(CLI::App& dsm, Runner* runner) {
  auto a = std::make_shared<ExportArgs>();
  CLI::App* cmd = dsm.add_subcommand("export", "Rasterize a Gaussian scene into a DSM GeoTIFF on a UTM grid");
  cmd->add_option("--scene", a->scene, "Inria 3DGS PLY in the AOI's ENU frame")->required()->check(CLI::ExistingFile);
  cmd->add_option("--frame", a->frame, "aoi.json giving the ENU frame (and the default grid: its truth)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", a->out, "Output GeoTIFF")->required();
  cmd->add_option("--grid", a->grid_txt, "A DFC2019 _DSM.txt grid (lower-left easting, northing, size, gsd)");
  cmd->add_option("--bounds", a->bounds, "min_easting min_northing max_easting max_northing [m]")->expected(4);
  cmd->add_option("--gsd", a->gsd_m, "Grid spacing with --bounds [m]")->capture_default_str();
  cmd->add_option("--epsg", a->epsg, "UTM EPSG code (default: the AOI's zone)");
  cmd->add_option("--depth", a->depth,
                  "Height of a pixel: 'median' (where opacity reaches 0.5) or 'expected' (opacity-weighted mean)")
      ->check(CLI::IsMember({"median", "expected"}))
      ->capture_default_str();
  cmd->callback([runner, a] {
    *runner = [a] {
      const AoiCatalog catalog = ReadAoiCatalog(a->frame);
      DsmGrid grid;
      grid.epsg = a->epsg ? a->epsg : catalog.epsg;
      if (!a->grid_txt.empty()) {
        grid = GridOfDsmTxt(ParseDsmTxt(ReadTextFile(a->grid_txt), a->grid_txt), grid.epsg);
      } else if (!a->bounds.empty()) {
        grid = GridOfBounds(a->bounds[0], a->bounds[1], a->bounds[2], a->bounds[3], a->gsd_m, grid.epsg, "--bounds");
      } else if (catalog.truth) {
        grid = GridOfTruth(*catalog.truth);
      } else {
        throw Error("dsm", a->frame, "has no truth grid: give --grid or --bounds/--gsd");
      }
      const GaussianCloud scene = ReadGaussiansPly(a->scene);
      DsmExportOptions export_options;
      export_options.median_depth = a->depth == "median";
      RasterizeDsm(scene, catalog.enu_origin, export_options, &grid);
      WriteDsm(a->out, grid);
      std::size_t valid = 0;
      for (float v : grid.height_m) valid += std::isfinite(v);
      spdlog::info("dsm export: {}x{} px at {} m, EPSG:{}, {:.1f}% with data -> {}", grid.width_px, grid.height_px,
                   grid.gsd_m, grid.epsg, 100.0 * valid / grid.height_m.size(), a->out);
      return 0;
    };
  });
}

// One line per class and rim band: its share of the cells, its own MAE and
// its part of the overall MAE.
void LogBreakdown(const DsmBreakdown& b) {
  for (const DsmErrorGroup& g : b.Groups()) {
    if (g.cells == 0) continue;
    spdlog::info("  {:<18} {:5.1f}% of cells, MAE {:.3f} m, bias {:+.3f} m, part of the MAE {:.3f} m", g.name,
                 100 * g.share, g.mae_m, g.bias_m, g.mae_part_m);
  }
}

struct CompareArgs {
  std::string pred, gt, gt_txt, cls, out;
  int epsg = 0;
};

void AddCompare(CLI::App& dsm, Runner* runner) {
  auto a = std::make_shared<CompareArgs>();
  auto opts = std::make_shared<DsmCompareOptions>();
  CLI::App* cmd = dsm.add_subcommand("compare", "Compare a DSM with LiDAR truth (Sat-NeRF / EO-NeRF / EOGS protocol)");
  cmd->add_option("--pred", a->pred, "Predicted DSM GeoTIFF")->required()->check(CLI::ExistingFile);
  cmd->add_option("--gt", a->gt, "Truth DSM")->required()->check(CLI::ExistingFile);
  cmd->add_option("--gt-txt", a->gt_txt, "The truth's _DSM.txt when the truth has no georeferencing");
  cmd->add_option("--cls", a->cls, "Truth classes (_CLS.tif); water (9) is masked");
  cmd->add_option("--epsg", a->epsg, "UTM EPSG of a truth read through --gt-txt (JAX: 32617)");
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--max-shift", opts->max_shift_px, "Shift search radius per pyramid level [px]")->capture_default_str();
  cmd->add_option("--rim-width", opts->breakdown.rim_width_m,
                  "With --cls: width of the bands on both sides of building outlines whose error is reported apart [m]")
      ->capture_default_str();
  cmd->add_option("--edge-band", opts->breakdown.edge_band_m,
                  "With --cls: width of each band of the edge profile (error by distance from building outlines) [m]")
      ->capture_default_str();
  cmd->add_option("--edge-bands", opts->breakdown.edge_bands, "With --cls: bands of the edge profile on each side")
      ->capture_default_str();
  cmd->callback([runner, a, opts] {
    *runner = [a, opts] {
      opts->Check();
      if (!a->gt_txt.empty() && a->epsg == 0) {
        throw Error("dsm", a->gt_txt, "a _DSM.txt grid carries no CRS: give --epsg (DFC2019 JAX is 32617)");
      }
      const DsmGrid truth = ReadDsm(a->gt, a->gt_txt, a->epsg);
      const DsmGrid cropped = SampleOnGrid(ReadDsm(a->pred), truth, a->pred);
      std::vector<float> cls;
      if (!a->cls.empty()) cls = ReadClassRaster(a->cls, truth);
      const DsmComparison r = CompareDsm(cropped, truth, a->cls.empty() ? nullptr : &cls, *opts);
      WriteDsmComparison(r, truth, *opts, {a->pred, a->gt, a->cls}, a->out);
      spdlog::info("dsm compare: MAE {:.3f} m, RMSE {:.3f} m, median {:.3f} m, NMAD {:.3f} m, completeness {:.1f}%, "
                   "within 1 m {:.1f}%, shift ({}, {}) px, vertical offset {:.3f} m -> {}",
                   r.mae_m, r.rmse_m, r.median_abs_m, r.nmad_m, 100 * r.completeness, 100 * r.within_fraction,
                   r.shift_col_px, r.shift_row_px, r.z_offset_m, a->out);
      if (r.has_breakdown) LogBreakdown(r.breakdown);
      return 0;
    };
  });
}

}  // namespace

void AddDsmCommand(CLI::App& app, Runner* runner) {
  CLI::App* dsm = app.add_subcommand("dsm", "DSM export and comparison with LiDAR truth");
  dsm->require_subcommand(1);
  AddExport(*dsm, runner);
  AddCompare(*dsm, runner);
}

}  // namespace skyfall::cli
