// Which pixels of each view the training trusts. Two masks clear a view's
// `valid` flags (TrainView): pixels that see past the tile's dense heights,
// and pixels hidden by a cloud on their date. Both start from the dense
// heights rendered opaque into every view (RenderDenseCover), which gives
// each pixel the ground point it sees.
#pragma once

#include <string>
#include <vector>

#include "core/option_range.h"
#include "dense/dense_cells.h"
#include "splat/rasterizer.h"
#include "splat/trainer.h"

namespace skyfall {

// The dense heights (thinned to `spacing_m`) and the walls between them,
// rendered as nearly opaque blobs into each view: alpha >= 0.5 where a
// pixel sees the tile's surface, and its depth there. Empty without cells.
std::vector<RenderOutput<float>> RenderDenseCover(const DenseCells& cells, double spacing_m,
                                                  const RasterOptions& raster, const std::vector<TrainView>& views);

// Masks out of each view's `valid` the pixels that see past the tile's
// dense heights: a crop's fringe beyond the extent (off-nadir views and tall
// buildings widen it). No Gaussian of the tile explains them; trained on,
// they pull the extent's edge Gaussians outwards, and scored, they measure
// the crop, not the model. Pixels the cover leaves uncovered (alpha < 0.5)
// are masked. Returns the share of the pixels with data that were masked
// (0 without cells).
double MaskBeyondReconstruction(const std::vector<RenderOutput<float>>& covers, std::vector<TrainView>* views);
double MaskBeyondReconstruction(const DenseCells& cells, double spacing_m, const RasterOptions& raster,
                                std::vector<TrainView>* views);

// The cloud mask. A cloud hides the ground from the views of one date and
// leaves it clear on the others, so a ground point's colour in a cloudy
// view stands out against the same point in the other views: brighter than
// nearly all of them in every channel, and whitish. Shadows that move with
// the sun also brighten a point on some dates, but seldom beyond nearly
// every other date, and on coloured ground in its own colour.
struct CloudMaskOptions {
  // Off by default: with the appearance model on, the cloudy date's
  // embeddings already take the clouds, and masking them moved neither the
  // DSM nor the views (decision D-137).
  bool enabled = false;
  // [0-1 image units] a pixel is cloudy when its colour exceeds the 75th
  // percentile of the other views' colours at its ground point (brought to
  // its own view's gain per channel) by this much on average...
  double min_brightening = 0.12;
  // ...in every channel, and the pixel itself is whitish: (max - min) / max
  // of its channels at most this (a cloud over green ground, half opaque,
  // stays under 0.3; green ground lit by the sun is about 0.7).
  double max_chroma = 0.35;
  // [m^2] cloudy patches smaller than this are left in (cars, glints: the
  // appearance model absorbs such transients).
  double min_area_m2 = 200.0;
  // [m] the mask grows by this much, over the cloud's faint fringe.
  double grow_m = 2.0;
  // [m] a view sees a ground point when its own cover depth there is within
  // this distance of the point's depth.
  double surface_tolerance_m = 2.0;
  // Other training views that must see a ground point before it is judged.
  int min_other_views = 2;
  void Check() const;  // throws Error("train", "cloud_mask...", ...)
};
template <class IO> void Visit(IO& io, CloudMaskOptions& o) {
  io("enabled", o.enabled,
     "Leave the training views' cloudy pixels out of the loss (a ground point far brighter and whiter than on the "
     "other dates); needs dense heights and three or more training views. Off: measured without benefit (D-137)");
  io("min_brightening", o.min_brightening,
     "A pixel is cloudy when it exceeds the 75th percentile of the other views at its ground point by this much "
     "(image units 0-1, the others brought to its view's gain)",
     range::Above(0));
  io("max_chroma", o.max_chroma,
     "...in every channel, and its own (max - min) / max over the channels is at most this (whitish)",
     range::In(0, 1));
  io("min_area_m2", o.min_area_m2,
     "Cloudy patches smaller than this are left in (cars, glints)", range::AtLeast(0));
  io("grow_m", o.grow_m, "The mask grows by this much over the cloud's faint fringe", range::AtLeast(0));
  io("surface_tolerance_m", o.surface_tolerance_m,
     "A view sees a ground point when its own surface depth there is within this distance", range::Above(0));
  io("min_other_views", o.min_other_views,
     "Other training views that must see a ground point before it is judged", range::AtLeast(1));
}

// Masks the cloudy pixels of the training views (held-out views are neither
// masked nor used as references: they are scored as given). `covers` from
// RenderDenseCover of `cells` over the same views. Pixels on walls (below
// or above the cells' top surface by more than surface_tolerance_m) and
// pixels too few others see are not judged; they join a cloud within 5 m. Returns, per view, the share of its
// pixels with data that were masked (0 for held-out views, and for every
// view when fewer than min_other_views + 1 training views exist).
std::vector<double> MaskClouds(const DenseCells& cells, const std::vector<RenderOutput<float>>& covers,
                               const CloudMaskOptions& options, std::vector<TrainView>* views);

}  // namespace skyfall
