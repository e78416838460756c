#include "splat/trainer.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <random>

#include "splat/dataset.h"
#include "splat/optimizer_state.h"
#include "testcity/testcity.h"
#include "tests/test_support.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// A small synthetic city with its true cameras as training views, and
// Gaussians seeded on its true surface (standing in for SfM points).
struct Fixture {
  std::vector<TrainView> views;
  GaussianCloud init;
};

Fixture MakeFixture(int downscale) {
  synth::SynthOptions o;
  o.size_m = 96;
  o.views = 5;
  o.seed = 9;
  NullProgress progress;
  const fs::path root = ScratchDir("synth");
  const synth::SynthResult scene = synth::RunSynth(o, root.string(), progress);
  Fixture f;
  for (size_t v = 0; v < scene.aois[0].views.size(); ++v) {
    const synth::SynthView& sv = scene.aois[0].views[v];
    PinholeCamera cam;
    cam.fx = cam.fy = sv.camera.focal_px;
    cam.cx = sv.camera.principal_px.x();
    cam.cy = sv.camera.principal_px.y();
    cam.cam_from_world_rotation = sv.camera.cam_from_enu;
    cam.cam_from_world_translation = -sv.camera.cam_from_enu * sv.camera.centre_enu_m;
    cam.width_px = sv.camera.width_px;
    cam.height_px = sv.camera.height_px;
    TrainView tv;
    tv.name = sv.name;
    tv.held_out = v == 1;
    tv.camera = DownscaledCamera(cam, downscale);
    const FloatImage img = ReadFloatImage(sv.path);
    const int w = tv.camera.width_px, h = tv.camera.height_px;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c)
          tv.rgb.push_back(img.values[(static_cast<size_t>(y * downscale) * img.width_px + x * downscale) * 3 + c] / 255.0f);
    f.views.push_back(std::move(tv));
  }
  // Points on the true height field (scene frame = ENU up to millimetres
  // over this area, see SceneFromEnu), grey.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-20.0, 116.0);
  std::vector<Eigen::Vector3f> points, colours;
  const synth::SceneFromEnu& m = scene.scene_from_enu;
  const Eigen::Matrix3d enu_from_scene = m.linear.inverse();
  for (int k = 0; k < 3000; ++k) {
    const double x = u(rng), y = u(rng);
    const Eigen::Vector3d s(x, y, scene.city.HeightAt(x, y));
    points.push_back((enu_from_scene * (s - m.offset_m)).cast<float>());
    colours.emplace_back(0.4f, 0.4f, 0.4f);
  }
  f.init = InitializeFromPoints(points, colours);
  return f;
}

// Training-view PSNR gain the appearance model must bring on views with
// per-date gains; see AppearanceModelAbsorbsPerDateBrightness for the figures.
constexpr double kAppearanceGainDb = 1.0;

TrainOptions ShortRun(int iterations) {
  TrainOptions o;
  o.iterations = iterations;
  o.density.from_step = 40;
  o.density.interval_steps = 40;
  o.density.until_step = 120;
  o.opacity_reg_from = 80;
  o.eval_interval = 50;
  o.checkpoint_interval = 30;
  return o;
}

TEST(Trainer, HeldOutPsnrRises) {
  const Fixture f = MakeFixture(2);
  NullProgress progress;
  // Photometric optimization alone: on this 4-view scene, densification and
  // the entropy term lower held-out PSNR in a 200-iteration run (measured:
  // 19.1 dB without, 17.4 with densification, 14.6 with entropy from 80).
  TrainOptions o = ShortRun(200);
  o.density.from_step = o.iterations + 1;
  o.lambda_opacity = 0;
  const TrainResult r = TrainGaussians(o, f.init, f.views, "", progress);
  ASSERT_GE(r.series.size(), 3u);
  const double before = r.series.front().psnr_test_db, after = r.series.back().psnr_test_db;
  std::printf("[figures] synthetic 200 iterations: held-out PSNR %.2f -> %.2f dB, %zu -> %zu Gaussians, %.1f s\n",
              before, after, f.init.size(), r.cloud.size(), r.report.seconds);
  EXPECT_GT(after, before + 2.0);
  EXPECT_EQ(r.series.front().iteration, 0);
  EXPECT_EQ(r.series.back().iteration, 200);
}

TEST(Trainer, DensificationGrowsAndPrunes) {
  Fixture f = MakeFixture(4);
  // Two Gaussians away from every view, so only pruning can change them: a
  // transparent one and a huge one (> max_scale_m).
  GaussianCloud extra = InitializeFromPoints({{500, 500, 0}, {-500, -500, 0}}, {{0.5f, 0.5f, 0.5f}, {0.5f, 0.5f, 0.5f}});
  extra.opacity_logits[0] = -10.0f;
  extra.log_scales[1] = Eigen::Vector3f::Constant(std::log(50.0f));
  for (size_t i = 0; i < 2; ++i) {
    f.init.means.push_back(extra.means[i]);
    f.init.log_scales.push_back(extra.log_scales[i]);
    f.init.rotations.push_back(extra.rotations[i]);
    f.init.opacity_logits.push_back(extra.opacity_logits[i]);
    f.init.sh.push_back(extra.sh[i]);
  }
  NullProgress progress;
  TrainOptions o = ShortRun(121);
  o.lambda_opacity = 0;
  const TrainResult r = TrainGaussians(o, f.init, f.views, "", progress);
  EXPECT_GT(r.cloud.size(), f.init.size());  // clones and splits
  for (size_t i = 0; i < r.cloud.size(); ++i) {
    EXPECT_GT(r.cloud.means[i].norm(), 0.0f);
    EXPECT_LT(r.cloud.means[i].head<2>().cwiseAbs().maxCoeff(), 400.0f) << "a pruned Gaussian survived";
  }
}

// A Gaussian with one NaN or infinite gradient component (any field, its
// colour transform's included) loses its whole update; the others keep theirs.
TEST(Trainer, DropNonFiniteGradientsZeroesOnlyTheAffectedGaussians) {
  GaussianGradients<float> gradients;
  gradients.d = InitializeFromPoints({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}},
                                     std::vector<Eigen::Vector3f>(5, Eigen::Vector3f(0.5f, 0.5f, 0.5f)));
  gradients.d_colour_affine.assign(5, ColourAffine<float>::Constant(0.4f));
  gradients.d_colour_affine[2](1) = std::numeric_limits<float>::quiet_NaN();
  GaussianCloud& g = gradients.d;
  for (std::size_t i = 0; i < g.size(); ++i) {
    g.means[i].setConstant(0.1f);
    g.sh[i].fill(0.2f);
    g.opacity_logits[i] = 0.3f;
  }
  g.means[1].y() = std::numeric_limits<float>::quiet_NaN();
  g.sh[3][5] = std::numeric_limits<float>::infinity();
  g.opacity_logits[4] = -std::numeric_limits<float>::infinity();
  EXPECT_EQ(DropNonFiniteGradients(&gradients), 4u);
  for (std::size_t i : {1, 2, 3, 4}) {
    EXPECT_TRUE(gradients.d_colour_affine[i].isZero()) << i;
    EXPECT_TRUE(g.means[i].isZero() && g.log_scales[i].isZero() && g.rotations[i].isZero()) << i;
    EXPECT_EQ(g.opacity_logits[i], 0.0f) << i;
    EXPECT_EQ(g.sh[i][5], 0.0f) << i;
  }
  for (std::size_t i : {0}) {
    EXPECT_EQ(gradients.d_colour_affine[i], ColourAffine<float>::Constant(0.4f));
    EXPECT_EQ(g.means[i], Eigen::Vector3f::Constant(0.1f)) << i;
    EXPECT_EQ(g.sh[i][5], 0.2f) << i;
    EXPECT_EQ(g.opacity_logits[i], 0.3f) << i;
  }
  EXPECT_EQ(DropNonFiniteGradients(&gradients), 0u);
  gradients.d_colour_affine.clear();  // rendered without a colour transform
  g.rotations[0].x() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(DropNonFiniteGradients(&gradients), 1u);
}

TEST(Trainer, CoincidentGaussiansCountsCentresWithinTheRadius) {
  GaussianCloud c;
  c.resize(6);
  c.means = {{0, 0, 0}, {0.004f, 0.003f, 0}, {1, 1, 1},  // the first two are 5 mm apart
             {2.009f, 0, 0}, {2.0f, 0, 0},              // 9 mm, across a cube's face at 2.00
             {5, 5, 0.02f}};                            // alone (2 cm from nothing)
  EXPECT_EQ(CoincidentGaussians(c, 0.01), 4u);
  EXPECT_EQ(CoincidentGaussians(c, 0.004), 0u);  // 5 and 9 mm are not within 4 mm
  EXPECT_EQ(CoincidentGaussians(c, 2.0), 5u);    // all but the far one (1.73 m and 1.41 m apart)
  EXPECT_EQ(CoincidentGaussians(GaussianCloud{}, 0.01), 0u);
  EXPECT_THROW(CoincidentGaussians(c, 0.0), Error);
}

// Every Gaussian twice: the copies get the same gradients, so they stay
// together until the first merge makes them one again.
TEST(Trainer, CopiesAreMergedDuringTraining) {
  Fixture f = MakeFixture(4);
  const std::size_t originals = f.init.size();
  for (std::size_t i = 0; i < originals; ++i) f.init.Append(f.init, i);
  NullProgress progress;
  TrainOptions o = ShortRun(101);
  o.density.from_step = o.iterations + 1;
  o.density.merge_interval_steps = 50;
  o.lambda_opacity = 0;
  const TrainResult merged = TrainGaussians(o, f.init, f.views, "", progress);
  o.density.merge_within_m = 0;
  const TrainResult kept = TrainGaussians(o, f.init, f.views, "", progress);
  std::printf("[figures] %zu Gaussians twice: %zu after merging (%zu coincident), held-out PSNR %.2f dB (%.2f dB "
              "without merging)\n",
              originals, merged.cloud.size(), CoincidentGaussians(merged.cloud, 0.01),
              merged.series.back().psnr_test_db, kept.series.back().psnr_test_db);
  EXPECT_LE(merged.cloud.size(), originals);
  EXPECT_EQ(kept.cloud.size(), 2 * originals);
  // One opaque Gaussian for two half as opaque ones renders the same at its
  // centre and close to it elsewhere; 0.3 dB is a tenth of what 100 steps gain.
  EXPECT_GT(merged.series.back().psnr_test_db, kept.series.back().psnr_test_db - 0.3);
}

TEST(Trainer, KilledRunResumesBitIdentically) {
  const Fixture f = MakeFixture(4);
  NullProgress progress;
  // With pseudo-camera depth supervision on, which must also resume exactly.
  SurfaceDepthPrior prior(f.init.means, 4.0);
  const auto run = [&](const std::string& dir, Progress& p) {
    TrainOptions o = ShortRun(90);
    o.pseudo_interval = 7;
    o.appearance.enabled = true;  // its embeddings, MLP and moments must resume too
    o.pseudo.size_px = 32;
    o.surface_at = 0.5;           // kept at step 45, before the kill: read back on resuming
    o.lr.scale_late = 0.012;
    return TrainGaussians(o, f.init, f.views, dir, p, &prior);
  };
  const TrainResult straight = run("", progress);
  const fs::path ck = ScratchDir("ck");
  // The same run killed right after its checkpoint at iteration 60...
  struct Killer : Progress {
    void Advance(std::size_t done, std::string_view) override {
      if (done == 60) throw std::runtime_error("killed");
    }
  } killer;
  EXPECT_THROW(run(ck.string(), killer), std::runtime_error);
  // ...and restarted.
  const TrainResult resumed = run(ck.string(), progress);
  EXPECT_EQ(resumed.start_iteration, 60);
  ASSERT_EQ(resumed.cloud.size(), straight.cloud.size());
  for (size_t i = 0; i < straight.cloud.size(); ++i) {
    ASSERT_EQ(resumed.cloud.means[i], straight.cloud.means[i]) << i;
    ASSERT_EQ(resumed.cloud.opacity_logits[i], straight.cloud.opacity_logits[i]) << i;
  }
  EXPECT_EQ(resumed.series.size(), straight.series.size());
  // The DSMs' surface: the scene at step 45, not the final one; the resumed
  // run has it from the file it wrote before the kill, to the bit (PLY
  // stores floats).
  ASSERT_TRUE(straight.surface && resumed.surface);
  EXPECT_EQ(straight.surface_iteration, 45);
  EXPECT_EQ(resumed.surface_iteration, 45);
  ASSERT_EQ(resumed.surface->size(), straight.surface->size());
  bool moved_after = false;
  for (size_t i = 0; i < straight.surface->size(); ++i) {
    ASSERT_EQ(resumed.surface->means[i], straight.surface->means[i]) << i;
    ASSERT_EQ(resumed.surface->log_scales[i], straight.surface->log_scales[i]) << i;
    if (i < straight.cloud.size() && straight.surface->log_scales[i] != straight.cloud.log_scales[i]) moved_after = true;
  }
  EXPECT_TRUE(moved_after) << "the steps after the surface's changed no scale";
  // With surface_at 0 there is none.
  TrainOptions without = ShortRun(10);
  without.surface_at = 0;
  EXPECT_FALSE(TrainGaussians(without, f.init, f.views, "", progress).surface);
}

// The held-out renders are made at the last step; a run killed after its
// last checkpoint and restarted has no step left and must still make them.
TEST(Trainer, ARunResumedAfterItsLastCheckpointStillRendersItsHeldOutViews) {
  const Fixture f = MakeFixture(4);
  NullProgress progress;
  TrainOptions o = ShortRun(40);
  o.appearance.enabled = true;
  const TrainResult straight = TrainGaussians(o, f.init, f.views, "", progress);
  ASSERT_EQ(straight.held_out.size(), 1u);
  const fs::path ck = ScratchDir("ck_last");
  struct Killer : Progress {
    int at = 0;
    void Advance(std::size_t done, std::string_view) override {
      if (static_cast<int>(done) == at) throw std::runtime_error("killed");
    }
  } killer;
  killer.at = o.iterations;
  EXPECT_THROW(TrainGaussians(o, f.init, f.views, ck.string(), killer), std::runtime_error);
  const TrainResult resumed = TrainGaussians(o, f.init, f.views, ck.string(), progress);
  EXPECT_EQ(resumed.start_iteration, o.iterations);
  ASSERT_EQ(resumed.held_out.size(), 1u);
  const HeldOutRender &a = straight.held_out[0], &b = resumed.held_out[0];
  EXPECT_EQ(b.rgb, a.rgb);
  EXPECT_EQ(b.psnr_db, a.psnr_db);
  EXPECT_EQ(b.fitted_psnr_db, a.fitted_psnr_db);
  EXPECT_EQ(b.best_embedding_view, a.best_embedding_view);
  for (const char* metric : {"psnr_test_db", "psnr_test_fitted_db", "psnr_test_best_embedding_db", "psnr_train_db"})
    EXPECT_EQ(resumed.report.metrics.at(metric), straight.report.metrics.at(metric)) << metric;
  // The series' last point is the held-out renders' mean, not a render of its own.
  EXPECT_EQ(straight.series.back().psnr_test_db, a.psnr_db);
}

// Centres scattered a quarter metre off the surface: the surface-height
// term brings them back while photometric training alone leaves them off.
TEST(Trainer, SurfaceHeightTermHoldsCentresOnTheSurface) {
  const Fixture f = MakeFixture(4);
  NullProgress progress;
  const SurfaceDepthPrior surface(f.init.means, 2.0);
  GaussianCloud scattered = f.init;
  std::mt19937 rng(11);
  std::normal_distribution<float> jitter(0.0f, 0.25f);
  for (auto& m : scattered.means) m.z() += jitter(rng);
  // Mean |z - surface height| over the centres within the term's band.
  const auto off_surface_m = [&](const GaussianCloud& c) {
    double sum = 0;
    int n = 0;
    for (const auto& m : c.means) {
      const double e = std::abs(m.z() - surface.HeightAt(m.x(), m.y()));
      if (e < 1.0) sum += e, ++n;
    }
    return sum / std::max(1, n);
  };
  const auto run = [&](double lambda) {
    TrainOptions o = ShortRun(60);
    o.density.from_step = o.iterations + 1;
    o.lambda_opacity = 0;
    o.surface.lambda_depth = o.surface.lambda_alpha = 0;  // the term alone
    o.surface.lambda_height = lambda;
    return TrainGaussians(o, scattered, f.views, "", progress, nullptr, &surface).cloud;
  };
  const double before = off_surface_m(scattered), without = off_surface_m(run(0.0)), with = off_surface_m(run(10.0));
  std::printf("[figures] centres off the surface: %.3f m at the start, %.3f m after 60 steps without the term, "
              "%.3f m with it\n", before, without, with);
  EXPECT_GT(without, 0.8 * before);
  EXPECT_LT(with, 0.5 * without);
  TrainOptions bad = ShortRun(1);
  bad.surface.height_band_m = 0;
  EXPECT_THROW(TrainGaussians(bad, scattered, f.views, "", progress, nullptr, &surface), Error);
}

TEST(Trainer, AppearanceModelAbsorbsPerDateBrightness) {
  // Multi-date imagery in miniature: each training view gets its own gain
  // (the held-out one keeps gain 1, the mean of the others).
  Fixture f = MakeFixture(2);
  const float gains[] = {0.7f, 1.0f, 1.3f, 0.8f, 1.2f};
  for (size_t v = 0; v < f.views.size(); ++v) {
    f.views[v].acquisition_time = "2016-0" + std::to_string(v + 1) + "-01T00:00:00Z";
    for (float& c : f.views[v].rgb) c = std::min(1.0f, c * gains[v % 5]);
  }
  EXPECT_EQ(DistinctAcquisitionDates(f.views), 4);  // training views only
  NullProgress progress;
  TrainOptions o = ShortRun(200);
  o.density.from_step = o.iterations + 1;
  o.lambda_opacity = 0;
  const TrainResult plain = TrainGaussians(o, f.init, f.views, "", progress);
  o.appearance.enabled = true;
  const TrainResult modelled = TrainGaussians(o, f.init, f.views, "", progress);
  // Training views, each rendered with its own appearance: without the
  // model one colour per Gaussian must serve gains 0.7-1.3.
  const double fit_plain = plain.report.metrics.at("psnr_train_db");
  const double fit_modelled = modelled.report.metrics.at("psnr_train_db");
  std::printf("[figures] per-view gains 0.7-1.3, 200 iterations: training-view PSNR %.2f dB without, %.2f dB with the "
              "appearance model; held-out (mean embedding) %.2f vs %.2f dB; %.1f s vs %.1f s; fused for %s\n",
              fit_plain, fit_modelled, plain.series.back().psnr_test_db, modelled.series.back().psnr_test_db,
              plain.report.seconds, modelled.report.seconds, modelled.appearance_image.c_str());
  EXPECT_GT(fit_modelled, fit_plain + kAppearanceGainDb);
  EXPECT_TRUE(plain.appearance_image.empty());
  EXPECT_FALSE(modelled.appearance_image.empty());
  EXPECT_NE(modelled.appearance_image, f.views[1].name) << "a held-out view has no embedding to fuse";
}

TEST(Trainer, HeldOutScoresNameTheTrainingEmbeddingThatMatchesTheView) {
  // Per-view gains as above, but the held-out view (1) shares view 0's gain
  // and no date: its metadata choose the mean embedding, while Sat-NeRF's
  // protocol (every training embedding tried on the view's pixels) must
  // find view 0's and score at least as well as the mean.
  Fixture f = MakeFixture(4);
  const float gains[] = {0.6f, 0.6f, 1.3f, 0.9f, 1.2f};
  for (size_t v = 0; v < f.views.size(); ++v) {
    if (v != 1) f.views[v].acquisition_time = "2016-0" + std::to_string(v + 1) + "-01T00:00:00Z";
    for (float& c : f.views[v].rgb) c = std::min(1.0f, c * gains[v]);
  }
  NullProgress progress;
  TrainOptions o = ShortRun(150);
  o.density.from_step = o.iterations + 1;
  o.lambda_opacity = 0;
  o.appearance.enabled = true;
  const TrainResult r = TrainGaussians(o, f.init, f.views, "", progress);
  ASSERT_EQ(r.held_out.size(), 1u);
  const HeldOutRender& h = r.held_out[0];
  std::printf("[figures] held-out view with view 0's gain: %.2f dB with the mean embedding, %.2f dB with %s's, "
              "%.2f dB fitted on half\n", h.psnr_db, h.best_embedding_psnr_db, h.best_embedding_view.c_str(),
              h.fitted_psnr_db);
  EXPECT_EQ(h.name, f.views[1].name);
  EXPECT_EQ(h.best_embedding_view, f.views[0].name);
  EXPECT_GT(h.best_embedding_psnr_db, h.psnr_db);
  EXPECT_NEAR(h.psnr_db, r.series.back().psnr_test_db, 1e-9) << "the series' last point scores the same render";
  EXPECT_NEAR(r.report.metrics.at("psnr_test_best_embedding_db"), h.best_embedding_psnr_db, 1e-12);
  ASSERT_EQ(h.rgb.size(), f.views[1].rgb.size());
  EXPECT_EQ(h.target, f.views[1].rgb);
}

TEST(Trainer, UnknownAppearanceImageIsRefusedBeforeTraining) {
  const Fixture f = MakeFixture(4);
  TrainOptions o = ShortRun(10);
  o.appearance.enabled = true;
  o.appearance_image = "no-such-view";
  NullProgress progress;
  try {
    TrainGaussians(o, f.init, f.views, "", progress);
    FAIL() << "must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-view"), std::string::npos) << e.what();
  }
}

// Adam's steps have the size of the learning rate while the gradient keeps
// its sign: the scales move at lr_scale until lr_scale_late_from of the
// steps, at lr_scale_late after.
TEST(Trainer, TheScalesRateTurnsToTheLateRateAfterItsShareOfTheSteps) {
  TrainOptions o;
  o.iterations = 10;
  o.lr.scale = 0.001;
  o.lr.scale_late = 0.012;
  o.lr.scale_late_from = 0.6;
  GaussianCloud cloud;
  cloud.resize(1);
  cloud.log_scales[0].setZero();
  GaussianCloud gradient = cloud;
  gradient.log_scales[0].setConstant(1.0f);
  Adam adam;
  adam.Resize(1);
  for (int step = 1; step <= o.iterations; ++step) {
    const float before = cloud.log_scales[0].x();
    AdamStep(cloud, adam, gradient, o, 0.0);
    const double expected = step <= 6 ? o.lr.scale : o.lr.scale_late;
    EXPECT_NEAR(before - cloud.log_scales[0].x(), expected, 1e-3 * expected) << "step " << step;
  }
  o.lr.scale_late = 0;  // off: lr_scale throughout
  Adam fresh;
  fresh.Resize(1);
  for (int step = 1; step <= o.iterations; ++step) {
    const float before = cloud.log_scales[0].x();
    AdamStep(cloud, fresh, gradient, o, 0.0);
    EXPECT_NEAR(before - cloud.log_scales[0].x(), o.lr.scale, 1e-3 * o.lr.scale) << "step " << step;
  }
}

TEST(Trainer, InitialScaleIsTheNeighbourDistanceUpToTheCap) {
  const std::vector<Eigen::Vector3f> points = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {10, 10, 0}};
  const std::vector<Eigen::Vector3f> grey(points.size(), Eigen::Vector3f::Constant(0.5f));
  // Neighbours at 10, 10 and 14.1 m: mean 11.4 m.
  const GaussianCloud free = InitializeFromPoints(points, grey);
  EXPECT_NEAR(std::exp(free.log_scales[0].x()), (20.0 + std::sqrt(200.0)) / 3.0, 1e-4);
  const GaussianCloud capped = InitializeFromPoints(points, grey, 1.5);
  for (const auto& s : capped.log_scales) EXPECT_NEAR(std::exp(s.maxCoeff()), 1.5, 1e-5);
  EXPECT_THROW(InitializeFromPoints(points, grey, 0.0), Error);
}

TEST(Trainer, CappedInitialGaussiansShareTheirPointsNeighbourhood) {
  const std::vector<Eigen::Vector3f> points = {{0, 0, 2}, {10, 0, 2}, {0, 10, 2}, {10, 10, 7}};
  const std::vector<Eigen::Vector3f> grey(points.size(), Eigen::Vector3f::Constant(0.5f));
  const double spacing = (20.0 + std::sqrt(200.0 + 25.0)) / 3.0;  // mean of the 3 nearest, for point 0
  // Uncapped or one piece: one Gaussian per point.
  EXPECT_EQ(InitializeFromPoints(points, grey, 1e9, 16).size(), points.size());
  EXPECT_EQ(InitializeFromPoints(points, grey, 1.5, 1).size(), points.size());
  // Capped at 1.5 m: (11.5 / 1.5)^2 ~ 59 pieces wanted, 16 allowed.
  const GaussianCloud c = InitializeFromPoints(points, grey, 1.5, 16);
  ASSERT_EQ(c.size(), 4u * 16u);
  for (std::size_t k = 0; k < c.size(); ++k) {
    const Eigen::Vector3f& p = points[k / 16];
    EXPECT_EQ(c.means[k].z(), p.z()) << "pieces stay at their point's height";
    EXPECT_LE((c.means[k] - p).head<2>().norm(), 0.5 * 12.0) << k;
    EXPECT_NEAR(std::exp(c.log_scales[k].maxCoeff()), 1.5, 1e-5);
  }
  // The pieces of point 0 spread over its disc, not clumped at the centre.
  float reach = 0;
  for (int k = 1; k < 16; ++k) reach = std::max(reach, (c.means[k] - points[0]).head<2>().norm());
  EXPECT_GT(reach, 0.25 * spacing);
  // Just enough pieces when the cap bites a little: (4.0 / 2.0)^2 = 4.
  const std::vector<Eigen::Vector3f> pair = {{0, 0, 0}, {4, 0, 0}};
  EXPECT_EQ(InitializeFromPoints(pair, {grey[0], grey[0]}, 2.0, 16).size(), 2u * 4u);
  // Deterministic.
  const GaussianCloud again = InitializeFromPoints(points, grey, 1.5, 16);
  for (std::size_t k = 0; k < c.size(); ++k) EXPECT_EQ(again.means[k], c.means[k]);
  EXPECT_THROW(InitializeFromPoints(points, grey, 1.5, 0), Error);
}

TEST(Trainer, DenseInitKeepsOnePointPerCellAndTiePointsInItsHoles) {
  // Dense points every 0.5 m over x in [0, 4), y in [0, 2); tie points at
  // (1.2, 0.3) (a cell the dense points fill) and (6.5, 0.5) (a hole).
  std::vector<Eigen::Vector3f> dense, dense_rgb;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 8; ++i) {
      dense.emplace_back(0.5f * i, 0.5f * j, 1.0f);
      dense_rgb.emplace_back(0.2f, 0.2f, 0.2f);
    }
  const std::vector<Eigen::Vector3f> ties = {{1.2f, 0.3f, 5.0f}, {6.5f, 0.5f, 3.0f}};
  const std::vector<Eigen::Vector3f> ties_rgb(2, Eigen::Vector3f::Constant(0.9f));
  std::vector<Eigen::Vector3f> points, colours;
  ThinToGrid(1.0, dense, dense_rgb, ties, ties_rgb, &points, &colours);
  ASSERT_EQ(points.size(), 4u * 2u + 1u);  // 4 x 2 one-metre cells, plus the hole's tie point
  EXPECT_EQ(points.back(), ties[1]);
  EXPECT_EQ(colours.back(), ties_rgb[1]);
  for (std::size_t k = 0; k + 1 < points.size(); ++k) EXPECT_EQ(points[k].z(), 1.0f) << "a dense cell kept its tie point";
  // Output may alias an input (the job thins the tie points in place).
  std::vector<Eigen::Vector3f> same = ties, same_rgb = ties_rgb;
  ThinToGrid(1.0, dense, dense_rgb, same, same_rgb, &same, &same_rgb);
  EXPECT_EQ(same.size(), points.size());
  EXPECT_THROW(ThinToGrid(0.0, dense, dense_rgb, ties, ties_rgb, &points, &colours), Error);
}

TEST(Trainer, DenseInitKeepsEveryMarkedCellAndThinsTheRestAroundThem) {
  // Dense points every 0.5 m over x in [0, 4), y in [0, 1); the column x = 1.5
  // (inside the one-metre cells x in [1, 2)) marked to keep, as beside a step.
  std::vector<Eigen::Vector3f> dense, dense_rgb;
  std::vector<std::uint8_t> keep;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 8; ++i) {
      dense.emplace_back(0.5f * i, 0.5f * j, 1.0f);
      dense_rgb.emplace_back(0.2f, 0.2f, 0.2f);
      keep.push_back(i == 3);
    }
  std::vector<Eigen::Vector3f> points, colours;
  ThinToGrid(1.0, dense, dense_rgb, {}, {}, &points, &colours, &keep);
  // Both marked points, then one point for each of the three other one-metre
  // cells: the marked points' cell takes no other.
  ASSERT_EQ(points.size(), 2u + 3u);
  EXPECT_EQ(points[0], dense[3]);
  EXPECT_EQ(points[1], dense[8 + 3]);
  for (std::size_t k = 2; k < points.size(); ++k)
    EXPECT_TRUE(points[k].x() < 1.0f || points[k].x() >= 2.0f) << "point " << k << " in the kept cell";
  // No marks: as without them.
  std::vector<Eigen::Vector3f> plain, plain_rgb;
  ThinToGrid(1.0, dense, dense_rgb, {}, {}, &plain, &plain_rgb);
  EXPECT_EQ(plain.size(), 4u);
  std::vector<std::uint8_t> short_marks(3, 1);
  EXPECT_THROW(ThinToGrid(1.0, dense, dense_rgb, {}, {}, &points, &colours, &short_marks), Error);
}

TEST(Trainer, FacadePointsStandOnTheWallsOfTheDenseHeights) {
  // 0.5 m cells over 8 x 8 m at 1 m, with a 4 x 4 cell block 7 m tall (cells
  // 6-9 each way, 6 m above the ground) and a 1 m kerb step that is below the
  // 2 m threshold.
  std::vector<Eigen::Vector3f> grid, rgb;
  for (int j = 0; j < 16; ++j)
    for (int i = 0; i < 16; ++i) {
      const bool block = i >= 6 && i < 10 && j >= 6 && j < 10;
      const bool kerb = i >= 13;
      grid.emplace_back(0.5f * i, 0.5f * j, block ? 7.0f : kerb ? 2.0f : 1.0f);
      rgb.emplace_back(block ? 0.9f : 0.1f, 0.5f, 0.5f);
    }
  std::vector<Eigen::Vector3f> points, colours;
  std::vector<int> normals;
  FacadePoints(grid, rgb, 0.5, 1.0, 2.0, &points, &colours, &normals);
  ASSERT_EQ(normals.size(), points.size());
  // 4 walls of 4 cell edges, a column every second edge: 8 columns of
  // floor(6 m / 1 m) = 6 points, at 1.5, 2.5, ..., 6.5 m.
  ASSERT_EQ(points.size(), 8u * 6u);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3f& p = points[k];
    const bool on_x_wall = std::abs(p.x() - 2.75f) < 1e-5f || std::abs(p.x() - 4.75f) < 1e-5f;
    const bool on_y_wall = std::abs(p.y() - 2.75f) < 1e-5f || std::abs(p.y() - 4.75f) < 1e-5f;
    EXPECT_TRUE(on_x_wall || on_y_wall) << p.transpose();
    EXPECT_EQ(normals[k], on_x_wall ? 0 : 1) << p.transpose();
    EXPECT_GT(p.z(), 1.0f);
    EXPECT_LT(p.z(), 7.0f);
    EXPECT_NEAR(std::fmod(p.z() - 1.5f, 1.0f), 0.0f, 1e-5f) << p.z();
    EXPECT_EQ(colours[k], rgb[0]) << "coloured like the lower cell";
  }
  FacadePoints({}, {}, 0.5, 1.0, 2.0, &points, &colours, &normals);
  EXPECT_TRUE(points.empty());
  EXPECT_THROW(FacadePoints(grid, rgb, 0.5, 1.0, 0.0, &points, &colours, &normals), Error);
  EXPECT_THROW(FacadePoints(grid, {}, 0.5, 1.0, 2.0, &points, &colours, &normals), Error);
}

TEST(Trainer, RefusesViewsThatDoNotMatchTheirCameras) {
  Fixture f;
  TrainView v;
  v.name = "bad";
  v.camera.width_px = 4;
  v.camera.height_px = 4;
  v.rgb.assign(5, 0.0f);
  f.views.push_back(v);
  NullProgress progress;
  EXPECT_THROW(TrainGaussians(ShortRun(10), InitializeFromPoints({{0, 0, 0}}, {{0.5f, 0.5f, 0.5f}}), f.views, "", progress),
               Error);
}

}  // namespace
}  // namespace skyfall
