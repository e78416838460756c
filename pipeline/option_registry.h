// The option registry: every option of a run, declared once, with its key
// and help, in the order --print-config writes them. Included by
// run_options.cpp only.
#pragma once

#include "pipeline/run_options.h"

namespace skyfall {

// Every options struct is described once, by a Visit() that names each
// field: io(key, field, help). The same description writes
// JSON and reads it strictly (Writer, Reader), lists every option with its
// default and unit for the docs (Describer), and proves itself complete
// (Coverage: every byte of RunOptions is a listed field, a field marked
// io.NotAnOption(field) with the reason beside it, or padding). Defaults are
// the structs' own initializers; units are the names' suffixes (UnitOfKey).

template <class IO> void Visit(IO& io, RadiometryOptions& o) {
  io("low_percentile", o.low_percentile,
     "The raw value at this fraction of an image's valid pixels maps to 0", range::In(0, 1));
  io("high_percentile", o.high_percentile,
     "The raw value at this fraction of an image's valid pixels maps to 1", range::In(0, 1));
  io("stretch_byte", o.stretch_byte,
     "Also stretch Byte images between the percentiles (off: their 0-255 values map to 0-1 as they are; other data "
     "types are always stretched)");
  io("max_sample_px", o.max_sample_px,
     "The percentiles come from a decimated read of at most this many pixels", range::AtLeast(1024));
}
template <class IO> void Visit(IO& io, IngestOptions& o) {
  io.NotAnOption(o.aois);  // which AOIs is part of the request, not of the options
  io("verify_pixels", o.verify_pixels,
     "Read every pixel once at ingest, so that corrupt rasters are found early");
  io("radiometry", o.radiometry);
  io("height_margin_m", o.height_margin_m,
     "Margin added on both sides of the height range given by the truth DSM or the Sat-NeRF JSONs", range::AtLeast(0));
  io("rpc_height_half_range_m", o.rpc_height_half_range_m,
     "Half-width of the height range around the RPC's HEIGHT_OFF when only the RPC is known (at most its "
     "HEIGHT_SCALE)", range::Above(0));
  io("nominal_orbit_height_m", o.nominal_orbit_height_m,
     "Orbit height assumed for each image's off-nadir angle", range::Above(0));
  io("view_ray_height_step_m", o.view_ray_height_step_m,
     "Vertical separation of the two points that define each image's viewing ray", range::Above(0));
}
template <class IO> void Visit(IO& io, TilingOptions& o) {
  io("tile_m", o.tile_m,
     "Tile core side; 0: sized by the imagery (a multiple of 256 m holding about tile_cells dense cells)",
     range::Or(range::AtLeast(16), 0, "automatic"));
  io("tile_cells", o.tile_cells,
     "What an automatic tile (tile_m 0) holds along a side, in cells of the automatic dense grid (0.5 m for "
     "sub-metre sensors, else about half the finest image's GSD)", range::AtLeast(64));
  io("overlap_m", o.overlap_m,
     "Overlap margin around each tile's core", range::AtLeast(0));
  io("min_coverage", o.min_coverage,
     "An image is used for a tile when at least this fraction of the tile's 3D box (extent x height range) projects "
     "inside it", range::AboveUpTo(0, 1));
  io("min_images", o.min_images,
     "A tile seen by fewer images is kept empty and skipped", range::AtLeast(2));
  io("city", o.city,
     "Name of the city (empty = the AOI's name, or the AOIs' common prefix)");
}
template <class IO> void Visit(IO& io, PinholeFitOptions& o) {
  io("grid_cols", o.grid_cols,
     "Columns of the image-space grid of RPC correspondences the pinhole camera is fitted to (edges included)",
     range::AtLeast(3));
  io("grid_rows", o.grid_rows,
     "Rows of the fit grid (edges included)", range::AtLeast(3));
  io("grid_heights", o.grid_heights,
     "Heights of the fit grid, spread across the height range", range::AtLeast(2));
  io("check_cols", o.check_cols,
     "Columns of the check grid (the cell centres of a finer grid) on which the fit's error against the RPC is "
     "measured", range::AtLeast(1));
  io("check_rows", o.check_rows,
     "Rows of the check grid", range::AtLeast(1));
  io("check_heights", o.check_heights,
     "Heights of the check grid", range::AtLeast(1));
  io("hartley_normalization", o.hartley_normalization,
     "Normalize both point sets (Hartley) before the DLT; without it the DLT loses most of its precision");
  io("refine", o.refine,
     "Refine the DLT's camera by nonlinear least squares");
  io("estimate_skew", o.estimate_skew,
     "Let the skew K(0,1) vary during the refinement");
}
template <class IO> void Visit(IO& io, FeatureOptions& o) {
  io("max_features", o.max_features,
     "Strongest SIFT keypoints kept per image", range::AtLeast(16));
  io("contrast_threshold", o.contrast_threshold,
     "SIFT contrast threshold (OpenCV's default is 0.04; satellite crops are low in contrast)", range::Inside(0, 1));
  io("ratio", o.ratio,
     "Lowe's ratio test: a match is kept when its descriptor distance is below this fraction of the second best's",
     range::Inside(0, 1));
  io("clahe_clip", o.clahe_clip,
     "CLAHE clip limit, applied after the percentile stretch", range::Above(0));
  io("stretch_low", o.stretch_low,
     "Percentile, as a fraction, of the grey image mapped to 0 before CLAHE", range::In(0, 1));
  io("stretch_high", o.stretch_high,
     "Percentile, as a fraction, of the grey image mapped to 255 before CLAHE", range::In(0, 1));
}
// The verification's height range comes from each catalog, so only its
// tolerances are options.
template <class IO> void Visit(IO& io, VerifyOptions& o) {
  io.NotAnOption(o.min_up);  // the height range comes from each catalog
  io.NotAnOption(o.max_up);
  io("min_threshold_px", o.min_threshold_px,
     "Smallest accepted distance of a match from its epipolar line", range::Above(0));
  io("mad_factor", o.mad_factor,
     "The epipolar threshold is max(min_threshold_px, this x 1.4826 x the median absolute deviation of the pair's "
     "distances)", range::Above(0));
  io("segment_slack", o.segment_slack,
     "Overshoot allowed beyond the ends of the epipolar segment of the height range, as a fraction of its length",
     range::AtLeast(0));
  io("height_pad_m", o.height_pad_m,
     "Added above and below the AOI's height range, so that tie points on what stands around the AOI are kept",
     range::AtLeast(0));
}
template <class IO> void Visit(IO& io, BundleOptions& o) {
  io("huber_px", o.huber_px,
     "Scale of the Huber robust loss on reprojection errors", range::Above(0));
  io("offset_prior_sigma_px", o.offset_prior_sigma_px,
     "Standard deviation of the prior that keeps each image's offset near zero", range::Above(0));
  io("max_iterations", o.max_iterations,
     "Most solver iterations per bundle adjustment round", range::AtLeast(1));
}
template <class IO> void Visit(IO& io, SfmOptions& o) {
  io("pinhole", o.pinhole);
  io("features", o.features);
  io("verify", o.verify);
  io("bundle", o.bundle);
  io("min_matches_per_pair", o.min_matches_per_pair,
     "Verified matches an image pair needs to count", range::AtLeast(5));
  io("min_observations_per_image", o.min_observations_per_image,
     "An image with fewer tie-point observations is left out", range::AtLeast(3));
  io("max_reprojection_before_ba_px", o.max_reprojection_before_ba_px,
     "Points that reproject worse than this before bundle adjustment are dropped (RPC biases reach tens of pixels)",
     range::Above(0));
  io("max_reprojection_after_ba_px", o.max_reprojection_after_ba_px,
     "Outlier cut on the reprojection error between bundle adjustment rounds", range::Above(0));
  io("min_triangulation_angle_deg", o.min_triangulation_angle_deg,
     "Points triangulated from rays meeting at a smaller angle are dropped", range::FromBelow(0, 90));
  io("ba_rounds", o.ba_rounds,
     "Bundle adjustment rounds, with an outlier cut between them", range::AtLeast(1));
  io("anchor_image", o.anchor_image,
     "What fixes the absolute position: empty = the robust average of all images' RPCs; else the name of one image "
     "whose RPC fixes the horizontal position (a tile without it falls back to the average)");
}
template <class IO> void Visit(IO& io, DenseOptions& o) {
  io("cell_m", o.cell_m,
     "Height grid cell; 0 = automatic from the imagery (0.5 m for sub-metre sensors, else the multiple of 0.5 m "
     "nearest the finest view's GSD)", range::Or(range::Above(0), 0, "automatic"));
  io("height_step_m", o.height_step_m,
     "Step between the candidate heights of the plane sweep", range::Above(0));
  io("height_margin_m", o.height_margin_m,
     "Added beyond the tie points' height percentiles to form the sweep's height range", range::AtLeast(0));
  io("height_percentile", o.height_percentile,
     "Tie-point heights outside the [p, 1-p] percentiles are ignored for the height range", range::FromBelow(0, 0.5));
  io("max_heights", o.max_heights,
     "Most candidate heights per sweep; longer ranges are swept in coarser steps (memory: cells x heights x 4 bytes)",
     range::AtLeast(2));
  io("range_probe_above_m", o.range_probe_above_m,
     "A coarse sweep up to this far above the tie points' height range looks for surfaces without tie points (a "
     "tower in coarse imagery) and raises the sweep's range to them; 0 = off", range::In(0, 5000));
  io("range_probe_min_gsd_m", o.range_probe_min_gsd_m,
     "The range probe runs only for imagery whose finest GSD is at least this (sub-metre imagery has tie points on "
     "its tall roofs)", range::AtLeast(0));
  io("window_cells", o.window_cells,
     "Side of the NCC window, odd", range::Odd(range::AtLeast(3)));
  io("max_pairs", o.max_pairs,
     "Image pairs used, most verified tie points first", range::AtLeast(1));
  io("min_pair_matches", o.min_pair_matches,
     "Verified tie points an image pair needs to be considered", range::AtLeast(0));
  io("min_pair_angle_deg", o.min_pair_angle_deg,
     "Pairs with a smaller intersection angle are not used (heights too weakly constrained)", range::AtLeast(0));
  io("max_pair_angle_deg", o.max_pair_angle_deg,
     "Pairs with a larger intersection angle are not used (views too different to correlate)",
     range::AboveUpTo(0, 180));
  io("cost_truncation", o.cost_truncation,
     "Each pair's matching cost (1 - NCC) is capped at this value", range::Above(0));
  io("min_std", o.min_std,
     "Window standard deviation (of the normalized image) below which NCC is undefined and the pair adds the capped "
     "cost", range::Above(0));
  io("sgm_p1", o.sgm_p1,
     "SGM penalty for a one-step height change between neighbouring cells, in cost units", range::AtLeast(0));
  io("sgm_p2", o.sgm_p2,
     "SGM penalty for a larger height change (walls), in cost units", range::AtLeast(0));
  io("max_cost", o.max_cost,
     "Cells whose matching cost at the chosen height exceeds this get no height", range::Above(0));
  io("max_median_deviation_m", o.max_median_deviation_m,
     "Cells further than this from their 3x3 median get no height (speckle)", range::Above(0));
  io("fill_holes", o.fill_holes,
     "Fill cells without a height from their surroundings and the terrain model (filled cells are flagged)");
  io("coarse_factor", o.coarse_factor,
     "Before filling, holes get a second sweep on a grid this many times coarser, on images blurred to it; 1 = off",
     range::AtLeast(1));
  io("coarse_window_cells", o.coarse_window_cells,
     "NCC window side of the coarse sweep, in coarse cells, odd", range::Odd(range::AtLeast(3)));
  io("step_min_m", o.step_min_m,
     "decide_filled_sides: a filled cell's roof side must stand more than this above its ground side", range::Above(0));
  io("step_reach_cells", o.step_reach_cells,
     "decide_filled_sides: a cell filled at the ground with measured ground this near keeps the ground",
     range::AtLeast(1));
  io("support_radius_cells", o.support_radius_cells,
     "Radius of the adaptive support-weight window", range::AtLeast(1));
  io("support_grey_sigma", o.support_grey_sigma,
     "Grey difference at which a cell's support weight falls to 1/e (on grey scaled so that its 99th percentile is "
     "1)", range::Above(0));
  io("step_cost_margin", o.step_cost_margin,
     "A cell changes side only when the other side's cost is lower by this much (and at most max_cost)",
     range::AtLeast(0));
  io("decide_filled_sides", o.decide_filled_sides,
     "After filling, score each filled cell at the ground and at a roof, and let it take the other side where that "
     "matches clearly better");
  io("fill_radius_m", o.fill.radius_m,
     "A seen hole takes the lowest height above the ground within this distance (doubled while nothing is in reach)",
     range::Above(0));
  io("fill_roof_rim_fraction", o.fill.roof_rim_fraction,
     "A seen hole whose rim of measured cells is at least this share roof takes the roof, even with ground in reach; "
     "0 = off", range::In(0, 1));
  io("fill_roof_rim_occluded", o.fill.roof_rim_occluded,
     "The roof-rim rule also counts holes whose ground no pair sees (a hole in the middle of a roof)");
  io("fill_roof_enclosed", o.fill.roof_enclosed,
     "A hole cell enclosed by roof on all sides takes the roof, even where its hole reaches hidden ground beyond the "
     "roof's edge");
  io("fill_far_raised_ground", o.fill.far_raised_takes_ground,
     "A seen hole cell with nothing measured within fill_radius_m, whose lowest measured neighbour further out is "
     "raised, takes the ground");
  io("fill_seen_ground_terrain", o.fill.seen_ground_takes_terrain,
     "A seen hole cell whose lowest measured neighbour in reach is ground takes the terrain model's height");
  io("fill_edge_hides", o.fill_edge_hides,
     "Ground whose ray toward a view leaves the grid counts as hidden from that view (the city goes on beyond the "
     "grid)");
  io("floating_patch_max_m2", o.floating_patch_max_m2,
     "Before filling, patches of matched cells smaller than this that stand wholly more than "
     "floating_patch_min_rise_m above the terrain model become holes; 0 = off", range::AtLeast(0));
  io("floating_patch_min_rise_m", o.floating_patch_min_rise_m,
     "Height above the terrain model beyond which a small patch counts as floating (see floating_patch_max_m2)",
     range::AtLeast(0));
  io("max_fill_reach_m", o.fill.max_reach_m,
     "Cells further than this from every measured cell stay empty", range::Above(0));
  io("fill_ground_radius_m", o.fill.ground_radius_m,
     "Radius of the morphological opening that gives the ground surface (larger than half the widest building)",
     range::Above(0));
  io("fill_ground_max_rise_m", o.fill.ground_max_rise_m,
     "Where the ground surface stands more than this above the opening of twice fill_ground_radius_m, it holds roofs "
     "only and the terrain model spans it; 0 = off", range::AtLeast(0));
  io("fill_ground_tolerance_m", o.fill.ground_tolerance_m,
     "Measured cells at most this far above the ground surface are ground and shape the terrain model",
     range::AtLeast(0));
  io("fill_terrain_block_cells", o.fill.terrain_block_cells,
     "Block side of the terrain model that spans hidden ground, in grid cells", range::AtLeast(1));
  io("fill_roof_rim_min_m", o.fill.roof_rim_min_m,
     "A measured cell more than this above the ground is raised (a roof) for the roof-rim and enclosure rules",
     range::AtLeast(0));
  io("visibility_pass", o.visibility_pass,
     "Run a second sweep that scores each height only with the pairs whose two views see that point");
  io("visibility_tolerance_m", o.visibility_tolerance_m,
     "A point counts as seen when the first surface rises at most this much above its ray toward the camera",
     range::AtLeast(0));
  io("visibility_near_cells", o.visibility_near_cells,
     "Surface cells this near a cell along the ray do not hide it; -1 = the NCC window's radius, 0 = every cell "
     "hides", range::Or(range::AtLeast(0), -1, "the NCC window's radius"));
  io("visibility_prior_pairs", o.visibility_prior_pairs,
     "In the visibility pass, each height's mean cost is taken as if this many more pairs had added the capped cost",
     range::AtLeast(0));
}
template <class IO> void Visit(IO& io, PseudoCameraOptions& o) {
  io("radius_m", o.radius_m,
     "Distance of a pseudo camera from its look-at point", range::Above(0));
  io("look_at_sigma_m", o.look_at_sigma_m,
     "Standard deviation of the look-at points' horizontal offset from the scene centre (also for the surface "
     "anchor's nadir patches)", range::AtLeast(0));
  io("min_elevation_deg", o.min_elevation_deg,
     "Lowest elevation of a pseudo camera (azimuths are random)", range::In(0, 90));
  io("max_elevation_deg", o.max_elevation_deg,
     "Highest elevation of a pseudo camera", range::In(0, 90));
  io("size_px", o.size_px,
     "Side of a pseudo view (square)", range::AtLeast(16));
  io("fov_deg", o.fov_deg,
     "Field of view of a pseudo camera", range::Inside(0, 170));
}
template <class IO> void Visit(IO& io, AppearanceOptions& o) {
  io.NotAnOption(o.enabled);  // decided by train.appearance
  io("model", o.model,
     "'mlp' (the paper's MLP on both embeddings and the colour) or 'bilinear' (a cheaper MLP on the image embedding "
     "alone)");
  io("image_dim", o.image_dim,
     "Size of the per-image embedding", range::In(1, 1024));
  io("gaussian_dim", o.gaussian_dim,
     "Size of the per-Gaussian embedding", range::In(1, 1024));
  io("hidden", o.hidden,
     "Width of the MLP's hidden layers", range::In(1, 4096));
  io("lr_image", o.lr_image,
     "Adam learning rate of the per-image embeddings", range::Above(0));
  io("lr_gaussian", o.lr_gaussian,
     "Adam learning rate of the per-Gaussian embeddings", range::Above(0));
  io("lr_mlp", o.lr_mlp,
     "Adam learning rate of the MLP's weights", range::Above(0));
  io("init_std", o.init_std,
     "Standard deviation of the embeddings' random start, N(0, init_std^2)", range::Above(0));
}
template <class IO> void Visit(IO& io, RasterOptions& o) {
  io.NotAnOption(o.median_depth);  // an output choice of each caller
  io("tile_px", o.tile_px,
     "Side of the square screen tiles the Gaussians are binned into", range::In(4, 64));
  io("min_alpha", o.min_alpha,
     "Contributions with a smaller alpha are skipped", range::AtLeast(0));
  io("max_alpha", o.max_alpha,
     "Alpha is clamped to this, which keeps transmittance invertible", range::Inside(0, 1));
  io("min_transmittance", o.min_transmittance,
     "A pixel stops blending once its transmittance falls below this", range::FromBelow(0, 1));
  io("dilation_px2", o.dilation_px2,
     "Added to the diagonal of each projected 2D covariance (anti-aliasing)", range::AtLeast(0));
  io("near_m", o.near_m,
     "Gaussians closer than this to the camera plane are culled", range::Above(0));
  io("guard_band", o.guard_band,
     "Gaussians whose centre projects further than this fraction of the image size beyond its edges are culled",
     range::AtLeast(0));
  io("sigma_extent", o.sigma_extent,
     "A Gaussian blends the pixels within this many standard deviations (Mahalanobis)", range::Above(0));
  io("sh_degree", o.sh_degree,
     "Degree of the spherical-harmonics colours: 0 or 1", range::OneOf({0, 1}));
  io("background", o.background,
     "Colour behind the Gaussians: red, green, blue, each in [0, 1]", range::In(0, 1));
}
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
  io("lr_mean_initial", t.lr_mean_initial,
     "Adam learning rate of the centres at the first step, times the scene extent; it decays exponentially to "
     "lr_mean_final", range::Above(0));
  io("lr_mean_final", t.lr_mean_final,
     "Learning rate of the centres at the last step, times the scene extent", range::Above(0));
  io("lr_scale", t.lr_scale,
     "Adam learning rate of the Gaussians' scales", range::Above(0));
  io("lr_rotation", t.lr_rotation,
     "Adam learning rate of the Gaussians' rotations", range::Above(0));
  io("lr_opacity", t.lr_opacity,
     "Adam learning rate of the Gaussians' opacities", range::Above(0));
  io("lr_sh_dc", t.lr_sh_dc,
     "Adam learning rate of the degree-0 spherical-harmonics colour", range::Above(0));
  io("lr_sh_rest", t.lr_sh_rest,
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
  io("lambda_surface_depth", t.lambda_surface_depth,
     "Weight of the surface anchor's Huber depth loss, per metre of depth error; 0 = off", range::AtLeast(0));
  io("lambda_surface_alpha", t.lambda_surface_alpha,
     "Weight of the surface anchor's (1 - accumulated opacity) term where the surface is seen; 0 = off",
     range::AtLeast(0));
  io("surface_huber_m", t.surface_huber_m,
     "Scale of the surface anchor's Huber loss: depth errors beyond it count linearly", range::Above(0));
  io("lambda_surface_height", t.lambda_surface_height,
     "Weight of the loss that holds Gaussian centres near the dense surface to its height, per m^2 and averaged over "
     "the Gaussians; 0 = off", range::AtLeast(0));
  io("surface_height_band_m", t.surface_height_band_m,
     "Gaussians whose centre is within this of the surface height below it are held by lambda_surface_height",
     range::Above(0));
  io("surface_nadir_interval", t.surface_nadir_interval,
     "Steps between the nadir patches the surface anchor also holds; 0 = never", range::AtLeast(0));
  io("surface_nadir_size_px", t.surface_nadir_size_px,
     "Side of the surface anchor's square nadir patch", range::AtLeast(16));
  io("surface_nadir_gsd_m", t.surface_nadir_gsd_m,
     "Ground pixel size of the surface anchor's nadir patch", range::Above(0));
  io("appearance_model", t.appearance);
  io("appearance_image", t.appearance_image,
     "Training view whose appearance is fused into scene.ply (empty = the view whose embedding is nearest the mean)");
  io("raster", t.raster);
}
template <class IO> void Visit(IO& io, OrbitOptions& o) {
  io("grid", o.grid,
     "The look-at points form a grid x grid square over the tile's core", range::In(1, 16));
  io("views_per_point", o.views_per_point,
     "Orbit views per look-at point in each episode", range::In(1, 64));
  io("episodes", o.episodes,
     "Episodes of the curriculum, from high to low elevation", range::In(1, 50));
  io("elevation_start_deg", o.elevation_start_deg,
     "Elevation of the orbit views in the first episode", range::Inside(5, 90));
  io("elevation_end_deg", o.elevation_end_deg,
     "Elevation of the orbit views in the last episode", range::Inside(5, 90));
  io("radius_start_per_core", o.radius_start_per_core,
     "Orbit radius in the first episode, as a multiple of the core's side", range::AboveUpTo(0, 10));
  io("radius_end_per_core", o.radius_end_per_core,
     "Orbit radius in the last episode, as a multiple of the core's side", range::AboveUpTo(0, 10));
  io("min_radius_m", o.min_radius_m,
     "Smallest orbit radius, which keeps the cameras of small tiles above the rooftops", range::AtLeast(0));
  io("fov_deg", o.fov_deg,
     "Field of view of the orbit views", range::In(5, 120));
  io("width_px", o.width_px,
     "Width of an orbit view", range::In(16, 4096));
  io("height_px", o.height_px,
     "Height of an orbit view", range::In(16, 4096));
}
template <class IO> void Visit(IO& io, RefineRequest& o) {
  // Set per episode by the synthesis stage from its own options (idu.samples, idu.seed).
  io.NotAnOption(o.samples);
  io.NotAnOption(o.seed);
  io.NotAnOption(o.episode);
  io("source_prompt", o.source_prompt,
     "Prompt that describes the rendered views, for external (diffusion) refiners");
  io("target_prompt", o.target_prompt,
     "Prompt that describes the refined views wanted, for external (diffusion) refiners");
  io("n_min", o.n_min,
     "FlowEdit's n_min, for external refiners: the last this many steps are plain sampling with the target prompt",
     range::AtLeast(0));
  io("n_max", o.n_max,
     "FlowEdit's n_max, for external refiners: editing starts this many steps before the end", range::AtLeast(0));
  io("n_avg", o.n_avg,
     "FlowEdit's n_avg, for external refiners: noise samples averaged per step", range::AtLeast(1));
  io("steps", o.steps,
     "Diffusion sampling steps, for external refiners", range::AtLeast(1));
  io("source_guidance_scale", o.source_guidance_scale,
     "Classifier-free guidance scale of the source prompt, for external refiners", range::AtLeast(0));
  io("target_guidance_scale", o.target_guidance_scale,
     "Classifier-free guidance scale of the target prompt, for external refiners", range::AtLeast(0));
}
template <class IO> void Visit(IO& io, ReprojectOptions& o) {
  io("visibility_tolerance_m", o.visibility_tolerance_m,
     "A satellite view sees an orbit pixel's surface point when the point's depth in that view is within this of the "
     "depth the scene renders there", range::Above(0));
  io("angle_weight_power", o.angle_weight_power,
     "A satellite view weighs (cos of the angle between its ray and the orbit ray)^this, so views from similar "
     "directions count most", range::AtLeast(0));
  io("keep_probability", o.keep_probability,
     "Each sample keeps each satellite view with this probability (at least one view is kept)", range::AboveUpTo(0, 1));
  io("weight_jitter", o.weight_jitter,
     "Each kept view's weight is scaled by a factor drawn from [1 - this, 1 + this]", range::FromBelow(0, 1));
  io("inpaint", o.inpaint,
     "Pixels no satellite view sees: 'telea' or 'ns' (OpenCV inpainting) or 'render' (the rendered colour is kept)");
  io("inpaint_radius_px", o.inpaint_radius_px,
     "Radius of the OpenCV inpainting", range::Above(0));
  io("smooth_diameter_px", o.smooth_diameter_px,
     "Diameter of the final edge-preserving bilateral filter; 0 = off", range::In(0, 31));
  io("smooth_sigma_colour", o.smooth_sigma_colour,
     "Colour sigma of the bilateral filter, in colour units of 0 to 1", range::Above(0));
  io("smooth_sigma_space_px", o.smooth_sigma_space_px,
     "Spatial sigma of the bilateral filter", range::Above(0));
}
template <class IO> void Visit(IO& io, IduAutoOptions& o) {
  io("step_m", o.step_m,
     "A height step between neighbouring dense cells at least this tall counts as a facade", range::Above(0));
  io("min_facade_ratio", o.min_facade_ratio,
     "Tiles with less facade than this, in m^2 of facade per m^2 of ground, are flat or low-rise and skipped",
     range::AtLeast(0));
  io("min_measured_fraction", o.min_measured_fraction,
     "Tiles whose dense heights matched a smaller fraction of the grid (water, featureless or empty) are skipped",
     range::In(0, 1));
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
template <class IO> void Visit(IO& io, SeamLineOptions& o) {
  io("enabled", o.enabled,
     "Cut between tiles along seam lines where their DSMs agree; off: the straight core boundaries");
  io("cell_m", o.cell_m,
     "Cell of the height maps and of the seam line", range::Above(0));
  io("band_fraction", o.band_fraction,
     "Seam lines stay within this fraction of the overlap margin of the core boundary", range::In(0, 1));
  io("max_step_m", o.max_step_m,
     "Height disagreements are capped at this, and a cell only one tile covers costs this much", range::Above(0));
  io("bend_m", o.bend_m,
     "Cost added per cell the line moves sideways, so that it stays straight where the tiles agree", range::AtLeast(0));
  io("centre_pull_m", o.centre_pull_m,
     "Cost added per cell along the line for each cell it is off the core boundary, so that a detour ends where the "
     "disagreement does", range::Above(0));
}
template <class IO> void Visit(IO& io, StitchOptions& o) {
  io("voxel_m", o.voxel_m,
     "Occupancy voxel edge", range::Above(0));
  io("min_opacity", o.min_opacity,
     "Gaussians more transparent than this neither mark occupancy nor fill holes", range::FromBelow(0, 1));
  io("match_radius_voxels", o.match_radius_voxels,
     "A neighbour's Gaussian is a duplicate when the owner's occupancy has an active voxel within this distance",
     range::In(0, 8));
  io("occupancy_columns", o.occupancy_columns,
     "Occupancy by ground column (a neighbour's Gaussian over ground the owner covers, at any height, is a "
     "duplicate); off: by voxel");
  io("seam_lines", o.seam_lines);
}
template <class IO> void Visit(IO& io, LodOptions& o) {
  io("max_levels", o.max_levels,
     "Coarser LOD levels to build", range::In(0, 24));
  io("base_voxel_m", o.base_voxel_m,
     "Smallest voxel edge tried; it doubles per attempt", range::Above(0));
  io("min_reduction", o.min_reduction,
     "A level is kept only when it has at most this fraction of the previous level's Gaussians; otherwise the voxel "
     "doubles again", range::AboveUpTo(0, 1));
  io("min_gaussians", o.min_gaussians,
     "No coarser level is built from a level of this many Gaussians or fewer", range::AtLeast(1));
}
template <class IO> void Visit(IO& io, MergeOptions& o) {
  io("stitch", o.stitch);
  io("lod", o.lod);
  io("seam_gsd_m", o.seam_gsd_m,
     "Spacing of the city DSM (dsm_city.tif) the seam metric is measured on", range::Above(0));
}
template <class IO> void Visit(IO& io, Tiles3dOptions& o) {
  io("leaf_m", o.leaf_m,
     "A node splits into quadrants while it is wider than this", range::Above(0));
  io("max_fractional_bits", o.max_fractional_bits,
     "The finest SPZ position step is 2^-bits metres (fewer bits when coordinates are large)", range::In(0, 20));
}
template <class IO> void Visit(IO& io, ExportOptions& o) {
  io("tiles3d", o.tiles3d,
     "Write OUT/<city>/3dtiles, 3D Tiles 1.1 with SPZ Gaussian splats, at the end of each city's run");
  io("tiles3d_options", o.tiles3d_options);
}
template <class IO> void Visit(IO& io, DsmExportOptions& o) {
  io("camera_height_m", o.camera_height_m,
     "Height of the nadir camera the DSM is rendered from (far, so nearly orthographic)", range::AtLeast(10000));
  io("min_alpha", o.min_alpha,
     "Pixels whose accumulated opacity is below this are nodata", range::Inside(0, 1));
  io("median_depth", o.median_depth,
     "A pixel's height is the depth where the accumulated opacity reaches 0.5; off: the opacity-weighted expected "
     "depth");
}
template <class IO> void Visit(IO& io, DsmCompareOptions& o) {
  io.NotAnOption(o.breakdown.building_class);  // the LiDAR classes' code (ASPRS 6), not a choice
  io("max_shift_px", o.max_shift_px,
     "Search radius of the horizontal alignment shift per pyramid level", range::AtLeast(0));
  io("pyramid_levels", o.pyramid_levels,
     "Levels of the 2x pyramid the shift is searched on, coarse to fine", range::AtLeast(1));
  io("mask_water", o.mask_water,
     "Leave water (class 9) out of the comparison");
  io("within_m", o.within_m,
     "The comparison reports the fraction of pixels whose error is at most this", range::Above(0));
  io("rim_width_m", o.breakdown.rim_width_m,
     "With classes: width of the bands inside and outside building outlines whose error is reported apart",
     range::Above(0));
  io("edge_band_m", o.breakdown.edge_band_m,
     "With classes: width of each band of the edge profile", range::Above(0));
  io("edge_bands", o.breakdown.edge_bands,
     "With classes: bands of the edge profile on each side of the building outlines", range::In(1, 100));
}
template <class IO> void Visit(IO& io, DsmOptions& o) {
  io("source", o.source,
     "Gaussians the DSMs are rasterized from: 'reconstruction' (each tile's scene trained on the real images) or "
     "'final' (the scene after the synthesis stage)");
  io("export", o.export_options);
  io("compare", o.compare);
}
template <class IO> void Visit(IO& io, LandCoverOptions& o) {
  io("object_min_m", o.object_min_m,
     "A cell standing more than this above the DTM is an object: a building or a tree", range::AboveUpTo(0, 50));
  io("green_sigmas", o.green_sigmas,
     "An object cell votes vegetation when its excess green (2g - r - b) / (r + g + b) exceeds the AOI's objects' "
     "median by this many robust sigmas (1.4826 x MAD) ...", range::In(0, 10));
  io("min_roughness_m", o.min_roughness_m,
     "... and its surface departs by more than this (RMS) from the least-squares plane around it", range::In(0, 10));
  io("plane_half_window_m", o.plane_half_window_m,
     "Half side of the window of that plane fit", range::AboveUpTo(0, 20));
  io("vote_radius_m", o.vote_radius_m,
     "Half side of the window whose majority of object cells' votes decides building or vegetation", range::In(0, 20));
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
