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
  TrainOptions& t = o.optimizer;
  // Set by the synthesis stage for its episodes from idu.* (IduOptions).
  io.NotAnOption(t.synthetic_fraction);
  io.NotAnOption(t.lambda_view_depth);
  io("iterations", t.iterations,
     "Splat training steps per tile", range::AtLeast(1));
  io("downscale", o.downscale,
     "Training image downscale factor (SfM and dense heights use full resolution)", range::AtLeast(1));
  io("depth_prior", o.depth_prior,
     "Pseudo-camera depth prior: 'surface', 'none' or 'cmd:COMMAND' (see splat train)");
  io("appearance", o.appearance,
     "Per-image appearance model: 'auto' (on for views from more than one date), 'on' or 'off'");
  io("init_max_scale_m", o.init_max_scale_m,
     "Cap on the initial Gaussian size (0 = none)", range::AtLeast(0));
  io("init_pieces", o.init_pieces,
     "Up to this many capped Gaussians per tie point (1 = one per point)", range::AtLeast(1));
  io("init_points", o.init_points,
     "Initial Gaussians from 'dense' heights, 'sparse' tie points (no dense stage) or 'auto' (dense when dense "
     "heights exist)");
  io("init_spacing_m", o.init_spacing_m,
     "A dense start keeps one dense point per cell of this size", range::Above(0));
  io("mask_beyond_reconstruction", o.mask_beyond_reconstruction,
     "With a dense start, leave the pixels that see past the tile's dense heights out of the loss and the scores");
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
  io("seed", t.seed,
     "Random seed of training");
  io("lambda_dssim", t.lambda_dssim,
     "Weight of the (1 - SSIM) term of the photometric loss; L1 weighs 1 minus this", range::In(0, 1));
  io("lambda_opacity", t.lambda_opacity,
     "Weight of the entropy opacity regularization; 0 = off", range::AtLeast(0));
  io("opacity_reg_from", t.opacity_reg_from,
     "First step of the entropy opacity term", range::AtLeast(0));
  io("lr_mean_initial", t.lr.mean_initial,
     "Adam learning rate of the centres at the first step, times the scene extent; it decays exponentially to "
     "lr_mean_final", range::Above(0));
  io("lr_mean_final", t.lr.mean_final,
     "Learning rate of the centres at the last step, times the scene extent", range::Above(0));
  io("lr_scale", t.lr.scale,
     "Adam learning rate of the Gaussians' scales", range::Above(0));
  io("lr_rotation", t.lr.rotation,
     "Adam learning rate of the Gaussians' rotations", range::Above(0));
  io("lr_opacity", t.lr.opacity,
     "Adam learning rate of the Gaussians' opacities", range::Above(0));
  io("lr_sh_dc", t.lr.sh_dc,
     "Adam learning rate of the degree-0 spherical-harmonics colour", range::Above(0));
  io("lr_sh_rest", t.lr.sh_rest,
     "Adam learning rate of the higher spherical-harmonics coefficients", range::Above(0));
  io("densify_from", t.density.from_step,
     "First step of adaptive density control (clone, split, prune)", range::AtLeast(0));
  io("densify_until", t.density.until_step,
     "Last step that adds Gaussians by cloning or splitting", range::AtLeast(0));
  io("densify_interval", t.density.interval_steps,
     "Steps between densification passes", range::AtLeast(1));
  io("densify_grad_threshold", t.density.grad_threshold,
     "Mean view-space gradient of a Gaussian's centre above which it is cloned or split, in the 3DGS reference's "
     "normalized units", range::Above(0));
  io("percent_dense", t.density.percent_dense,
     "Gaussians smaller than this fraction of the scene extent are cloned, larger ones split", range::AboveUpTo(0, 1));
  io("min_opacity", t.density.min_opacity,
     "Gaussians more transparent than this are pruned", range::FromBelow(0, 1));
  io("max_scale_m", t.density.max_scale_m,
     "Gaussians larger than this are pruned", range::Above(0));
  io("max_gaussians", t.density.max_gaussians,
     "Densification adds no Gaussians beyond this count", range::AtLeast(1));
  io("merge_within_m", t.density.merge_within_m,
     "Gaussians whose centres are closer than this and whose shapes are alike are merged into one, every "
     "merge_interval steps (0 = off)", range::AtLeast(0));
  io("merge_interval", t.density.merge_interval_steps,
     "Steps between merges of coincident Gaussians; none on the last step", range::AtLeast(1));
  io("merge_max_shape_difference", t.density.merge_max_shape_difference,
     "Coincident Gaussians merge only when their covariances differ by at most this fraction (relative Frobenius "
     "norm)", range::AtLeast(0));
  io("eval_interval", t.eval_interval,
     "Steps between held-out PSNR evaluations, recorded in the report", range::AtLeast(1));
  io("checkpoint_interval", t.checkpoint_interval,
     "Steps between resumable checkpoints", range::AtLeast(1));
  io("keep_snapshots", t.keep_snapshots,
     "Also keep scene_<iteration>.ply under checkpoints/snapshots at every checkpoint (for skyfall report)");
  io("lambda_depth", t.lambda_depth,
     "Weight of the pseudo views' Pearson depth loss", range::AtLeast(0));
  io("pseudo_interval", t.pseudo_interval,
     "Steps between pseudo views; 0 = none (takes effect only with a depth prior)", range::AtLeast(0));
  io("pseudo_cameras", t.pseudo);
  io("lambda_surface_depth", t.surface.lambda_depth,
     "Weight of the surface anchor's Huber depth loss, per metre of depth error; 0 = off", range::AtLeast(0));
  io("lambda_surface_alpha", t.surface.lambda_alpha,
     "Weight of the surface anchor's (1 - accumulated opacity) term where the surface is seen; 0 = off",
     range::AtLeast(0));
  io("surface_huber_m", t.surface.huber_m,
     "Scale of the surface anchor's Huber loss: depth errors beyond it count linearly", range::Above(0));
  io("lambda_surface_height", t.surface.lambda_height,
     "Weight of the loss that holds Gaussian centres near the dense surface to its height, per m^2 and averaged over "
     "the Gaussians; 0 = off", range::AtLeast(0));
  io("surface_height_band_m", t.surface.height_band_m,
     "Gaussians whose centre is within this of the surface height below it are held by lambda_surface_height",
     range::Above(0));
  io("surface_nadir_interval", t.surface.nadir_interval,
     "Steps between the nadir patches the surface anchor also holds; 0 = never", range::AtLeast(0));
  io("surface_nadir_size_px", t.surface.nadir_size_px,
     "Side of the surface anchor's square nadir patch", range::AtLeast(16));
  io("surface_nadir_gsd_m", t.surface.nadir_gsd_m,
     "Ground pixel size of the surface anchor's nadir patch", range::Above(0));
  io("appearance_model", t.appearance);
  io("appearance_image", t.appearance_image,
     "Training view whose appearance is fused into scene.ply (empty = the view whose embedding is nearest the mean)");
  io("raster", t.raster);
}
template <class IO> void Visit(IO& io, IduStageOptions& o) {
  IduOptions& i = o.options;
  io("mode", o.mode,
     "Synthesis stage (curriculum IDU): 'auto' (where the dense heights show facades), 'on' or 'off'");
  io("refiner", o.refiner,
     "IDU refiner: 'reproject' (built in, no model weights) or 'cmd:COMMAND' (an external refiner such as a FlowEdit "
     "script; see README)");
  io("orbit", i.orbit);
  io("iterations_per_episode", i.iterations_per_episode,
     "Training steps per episode", range::AtLeast(1));
  io("samples", i.samples,
     "Refined images per orbit view", range::In(1, 16));
  io("synthetic_fraction", i.synthetic_fraction,
     "Share of the training steps on refined views; the others use satellite views", range::In(0, 1));
  io("lambda_depth", i.lambda_depth,
     "Weight of the Pearson depth loss on refined views", range::AtLeast(0));
  io("lambda_opacity", i.lambda_opacity,
     "Weight of the entropy opacity regularization during the episodes; 0 = off", range::AtLeast(0));
  io("densify", i.densify,
     "Adaptive density control (clone, split, prune) within each episode");
  io("densify_from_fraction", i.densify_from_fraction,
     "Densification starts at this fraction of each episode", range::In(0, 1));
  io("densify_until_fraction", i.densify_until_fraction,
     "Densification ends at this fraction of each episode", range::In(0, 1));
  io("densify_interval", i.densify_interval,
     "Steps between densification passes within an episode", range::AtLeast(1));
  io("geometry", i.geometry,
     "Where refined views get their geometry: 'surface' (the dense heights' height field, walls included) or "
     "'render' (the depth the scene renders at the episode's start)");
  io("fill_holes", i.fill_holes,
     "With geometry 'surface', also refine and train on orbit pixels where the height field has a surface but the "
     "scene is transparent, adding Gaussians there");
  io("fill_voxel_m", i.fill_voxel_m,
     "Edge of the cubes in which fill_holes adds one Gaussian each", range::Above(0));
  io("seed", i.seed,
     "Random seed of the stage's training and refined samples");
  io("prompts", i.request);
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
