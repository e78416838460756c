#include "splat/appearance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "core/error.h"
#include "splat/raster_test_support.h"
#include "splat/rasterizer.h"

namespace skyfall {
namespace {

using Cloud = GaussianCloudT<double>;
using Model = AppearanceModelT<double>;

// Central differences in double through the MLP and the rasterizer agree
// with the analytic gradients to ~1e-7 relative; 1e-5 leaves room for the
// O(step^2) truncation error and the rare ReLU kink near a sample point.
constexpr double kRelTol = 1e-5;
constexpr double kAbsTol = 1e-8;
constexpr double kStep = 1e-6;

PinholeCamera TopCamera(int size_px, double height_m) {
  PinholeCamera cam;
  cam.fx = cam.fy = 1.2 * size_px;
  cam.cx = cam.cy = 0.5 * (size_px - 1);
  cam.width_px = cam.height_px = size_px;
  Eigen::Matrix3d down;
  down << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  cam.cam_from_world_rotation = Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitX()).toRotationMatrix() * down;
  const Eigen::Vector3d forward = cam.cam_from_world_rotation.row(2).transpose();
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * (-height_m * forward);
  return cam;
}

Cloud SmallCloud(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  Cloud c;
  c.resize(n);
  for (int i = 0; i < n; ++i) {
    c.means[i] = Eigen::Vector3d(3 * u(rng), 3 * u(rng), 0.5 * u(rng));
    c.log_scales[i] = Eigen::Vector3d::Constant(std::log(1.0)) + 0.2 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    c.rotations[i] = Eigen::Vector4d(1, 0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng));
    c.opacity_logits[i] = 0.5 * u(rng);
    for (auto& v : c.sh[i]) v = 0.4 * u(rng);
  }
  return c;
}

// A model in double with every layer random (the trained state, not the
// identity start, so every weight has a gradient).
Model RandomModel(int gaussians, std::uint64_t seed, const std::string& kind) {
  AppearanceOptions o;
  o.model = *EnumFromName<AppearanceModelKind>(kind);
  o.image_dim = 5;
  o.gaussian_dim = 4;
  o.hidden = 16;
  const AppearanceModel f = InitAppearance(o, 3, gaussians, seed);
  Model m;
  m.image_embeddings = f.image_embeddings.cast<double>();
  m.gaussian_embeddings = f.gaussian_embeddings.cast<double>() * 10.0;
  m.w1 = f.w1.cast<double>();
  m.w2 = f.w2.cast<double>();
  m.b1 = f.b1.cast<double>();
  m.b2 = f.b2.cast<double>();
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  if (kind == "bilinear") {  // the output layer is w2 (zero at the start)
    m.w2 = Eigen::MatrixXd::NullaryExpr(m.w2.rows(), m.w2.cols(), [&] { return u(rng); });
    m.b2 = Eigen::VectorXd::NullaryExpr(m.b2.size(), [&] { return u(rng); });
    return m;
  }
  m.w3 = Eigen::MatrixXd::NullaryExpr(6, o.hidden, [&] { return u(rng); });
  m.b3 = Eigen::VectorXd::NullaryExpr(6, [&] { return u(rng); });
  return m;
}

using testing::SmoothRasterOptions;
using testing::ToFloat;

const char* const kKinds[] = {"mlp", "bilinear"};

struct Scene {
  Cloud cloud = SmallCloud(12, 5);
  Model model;
  Eigen::VectorXd embedding;
  PinholeCamera cam = TopCamera(40, 30.0);
  RasterOptions raster = SmoothRasterOptions();
  std::vector<double> weights;
  explicit Scene(const std::string& kind = "mlp") : model(RandomModel(12, 6, kind)) {
    embedding = model.image_embeddings.col(1);
    std::mt19937_64 rng(8);
    std::uniform_real_distribution<double> u(-1, 1);
    weights.resize(3 * cam.width_px * cam.height_px);
    for (double& w : weights) w = u(rng);
  }
  // L = sum of weighted rendered RGB, through the appearance transform.
  double Loss() const {
    const auto affine = EvaluateAppearance(model, embedding, cloud);
    const RenderOutput<double> r = RenderGaussians(cloud, cam, raster, &affine);
    double l = 0;
    for (std::size_t k = 0; k < r.rgb.size(); ++k) l += weights[k] * r.rgb[k];
    return l;
  }
};

struct Gradients {
  Model model;
  Eigen::VectorXd embedding;
  std::vector<std::array<double, 12>> sh;
};

Gradients Analytic(const Scene& s) {
  const auto affine = EvaluateAppearance(s.model, s.embedding, s.cloud);
  const RenderOutput<double> r = RenderGaussians(s.cloud, s.cam, s.raster, &affine);
  const GaussianGradients<double> g = BackwardGaussians(s.cloud, s.cam, s.raster, r, s.weights, {}, {}, &affine);
  Gradients out;
  out.model = s.model.ZerosLike();
  out.sh = g.d.sh;
  out.embedding = BackwardAppearance(s.model, s.embedding, s.cloud, g.d_colour_affine, &out.model, &out.sh);
  return out;
}

double CentralDifference(Scene& s, double* param) {
  const double keep = *param;
  *param = keep + kStep;
  const double lp = s.Loss();
  *param = keep - kStep;
  const double lm = s.Loss();
  *param = keep;
  return (lp - lm) / (2 * kStep);
}

void ExpectMatches(Scene& s, double* param, double analytic, const std::string& what) {
  const double fd = CentralDifference(s, param);
  EXPECT_NEAR(analytic, fd, kAbsTol + kRelTol * std::abs(fd)) << what;
}

TEST(Appearance, FreshModelIsTheIdentityTransform) {
  const GaussianCloud cloud = ToFloat(SmallCloud(50, 1));
  const AppearanceModel m = InitAppearance(AppearanceOptions{}, 4, cloud.size(), 3);
  EXPECT_EQ(m.image_embeddings.rows(), 32);
  EXPECT_EQ(m.gaussian_embeddings.rows(), 24);
  EXPECT_EQ(m.w1.cols(), 32 + 24 + 3);
  EXPECT_EQ(m.w2.rows(), 32);
  EXPECT_STREQ(m.kind(), "mlp");
  AppearanceOptions bilinear;
  bilinear.model = AppearanceModelKind::kBilinear;
  const AppearanceModel b = InitAppearance(bilinear, 4, cloud.size(), 3);
  EXPECT_STREQ(b.kind(), "bilinear");
  EXPECT_EQ(b.w1.cols(), 32);
  EXPECT_EQ(b.w2.rows(), 6 * (24 + 4));
  EXPECT_EQ(b.w2.cols(), 32);
  EXPECT_STREQ(b.ZerosLike().kind(), "bilinear");
  for (const AppearanceModel* model : {&m, &b}) {
    const auto affine = EvaluateAppearance(*model, Eigen::VectorXf(model->image_embeddings.col(2)), cloud);
    for (const auto& a : affine) EXPECT_EQ(a, (ColourAffine<float>() << 1, 1, 1, 0, 0, 0).finished()) << model->kind();
  }
}

TEST(Appearance, GradientsOfMlpWeightsMatchFiniteDifferences) {
  for (const char* kind : kKinds) {
  SCOPED_TRACE(kind);
  Scene s(kind);
  const Gradients g = Analytic(s);
  for (auto [param, grad, name] : {std::tuple{&s.model.w1, &g.model.w1, "w1"}, std::tuple{&s.model.w2, &g.model.w2, "w2"},
                                   std::tuple{&s.model.w3, &g.model.w3, "w3"}}) {
    // A spread of entries of each layer (all of them would be slow and add nothing).
    for (Eigen::Index k = 0; k < param->size(); k += 7)
      ExpectMatches(s, param->data() + k, grad->data()[k], std::string(name) + "[" + std::to_string(k) + "]");
  }
  for (auto [param, grad, name] : {std::tuple{&s.model.b1, &g.model.b1, "b1"}, std::tuple{&s.model.b2, &g.model.b2, "b2"},
                                   std::tuple{&s.model.b3, &g.model.b3, "b3"}}) {
    for (Eigen::Index k = 0; k < param->size(); ++k)
      ExpectMatches(s, param->data() + k, (*grad)[k], std::string(name) + "[" + std::to_string(k) + "]");
  }
  // Guard against a vacuous pass: the weights do matter.
  EXPECT_GT(g.model.w2.norm(), 1e-3);
  EXPECT_GT(g.model.w1.norm(), 1e-3);
  }
}

TEST(Appearance, GradientsOfEmbeddingsAndBaseColourMatchFiniteDifferences) {
  for (const char* kind : kKinds) {
  SCOPED_TRACE(kind);
  Scene s(kind);
  const Gradients g = Analytic(s);
  for (Eigen::Index k = 0; k < s.embedding.size(); ++k)
    ExpectMatches(s, &s.embedding[k], g.embedding[k], "image embedding " + std::to_string(k));
  for (Eigen::Index i = 0; i < s.model.gaussian_embeddings.cols(); ++i) {
    for (Eigen::Index k = 0; k < s.model.gaussian_embeddings.rows(); ++k) {
      ExpectMatches(s, &s.model.gaussian_embeddings(k, i), g.model.gaussian_embeddings(k, i),
                    "Gaussian embedding " + std::to_string(i) + "," + std::to_string(k));
    }
    // The SH colour enters twice: through the rasterized colour and as the MLP input.
    for (int k = 0; k < 12; ++k)
      ExpectMatches(s, &s.cloud.sh[i][k], g.sh[i][k], "sh of Gaussian " + std::to_string(i) + "[" + std::to_string(k) + "]");
  }
  EXPECT_GT(g.embedding.norm(), 1e-4);
  }
}

TEST(Appearance, KeptActivationsGiveTheSameGradients) {
  Scene s;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<ColourAffine<double>> d_affine(s.cloud.size());
  for (auto& d : d_affine) d = ColourAffine<double>::NullaryExpr([&] { return u(rng); });
  AppearanceActivations<double> kept;
  const auto with_kept = EvaluateAppearance(s.model, s.embedding, s.cloud, &kept);
  EXPECT_EQ(with_kept, EvaluateAppearance(s.model, s.embedding, s.cloud));
  Model g_kept = s.model.ZerosLike(), g_recomputed = s.model.ZerosLike();
  const Eigen::VectorXd e_kept = BackwardAppearance<double>(s.model, s.embedding, s.cloud, d_affine, &g_kept, nullptr, &kept);
  const Eigen::VectorXd e_recomputed = BackwardAppearance<double>(s.model, s.embedding, s.cloud, d_affine, &g_recomputed, nullptr);
  EXPECT_EQ(e_kept, e_recomputed);
  EXPECT_EQ(g_kept.w1, g_recomputed.w1);
  EXPECT_EQ(g_kept.w2, g_recomputed.w2);
  EXPECT_EQ(g_kept.gaussian_embeddings, g_recomputed.gaussian_embeddings);
  Cloud fewer = s.cloud;
  fewer.resize(5);
  Model m5 = s.model;
  m5.gaussian_embeddings.conservativeResize(Eigen::NoChange, 5);
  Model g5 = m5.ZerosLike();
  std::vector<ColourAffine<double>> d5(d_affine.begin(), d_affine.begin() + 5);
  EXPECT_THROW(BackwardAppearance<double>(m5, s.embedding, fewer, d5, &g5, nullptr, &kept), Error);
}

// Largest |a - b| over the entries, relative to the largest |b| (at least 1e-30).
double RelativeDifference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1e-30, b.cwiseAbs().maxCoeff());
}

TEST(Appearance, EverySimdPathGivesTheBaselineResults) {
  // The MLP in float on every path against the baseline path, over 1100
  // Gaussians (three blocks, the last one padded). Each output is a sum of
  // at most hidden + 7 products, each weight gradient a sum over 1100
  // Gaussians; the paths add them in a different order (lane width) and the
  // wider ones multiply-add in one rounding. Float keeps 6e-8 relative per
  // operation, so sums of a few thousand terms agree within 1e-5 of their
  // largest entry; 1e-4 leaves room for cancellation in single entries.
  constexpr double kPathTol = 1e-4;
  const std::size_t n = 1100;
  const Model md = RandomModel(static_cast<int>(n), 21, "mlp");
  AppearanceModel m;
  for (auto [dst, src] : {std::pair{&m.image_embeddings, &md.image_embeddings},
                          std::pair{&m.gaussian_embeddings, &md.gaussian_embeddings}, std::pair{&m.w1, &md.w1},
                          std::pair{&m.w2, &md.w2}, std::pair{&m.w3, &md.w3}})
    *dst = src->cast<float>();
  m.b1 = md.b1.cast<float>();
  m.b2 = md.b2.cast<float>();
  m.b3 = md.b3.cast<float>();
  const GaussianCloud cloud = ToFloat(SmallCloud(static_cast<int>(n), 22));
  const Eigen::VectorXf e = m.image_embeddings.col(0);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<ColourAffine<float>> d_affine(n);
  for (auto& d : d_affine) d = ColourAffine<float>::NullaryExpr([&] { return u(rng); });
  struct Result {
    Eigen::MatrixXd affine, d_embedding, d_w1, d_w2, d_w3, d_gaussian, d_sh;
  };
  auto run = [&] {
    Result r;
    const auto affine = EvaluateAppearance(m, e, cloud);
    r.affine.resize(6, n);
    for (std::size_t i = 0; i < n; ++i) r.affine.col(i) = affine[i].cast<double>();
    AppearanceModel g = m.ZerosLike();
    std::vector<std::array<float, 12>> d_sh(n, std::array<float, 12>{});
    r.d_embedding = BackwardAppearance(m, e, cloud, d_affine, &g, &d_sh).cast<double>();
    r.d_w1 = g.w1.cast<double>();
    r.d_w2 = g.w2.cast<double>();
    r.d_w3 = g.w3.cast<double>();
    r.d_gaussian = g.gaussian_embeddings.cast<double>();
    r.d_sh.resize(3, n);
    for (std::size_t i = 0; i < n; ++i)
      for (int ch = 0; ch < 3; ++ch) r.d_sh(ch, i) = d_sh[i][ch * 4];
    return r;
  };
  Result base;
  {
    testing::ScopedSimdPath scoped(SimdPath::kBaseline);
    base = run();
  }
  EXPECT_GT(base.d_w2.norm(), 1e-3);  // not a vacuous comparison
  // The baseline against the paper's formula written out in double:
  // gamma = 1 + o[0..2], beta = o[3..5], o = w3 relu(w2 relu(w1 [e; g; c] + b1) + b2) + b3.
  for (std::size_t i = 0; i < n; i += 97) {
    Eigen::VectorXd input(md.w1.cols());
    input << e.cast<double>(), m.gaussian_embeddings.col(i).cast<double>(),
        Eigen::Vector3d(kShC0 * cloud.sh[i][0] + 0.5, kShC0 * cloud.sh[i][4] + 0.5, kShC0 * cloud.sh[i][8] + 0.5);
    const Eigen::VectorXd h1 = (m.w1.cast<double>() * input + m.b1.cast<double>()).cwiseMax(0.0);
    const Eigen::VectorXd h2 = (m.w2.cast<double>() * h1 + m.b2.cast<double>()).cwiseMax(0.0);
    Eigen::VectorXd o = m.w3.cast<double>() * h2 + m.b3.cast<double>();
    o.head(3).array() += 1.0;
    EXPECT_LT((base.affine.col(i) - o).cwiseAbs().maxCoeff(), kPathTol * std::max(1.0, o.cwiseAbs().maxCoeff()))
        << "Gaussian " << i;
  }
  for (SimdPath path : SupportedSimdPaths()) {
    SCOPED_TRACE(SimdPathName(path));
    testing::ScopedSimdPath scoped(path);
    const Result r = run();
    EXPECT_LT(RelativeDifference(r.affine, base.affine), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_embedding, base.d_embedding), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_w1, base.d_w1), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_w2, base.d_w2), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_w3, base.d_w3), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_gaussian, base.d_gaussian), kPathTol);
    EXPECT_LT(RelativeDifference(r.d_sh, base.d_sh), kPathTol);
  }
}

TEST(Appearance, ColourTransformGradientsOfTheRasterizerMatchFiniteDifferences) {
  Scene s;
  std::vector<ColourAffine<double>> affine = EvaluateAppearance(s.model, s.embedding, s.cloud);
  auto loss = [&] {
    const RenderOutput<double> r = RenderGaussians(s.cloud, s.cam, s.raster, &affine);
    double l = 0;
    for (std::size_t k = 0; k < r.rgb.size(); ++k) l += s.weights[k] * r.rgb[k];
    return l;
  };
  const RenderOutput<double> r = RenderGaussians(s.cloud, s.cam, s.raster, &affine);
  const GaussianGradients<double> g = BackwardGaussians(s.cloud, s.cam, s.raster, r, s.weights, {}, {}, &affine);
  ASSERT_EQ(g.d_colour_affine.size(), s.cloud.size());
  for (std::size_t i = 0; i < s.cloud.size(); ++i) {
    for (int k = 0; k < 6; ++k) {
      const double keep = affine[i][k];
      affine[i][k] = keep + kStep;
      const double lp = loss();
      affine[i][k] = keep - kStep;
      const double lm = loss();
      affine[i][k] = keep;
      const double fd = (lp - lm) / (2 * kStep);
      EXPECT_NEAR(g.d_colour_affine[i][k], fd, kAbsTol + kRelTol * std::abs(fd)) << "Gaussian " << i << " field " << k;
    }
  }
}

TEST(Appearance, ClampedChannelGetsNoGradient) {
  // beta = -5 drives every colour below 0: the rendered colour is the clamp,
  // flat in every colour parameter.
  Scene s;
  std::vector<ColourAffine<double>> affine(s.cloud.size(), (ColourAffine<double>() << 1, 1, 1, -5, -5, -5).finished());
  const RenderOutput<double> r = RenderGaussians(s.cloud, s.cam, s.raster, &affine);
  const GaussianGradients<double> g = BackwardGaussians(s.cloud, s.cam, s.raster, r, s.weights, {}, {}, &affine);
  for (std::size_t i = 0; i < s.cloud.size(); ++i) {
    EXPECT_EQ(g.d_colour_affine[i].norm(), 0.0);
    EXPECT_EQ(g.d.sh[i][0], 0.0);
  }
}

TEST(Appearance, FusedCloudRendersLikeTheModel) {
  const GaussianCloud cloud = ToFloat(SmallCloud(40, 12));
  for (const char* kind : kKinds) {
  SCOPED_TRACE(kind);
  const Model md = RandomModel(static_cast<int>(cloud.size()), 4, kind);
  AppearanceModel m;
  m.image_embeddings = md.image_embeddings.cast<float>();
  m.gaussian_embeddings = md.gaussian_embeddings.cast<float>();
  m.w1 = md.w1.cast<float>();
  m.w2 = md.w2.cast<float>();
  m.w3 = md.w3.cast<float>();
  m.b1 = md.b1.cast<float>();
  m.b2 = md.b2.cast<float>();
  m.b3 = md.b3.cast<float>();
  const Eigen::VectorXf e = m.image_embeddings.col(0);
  const auto affine = EvaluateAppearance(m, e, cloud);
  const PinholeCamera cam = TopCamera(48, 25.0);
  const RenderOutput<float> with_model = RenderGaussians(cloud, cam, RasterOptions{}, &affine);
  const RenderOutput<float> fused = RenderGaussians(FuseAppearance(m, e, cloud), cam, RasterOptions{});
  // float rounding of the fused coefficients: ~1e-7 relative per colour.
  constexpr float kFusedTol = 2e-5f;
  const RenderOutput<float> plain = RenderGaussians(cloud, cam, RasterOptions{});
  double max_diff = 0, spread = 0;
  for (std::size_t k = 0; k < fused.rgb.size(); ++k) {
    max_diff = std::max(max_diff, static_cast<double>(std::abs(fused.rgb[k] - with_model.rgb[k])));
    spread = std::max(spread, static_cast<double>(std::abs(with_model.rgb[k] - plain.rgb[k])));
  }
  EXPECT_LT(max_diff, kFusedTol);
  EXPECT_GT(spread, 0.01) << "the transform must change the image, or fusing proves nothing";
  }
}

TEST(Appearance, GatherKeepsEmbeddingsWithTheirGaussians) {
  AppearanceModel m = InitAppearance(AppearanceOptions{}, 2, 5, 1);
  const Eigen::MatrixXf before = m.gaussian_embeddings;
  m.GatherGaussians({4, 4, 0, 2});
  ASSERT_EQ(m.gaussian_embeddings.cols(), 4);
  EXPECT_EQ(m.gaussian_embeddings.col(0), before.col(4));
  EXPECT_EQ(m.gaussian_embeddings.col(1), before.col(4));
  EXPECT_EQ(m.gaussian_embeddings.col(2), before.col(0));
  EXPECT_EQ(m.gaussian_embeddings.col(3), before.col(2));
}

TEST(Appearance, TypicalImageIsNearestTheMeanEmbedding) {
  AppearanceModel m = InitAppearance(AppearanceOptions{}, 3, 1, 1);
  m.image_embeddings.col(0).setConstant(1.0f);
  m.image_embeddings.col(1).setConstant(0.1f);
  m.image_embeddings.col(2).setConstant(-1.0f);
  EXPECT_EQ(TypicalImage(m, {0, 1, 2}), 1);
  EXPECT_EQ(TypicalImage(m, {0, 1}), 0);  // a tie resolves to the first
  EXPECT_THROW(TypicalImage(m, {}), Error);
}

TEST(Appearance, SunAnglesAreMeasuredBetweenDirections) {
  // Both 45 deg high, 90 deg apart in azimuth: unit vectors (0, c, c) and
  // (c, 0, c) with c = cos 45, whose dot product is 1/2: 60 deg.
  EXPECT_NEAR(SunDirection(45, 0).AngleToDeg(SunDirection(45, 90)), 60.0, 1e-9);
  EXPECT_NEAR(SunDirection(30, 150).AngleToDeg(SunDirection(40, 150)), 10.0, 1e-9);
  // Azimuths wrap: 359 and 1 deg are 2 deg apart at the horizon.
  EXPECT_NEAR(SunDirection(0, 359).AngleToDeg(SunDirection(0, 1)), 2.0, 1e-9);
}

// Embeddings 0..3 hold the values 0, 1, 2, 3: which training images chose
// an embedding can be read off its value.
TEST(Appearance, AHeldOutDateTakesItsDaysOrNearestSunsEmbedding) {
  AppearanceModel m = InitAppearance(AppearanceOptions{}, 4, 1, 1);
  for (int j = 0; j < 4; ++j) m.image_embeddings.col(j).setConstant(static_cast<float>(j));
  const std::vector<EmbeddingSource> training = {{0, "2015-01-15T15:55:00Z", SunDirection(34, 154)},
                                                 {1, "2015-01-15T15:55:11Z", SunDirection(34, 154)},
                                                 {2, "2015-05-18T16:16:00Z", SunDirection(70, 120)},
                                                 {3, "2015-08-08T16:00:00Z", SunDirection(65.5, 121)}};
  std::string how;
  // The same UTC day (another pass seconds later): that day's images alone.
  EXPECT_FLOAT_EQ(EmbeddingForDate(m, training, "2015-01-15T15:56:00Z", SunDirection(34, 154), &how)(0), 0.5f);
  EXPECT_EQ(how, "same_date");
  // Another day: the sun nearest its own; 2 and 3 are 5.1 deg apart, so
  // only the nearest counts at the default 1 deg tolerance...
  EXPECT_FLOAT_EQ(EmbeddingForDate(m, training, "2015-06-01T16:00:00Z", SunDirection(71, 119), &how)(0), 2.0f);
  EXPECT_EQ(how, "nearest_sun");
  // ...and both within a wider one.
  EXPECT_FLOAT_EQ(EmbeddingForDate(m, training, "2015-06-01T16:00:00Z", SunDirection(71, 119), &how, 10.0)(0), 2.5f);
  // Neither a date in common nor a sun: the mean of all.
  EXPECT_FLOAT_EQ(EmbeddingForDate(m, training, "", SunDirection(), &how)(0), 1.5f);
  EXPECT_EQ(how, "mean");
  // Training images without sun angles give none to compare with.
  std::vector<EmbeddingSource> undated = training;
  for (EmbeddingSource& t : undated) t = {t.image, "", SunDirection()};
  EXPECT_FLOAT_EQ(EmbeddingForDate(m, undated, "2015-01-15T15:56:00Z", SunDirection(34, 154), &how)(0), 1.5f);
  EXPECT_EQ(how, "mean");
  EXPECT_THROW(EmbeddingForDate(m, {}, "", SunDirection()), Error);
}

TEST(Appearance, BadShapesAndOptionsAreNamed) {
  AppearanceOptions o;
  o.hidden = 0;
  EXPECT_THROW(o.Check(), Error);
  const AppearanceModel m = InitAppearance(AppearanceOptions{}, 2, 3, 1);
  GaussianCloud four;
  four.resize(4);
  try {
    EvaluateAppearance(m, Eigen::VectorXf(m.image_embeddings.col(0)), four);
    FAIL() << "a size mismatch must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("3 embeddings for 4 Gaussians"), std::string::npos) << e.what();
  }
  GaussianCloud three;
  three.resize(3);
  EXPECT_THROW(EvaluateAppearance(m, Eigen::VectorXf(Eigen::VectorXf::Zero(7)), three), Error);
}

}  // namespace
}  // namespace skyfall
