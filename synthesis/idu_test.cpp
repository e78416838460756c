#include "synthesis/idu.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "splat/dataset.h"
#include "synthesis/orbit.h"
#include "synthesis/refiner.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

GroundBox Box(double x0, double y0, double x1, double y1) {
  GroundBox b;
  b.min_m = {x0, y0};
  b.max_m = {x1, y1};
  return b;
}

// Numerical tolerance of camera geometry built in double [m, deg, px].
constexpr double kGeometryTol = 1e-6;

TEST(Orbit, LookAtCameraSeesTheTargetAtThePrincipalPointFromTheOrbit) {
  const Eigen::Vector3d target(10, -5, 3);
  for (double elevation : {85.0, 60.0, 45.0}) {
    const auto ring = OrbitRing(target, 150.0, elevation, 6, 15.0, 60.0, 128, 96);
    ASSERT_EQ(ring.size(), 6u);
    for (const OrbitView& v : ring) {
      const Eigen::Vector2d uv = v.camera.Project(target);
      EXPECT_NEAR(uv.x(), v.camera.cx, kGeometryTol);
      EXPECT_NEAR(uv.y(), v.camera.cy, kGeometryTol);
      const Eigen::Vector3d eye = v.camera.Centre();
      EXPECT_NEAR((eye - target).norm(), 150.0, kGeometryTol);
      EXPECT_NEAR(std::asin((eye.z() - target.z()) / 150.0) * 180 / M_PI, elevation, kGeometryTol);
      // Azimuth clockwise from north: the camera stands at that bearing from the target.
      const double bearing = std::atan2(eye.x() - target.x(), eye.y() - target.y()) * 180 / M_PI;
      EXPECT_NEAR(std::remainder(bearing - v.azimuth_deg, 360.0), 0.0, kGeometryTol);
      // Up in the world is up in the image: a point above the target projects higher (smaller row).
      EXPECT_LT(v.camera.Project(target + Eigen::Vector3d(0, 0, 5)).y(), v.camera.cy);
      // Field of view across the width.
      EXPECT_NEAR(2 * std::atan(0.5 * 128 / v.camera.fx) * 180 / M_PI, 60.0, kGeometryTol);
    }
    EXPECT_NEAR(ring[1].azimuth_deg - ring[0].azimuth_deg, 60.0, kGeometryTol);
  }
}

TEST(Orbit, EpisodesDescendFromHighToLowAndLookAtAGridOnTheSurface) {
  OrbitOptions o;  // paper: 85 -> 45 deg over 5 episodes, radii 0.59 -> 0.49 of the side
  o.episodes = 5;
  const GroundBox core = Box(0, 0, 200, 200);
  const double expected[] = {85, 75, 65, 55, 45};
  for (int e = 0; e < 5; ++e) EXPECT_NEAR(EpisodeElevationDeg(o, e), expected[e], kGeometryTol);
  o.min_radius_m = 0;
  EXPECT_NEAR(EpisodeRadiusM(o, core, 0), 118.0, kGeometryTol);
  EXPECT_NEAR(EpisodeRadiusM(o, core, 4), 98.0, kGeometryTol);
  o.min_radius_m = 150;  // the floor for small tiles
  EXPECT_NEAR(EpisodeRadiusM(o, core, 4), 150.0, kGeometryTol);
  const auto grid = LookAtGrid(core, 3, [](double x, double y) { return x < 100 ? 0.1 * x + y * 0.0 : NAN; }, -7.0);
  ASSERT_EQ(grid.size(), 9u);
  EXPECT_NEAR(grid[0].x(), 200.0 / 6, kGeometryTol);
  EXPECT_NEAR(grid[0].y(), 200.0 / 6, kGeometryTol);
  EXPECT_NEAR(grid[0].z(), 20.0 / 6, kGeometryTol);   // on the surface
  EXPECT_NEAR(grid[8].z(), -7.0, kGeometryTol);       // no surface there: the fallback
  const auto views = EpisodeViews(o, core, grid, 2);
  ASSERT_EQ(views.size(), 9u * 6u);
  EXPECT_EQ(views[7].name, "e2_p1_v1");
  for (const OrbitView& v : views) EXPECT_NEAR(v.elevation_deg, 65.0, kGeometryTol);
  // Episodes turn their rings: the first view of point 0 differs between episodes.
  EXPECT_GT(std::abs(EpisodeViews(o, core, grid, 1)[0].azimuth_deg - EpisodeViews(o, core, grid, 0)[0].azimuth_deg), 1.0);
}

TEST(Dataset, CameraEntriesCarryTheSunWhenBothAnglesAreStated) {
  const std::string camera = R"("K": [[100, 0, 50], [0, 100, 40], [0, 0, 1]], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                  "t": [0, 0, 500], "width_px": 100, "height_px": 80)";
  const std::string text = R"({"images": [{"name": "a", )" + camera +
                           R"(, "acquisition_time": "2015-01-15T15:55:00Z", "sun_elevation_deg": 33.8,
                              "sun_azimuth_deg": 154.1}, {"name": "b", )" + camera +
                           R"(, "sun_elevation_deg": 40}, {"name": "c", )" + camera +
                           R"(, "sun_elevation_deg": null, "sun_azimuth_deg": null}]})";
  const std::vector<CameraEntry> entries = ParseCameraEntries(text, "cameras.json");
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_FALSE(entries[2].sun.known);  // null: not stated
  EXPECT_TRUE(entries[0].sun.known);
  EXPECT_DOUBLE_EQ(entries[0].sun.elevation_deg, 33.8);
  EXPECT_DOUBLE_EQ(entries[0].sun.azimuth_deg, 154.1);
  EXPECT_EQ(entries[0].acquisition_time, "2015-01-15T15:55:00Z");
  EXPECT_FALSE(entries[1].sun.known);  // one angle alone is no direction
  const std::string bad = R"({"images": [{"name": "a", )" + camera +
                          R"(, "sun_elevation_deg": "high", "sun_azimuth_deg": 10}]})";
  EXPECT_THROW(ParseCameraEntries(bad, "cameras.json"), Error);
}

TEST(Orbit, CamerasFileReadsBackAsCameras) {
  const fs::path dir = ScratchDir("orbit");
  const auto ring = OrbitRing({1, 2, 3}, 80.0, 50.0, 3, 0.0, 45.0, 64, 48);
  GeodeticPoint origin{-81.66, 30.35, 2.0};
  WriteFileAtomic((dir / "cameras.json").string(), OrbitCamerasJson(ring, origin));
  const auto back = ReadCameras((dir / "cameras.json").string());
  ASSERT_EQ(back.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(back[k].second.width_px, 64);
    EXPECT_LT((back[k].second.Centre() - ring[k].camera.Centre()).norm(), kGeometryTol);
  }
}

// A flat square of small opaque grey Gaussians at height z_m.
GaussianCloud Plane(double half_m, double spacing_m, double z_m) {
  GaussianCloud c;
  for (double y = -half_m; y <= half_m; y += spacing_m) {
    for (double x = -half_m; x <= half_m; x += spacing_m) {
      const std::size_t k = c.size();
      c.resize(k + 1);
      c.means[k] = Eigen::Vector3f(x, y, z_m);
      c.log_scales[k] = Eigen::Vector3f(std::log(0.6 * spacing_m), std::log(0.6 * spacing_m), std::log(0.05));
      c.rotations[k] = Eigen::Vector4f(1, 0, 0, 0);
      c.opacity_logits[k] = 5.0f;
      c.sh[k].fill(0.0f);
    }
  }
  return c;
}

// The ground colour the satellite photographs: smooth, so bilinear sampling is exact to ~1e-3.
Eigen::Vector3f GroundColour(double x, double y) {
  return {0.5f + 0.3f * static_cast<float>(std::sin(x / 4.0)), 0.5f + 0.3f * static_cast<float>(std::cos(y / 5.0)),
          0.4f};
}

TrainView NadirSatellite(double gsd_m, int size_px) {
  TrainView v;
  v.name = "sat";
  v.camera = NadirCamera({0, 0, 0}, gsd_m, size_px, 5.0e5);
  const Eigen::Matrix3d K_inv = v.camera.K().inverse(), R_t = v.camera.cam_from_world_rotation.transpose();
  for (int y = 0; y < size_px; ++y) {
    for (int x = 0; x < size_px; ++x) {
      const Eigen::Vector3d ray = R_t * (K_inv * Eigen::Vector3d(x, y, 1));
      const Eigen::Vector3d eye = v.camera.Centre();
      const Eigen::Vector3d ground = eye + ray * (-eye.z() / ray.z());
      const Eigen::Vector3f c = GroundColour(ground.x(), ground.y());
      v.rgb.insert(v.rgb.end(), {c.x(), c.y(), c.z()});
    }
  }
  return v;
}

RefineInput Render(const GaussianCloud& scene, const OrbitView& view) {
  RasterOptions raster;
  raster.median_depth = true;
  const RenderOutput<float> r = RenderGaussians(scene, view.camera, raster);
  RefineInput in;
  in.name = view.name.empty() ? "v" + std::to_string(view.view) : view.name;
  in.camera = view.camera;
  in.rgb = r.rgb;
  in.depth_m.assign(r.alpha.size(), NAN);
  for (std::size_t k = 0; k < r.alpha.size(); ++k)
    if (r.alpha[k] > 0.5f) in.depth_m[k] = r.median_depth[k] + static_cast<float>(r.reference_depth_m);
  in.elevation_deg = view.elevation_deg;
  in.azimuth_deg = view.azimuth_deg;
  return in;
}

// Colour error the reprojection may leave on a smooth texture: bilinear
// sampling at 0.25 m pixels and the depth of a 5 cm thick Gaussian layer.
constexpr float kReprojectColourTol = 0.03f;

TEST(ReprojectRefiner, PaintsOrbitPixelsWithTheColourTheSatelliteSawThere) {
  const GaussianCloud plane = Plane(30.0, 0.5, 0.0);
  const std::vector<TrainView> satellite = {NadirSatellite(0.25, 256)};
  ReprojectOptions o;
  o.smooth_diameter_px = 0;
  o.keep_probability = 1.0;
  o.weight_jitter = 0.0;
  ReprojectRefiner refiner(satellite, o);
  const auto ring = OrbitRing({0, 0, 0}, 40.0, 55.0, 2, 30.0, 40.0, 64, 64);
  std::vector<RefineInput> inputs = {Render(plane, ring[0]), Render(plane, ring[1])};
  NullProgress quiet;
  RefineRequest request;
  request.samples = 2;
  const auto refined = refiner.Refine(plane, inputs, request, quiet);
  ASSERT_EQ(refined.size(), 2u);
  for (std::size_t v = 0; v < 2; ++v) {
    ASSERT_EQ(refined[v].size(), 2u);
    const PinholeCamera& cam = inputs[v].camera;
    const Eigen::Matrix3d K_inv = cam.K().inverse(), R_t = cam.cam_from_world_rotation.transpose();
    double worst = 0;
    int checked = 0;
    for (int y = 4; y < 60; ++y) {
      for (int x = 4; x < 60; ++x) {
        const std::size_t p = static_cast<std::size_t>(y) * 64 + x;
        if (!std::isfinite(inputs[v].depth_m[p])) continue;
        // Where the orbit ray meets the plane z = 0.
        const Eigen::Vector3d ray = R_t * (K_inv * Eigen::Vector3d(x, y, 1)), eye = cam.Centre();
        const Eigen::Vector3d ground = eye + ray * (-eye.z() / ray.z());
        if (std::abs(ground.x()) > 25 || std::abs(ground.y()) > 25) continue;
        const Eigen::Vector3f truth = GroundColour(ground.x(), ground.y());
        for (int c = 0; c < 3; ++c) worst = std::max<double>(worst, std::abs(refined[v][0][3 * p + c] - truth[c]));
        ++checked;
      }
    }
    EXPECT_GT(checked, 1000);
    EXPECT_LT(worst, kReprojectColourTol);
    // The render itself is grey (0.5): the refiner changed it (green at the look-at point is 0.8).
    EXPECT_GT(std::abs(inputs[v].rgb[3 * (32 * 64 + 32) + 1] - refined[v][0][3 * (32 * 64 + 32) + 1]), 0.2f);
  }
}

TEST(Idu, SatelliteViewsOfAnotherDateTakeTheScenesAppearance) {
  // The scene: a plane whose colours vary per channel. A satellite view of
  // "another date": the same image with each channel's gain and offset
  // changed (clamped nowhere). Matched, it returns to the scene's colours;
  // a view that barely sees the scene keeps its own.
  GaussianCloud plane = Plane(30.0, 0.5, 0.0);
  for (std::size_t k = 0; k < plane.size(); ++k) {
    const float x = plane.means[k].x(), y = plane.means[k].y();
    const Eigen::Vector3f c = GroundColour(x, y) + Eigen::Vector3f(0, 0, 0.2f * std::sin((x + y) / 6.0f));
    for (int ch = 0; ch < 3; ++ch) plane.sh[k][ch * kShCoeffsPerChannel] = static_cast<float>((c[ch] - 0.5) / kShC0);
  }
  RasterOptions raster;
  TrainView seen = NadirSatellite(0.25, 96);
  const RenderOutput<float> scene = RenderGaussians(plane, seen.camera, raster);
  const float gain[3] = {0.6f, 1.3f, 0.8f}, offset[3] = {0.1f, -0.1f, 0.15f};
  seen.rgb = scene.rgb;
  for (std::size_t p = 0; p < seen.rgb.size(); ++p) seen.rgb[p] = gain[p % 3] * seen.rgb[p] + offset[p % 3];
  TrainView aside = seen;
  aside.camera = NadirCamera({200, 0, 0}, 0.25, 96, 5.0e5);  // 200 m east: the plane is not in view
  const std::vector<TrainView> matched = MatchSceneAppearance(plane, {seen, aside}, raster);
  ASSERT_EQ(matched.size(), 2u);
  float worst = 0;
  for (std::size_t p = 0; p < scene.rgb.size(); ++p)
    if (scene.alpha[p / 3] > 0.5f) worst = std::max(worst, std::abs(matched[0].rgb[p] - scene.rgb[p]));
  EXPECT_LT(worst, 1e-4f);  // an exact affine change: recovered to float rounding
  EXPECT_EQ(matched[1].rgb, aside.rgb);
}

TEST(ReprojectRefiner, InpaintsWhatNoSatelliteSeesAndRejectsBadOptions) {
  const GaussianCloud plane = Plane(30.0, 0.5, 0.0);
  // The satellite sees only the middle 16 x 16 m: the rest of the orbit view must be inpainted.
  std::vector<TrainView> satellite = {NadirSatellite(0.25, 64)};
  for (std::size_t k = 0; k < satellite[0].rgb.size(); ++k) satellite[0].rgb[k] = k % 3 == 1 ? 0.9f : 0.2f;  // green
  ReprojectOptions o;
  o.smooth_diameter_px = 0;
  const auto ring = OrbitRing({0, 0, 0}, 40.0, 70.0, 1, 0.0, 50.0, 64, 64);
  NullProgress quiet;
  ReprojectRefiner refiner(satellite, o);
  const RefineInput in = Render(plane, ring[0]);
  const auto refined = refiner.Refine(plane, {in}, RefineRequest{}, quiet);
  // A corner no satellite view sees takes the colours of the seen middle by
  // inpainting, not the grey (0.5) render: green there is 0.9, to the 8-bit
  // steps inpainting works in plus the few levels Telea's gradient term adds.
  EXPECT_NEAR(refined[0][0][3 * (2 * 64 + 2) + 1], 0.9f, 4.0f / 255);
  o.inpaint = Inpaint::kRender;
  const auto kept = ReprojectRefiner(satellite, o).Refine(plane, {in}, RefineRequest{}, quiet);
  EXPECT_NEAR(kept[0][0][3 * (2 * 64 + 2) + 1], in.rgb[3 * (2 * 64 + 2) + 1], 1e-6);
  EXPECT_FALSE(EnumFromName<Inpaint>("fill"));  // no such mode can be asked for
  o.inpaint = Inpaint::kTelea;
  o.keep_probability = 0.0;
  EXPECT_THROW(ReprojectRefiner(satellite, o), Error);
}

TEST(CommandRefiner, DrivesAnExternalProgramThroughTheFolderProtocol) {
  const fs::path dir = ScratchDir("cmd");
  const fs::path script = dir / "refine.sh";
  // A stand-in for a FlowEdit script: checks the request, then writes each
  // render, inverted by ImageMagick-free means (a copy), as every sample.
  std::ofstream(script) << "#!/bin/sh\nset -e\nin=$1; out=$2\n"
                           "grep -q '\"target_prompt\"' \"$in/request.json\"\n"
                           "grep -q '\"n_max\": 10' \"$in/request.json\"\n"
                           "for f in \"$in\"/*.png; do b=$(basename \"$f\" .png); cp \"$f\" \"$out/${b}_s0.png\"; "
                           "cp \"$f\" \"$out/${b}_s1.png\"; done\n";
  fs::permissions(script, fs::perms::owner_all);
  const GaussianCloud plane = Plane(10.0, 0.5, 0.0);
  const auto ring = OrbitRing({0, 0, 0}, 30.0, 60.0, 2, 0.0, 50.0, 32, 24);
  std::vector<RefineInput> inputs = {Render(plane, ring[0]), Render(plane, ring[1])};
  inputs[1].name = "second";
  CommandRefiner refiner(script.string(), (dir / "work").string());
  NullProgress quiet;
  RefineRequest request;
  request.episode = 3;
  const auto refined = refiner.Refine(plane, inputs, request, quiet);
  ASSERT_EQ(refined.size(), 2u);
  ASSERT_EQ(refined[1].size(), 2u);
  // The copy comes back as the render, to 8-bit quantization.
  for (std::size_t k = 0; k < inputs[1].rgb.size(); ++k) ASSERT_NEAR(refined[1][1][k], inputs[1].rgb[k], 0.5 / 255 + 1e-6);
  const auto request_json = nlohmann::json::parse(ReadTextFile((dir / "work/episode_3/in/request.json").string()));
  EXPECT_EQ(request_json.at("views").size(), 2u);
  EXPECT_EQ(request_json.at("views")[1].at("seeds")[1].get<std::uint64_t>(), SampleSeed(request, 1, 1));
  EXPECT_DOUBLE_EQ(request_json.at("views")[0].at("elevation_deg").get<double>(), 60.0);

  // A refiner that writes nothing: the error names the missing file.
  std::ofstream(dir / "lazy.sh") << "#!/bin/sh\nexit 0\n";
  fs::permissions(dir / "lazy.sh", fs::perms::owner_all);
  CommandRefiner lazy((dir / "lazy.sh").string(), (dir / "work2").string());
  try {
    lazy.Refine(plane, inputs, request, quiet);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("v0_s0.png"), std::string::npos) << e.what();
  }
  // A failing refiner: the error names the command.
  CommandRefiner failing("false", (dir / "work3").string());
  EXPECT_THROW(failing.Refine(plane, inputs, request, quiet), Error);
  EXPECT_THROW(MakeRefiner("flowedit", {}, {}, dir.string(), "idu.refiner"), Error);
}

// Dense cells on a 0.5 m grid over 60 x 60 m with heights from `height`.
void Cells(const std::function<double(double, double)>& height, std::vector<Eigen::Vector3f>* points,
           std::vector<std::uint8_t>* filled, double filled_share = 0.0) {
  int k = 0;
  for (double y = 0; y < 60; y += 0.5)
    for (double x = 0; x < 60; x += 0.5, ++k) {
      points->emplace_back(x, y, height(x, y));
      filled->push_back((k % 100) < filled_share * 100);
    }
}

TEST(IduAuto, SkipsFlatEmptyAndUnmeasuredTilesAndRunsOnTallBuildings) {
  IduAutoOptions o;
  std::vector<Eigen::Vector3f> flat, tall, water;
  std::vector<std::uint8_t> flat_f, tall_f, water_f;
  // Flat ground with 0.3 m noise and 1.5 m garden sheds: no facade of 3 m.
  Cells([](double x, double y) { return 0.3 * std::sin(7 * x) * std::cos(5 * y) + ((int(x / 10) + int(y / 10)) % 4 == 0 && std::fmod(x, 10) < 3 ? 1.5 : 0.0); },
        &flat, &flat_f);
  const IduDecision d_flat = DecideIdu(Switch::kAuto, o, flat, flat_f, 0.5);
  EXPECT_FALSE(d_flat.on) << d_flat.why;
  EXPECT_NE(d_flat.why.find("flat or low-rise"), std::string::npos) << d_flat.why;
  EXPECT_LT(d_flat.facade_ratio, o.min_facade_ratio);
  // A 40 m tower of 20 x 20 m: 4 x 20 x 40 = 3200 m2 of facade over 3600 m2.
  Cells([](double x, double y) { return x >= 20 && x < 40 && y >= 20 && y < 40 ? 40.0 : 0.0; }, &tall, &tall_f);
  const IduDecision d_tall = DecideIdu(Switch::kAuto, o, tall, tall_f, 0.5);
  EXPECT_TRUE(d_tall.on) << d_tall.why;
  EXPECT_NEAR(d_tall.facade_ratio, 3200.0 / 3600.0, 0.05);
  // Water: almost every cell filled rather than measured.
  Cells([](double, double) { return 0.0; }, &water, &water_f, 0.99);
  const IduDecision d_water = DecideIdu(Switch::kAuto, o, water, water_f, 0.5);
  EXPECT_FALSE(d_water.on);
  EXPECT_NE(d_water.why.find("measured"), std::string::npos) << d_water.why;
  EXPECT_FALSE(DecideIdu(Switch::kAuto, o, {}, {}, 0.5).on);
  EXPECT_TRUE(DecideIdu(Switch::kOn, o, {}, {}, 0.5).on);
  EXPECT_FALSE(DecideIdu(Switch::kOff, o, tall, tall_f, 0.5).on);
  EXPECT_FALSE(EnumFromName<Switch>("sometimes"));  // a mode that is none of the three cannot be asked for
}

// A refiner that fails in one episode, as a killed run would stop there.
class FailingRefiner final : public Refiner {
 public:
  FailingRefiner(Refiner& inner, int fail_episode) : inner_(inner), fail_episode_(fail_episode) {}
  std::vector<RefinedSamples> Refine(const GaussianCloud& scene, const std::vector<RefineInput>& views,
                                     const RefineRequest& request, Progress& progress) override {
    if (request.episode == fail_episode_) throw std::runtime_error("killed");
    return inner_.Refine(scene, views, request, progress);
  }

 private:
  Refiner& inner_;
  int fail_episode_;
};

IduOptions TinyIdu() {
  IduOptions o;
  o.orbit.grid = 1;
  o.orbit.views_per_point = 2;
  o.orbit.episodes = 2;
  o.orbit.width_px = o.orbit.height_px = 32;
  o.orbit.min_radius_m = 0;  // orbits of 0.59 -> 0.49 x 32 m around the 40 m plane
  o.iterations_per_episode = 6;
  o.densify = false;
  return o;
}

TEST(Idu, EpisodesCheckpointAndAKilledRunResumesAfterTheLastFinishedOne) {
  const fs::path dir = ScratchDir("idu");
  const GaussianCloud plane = Plane(20.0, 1.0, 0.0);
  std::vector<TrainView> satellite = {NadirSatellite(0.5, 64)};
  ReprojectRefiner reproject(satellite, ReprojectOptions{});
  TrainOptions train;
  train.surface.lambda_depth = train.surface.lambda_alpha = 0;
  const IduOptions o = TinyIdu();
  const GroundBox core = Box(-16, -16, 16, 16);
  auto flat = [](double, double) { return 0.0; };
  NullProgress quiet;
  FailingRefiner killed(reproject, 1);
  EXPECT_THROW(RunIdu(o, train, plane, satellite, core, {}, flat, nullptr, killed, dir.string(), "A", quiet),
               std::runtime_error);
  EXPECT_TRUE(fs::exists(dir / "episode_0" / "episode.json"));
  EXPECT_TRUE(fs::exists(dir / "episode_0" / "refined" / "e0_p0_v1.png"));
  EXPECT_FALSE(fs::exists(dir / "episode_1" / "episode.json"));
  const std::string episode0 = ReadTextFile((dir / "episode_0" / "scene.ply").string());

  const IduResult resumed = RunIdu(o, train, plane, satellite, core, {}, flat, nullptr, reproject, dir.string(), "A", quiet);
  ASSERT_EQ(resumed.episodes.size(), 2u);
  EXPECT_TRUE(resumed.episodes[0].reused);
  EXPECT_FALSE(resumed.episodes[1].reused);
  EXPECT_EQ(ReadTextFile((dir / "episode_0" / "scene.ply").string()), episode0);  // not redone
  EXPECT_NEAR(resumed.episodes[1].elevation_deg, 45.0, kGeometryTol);
  EXPECT_GT(resumed.episodes[1].refined_coverage, 0.5);

  // Changed options: the old episodes are discarded, not mixed in.
  const IduResult fresh = RunIdu(o, train, plane, satellite, core, {}, flat, nullptr, reproject, dir.string(), "B", quiet);
  EXPECT_FALSE(fresh.episodes[0].reused);
}

TEST(Idu, HolesWhereTheHeightFieldHasASurfaceGetGaussiansOfTheRefinedColour) {
  // The plane with a 10 m square hole; the height field (the dense heights)
  // covers the whole plane, and the satellite saw the ground there.
  const GaussianCloud plane = Plane(20.0, 1.0, 0.0);
  GaussianCloud holed;
  for (std::size_t i = 0; i < plane.size(); ++i)
    if (std::abs(plane.means[i].x()) > 5 || std::abs(plane.means[i].y()) > 5) holed.Append(plane, i);
  std::vector<Eigen::Vector3f> ground;
  for (float y = -19.75f; y < 20; y += 0.5f)
    for (float x = -19.75f; x < 20; x += 0.5f) ground.emplace_back(x, y, 0.0f);
  const SurfaceDepthPrior surface(ground, 0.5);
  std::vector<TrainView> satellite = {NadirSatellite(0.5, 64)};
  ReprojectRefiner reproject(satellite, ReprojectOptions{}, RasterOptions{}, &surface);
  TrainOptions train;
  train.surface.lambda_depth = train.surface.lambda_alpha = 0;
  IduOptions o = TinyIdu();
  o.orbit.episodes = 1;
  o.fill_voxel_m = 1.0;
  const GroundBox core = Box(-16, -16, 16, 16);
  auto flat = [](double, double) { return 0.0; };
  NullProgress quiet;
  const PinholeCamera hole_view = NadirCamera({0, 0, 0}, 0.5, 16, 5.0e5);  // 8 m, inside the hole
  auto mean_alpha = [&](const GaussianCloud& c) {
    const RenderOutput<float> r = RenderGaussians(c, hole_view, RasterOptions{});
    double sum = 0;
    for (float a : r.alpha) sum += a;
    return sum / static_cast<double>(r.alpha.size());
  };
  ASSERT_LT(mean_alpha(holed), 0.05);

  const IduResult filled = RunIdu(o, train, holed, satellite, core, {}, flat, &surface, reproject,
                                  ScratchDir("idu_fill").string(), "A", quiet);
  ASSERT_EQ(filled.episodes.size(), 1u);
  const std::size_t added = filled.episodes[0].hole_gaussians;
  EXPECT_GT(added, 50u);  // the hole is 100 m^2 of 1 m cubes
  EXPECT_EQ(filled.cloud.size(), holed.size() + added);
  EXPECT_GT(mean_alpha(filled.cloud), 0.5);
  // The added Gaussians: in the hole (its rim included: a plane's border
  // renders less than opaque too), on the ground, of the ground's colour.
  // Training reorders the cloud (spatially), so they are told by place:
  // the box 1 m around the hole gained at least 80% of them, and every
  // Gaussian well inside the hole (where the holed plane had none) is one.
  auto in_box = [](const GaussianCloud& c, float half_m) {
    std::vector<std::size_t> inside;
    for (std::size_t i = 0; i < c.size(); ++i)
      if (std::abs(c.means[i].x()) < half_m && std::abs(c.means[i].y()) < half_m) inside.push_back(i);
    return inside;
  };
  EXPECT_GE(in_box(filled.cloud, 6).size(), in_box(holed, 6).size() + added * 8 / 10);
  ASSERT_TRUE(in_box(holed, 4.5f).empty());
  const std::vector<std::size_t> inner = in_box(filled.cloud, 4.5f);
  ASSERT_GE(inner.size(), added / 3);
  double colour_error = 0;
  for (std::size_t i : inner) {
    const Eigen::Vector3f m = filled.cloud.means[i];
    EXPECT_NEAR(m.z(), 0.0, 0.3) << i;
    const Eigen::Vector3f truth = GroundColour(m.x(), m.y());
    for (int c = 0; c < 3; ++c)
      colour_error += std::abs(kShC0 * filled.cloud.sh[i][c * kShCoeffsPerChannel] + 0.5 - truth[c]) / (3.0 * inner.size());
  }
  EXPECT_LT(colour_error, 0.1);  // trained a few steps from the refined colour: smoothing, inpainting
  // Discs in the ground's plane (a tenth as thick as wide when added), not
  // balls: their thinnest axis stays near vertical.
  std::size_t discs = 0;
  for (std::size_t i : inner) {
    const Eigen::Vector4f q = filled.cloud.rotations[i].normalized();
    const Eigen::Matrix3f R = Eigen::Quaternionf(q[0], q[1], q[2], q[3]).toRotationMatrix();
    const Eigen::Vector3f& s = filled.cloud.log_scales[i];
    int thin = 0;
    s.minCoeff(&thin);
    if (std::abs(R.col(thin).z()) > 0.9f && s[thin] < s.maxCoeff() - std::log(3.0f)) ++discs;
  }
  EXPECT_GE(discs, inner.size() * 9 / 10);

  o.fill_holes = false;
  const IduResult unfilled = RunIdu(o, train, holed, satellite, core, {}, flat, &surface, reproject,
                                    ScratchDir("idu_nofill").string(), "A", quiet);
  EXPECT_EQ(unfilled.episodes[0].hole_gaussians, 0u);
  EXPECT_LT(mean_alpha(unfilled.cloud), 0.05);
}

}  // namespace
}  // namespace skyfall
