#include "splat/appearance.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#if defined(__x86_64__)
#include <immintrin.h>  // lanes_body.inc: one-instruction mask tests
#endif
#include <limits>
#include <memory>
#include <random>

#include "core/error.h"
#include "core/format.h"
#include "core/simd.h"
#include "core/simd_target.h"

namespace skyfall {
namespace {
// What a layer kernel does to W x + b before it stores it (mlp_kernels.inc).
enum class Epilogue { kNone, kRelu, kGate };
}  // namespace

// The MLP's kernels, once per SIMD path (core/simd_target.h): the same
// source at 4 lanes for the x86-64 baseline, 8 for AVX2 + FMA and 16 for
// AVX-512. GCC contracts a * b + c into one fused multiply-add where the
// target has FMA (its default for C++), so the wider paths also round once
// per multiply-add.
namespace mlp_baseline {
#define SKYFALL_MLP_LANES 4
#include "splat/mlp_kernels.inc"
#undef SKYFALL_MLP_LANES
}  // namespace mlp_baseline

#if defined(__x86_64__)
SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX2)
namespace mlp_avx2 {
#define SKYFALL_MLP_LANES 8
#include "splat/mlp_kernels.inc"
#undef SKYFALL_MLP_LANES
}  // namespace mlp_avx2
SKYFALL_TARGET_END

SKYFALL_TARGET_BEGIN(SKYFALL_TARGET_AVX512)
namespace mlp_avx512 {
#define SKYFALL_MLP_LANES 16
#include "splat/mlp_kernels.inc"
#undef SKYFALL_MLP_LANES
}  // namespace mlp_avx512
SKYFALL_TARGET_END
#endif
#define SKYFALL_MLP_PATHS(call) SKYFALL_RETURN_FOR_ACTIVE_PATH(mlp, call)

namespace {

// Gaussians per block of the batched MLP: enough columns for the kernels'
// passes, few enough that a block's inputs and activations (about 3 x hidden
// x block values, 200 kB in float) stay in the core's L2 cache.
constexpr std::size_t kBlock = 512;
// Blocks are padded with zero columns to a multiple of the widest path's
// pass (2 x 16 lanes).
constexpr std::size_t kColumnMultiple = 32;
std::size_t PaddedColumns(std::size_t n) { return (n + kColumnMultiple - 1) / kColumnMultiple * kColumnMultiple; }

template <typename T>
void LayerForward(const T* w, int out, int in, const T* bias, const T* x, int n, T* y, Epilogue e,
                  const T* gate = nullptr) {
  SKYFALL_MLP_PATHS(LayerForward(w, out, in, bias, x, n, n, y, n, e, gate));
}
template <typename T>
void AccumulateOuter(const T* a, int rows_a, const T* b, int rows_b, int n, T* c) {
  SKYFALL_MLP_PATHS(AccumulateOuter(a, rows_a, n, b, rows_b, n, n, c));
}
template <typename T>
void AccumulateRowSums(const T* a, int rows, int n, T* s) {
  SKYFALL_MLP_PATHS(AccumulateRowSums(a, rows, n, n, s));
}

template <typename T>
using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
template <typename T>
using Vec = Eigen::Matrix<T, Eigen::Dynamic, 1>;

// The MLP input colour: the SH degree-0 colour of Gaussians [a, a + n).
template <typename T>
Mat<T> BaseColours(const GaussianCloudT<T>& cloud, std::size_t a, std::size_t n) {
  Mat<T> c(3, n);
  for (std::size_t k = 0; k < n; ++k)
    for (int ch = 0; ch < 3; ++ch) c(ch, k) = T(kShC0) * cloud.sh[a + k][ch * 4] + T(0.5);
  return c;
}

template <typename T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The MLP's weights laid out for the kernels: row-major, and transposed for
// the backward pass. A column-major Eigen matrix is its transpose in
// row-major order, so the transposes are the model's own storage.
template <typename T>
struct MlpLayers {
  int hidden = 0, inputs = 0;  // inputs per Gaussian: gaussian_dim + 3 (the image's part is in b1)
  RowMat<T> w1, w2, w3;        // (hidden x inputs), (hidden x hidden), (6 x hidden)
  const T* w1_t = nullptr;     // (inputs x hidden)
  const T* w2_t = nullptr;     // (hidden x hidden)
  const T* w3_t = nullptr;     // (hidden x 6)
  Vec<T> b1;                   // the first layer's bias plus its image term
  const T* b2 = nullptr;
  const T* b3 = nullptr;
};

template <typename T>
MlpLayers<T> LayoutMlp(const AppearanceModelT<T>& m, const Vec<T>& first_layer_image_term) {
  MlpLayers<T> l;
  l.hidden = static_cast<int>(m.w1.rows());
  l.inputs = m.gaussian_dim() + 3;
  l.w1 = m.w1.rightCols(l.inputs);
  l.w2 = m.w2;
  l.w3 = m.w3;
  l.w1_t = m.w1.data() + static_cast<std::size_t>(m.image_dim()) * l.hidden;
  l.w2_t = m.w2.data();
  l.w3_t = m.w3.data();
  // The first layer is linear in the concatenated input [e; g; c], so the
  // image term is computed once per call, not once per Gaussian.
  l.b1 = first_layer_image_term;
  l.b2 = m.b2.data();
  l.b3 = m.b3.data();
  return l;
}

// The MLP's per-Gaussian input of Gaussians [a, a + n), feature-major with
// `np` columns: the embedding, then the SH degree-0 colour; padding is 0.
template <typename T>
std::vector<T> BlockInput(const AppearanceModelT<T>& m, const GaussianCloudT<T>& cloud, std::size_t a, std::size_t n,
                          std::size_t np) {
  const int dg = m.gaussian_dim();
  std::vector<T> x((dg + 3) * np, T(0));
  Eigen::Map<RowMat<T>> rows(x.data(), dg + 3, static_cast<Eigen::Index>(np));
  rows.topLeftCorner(dg, static_cast<Eigen::Index>(n)) =
      m.gaussian_embeddings.middleCols(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(n));
  rows.block(dg, 0, 3, static_cast<Eigen::Index>(n)) = BaseColours(cloud, a, n);
  return x;
}

// Forward activations of one block of Gaussians, feature-major (hidden x np).
// ReLU masks are read off h > 0 (equivalent to z > 0), so the
// pre-activations need not be kept.
template <typename T>
struct BlockActivations {
  std::vector<T> h1, h2, out;
};

template <typename T>
BlockActivations<T> ForwardBlock(const MlpLayers<T>& l, const std::vector<T>& x, std::size_t np) {
  const int n = static_cast<int>(np), h = l.hidden;
  BlockActivations<T> act;
  act.h1.resize(h * np);
  act.h2.resize(h * np);
  act.out.resize(6 * np);
  LayerForward(l.w1.data(), h, l.inputs, l.b1.data(), x.data(), n, act.h1.data(), Epilogue::kRelu);
  LayerForward(l.w2.data(), h, h, l.b2, act.h1.data(), n, act.h2.data(), Epilogue::kRelu);
  LayerForward(l.w3.data(), 6, h, l.b3, act.h2.data(), n, act.out.data(), Epilogue::kNone);
  return act;
}

template <typename T>
void CheckEmbedding(const AppearanceModelT<T>& m, const Vec<T>& embedding) {
  if (embedding.size() != m.image_dim()) {
    throw Error("appearance", "embedding", "has " + std::to_string(embedding.size()) + " values, the model takes " +
                                               std::to_string(m.image_dim()));
  }
}

template <typename T>
Vec<T> ImageTerm(const AppearanceModelT<T>& m, const Vec<T>& embedding) {
  CheckEmbedding(m, embedding);
  return m.w1.leftCols(m.image_dim()) * embedding + m.b1;
}

template <typename T>
void CheckCloud(const AppearanceModelT<T>& m, const GaussianCloudT<T>& cloud) {
  if (static_cast<std::size_t>(m.gaussian_embeddings.cols()) != cloud.size()) {
    throw Error("appearance", "gaussian_embeddings",
                std::to_string(m.gaussian_embeddings.cols()) + " embeddings for " + std::to_string(cloud.size()) +
                    " Gaussians");
  }
}

std::size_t Blocks(std::size_t n) { return (n + kBlock - 1) / kBlock; }

// Bilinear form: per-Gaussian features [g; c; 1] have gaussian_dim + 4 rows.
template <typename T>
int FeatureDim(const AppearanceModelT<T>& m) {
  return m.gaussian_dim() + 4;
}

// The image's matrix M (6 x features) and the hidden activations behind it.
template <typename T>
struct ImageMatrix {
  Vec<T> hidden;
  Mat<T> m;
};
template <typename T>
ImageMatrix<T> BilinearImageMatrix(const AppearanceModelT<T>& m, const Vec<T>& embedding) {
  CheckEmbedding(m, embedding);
  ImageMatrix<T> im;
  im.hidden = (m.w1 * embedding + m.b1).cwiseMax(T(0));
  const Vec<T> flat = m.w2 * im.hidden + m.b2;
  im.m = Eigen::Map<const Mat<T>>(flat.data(), 6, FeatureDim(m));
  return im;
}

// M [g; c; 1] for Gaussians [a, a + n).
template <typename T>
Mat<T> BilinearBlock(const AppearanceModelT<T>& m, const Mat<T>& im, const GaussianCloudT<T>& cloud, std::size_t a,
                     std::size_t n) {
  const int dg = m.gaussian_dim();
  Mat<T> out = im.leftCols(dg) * m.gaussian_embeddings.middleCols(a, n) + im.middleCols(dg, 3) * BaseColours(cloud, a, n);
  out.colwise() += im.col(dg + 3);
  return out;
}

template <typename T>
std::vector<ColourAffine<T>> EvaluateBilinear(const AppearanceModelT<T>& m, const Vec<T>& embedding,
                                              const GaussianCloudT<T>& cloud) {
  const Mat<T> im = BilinearImageMatrix(m, embedding).m;
  std::vector<ColourAffine<T>> affine(cloud.size());
  tbb::parallel_for(std::size_t{0}, Blocks(cloud.size()), [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a);
    const Mat<T> out = BilinearBlock(m, im, cloud, a, n);
    for (std::size_t k = 0; k < n; ++k) {
      affine[a + k] = out.col(k);
      affine[a + k].template head<3>().array() += T(1);
    }
  });
  return affine;
}

template <typename T>
Vec<T> BackwardBilinear(const AppearanceModelT<T>& m, const Vec<T>& embedding, const GaussianCloudT<T>& cloud,
                        const std::vector<ColourAffine<T>>& d_affine, AppearanceModelT<T>* grad,
                        std::vector<std::array<T, 3 * kShCoeffsPerChannel>>* d_sh) {
  const int dg = m.gaussian_dim();
  const ImageMatrix<T> im = BilinearImageMatrix(m, embedding);
  // dL/dM is summed per block, then over blocks in block order, so the
  // result does not depend on thread scheduling.
  const std::size_t blocks = Blocks(cloud.size());
  std::vector<Mat<T>> partial(blocks);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a);
    Mat<T> d_out(6, n);
    for (std::size_t k = 0; k < n; ++k) d_out.col(k) = d_affine[a + k];
    const Mat<T> colour = BaseColours(cloud, a, n);
    Mat<T>& d_m = partial[b];
    d_m.resize(6, FeatureDim(m));
    d_m.leftCols(dg) = d_out * m.gaussian_embeddings.middleCols(a, n).transpose();
    d_m.middleCols(dg, 3) = d_out * colour.transpose();
    d_m.col(dg + 3) = d_out.rowwise().sum();
    grad->gaussian_embeddings.middleCols(a, n) += im.m.leftCols(dg).transpose() * d_out;
    if (d_sh) {
      const Mat<T> d_colour = im.m.middleCols(dg, 3).transpose() * d_out;
      for (std::size_t k = 0; k < n; ++k)
        for (int ch = 0; ch < 3; ++ch) (*d_sh)[a + k][ch * 4] += T(kShC0) * d_colour(ch, k);
    }
  });
  Mat<T> d_m = Mat<T>::Zero(6, FeatureDim(m));
  for (const Mat<T>& p : partial) d_m += p;
  // Through the image MLP: flat = w2 h + b2, h = relu(w1 e + b1).
  const Eigen::Map<const Vec<T>> d_flat(d_m.data(), d_m.size());
  grad->w2 += d_flat * im.hidden.transpose();
  grad->b2 += d_flat;
  const Vec<T> d_z = (m.w2.transpose() * d_flat).cwiseProduct((im.hidden.array() > T(0)).matrix().template cast<T>());
  grad->w1 += d_z * embedding.transpose();
  grad->b1 += d_z;
  return m.w1.transpose() * d_z;
}

}  // namespace

void AppearanceOptions::Check() const {
  CheckOptionRanges(*this, "appearance");
}

template <typename T>
AppearanceModelT<T> AppearanceModelT<T>::ZerosLike() const {
  AppearanceModelT z;
  for (auto [dst, src] : {std::pair{&z.image_embeddings, &image_embeddings},
                          std::pair{&z.gaussian_embeddings, &gaussian_embeddings}, std::pair{&z.w1, &w1},
                          std::pair{&z.w2, &w2}, std::pair{&z.w3, &w3}})
    dst->setZero(src->rows(), src->cols());
  z.b1.setZero(b1.size());
  z.b2.setZero(b2.size());
  z.b3.setZero(b3.size());
  return z;
}

template <typename T>
void AppearanceModelT<T>::GatherGaussians(const std::vector<std::size_t>& source) {
  Mat kept(gaussian_embeddings.rows(), static_cast<Eigen::Index>(source.size()));
  for (std::size_t k = 0; k < source.size(); ++k) kept.col(k) = gaussian_embeddings.col(source[k]);
  gaussian_embeddings = std::move(kept);
}

AppearanceModel InitAppearance(const AppearanceOptions& o, int images, std::size_t gaussians, std::uint64_t seed) {
  o.Check();
  if (images < 1) throw Error("appearance", "images", "a model needs at least one image");
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal(0.0f, static_cast<float>(o.init_std));
  AppearanceModel m;
  const int in = o.image_dim + o.gaussian_dim + 3;
  m.image_embeddings = Eigen::MatrixXf::NullaryExpr(o.image_dim, images, [&] { return normal(rng); });
  m.gaussian_embeddings =
      Eigen::MatrixXf::NullaryExpr(o.gaussian_dim, static_cast<Eigen::Index>(gaussians), [&] { return normal(rng); });
  // Hidden layers: the usual uniform(-1/sqrt(fan_in), 1/sqrt(fan_in)).
  auto uniform = [&](int rows, int cols, int fan_in) {
    std::uniform_real_distribution<float> u(-1.0f / std::sqrt(static_cast<float>(fan_in)),
                                            1.0f / std::sqrt(static_cast<float>(fan_in)));
    return Eigen::MatrixXf(Eigen::MatrixXf::NullaryExpr(rows, cols, [&] { return u(rng); }));
  };
  if (o.model == AppearanceModelKind::kBilinear) {
    const int out = 6 * (o.gaussian_dim + 4);
    m.w1 = uniform(o.hidden, o.image_dim, o.image_dim);
    m.b1 = uniform(o.hidden, 1, o.image_dim);
    m.w2.setZero(out, o.hidden);  // M = 0: gamma = 1, beta = 0 until training moves it
    m.b2.setZero(out);
    m.w3.resize(0, 0);
    m.b3.resize(0);
    return m;
  }
  m.w1 = uniform(o.hidden, in, in);
  m.b1 = uniform(o.hidden, 1, in);
  m.w2 = uniform(o.hidden, o.hidden, o.hidden);
  m.b2 = uniform(o.hidden, 1, o.hidden);
  // Zero output layer: gamma = 1, beta = 0 until training moves it.
  m.w3.setZero(6, o.hidden);
  m.b3.setZero(6);
  return m;
}

template <typename T>
std::vector<ColourAffine<T>> EvaluateAppearance(const AppearanceModelT<T>& m, const Vec<T>& embedding,
                                                const GaussianCloudT<T>& cloud, AppearanceActivations<T>* keep) {
  CheckCloud(m, cloud);
  if (m.bilinear()) {
    if (keep) *keep = AppearanceActivations<T>{{}, {}, {}, cloud.size()};
    return EvaluateBilinear(m, embedding, cloud);
  }
  const MlpLayers<T> layers = LayoutMlp(m, ImageTerm(m, embedding));
  std::vector<ColourAffine<T>> affine(cloud.size());
  const std::size_t blocks = Blocks(cloud.size());
  if (keep) {
    keep->x.assign(blocks, {});
    keep->h1.assign(blocks, {});
    keep->h2.assign(blocks, {});
    keep->gaussians = cloud.size();
  }
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a), np = PaddedColumns(n);
    std::vector<T> x = BlockInput(m, cloud, a, n, np);
    BlockActivations<T> act = ForwardBlock(layers, x, np);
    for (std::size_t k = 0; k < n; ++k) {
      for (int f = 0; f < 6; ++f) affine[a + k][f] = act.out[f * np + k];
      affine[a + k].template head<3>().array() += T(1);
    }
    if (keep) {
      keep->x[b] = std::move(x);
      keep->h1[b] = std::move(act.h1);
      keep->h2[b] = std::move(act.h2);
    }
  });
  return affine;
}

template <typename T>
Vec<T> BackwardAppearance(const AppearanceModelT<T>& m, const Vec<T>& embedding, const GaussianCloudT<T>& cloud,
                          const std::vector<ColourAffine<T>>& d_affine, AppearanceModelT<T>* grad,
                          std::vector<std::array<T, 3 * kShCoeffsPerChannel>>* d_sh,
                          const AppearanceActivations<T>* kept) {
  CheckCloud(m, cloud);
  if (kept && kept->gaussians != cloud.size()) {
    throw Error("appearance", "kept activations", "are for " + std::to_string(kept->gaussians) + " Gaussians, not " +
                                                      std::to_string(cloud.size()));
  }
  if (d_affine.size() != cloud.size()) throw Error("appearance", "d_affine", "size differs from the cloud");
  if (m.bilinear()) return BackwardBilinear(m, embedding, cloud, d_affine, grad, d_sh);
  const int de = m.image_dim(), dg = m.gaussian_dim();
  const MlpLayers<T> l = LayoutMlp(m, ImageTerm(m, embedding));
  const int h = l.hidden;
  // Weight gradients (row-major, as the kernels write them) are summed per
  // block, then over blocks in block order, so the result does not depend
  // on thread scheduling.
  const std::size_t blocks = Blocks(cloud.size());
  struct Partial {
    RowMat<T> w1, w2, w3;  // w1: the per-Gaussian inputs' columns only
    Vec<T> b1, b2, b3;
  };
  std::vector<Partial> partial(blocks);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a), np = PaddedColumns(n);
    const int cols = static_cast<int>(np);
    std::vector<T> fresh_x;
    if (!kept) fresh_x = BlockInput(m, cloud, a, n, np);
    const std::vector<T>& x = kept ? kept->x[b] : fresh_x;
    BlockActivations<T> recomputed;
    if (!kept) recomputed = ForwardBlock(l, x, np);
    const std::vector<T>& h1 = kept ? kept->h1[b] : recomputed.h1;
    const std::vector<T>& h2 = kept ? kept->h2[b] : recomputed.h2;
    std::vector<T> d_out(6 * np, T(0));  // zero in the padding: no gradient flows from it
    for (std::size_t k = 0; k < n; ++k)
      for (int f = 0; f < 6; ++f) d_out[f * np + k] = d_affine[a + k][f];
    Partial& p = partial[b];
    p.w3.setZero(6, h);
    p.w2.setZero(h, h);
    p.w1.setZero(h, l.inputs);
    p.b3.setZero(6);
    p.b2.setZero(h);
    p.b1.setZero(h);
    AccumulateOuter(d_out.data(), 6, h2.data(), h, cols, p.w3.data());
    AccumulateRowSums(d_out.data(), 6, cols, p.b3.data());
    // Written whole by LayerForward, so not zeroed first (zeroing every
    // block's buffers cost about a tenth of the appearance model's time).
    const std::unique_ptr<T[]> d_z2(new T[h * np]), d_z1(new T[h * np]), d_x(new T[l.inputs * np]);
    LayerForward(l.w3_t, h, 6, static_cast<const T*>(nullptr), d_out.data(), cols, d_z2.get(), Epilogue::kGate, h2.data());
    AccumulateOuter(d_z2.get(), h, h1.data(), h, cols, p.w2.data());
    AccumulateRowSums(d_z2.get(), h, cols, p.b2.data());
    LayerForward(l.w2_t, h, h, static_cast<const T*>(nullptr), d_z2.get(), cols, d_z1.get(), Epilogue::kGate, h1.data());
    AccumulateOuter(d_z1.get(), h, x.data(), l.inputs, cols, p.w1.data());
    AccumulateRowSums(d_z1.get(), h, cols, p.b1.data());
    LayerForward(l.w1_t, l.inputs, h, static_cast<const T*>(nullptr), d_z1.get(), cols, d_x.get(), Epilogue::kNone);
    for (std::size_t k = 0; k < n; ++k) {
      T* g = grad->gaussian_embeddings.col(static_cast<Eigen::Index>(a + k)).data();
      for (int f = 0; f < dg; ++f) g[f] += d_x[f * np + k];
    }
    if (d_sh) {
      for (std::size_t k = 0; k < n; ++k)
        for (int ch = 0; ch < 3; ++ch) (*d_sh)[a + k][ch * 4] += T(kShC0) * d_x[(dg + ch) * np + k];
    }
  });
  Vec<T> d_b1_total = Vec<T>::Zero(m.b1.size());
  for (const Partial& p : partial) {
    grad->w1.rightCols(l.inputs) += p.w1;
    grad->w2 += p.w2;
    grad->w3 += p.w3;
    grad->b1 += p.b1;
    grad->b2 += p.b2;
    grad->b3 += p.b3;
    d_b1_total += p.b1;
  }
  // The image embedding enters only through w1's left block, like a bias:
  // that block's gradient is the summed first-layer gradient times e^T, and
  // the embedding's is the block's transpose times that sum.
  grad->w1.leftCols(de) += d_b1_total * embedding.transpose();
  return m.w1.leftCols(de).transpose() * d_b1_total;
}

GaussianCloud FuseAppearance(const AppearanceModel& model, const Eigen::VectorXf& embedding, const GaussianCloud& cloud) {
  const std::vector<ColourAffine<float>> affine = EvaluateAppearance(model, embedding, cloud);
  GaussianCloud fused = cloud;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int ch = 0; ch < 3; ++ch) {
      // gamma (C0 dc + 0.5 + rest) + beta = C0 dc' + 0.5 + rest'
      const double gamma = affine[i][ch], beta = affine[i][3 + ch];
      const double dc = cloud.sh[i][ch * 4];
      fused.sh[i][ch * 4] = static_cast<float>((gamma * (kShC0 * dc + 0.5) + beta - 0.5) / kShC0);
      for (int k = 1; k < kShCoeffsPerChannel; ++k)
        fused.sh[i][ch * 4 + k] = static_cast<float>(gamma * cloud.sh[i][ch * 4 + k]);
    }
  }
  return fused;
}

int TypicalImage(const AppearanceModel& model, const std::vector<int>& images) {
  if (images.empty()) throw Error("appearance", "images", "no image to choose an embedding from");
  Eigen::VectorXf mean = Eigen::VectorXf::Zero(model.image_dim());
  for (int j : images) mean += model.image_embeddings.col(j);
  mean /= static_cast<float>(images.size());
  int best = images.front();
  float best_d = std::numeric_limits<float>::infinity();
  for (int j : images) {
    const float d = (model.image_embeddings.col(j) - mean).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best = j;
    }
  }
  return best;
}

double SunDirection::AngleToDeg(const SunDirection& other) const {
  auto unit = [](const SunDirection& s) {
    const double el = s.elevation_deg * M_PI / 180, az = s.azimuth_deg * M_PI / 180;
    return Eigen::Vector3d(std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), std::sin(el));
  };
  const double c = std::clamp(unit(*this).dot(unit(other)), -1.0, 1.0);
  return std::acos(c) * 180 / M_PI;
}

Eigen::VectorXf EmbeddingForDate(const AppearanceModel& model, const std::vector<EmbeddingSource>& training,
                                 const std::string& acquisition_time, const SunDirection& sun, std::string* how,
                                 double sun_tolerance_deg) {
  if (training.empty()) throw Error("appearance", "images", "no training image to choose an embedding from");
  auto mean_of = [&](auto&& chosen) {
    Eigen::VectorXf sum = Eigen::VectorXf::Zero(model.image_dim());
    int n = 0;
    for (const EmbeddingSource& t : training)
      if (chosen(t)) {
        sum += model.image_embeddings.col(t.image);
        ++n;
      }
    return std::make_pair(n, n ? Eigen::VectorXf(sum / static_cast<float>(n)) : sum);
  };
  auto say = [&](const char* rule) {
    if (how) *how = rule;
  };
  constexpr std::size_t kDay = 10;  // "YYYY-MM-DD"
  if (acquisition_time.size() >= kDay) {
    const auto [n, e] = mean_of([&](const EmbeddingSource& t) {
      return t.acquisition_time.size() >= kDay && t.acquisition_time.compare(0, kDay, acquisition_time, 0, kDay) == 0;
    });
    if (n) {
      say("same_date");
      return e;
    }
  }
  if (sun.known) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const EmbeddingSource& t : training)
      if (t.sun.known) nearest = std::min(nearest, sun.AngleToDeg(t.sun));
    const auto [n, e] = mean_of(
        [&](const EmbeddingSource& t) { return t.sun.known && sun.AngleToDeg(t.sun) <= nearest + sun_tolerance_deg; });
    if (n) {
      say("nearest_sun");
      return e;
    }
  }
  say("mean");
  return mean_of([](const EmbeddingSource&) { return true; }).second;
}

template struct AppearanceModelT<float>;
template struct AppearanceModelT<double>;
template std::vector<ColourAffine<float>> EvaluateAppearance(const AppearanceModelT<float>&, const Vec<float>&,
                                                             const GaussianCloudT<float>&,
                                                             AppearanceActivations<float>*);
template std::vector<ColourAffine<double>> EvaluateAppearance(const AppearanceModelT<double>&, const Vec<double>&,
                                                              const GaussianCloudT<double>&,
                                                              AppearanceActivations<double>*);
template Vec<float> BackwardAppearance(const AppearanceModelT<float>&, const Vec<float>&, const GaussianCloudT<float>&,
                                       const std::vector<ColourAffine<float>>&, AppearanceModelT<float>*,
                                       std::vector<std::array<float, 12>>*, const AppearanceActivations<float>*);
template Vec<double> BackwardAppearance(const AppearanceModelT<double>&, const Vec<double>&,
                                        const GaussianCloudT<double>&, const std::vector<ColourAffine<double>>&,
                                        AppearanceModelT<double>*, std::vector<std::array<double, 12>>*,
                                        const AppearanceActivations<double>*);

}  // namespace skyfall
