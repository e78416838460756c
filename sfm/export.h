// SfM products: cameras.json, points.ply, sfm_report.json and a COLMAP text
// model (cameras.txt, images.txt, points3D.txt) with de-skewed images.
#pragma once

#include <string>

#include "core/aoi.h"
#include "sfm/sfm.h"

namespace skyfall {

// Writes every product under `out_dir` (each file atomically). COLMAP has no
// skewed pinhole model, so colmap/images/ holds each image resampled by the
// shear that removes K(0,1), and the model uses PINHOLE with COLMAP's pixel
// convention (top-left pixel centre at (0.5, 0.5)).
void WriteSfmOutputs(const SfmResult& result, const AoiCatalog& catalog, const std::string& out_dir,
                     bool write_colmap_images = true);

// The PLY layout of points.ply (ASCII): x y z (double, ENU metres), red green
// blue (uchar), track_length (int), reprojection_error (float, px).
std::string PointsToPly(const SfmResult& result);

}  // namespace skyfall
