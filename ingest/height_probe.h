// Where in height an AOI lies when only its RPCs are known: a one-point plane
// sweep over the RPCs' height validity range. A vendor RPC's HEIGHT_OFF can
// sit a kilometre from a valley AOI (it is the mean of the whole scene);
// searching around it would look for the city in the air.
#pragma once

#include <optional>
#include <vector>

#include "core/aoi.h"

namespace skyfall {

struct HeightProbeOptions {
  int max_images = 4;             // the first image against up to max_images-1 others
  int downsample = 4;             // images are box-averaged by this factor first (wider NCC peak)
  int patch_px = 24;              // side of each correlation patch, in downsampled pixels
  int patches_per_side = 3;       // patches on a grid over the reference image's centre half
  double coarse_step_m = 2.0;     // [m] first sweep step over the validity range
  double fine_step_m = 0.25;      // [m] second sweep, +-2 coarse steps around the best
  double min_score = 0.3;         // mean NCC below this: no height is trusted
  double max_image_mpx = 16.0;    // larger images are left out of the probe (it reads images whole) [Mpx]
  void Check() const;             // throws Error("height_probe", field, ...)
};

struct HeightProbe {
  double height_m = 0;  // ellipsoidal height where the views agree best [m]
  double score = 0;     // mean NCC over patches and pairs at that height
};

// The height at which the images' centres agree best, or nothing when fewer
// than two images are readable or no height correlates (min_score).
std::optional<HeightProbe> ProbeSceneHeight(const std::vector<ImageRecord>& images,
                                            const HeightProbeOptions& options = {});

}  // namespace skyfall
