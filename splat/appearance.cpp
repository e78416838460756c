#include "splat/appearance.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"
#include "core/format.h"

namespace skyfall {
namespace {

// Gaussians per block of the batched MLP: large enough for efficient matrix
// products, small enough that a block's activations (2 x hidden x block
// floats = 2 MB) stay in cache and the blocks spread over the cores.
constexpr std::size_t kBlock = 2048;

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

// Forward activations of one block of Gaussians. ReLU masks are read off
// h > 0 (equivalent to z > 0), so the pre-activations need not be kept.
template <typename T>
struct BlockActivations {
  Mat<T> colour, h1, h2, out;
};

template <typename T>
BlockActivations<T> ForwardBlock(const AppearanceModelT<T>& m, const Vec<T>& first_layer_image_term,
                                 const GaussianCloudT<T>& cloud, std::size_t a, std::size_t n) {
  const int de = m.image_dim(), dg = m.gaussian_dim();
  BlockActivations<T> act;
  act.colour = BaseColours(cloud, a, n);
  // The first layer is linear in the concatenated input [e; g; c], so the
  // image term is computed once per call, not once per Gaussian.
  act.h1 = m.w1.middleCols(de, dg) * m.gaussian_embeddings.middleCols(a, n) + m.w1.rightCols(3) * act.colour;
  act.h1.colwise() += first_layer_image_term;
  act.h1 = act.h1.cwiseMax(T(0));
  act.h2 = m.w2 * act.h1;
  act.h2.colwise() += m.b2;
  act.h2 = act.h2.cwiseMax(T(0));
  act.out = m.w3 * act.h2;
  act.out.colwise() += m.b3;
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
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw Error("appearance", field, FormatDouble(v) + " is out of range");
  };
  need(image_dim >= 1 && image_dim <= 1024, "image_dim", image_dim);
  need(gaussian_dim >= 1 && gaussian_dim <= 1024, "gaussian_dim", gaussian_dim);
  need(hidden >= 1 && hidden <= 4096, "hidden", hidden);
  for (double lr : {lr_image, lr_gaussian, lr_mlp}) need(lr > 0 && std::isfinite(lr), "learning rate", lr);
  need(init_std > 0 && std::isfinite(init_std), "init_std", init_std);
  if (model != "mlp" && model != "bilinear") throw Error("appearance", "model", "'" + model + "' is not 'mlp' or 'bilinear'");
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
  if (o.model == "bilinear") {
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
    if (keep) *keep = AppearanceActivations<T>{{}, {}, cloud.size()};
    return EvaluateBilinear(m, embedding, cloud);
  }
  const Vec<T> image_term = ImageTerm(m, embedding);
  std::vector<ColourAffine<T>> affine(cloud.size());
  const std::size_t blocks = Blocks(cloud.size());
  if (keep) {
    keep->h1.assign(blocks, Mat<T>());
    keep->h2.assign(blocks, Mat<T>());
    keep->gaussians = cloud.size();
  }
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a);
    BlockActivations<T> act = ForwardBlock(m, image_term, cloud, a, n);
    for (std::size_t k = 0; k < n; ++k) {
      affine[a + k] = act.out.col(k);
      affine[a + k].template head<3>().array() += T(1);
    }
    if (keep) {
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
  const Vec<T> image_term = ImageTerm(m, embedding);
  // Weight gradients are summed per block, then over blocks in block order,
  // so the result does not depend on thread scheduling.
  const std::size_t blocks = Blocks(cloud.size());
  struct Partial {
    Mat<T> w1, w2, w3;
    Vec<T> b1, b2, b3;
  };
  std::vector<Partial> partial(blocks);
  tbb::parallel_for(std::size_t{0}, blocks, [&](std::size_t b) {
    const std::size_t a = b * kBlock, n = std::min(kBlock, cloud.size() - a);
    BlockActivations<T> recomputed;
    if (!kept) recomputed = ForwardBlock(m, image_term, cloud, a, n);
    const Mat<T>& h1 = kept ? kept->h1[b] : recomputed.h1;
    const Mat<T>& h2 = kept ? kept->h2[b] : recomputed.h2;
    const Mat<T> colour = kept ? BaseColours(cloud, a, n) : recomputed.colour;
    Mat<T> d_out(6, n);
    for (std::size_t k = 0; k < n; ++k) d_out.col(k) = d_affine[a + k];
    Partial& p = partial[b];
    p.w3 = d_out * h2.transpose();
    p.b3 = d_out.rowwise().sum();
    const Mat<T> d_z2 = (m.w3.transpose() * d_out).cwiseProduct((h2.array() > T(0)).matrix().template cast<T>());
    p.w2 = d_z2 * h1.transpose();
    p.b2 = d_z2.rowwise().sum();
    const Mat<T> d_z1 = (m.w2.transpose() * d_z2).cwiseProduct((h1.array() > T(0)).matrix().template cast<T>());
    p.b1 = d_z1.rowwise().sum();
    p.w1.setZero(m.w1.rows(), m.w1.cols());
    p.w1.leftCols(de) = p.b1 * embedding.transpose();
    p.w1.middleCols(de, dg) = d_z1 * m.gaussian_embeddings.middleCols(a, n).transpose();
    p.w1.rightCols(3) = d_z1 * colour.transpose();
    grad->gaussian_embeddings.middleCols(a, n) += m.w1.middleCols(de, dg).transpose() * d_z1;
    if (d_sh) {
      const Mat<T> d_colour = m.w1.rightCols(3).transpose() * d_z1;
      for (std::size_t k = 0; k < n; ++k)
        for (int ch = 0; ch < 3; ++ch) (*d_sh)[a + k][ch * 4] += T(kShC0) * d_colour(ch, k);
    }
  });
  Vec<T> d_b1_total = Vec<T>::Zero(m.b1.size());
  for (const Partial& p : partial) {
    grad->w1 += p.w1;
    grad->w2 += p.w2;
    grad->w3 += p.w3;
    grad->b1 += p.b1;
    grad->b2 += p.b2;
    grad->b3 += p.b3;
    d_b1_total += p.b1;
  }
  // The embedding enters only through w1's left block: its gradient is that
  // block's transpose times the summed first-layer gradient.
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
