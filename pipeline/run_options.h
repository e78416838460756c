// One configuration for a whole run: the options of every stage, nested, with
// one Check() that validates every field and mode before any stage starts, and
// one JSON form (schema skyfall.run_options/1) that `skyfall run --config`
// reads, `--print-config` writes, resume compares and child tile processes
// receive. The defaults here are the product's defaults; the CLI never
// restates them.
#pragma once

#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/enum_codec.h"
#include "core/option_range.h"
#include "dense/dense.h"
#include "ingest/dfc2019.h"
#include "merge/lod.h"
#include "merge/stitch.h"
#include "products/dsm.h"
#include "products/land_cover.h"
#include "products/point_cloud.h"
#include "pipeline/view_masks.h"
#include "products/tiles3d.h"
#include "sfm/sfm.h"
#include "splat/trainer.h"
#include "synthesis/idu.h"
#include "tiling/tiling.h"

namespace skyfall {

// How much the surface anchor trusts each dense cell (AnchorCellWeights):
// 1, less where the dense heights are least sure. Run configuration keys
// train.surface_filled_weight, train.surface_step_weight, ... (the same
// names after "surface_").
struct AnchorWeightOptions {
  // Cells no image pair matched (FillHoles), against 1 for matched cells.
  double filled_weight = 1.0;
  // Cells within step_reach_m of a step (cells within that reach differing
  // by more than step_min_m). Windows fatten roofs onto the ground beside
  // them by about a window radius, so the dense heights are least sure
  // there; 0 leaves the edge to the photometric loss alone.
  double step_weight = 0.0;
  double step_reach_m = 1.0;
  double step_min_m = 2.0;
};

// Where a tile's initial Gaussians come from.
enum class InitPoints { kAuto, kDense, kSparse };
template <>
struct EnumNames<InitPoints> {
  static constexpr std::array<std::pair<InitPoints, const char*>, 3> kNames = {
      {{InitPoints::kAuto, "auto"}, {InitPoints::kDense, "dense"}, {InitPoints::kSparse, "sparse"}}};
};

// The training stage of a tile: the optimizer's options plus the choices made
// around it (resolution, initialization, which regularizers run).
struct TrainStageOptions {
  TrainOptions optimizer;               // steps, learning rates, losses, densification schedule
  // Training image downscale (SfM and dense use full resolution); 0 =
  // automatic, from the finest view's GSD (core/ground_cell.h).
  int downscale = 0;
  std::string depth_prior = "surface";  // pseudo-camera depth: "surface", "none" or "cmd:COMMAND"
  // Appearance model: "on", "off" or "auto" (on when the training views come
  // from more than one acquisition date; one date has nothing to explain).
  Switch appearance = Switch::kAuto;
  // [m] cap on the initial Gaussian size (0 = none): uncapped, Gaussians sized
  // by the tie-point spacing start as blobs that the scaling learning rate
  // shrinks only slowly. A dense start's cap is at least its spacing: capped
  // below it, its Gaussians leave gaps between them.
  double init_max_scale_m = 1.0;
  // Up to this many capped Gaussians per tie point, covering its neighbourhood
  // (1 = one per point): the cap alone leaves gaps between sparse points.
  int init_pieces = 16;
  // Where the initial Gaussians come from: "dense" (the dense heights, thinned
  // to init_spacing_m, plus tie points in their holes), "sparse" (tie points
  // only; the dense stage is skipped) or "auto" (dense when dense heights exist).
  InitPoints init_points = InitPoints::kAuto;
  // [m] one dense point per cell of this size; 0 = automatic, two dense
  // cells (InitSpacingForDenseCellM, core/ground_cell.h).
  double init_spacing_m = 0.0;
  // Dense cells within init_step_reach_m of a step of more than
  // init_step_min_m are all kept (at the dense grid's spacing); 0 = none.
  double init_step_reach_m = 0.0;
  double init_step_min_m = 2.0;
  // (Wall Gaussians at the start, from the dense heights' steps, were tried
  // and not adopted: decision D-034.)
  AnchorWeightOptions anchor;  // per dense cell, the surface anchor's confidence
  // With a dense start, each view's pixels that see past the tile's dense
  // heights (a crop's fringe beyond the extent) are left out of the loss and
  // the scores (MaskBeyondReconstruction, stage_jobs.h).
  bool mask_beyond_reconstruction = true;
  // With a dense start and cloud_mask.enabled, the training views' cloudy
  // pixels are left out of the loss (MaskClouds, view_masks.h); held-out
  // views are scored as given.
  CloudMaskOptions cloud_mask;
  // Clone/split/prune: "on", "off" or "auto" (on for tie-point starts, which it
  // grows over the gaps; off for dense starts, which already hold one Gaussian
  // per init_spacing_m and which densification degrades).
  Switch densify = Switch::kAuto;
  void Check() const;  // throws Error("train", field, ...)
};

// The synthesis stage of a tile (curriculum IDU), after training, before merge.
struct IduStageOptions {
  // "auto" (run where the dense heights show facades to synthesize; skip
  // flat, low-rise, water or empty tiles), "on" or "off".
  Switch mode = Switch::kAuto;
  // "reproject" (built in, no model weights) or "cmd:COMMAND" (an external
  // refiner such as a FlowEdit script; see README).
  std::string refiner = "reproject";
  IduOptions options;          // episodes, orbit, samples, mix, prompts
  ReprojectOptions reproject;  // the built-in refiner
  IduAutoOptions auto_decision;
  void Check() const;          // throws Error("idu", field, ...)
};

struct MergeOptions {
  StitchOptions stitch;
  LodOptions lod;
  double seam_gsd_m = 0.5;  // [m] DSM spacing of the seam metric
  void Check() const;       // throws Error("merge", field, ...)
};

// Exports written at the end of each city's run, beside the scene.
struct ExportOptions {
  bool tiles3d = false;           // OUT/<city>/3dtiles: 3D Tiles 1.1 with SPZ Gaussian splats
  Tiles3dOptions tiles3d_options;
  void Check() const;
};

// The Gaussians the DSMs are rasterized from.
enum class DsmSource { kReconstruction, kFinal };
template <>
struct EnumNames<DsmSource> {
  static constexpr std::array<std::pair<DsmSource, const char*>, 2> kNames = {
      {{DsmSource::kReconstruction, "reconstruction"}, {DsmSource::kFinal, "final"}}};
};

struct DsmOptions {
  // The Gaussians the DSMs (OUT/<AOI>/dsm.tif, the city's dsm_city.tif) are
  // rasterized from: "reconstruction", each tile's scene trained on the real
  // images (splat/scene.ply), or "final", the scene after the synthesis stage
  // (the one scene.ply and the LOD hold). The synthesis stage trains on the
  // refiner's renders of orbit views, which no image measured: they improve
  // oblique views but move the nadir surface, so heights come from the
  // reconstruction unless asked otherwise (decision D-073).
  DsmSource source = DsmSource::kReconstruction;
  DsmExportOptions export_options;   // JSON key "export"
  DsmCompareOptions compare;
  void Check() const;                // throws Error("dsm", field, ...)
};

// The GIS products of each AOI beside its DSM (OUT/<AOI>/: dtm.tif,
// ndsm.tif, quality.tif, ortho.tif, classes.tif, points.laz) and the datum of every
// height the run hands out.
struct ProductOptions {
  // Heights of dsm.tif, dtm.tif and the point cloud: above the WGS84 ellipsoid
  // (the frame of the RPCs and of the DFC2019 LiDAR) or above the EGM96
  // geoid (orthometric). Comparisons always run on ellipsoidal heights.
  HeightReference vertical_datum = HeightReference::kEllipsoid;
  double gsd_m = 0.5;                // grid of an AOI without truth (one with truth uses the truth's)
  bool terrain = true;               // dtm.tif and ndsm.tif
  bool quality = true;               // quality.tif
  bool ortho = true;                 // ortho.tif
  int ortho_bits = 8;                // 8 or 16
  std::string ortho_image;           // the image whose date ortho.tif's colours take (empty: closest to nadir)
  bool points = true;                // the point cloud
  PointCloudEncoding points_format = PointCloudEncoding::kLaz;  // points.laz; also points.las or points.copc.laz
  bool classes = true;               // classes.tif, and building and vegetation classes in the point cloud
  LandCoverOptions land_cover;       // how classes.tif tells buildings, trees and ground apart
  double min_opacity = 0.1;          // Gaussians more transparent are left out of the point cloud and the height spread
  double ground_tolerance_m = 1.0;   // a point this close above the DTM is ground (class 2)
  void Check() const;                // throws Error("products", field, ...)
};

// Resources of the Slurm jobs (executor kind "slurm").
struct SlurmOptions {
  std::string partition;   // empty = the cluster's default partition
  std::string account;     // empty = the user's default account
  std::string time_limit;  // per tile job, Slurm syntax ("2:00:00"); empty = the partition's limit
  int cpus_per_task = 2;   // CPUs (and threads) per tile
  int mem_mb = 0;          // memory per tile job (0 = the per-tile estimate, at least 1024 MB)
  double poll_s = 5;       // how often the scheduler is asked while waiting
  void Check() const;
};

// How tiles are executed (see ExecutorOptions::kind).
enum class ExecutorKind { kLocal, kInline, kSlurm };
template <>
struct EnumNames<ExecutorKind> {
  static constexpr std::array<std::pair<ExecutorKind, const char*>, 3> kNames = {
      {{ExecutorKind::kLocal, "local"}, {ExecutorKind::kInline, "inline"}, {ExecutorKind::kSlurm, "slurm"}}};
};

struct ExecutorOptions {
  // "local": each tile is its own `skyfall run-tile` process (memory and crash
  // isolation), several at once; "inline": tiles run one after the other in
  // the calling process (library users without the skyfall binary);
  // "slurm": the tiles go out as one sbatch job array, the city's merge and
  // DSM export as a job that depends on it (see pipeline/slurm.h).
  ExecutorKind kind = ExecutorKind::kLocal;
  int jobs = 0;         // tiles at once with "local" (0 = bounded by cores and memory only)
  std::string program;  // the skyfall executable for "local" and "slurm" (empty = found beside this program)
  SlurmOptions slurm;
  void Check() const;   // throws Error("executor", field, ...)
};

struct RunOptions {
  IngestOptions ingest;      // `aois` is part of the request, not of the options
  TilingOptions tiling;
  SfmOptions sfm;
  DenseOptions dense;
  TrainStageOptions train;
  IduStageOptions idu;
  MergeOptions merge;
  DsmOptions dsm;
  ProductOptions products;
  ExportOptions exports;
  ExecutorOptions executor;
  // Validates every stage's options; throws Error("run options", "<section>.<field>", ...).
  void Check() const;
};

// The JSON form (pretty-printed, with "schema": "skyfall.run_options/1").
std::string RunOptionsToJson(const RunOptions& options);

// Parses the JSON form. Missing fields keep their defaults; an unknown field,
// a value of the wrong type or a wrong schema throws Error naming `subject`
// (the file) and the field's dotted path. Does not call Check().
RunOptions RunOptionsFromJson(const std::string& text, const std::string& subject);

// Applies "section.field=value" (value: JSON, or else a plain string), e.g.
// "dense.sgm_p2=1.5" or "train.depth_prior=none"; throws Error naming the path.
void SetRunOption(RunOptions* options, const std::string& assignment);

// The JSON of the options that decide a tile's products (SfM, dense heights,
// training, synthesis); a tile finished under other values is redone.
std::string TileOptionsJson(const RunOptions& options);

// The JSON of one stage's options (recorded beside its products, so that a
// finished stage is reused only under the same options).
std::string DenseOptionsJson(const DenseOptions& options);
// What a tile's synthesis episodes depend on (the stages before it and the
// synthesis options, not the on/off decision): finished episodes are reused
// only under the same value.
std::string IduEpisodesJson(const RunOptions& options);
std::string SfmOptionsJson(const SfmOptions& options);
// What a training checkpoint depends on: every training option except those
// that only say when to checkpoint, evaluate or keep snapshots. A checkpoint
// written under other values is set aside, not resumed.
std::string TrainCheckpointJson(const TrainStageOptions& options);

// Whether settings recorded beside finished work (a tile report's options, a
// stage's options, a checkpoint's settings) still hold for `current`: equal,
// except that a key the record lacks matches when `current` has the value that
// `defaults` (the same JSON of default options) gives it. An option added by a
// later version, at the default that keeps the earlier behaviour, then leaves
// finished tiles finished, which a city-wide rerun after an upgrade needs; any
// other difference (a changed value, a key the record has and `current` lacks,
// a new key without a default) does not hold. JSON text in, so that callers
// keep their stamps as text.
bool SettingsStillHold(const std::string& recorded_json, const std::string& current_json,
                       const std::string& defaults_json);

// The option registry (option_registry.h): every field of RunOptions, listed
// once with its help and range; the JSON form, --set, --print-config, the
// flags of `skyfall run`, the range checks and the reference tables of
// docs/cli.md all come from it.
struct OptionDescription {
  std::string path;          // dotted, as --set takes it: "dense.sgm_p2"
  std::string type;          // bool, integer, number, string, 3 numbers
  std::string default_json;  // the library default, as JSON
  std::string unit;          // from the name's suffix ("m" for *_m), empty when none
  std::string help;
  std::vector<std::string> choices;  // a mode's names; empty for other options
  OptionRange range;                 // numbers and integers (each of 3 numbers); undeclared for the rest
};
std::vector<OptionDescription> DescribeRunOptions();
// The description of one option; throws Error naming `path` when there is none.
OptionDescription DescribeRunOption(const std::string& path);
// The unit a field's name states by its suffix: "cell_m" -> "m", "fov_deg" ->
// "deg"; empty for a name without one.
std::string UnitOfKey(const std::string& key);
// The reference of every option as Markdown, one table per section (the
// block between the options markers of docs/cli.md).
std::string RunOptionsReferenceMarkdown();

// Fields of RunOptions that the registry does not list: each entry names the
// innermost listed section around the bytes and their offsets. Empty when
// the registry is complete.
std::vector<std::string> RunOptionsRegistryGaps();
// The byte ranges [begin, end) no field claims that are not padding: bytes
// two default constructions over different fill patterns (`a`, `b`) agree on
// were written by an initializer, so they belong to a field.
std::vector<std::pair<std::size_t, std::size_t>> UnclaimedFieldBytes(const std::vector<unsigned char>& a,
                                                                     const std::vector<unsigned char>& b,
                                                                     const std::vector<bool>& claimed);

}  // namespace skyfall
