// Training data from an SfM folder: cameras.json + the source images, and
// the coloured tie points of points.ply.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "splat/trainer.h"

namespace skyfall {

// Loads every used image of cameras.json, box-downscaled by `downscale`
// (1 = full resolution), with the camera scaled to match. Images whose
// cameras.json "split" is "test" are held out.
std::vector<TrainView> LoadTrainViews(const std::string& sfm_dir, int downscale);

// Reads the ASCII points.ply written by `skyfall sfm` (ENU, colour 0-255).
void ReadSfmPoints(const std::string& path, std::vector<Eigen::Vector3f>* points,
                   std::vector<Eigen::Vector3f>* colours_01);

// Initial points from dense heights: the first dense point in each
// spacing_m x spacing_m cell (horizontal), then every extra point (tie
// points) whose cell no dense point reached, so holes keep their tie points.
// `keep_all` (optional, one per dense point): points kept whatever their
// cell (first, at the dense grid's own spacing); their spacing_m cells are
// then taken for the others.
void ThinToGrid(double spacing_m, const std::vector<Eigen::Vector3f>& dense,
                const std::vector<Eigen::Vector3f>& dense_colours, const std::vector<Eigen::Vector3f>& extra,
                const std::vector<Eigen::Vector3f>& extra_colours, std::vector<Eigen::Vector3f>* points,
                std::vector<Eigen::Vector3f>* colours, const std::vector<std::uint8_t>* keep_all = nullptr);

// Points on the walls of a height grid (`grid_points`, one per cell of
// `cell_m`, ENU): where a cell stands at least `min_step_m` above a
// neighbour, a column of points on their shared edge from the lower height
// to the upper one, every `spacing_m` up and along the wall, coloured like
// the lower cell. The Gaussians of a height grid hold roofs and ground but
// no walls; started without them, training pulls the roofs' edge Gaussians
// down to paint the walls that oblique views show.
// `normal_axis` gets, per point, the ENU axis its wall faces (0: east-west,
// 1: north-south).
void FacadePoints(const std::vector<Eigen::Vector3f>& grid_points, const std::vector<Eigen::Vector3f>& colours_01,
                  double cell_m, double spacing_m, double min_step_m, std::vector<Eigen::Vector3f>* points,
                  std::vector<Eigen::Vector3f>* colours, std::vector<int>* normal_axis);

// One used image of cameras.json.
struct CameraEntry {
  std::string name;
  PinholeCamera camera;
  std::string source_image;      // the pixels the camera describes
  bool held_out = false;         // "split": "test"
  std::string acquisition_time;  // empty when unknown
  SunDirection sun;              // unknown unless cameras.json states both angles
  Radiometry radiometry;         // how the source image's pixels are read (not measured: measured on read)
};

// The used images of cameras.json, in file order; throws Error naming the
// file for invalid JSON or an entry without a camera or source image.
std::vector<CameraEntry> ReadCameraEntries(const std::string& cameras_json);
// The same from the file's text; `subject` names it in errors.
std::vector<CameraEntry> ParseCameraEntries(const std::string& text, const std::string& subject);

// The origin of the ENU frame a cameras.json's cameras live in ("frame":
// {"origin": ...}); throws Error naming the file when it has none.
GeodeticPoint ReadCamerasFrameOrigin(const std::string& cameras_json);

// Cameras of cameras.json (used images), by name, for rendering.
std::vector<std::pair<std::string, PinholeCamera>> ReadCameras(const std::string& cameras_json);

// A camera for an image `downscale` times smaller (pixel centres at integers).
PinholeCamera DownscaledCamera(const PinholeCamera& camera, int downscale);

}  // namespace skyfall
