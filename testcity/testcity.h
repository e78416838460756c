// `skyfall synth`: writes a DFC2019-style tree of a procedural city that
// `skyfall ingest` reads exactly like real data: RGB crops with fitted RPCs
// and NITF dates, the truth DSM (+ _DSM.txt, lower-left convention) and CLS
// rasters in UTM, and Sat-NeRF-style camera JSONs with sun angles and split.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/pinhole.h"
#include "core/stage.h"
#include "testcity/city.h"
#include "testcity/render.h"

namespace skyfall::synth {

struct SynthOptions {
  std::string aoi = "SYN_001";   // AOI name; blocks of a city get _X<i>Y<j> appended
  std::uint64_t seed = 1;
  double size_m = 256.0;         // AOI (block) side [m]
  double gsd_m = 0.5;            // truth DSM and nominal image GSD [m]
  int views = 12;                // images per AOI
  int views_per_date = 2;        // images taken on one pass (same sun, gain, cars)
  double lat_deg = 30.3488;      // city centre (default: Jacksonville, UTM 17N like JAX_068)
  double lon_deg = -81.6637;
  int blocks_x = 1;              // adjacent AOIs along x (east) and y (north)
  int blocks_y = 1;
  double min_off_nadir_deg = 5.0;
  double max_off_nadir_deg = 35.0;
  double orbit_height_m = 617000.0;  // WorldView-3
  int cars_per_block = 40;
  int image_margin_px = 16;      // image border beyond the AOI's projection [px]
  // Sensor radiometry of the written images: 8 bits (Byte) or 11-16 bits
  // (UInt16 digital numbers over most of the range, as WorldView and
  // Pleiades deliver them); 3 bands (RGB) or 1 (panchromatic luminance).
  int bit_depth = 8;
  int bands = 3;
  double max_building_m = 80.0;  // tallest building above ground [m]
  double relief_m = 0.0;         // hills under the city (see CityOptions::relief_m) [m]
  // Strength of the radiometric change between dates (sun gain and colour
  // tint); 1 is the default variety, 3 a strong one (gain 0.64-1.36).
  double date_contrast = 1.0;
  // Atmospheric haze: the share of each pixel's light that is path radiance
  // (0 clear; 0.7 leaves crowns about as little greener than roofs as in
  // the DFC2019 WorldView-3 crops) [0, 0.9].
  double haze = 0.0;
  // Sensor noise: Gaussian, this many DN (8-bit scale) of standard deviation
  // per band and pixel, on top of the +-1 DN every image has. Real
  // satellite images carry a few DN; the default city's images are nearly
  // noise-free, and a matcher tuned on them can trust grey levels more than
  // real imagery allows (decision D-157) [0, 20].
  double noise_dn = 0.0;
  // Sensor blur: each image's optics as a Gaussian point-spread function of
  // this standard deviation [px], before the detector's noise. Real crops
  // carry 2.5-3x less texture at the pixel's scale than the generator's
  // sharp views (decision D-157) [0, 3].
  double blur_px = 0.0;
  // Cumulus over every second date (dates 1, 3, ...; date 0 stays clear): a
  // layer 1,000 m above the tallest roof whose puffs (60-200 m in radius) would
  // cover this share of the sky if none overlapped [0, 0.8]. Each cloudy
  // date has its own puffs, which both images of its pass see (with
  // parallax) and whose shadows darken the ground; per image, the share of
  // pixels behind a cloud is in synth_report.json.
  double clouds = 0.0;
  // Shifts the RPCs' height normalization: the fit domain reaches this far
  // above (or below) the scene, so HEIGHT_OFF lies far from the ground, as in
  // a vendor RPC of a whole mountain scene seen from a valley AOI [m].
  double rpc_height_offset_m = 0.0;
  // Mean ground height of the city above the WGS84 ellipsoid [m]: 0 near the
  // sea, 2,300 or 4,000 m for a city in the mountains. The default is about
  // Jacksonville's (the DFC2019 scenes').
  double ground_height_m = -20.0;
  // Vendor RPCs point a few metres off the ground and off each other. Each
  // acquisition's written RPC is off its true camera by a shift of up to
  // rpc_bias_px [px] (uniform in a disc) and a rotation about the image
  // centre of up to rpc_bias_rotation_deg [deg, at most 0.1]; every AOI's
  // crop of an acquisition has its shift, as crops of one vendor image do.
  // The part of the shifts that a shift of the whole city would explain is
  // removed: tie points cannot see it (only ground control could), so the
  // truth's frame is the average of all acquisitions. Seeded by `seed`,
  // recorded per image in synth_report.json.
  double rpc_bias_px = 0.0;
  double rpc_bias_rotation_deg = 0.0;
  // Each AOI of a city keeps its own seeded choice of this many of the
  // `views` acquisitions (0: all), as the AOIs of a DFC2019 tree hold
  // different passes. With biased RPCs, neighbouring AOIs then average
  // different images' biases in their bundle adjustments.
  int views_per_aoi = 0;
  // A three-line (along-track) camera instead of views from many orbits: when
  // > 0, the views lie on one orbit track with off-nadir angles spread evenly
  // from -along_track_deg (forward) to +along_track_deg (backward), taken on
  // one pass (views_per_date = views; ZY-3: nadir and +-22 deg) [deg].
  double along_track_deg = 0.0;
  void Check() const;            // throws Error("synth", field, ...)
};

// Scene options drawn at random, for accuracy checks on scenes that no
// setting was chosen on (`skyfall synth --draw`, scripts/bench_accuracy.sh
// --draw). `base` gives what is not drawn (AOI name, size, GSD, blocks,
// orbit, cars, margins); drawn: the city's seed, latitude (-60..60 deg) and
// longitude, off-nadir range (smallest 0-20 deg, largest 10-25 deg more, at
// most 45), views (3-16) and views per date (1-3), sensor (1 band in a
// third of the draws; 8, 11, 12, 14 or 16 bits), relief (none in half of
// the draws, else 10-100 m), tallest building (15-180 m) and date contrast
// (0.5-3). Equal `draw` numbers give equal options on every platform (the
// generator's bits are mapped by hand, not by std:: distributions).
SynthOptions DrawSceneOptions(std::uint64_t draw, const SynthOptions& base);

// One image as written, with what a test needs to check it.
struct SynthView {
  std::string name;               // NAME_NNN_RGB
  std::string path;               // written TIFF
  SatelliteCamera camera;         // the true projection
  Lighting lighting;
  std::string acquisition_time;   // ISO 8601 UTC
  double sun_elevation_deg = 0, sun_azimuth_deg = 0;
  double off_nadir_deg = 0, view_zenith_deg = 0, view_azimuth_deg = 0, range_km = 0;
  double rpc_fit_max_px = 0, rpc_fit_rms_px = 0;  // fitted RPC vs the (biased) camera it models
  // The written RPC's pointing bias: pixel_rpc = centre + R(rotation) (pixel_true - centre) + shift,
  // centre = ((width-1)/2, (height-1)/2), pixel centres at integers.
  Eigen::Vector2d rpc_bias_shift_px = Eigen::Vector2d::Zero();
  double rpc_bias_rotation_deg = 0.0;
  double cloud_covered_fraction = 0.0;  // share of pixels behind clouds of opacity >= 0.5
};

struct SynthAoi {
  std::string name;
  double x0_m = 0, y0_m = 0;  // lower-left corner in the scene frame
  std::vector<SynthView> views;
};

struct SynthResult {
  City city;                      // the truth (without transient cars)
  double utm_easting0_m = 0;      // UTM of the scene frame's origin
  double utm_northing0_m = 0;
  int epsg = 0;
  GeodeticPoint enu_origin;       // origin of the ENU frame the cameras live in
  SceneFromEnu scene_from_enu;
  std::vector<SynthAoi> aois;
  StageReport report;
};

// Generates the city, renders every view and writes the tree under `root`.
SynthResult RunSynth(const SynthOptions& options, const std::string& root, Progress& progress);

// Truth images of the city `options` describes (the same options that wrote
// its tree) for any pinhole cameras given in an ENU frame at
// `cameras_origin` (e.g. the orbit cameras.json of the synthesis stage).
// Lit as image `lighting_view` (0-based) of the first AOI, without its cars.
// Writes, per camera, out_dir/<name>.png (RGB) and out_dir/<name>_mask.png
// (255 where the pixel sees the city inside its AOIs, 0 elsewhere: beyond
// them, or the sky). Returns the number of images written.
int RenderTruthViews(const SynthOptions& options,
                     const std::vector<std::pair<std::string, PinholeCamera>>& cameras,
                     const GeodeticPoint& cameras_origin, int lighting_view, const std::string& out_dir,
                     Progress& progress);

}  // namespace skyfall::synth
