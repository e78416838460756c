// The option registry: every option of a run, declared once, with its key,
// help and range, in the order --print-config writes them. Included by
// run_options.cpp only.
#pragma once

#include "pipeline/run_options.h"

namespace skyfall {

// Every options struct is described once, by a Visit() that names each
// field: io(key, field, help, range). A library's struct has its Visit()
// beside it in the library's header, so that its Check() derives its ranges
// from it (CheckOptionRanges, core/option_range.h); the pipeline's own
// sections are described here. The same description writes JSON and reads
// it strictly (Writer, Reader), lists every option with its default and unit
// for the docs (Describer), and proves itself complete (Coverage: every byte
// of RunOptions is a listed field, a field marked io.NotAnOption(field) with
// the reason beside it, or padding). Defaults are the structs' own
// initializers; units are the names' suffixes (UnitOfKey).

template <class IO> void Visit(IO& io, TrainStageOptions& o) {
  Visit(io, o.optimizer);  // the optimizer's own options (splat/trainer.h), under the same keys
  io("downscale", o.downscale,
     "Training image downscale factor (SfM and dense heights use full resolution); 0 = automatic: 2 for imagery "
     "finer than 1 m GSD, 1 for coarser",
     range::AtLeast(0));
  io("depth_prior", o.depth_prior,
     "Pseudo-camera depth prior: 'surface', 'none' or 'cmd:COMMAND' (see splat train)");
  io("appearance", o.appearance,
     "Per-image appearance model: 'auto' (on for views from more than one date), 'on' or 'off'");
  io("init_max_scale_m", o.init_max_scale_m,
     "Cap on the initial Gaussian size (0 = none); a dense start's cap is at least its spacing", range::AtLeast(0));
  io("init_pieces", o.init_pieces,
     "Up to this many capped Gaussians per tie point (1 = one per point)", range::AtLeast(1));
  io("init_points", o.init_points,
     "Initial Gaussians from 'dense' heights, 'sparse' tie points (no dense stage) or 'auto' (dense when dense "
     "heights exist)");
  io("init_spacing_m", o.init_spacing_m,
     "A dense start keeps one dense point per cell of this size; 0 = automatic: two dense cells, at least 1 m (1 m "
     "for sub-metre imagery, 2 m for a 2 m sensor)",
     range::Or(range::Above(0), 0, "automatic"));
  io("init_step_reach_m", o.init_step_reach_m,
     "A dense start keeps every dense cell (not one per init_spacing_m) within this distance of a step; 0 = none",
     range::AtLeast(0));
  io("init_step_min_m", o.init_step_min_m,
     "Dense cells that differ by more than this within init_step_reach_m form a step for init_step_reach_m",
     range::Above(0));
  io("mask_beyond_reconstruction", o.mask_beyond_reconstruction,
     "With a dense start, leave the pixels that see past the tile's dense heights out of the loss and the scores");
  io("cloud_mask", o.cloud_mask);
  io("surface_filled_weight", o.anchor.filled_weight,
     "Weight of the surface anchor's depth term where the ray meets a filled cell (one no pair matched), against 1 "
     "for matched cells", range::In(0, 1));
  io("surface_step_weight", o.anchor.step_weight,
     "Weight of the surface anchor's depth term within surface_step_reach_m of a step; 0 leaves edges to the "
     "photometric loss, 1 = no weighting", range::In(0, 1));
  io("surface_step_reach_m", o.anchor.step_reach_m,
     "Distance from a step within which surface_step_weight applies", range::AtLeast(0));
  io("surface_step_min_m", o.anchor.step_min_m,
     "Neighbouring dense cells that differ by more than this form a step", range::Above(0));
  io("densify", o.densify,
     "Clone/split/prune: 'on', 'off' or 'auto' (on for tie-point starts, off for dense starts)");
}
template <class IO> void Visit(IO& io, IduStageOptions& o) {
  io("mode", o.mode,
     "Synthesis stage (curriculum IDU): 'auto' (where the dense heights show facades), 'on' or 'off'");
  io("refiner", o.refiner,
     "IDU refiner: 'reproject' (built in, no model weights) or 'cmd:COMMAND' (an external refiner such as a FlowEdit "
     "script; see README)");
  Visit(io, o.options);  // the episodes' own options, under the same keys
  io("reproject", o.reproject);
  io("auto", o.auto_decision);
}
template <class IO> void Visit(IO& io, MergeOptions& o) {
  io("stitch", o.stitch);
  io("lod", o.lod);
  io("seam_gsd_m", o.seam_gsd_m,
     "Spacing of the city DSM (dsm_city.tif) the seam metric is measured on", range::Above(0));
}
template <class IO> void Visit(IO& io, ExportOptions& o) {
  io("tiles3d", o.tiles3d,
     "Write OUT/<city>/3dtiles, 3D Tiles 1.1 with SPZ Gaussian splats, at the end of each city's run");
  io("tiles3d_options", o.tiles3d_options);
}
template <class IO> void Visit(IO& io, DsmOptions& o) {
  io("source", o.source,
     "Gaussians the DSMs are rasterized from: 'reconstruction' (each tile's scene trained on the real images) or "
     "'final' (the scene after the synthesis stage)");
  io("export", o.export_options);
  io("compare", o.compare);
}
template <class IO> void Visit(IO& io, ProductOptions& o) {
  io("vertical_datum", o.vertical_datum,
     "Heights of dsm.tif, dtm.tif and the point cloud: 'ellipsoid' (WGS84, as the RPCs and the DFC2019 LiDAR) or "
     "'egm96' (above the EGM96 geoid); comparisons run on ellipsoidal heights either way");
  io("gsd_m", o.gsd_m,
     "Pixel size of the products of an AOI without truth (an AOI with truth uses the truth's grid)", range::Above(0));
  io("terrain", o.terrain,
     "Write dtm.tif (the dense stage's terrain model) and ndsm.tif (DSM above it)");
  io("quality", o.quality,
     "Write quality.tif: views that see each cell, how it got its height, matching cost, Gaussian height spread");
  io("ortho", o.ortho,
     "Write ortho.tif, the true orthophoto: the scene's nadir render (grey for a panchromatic scene)");
  io("ortho_bits", o.ortho_bits,
     "Bits per sample of ortho.tif: 8 or 16", range::OneOf({8, 16}));
  io("ortho_image", o.ortho_image,
     "The image whose date ortho.tif's colours take (a per-band gain and offset fitted on the cells it sees); empty "
     "= the image closest to nadir");
  io("points", o.points,
     "Write the point cloud: the scene's Gaussians as LAS 1.4 points (format 7) with colour and classes");
  io("points_format", o.points_format,
     "Its encoding: 'laz' (points.laz, LAZ-compressed), 'copc' (points.copc.laz, a Cloud Optimized Point Cloud "
     "that viewers stream by octree node) or 'las' (points.las, uncompressed)");
  io("classes", o.classes,
     "Write classes.tif (ground, building, high vegetation in ASPRS codes) and give the point cloud those classes; a "
     "panchromatic scene's objects stay class 1, as no colour tells a crown from a roof");
  io("land_cover", o.land_cover);
  io("min_opacity", o.min_opacity,
     "Gaussians more transparent than this are left out of the point cloud and of quality.tif's height spread",
     range::In(0, 1));
  io("ground_tolerance_m", o.ground_tolerance_m,
     "A point at most this far above the DTM is ground (LAS class 2)", range::AtLeast(0));
}
template <class IO> void Visit(IO& io, SlurmOptions& o) {
  io("partition", o.partition,
     "Slurm partition (empty = the cluster's default)");
  io("account", o.account,
     "Slurm account (empty = the user's default)");
  io("time_limit", o.time_limit,
     "Time limit per tile job, Slurm syntax, e.g. 2:00:00 (empty = the partition's)");
  io("cpus_per_task", o.cpus_per_task,
     "CPUs (and threads) per tile job", range::AtLeast(1));
  io("mem_mb", o.mem_mb,
     "Memory per tile job (0 = the per-tile estimate, at least 1024 MB)", range::AtLeast(0));
  io("poll_s", o.poll_s,
     "How often the scheduler is asked while waiting", range::Above(0));
}
template <class IO> void Visit(IO& io, ExecutorOptions& o) {
  io("kind", o.kind,
     "'local' (each tile its own process), 'inline' (tiles in this process, one at a time) or 'slurm' (tiles as one "
     "sbatch array job, merge and DSM as a job depending on it)");
  io("jobs", o.jobs,
     "Tiles run at once with the local executor (0 = bounded by cores and memory)", range::AtLeast(0));
  io("program", o.program,
     "The skyfall executable for the local and slurm executors (empty = the one beside this program)");
  io("slurm", o.slurm);
}
template <class IO> void Visit(IO& io, RunOptions& o) {
  io("ingest", o.ingest);
  io("tiling", o.tiling);
  io("sfm", o.sfm);
  io("dense", o.dense);
  io("train", o.train);
  io("idu", o.idu);
  io("merge", o.merge);
  io("dsm", o.dsm);
  io("products", o.products);
  io("exports", o.exports);
  io("executor", o.executor);
}

}  // namespace skyfall
