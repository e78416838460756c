// Appearance modelling for multi-date imagery (Skyfall-GS, after
// WildGaussians): a per-image embedding e_j, a per-Gaussian embedding g_i and
// a small MLP f give an affine colour transform per Gaussian and image,
//   (gamma, beta) = f(e_j, g_i, c_i),   colour = gamma * c(view) + beta,
// where c_i is the Gaussian's SH degree-0 colour (kShC0 * dc + 0.5). The
// transform is applied before the rasterizer's clamp at 0, so fusing it into
// static SH colours for a chosen embedding (FuseAppearance) renders exactly
// what the model renders with that embedding.
//
// Two forms of f, both starting at gamma = 1, beta = 0 (the plain 3DGS
// colours), since their last layer starts at zero:
// - "mlp" (the paper's): in -> hidden -> hidden -> 6 with ReLU on the
//   concatenated input [e_j; g_i; c_i]; its output o gives gamma = 1 + o[0..2]
//   and beta = o[3..5]. About 20k multiply-adds per Gaussian and step,
//   forward, at the paper's hidden width 128; 3k at the default 32.
// - "bilinear": a small MLP of the image embedding alone (e_j -> hidden -> 6
//   x (gaussian_dim + 4), ReLU) gives a matrix M_j, and o = M_j [g_i; c_i; 1].
//   Every Gaussian still has its own transform in every image, but the
//   per-Gaussian cost is one 6 x (gaussian_dim + 4) product (168
//   multiply-adds at the paper's embedding sizes).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/enum_codec.h"
#include "core/gaussians.h"
#include "core/option_range.h"

namespace skyfall {

// Which appearance network (see above).
enum class AppearanceModelKind { kMlp, kBilinear };
template <>
struct EnumNames<AppearanceModelKind> {
  static constexpr std::array<std::pair<AppearanceModelKind, const char*>, 2> kNames = {
      {{AppearanceModelKind::kMlp, "mlp"}, {AppearanceModelKind::kBilinear, "bilinear"}}};
};

struct AppearanceOptions {
  bool enabled = false;
  AppearanceModelKind model = AppearanceModelKind::kMlp;
  int image_dim = 32;        // per-image embedding size (paper: 32)
  int gaussian_dim = 24;     // per-Gaussian embedding size (paper: 24)
  // Width of the hidden layers. The paper has 2 x 128; 32 gives about the
  // same DSM and held-out views for much less time (decision D-028).
  int hidden = 32;
  double lr_image = 0.001;   // Adam learning rates (paper)
  double lr_gaussian = 0.005;
  double lr_mlp = 0.0005;
  // Embeddings start as N(0, init_std^2): small, so that the first layer's
  // random weights see a well-scaled input, and distinct, so that images can
  // diverge from the first step.
  double init_std = 0.1;
  void Check() const;  // throws Error("appearance", field, ...)
};
template <class IO> void Visit(IO& io, AppearanceOptions& o) {
  io.NotAnOption(o.enabled);  // decided by train.appearance
  io("model", o.model,
     "'mlp' (the paper's MLP on both embeddings and the colour) or 'bilinear' (a cheaper MLP on the image embedding "
     "alone)");
  io("image_dim", o.image_dim,
     "Size of the per-image embedding", range::In(1, 1024));
  io("gaussian_dim", o.gaussian_dim,
     "Size of the per-Gaussian embedding", range::In(1, 1024));
  io("hidden", o.hidden,
     "Width of the MLP's hidden layers", range::In(1, 4096));
  io("lr_image", o.lr_image,
     "Adam learning rate of the per-image embeddings", range::Above(0));
  io("lr_gaussian", o.lr_gaussian,
     "Adam learning rate of the per-Gaussian embeddings", range::Above(0));
  io("lr_mlp", o.lr_mlp,
     "Adam learning rate of the MLP's weights", range::Above(0));
  io("init_std", o.init_std,
     "Standard deviation of the embeddings' random start, N(0, init_std^2)", range::Above(0));
}

// Per Gaussian: gamma (r, g, b) then beta (r, g, b).
template <typename T>
using ColourAffine = Eigen::Matrix<T, 6, 1>;

template <typename T>
struct AppearanceModelT {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  using Vec = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  Mat image_embeddings;     // image_dim x images
  Mat gaussian_embeddings;  // gaussian_dim x Gaussians (column i belongs to Gaussian i)
  // "mlp": layers (hidden x in), (hidden x hidden), (6 x hidden).
  // "bilinear": (hidden x image_dim), (6 (gaussian_dim + 4) x hidden), w3
  // and b3 empty.
  Mat w1, w2, w3;
  Vec b1, b2, b3;

  bool bilinear() const { return w3.size() == 0; }
  const char* kind() const { return bilinear() ? "bilinear" : "mlp"; }
  int image_dim() const { return static_cast<int>(image_embeddings.rows()); }
  int gaussian_dim() const { return static_cast<int>(gaussian_embeddings.rows()); }
  // The same shapes, all zero (gradients, optimizer moments).
  AppearanceModelT ZerosLike() const;
  // Keeps Gaussian columns `source[k]` in order (densification and pruning).
  void GatherGaussians(const std::vector<std::size_t>& source);
};
using AppearanceModel = AppearanceModelT<float>;

// A model for `images` images and `gaussians` Gaussians.
AppearanceModel InitAppearance(const AppearanceOptions& options, int images, std::size_t gaussians, std::uint64_t seed);

// The inputs and hidden activations of one evaluation, kept for the
// backward pass (gaussian_dim + 3 + 2 x hidden floats per Gaussian: 1.1 kB at
// the paper's sizes) so that it need not recompute them.
template <typename T>
struct AppearanceActivations {
  std::vector<std::vector<T>> x, h1, h2;  // per block of Gaussians, feature-major
  std::size_t gaussians = 0;
};

// The colour transform of every Gaussian for image embedding `embedding`
// (a column of image_embeddings, or any vector of that size, e.g. their mean).
// With `keep`, the activations are kept there for BackwardAppearance.
template <typename T>
std::vector<ColourAffine<T>> EvaluateAppearance(const AppearanceModelT<T>& model,
                                                const Eigen::Matrix<T, Eigen::Dynamic, 1>& embedding,
                                                const GaussianCloudT<T>& cloud,
                                                AppearanceActivations<T>* keep = nullptr);

// Back-propagates dL/d(gamma, beta) through the MLP. Adds to `grad` (same
// shapes as the model: weights, biases, the Gaussian embeddings) and returns
// dL/d(embedding); adds dL/d(SH dc) through the MLP's colour input to `d_sh`.
// `kept` (from EvaluateAppearance with the same model, embedding and cloud)
// saves recomputing the forward pass.
template <typename T>
Eigen::Matrix<T, Eigen::Dynamic, 1> BackwardAppearance(const AppearanceModelT<T>& model,
                                                       const Eigen::Matrix<T, Eigen::Dynamic, 1>& embedding,
                                                       const GaussianCloudT<T>& cloud,
                                                       const std::vector<ColourAffine<T>>& d_affine,
                                                       AppearanceModelT<T>* grad,
                                                       std::vector<std::array<T, 3 * kShCoeffsPerChannel>>* d_sh,
                                                       const AppearanceActivations<T>* kept = nullptr);

// A plain 3DGS cloud whose SH colours render as the model does with
// `embedding` (the embeddings and the MLP are then no longer needed).
GaussianCloud FuseAppearance(const AppearanceModel& model, const Eigen::VectorXf& embedding, const GaussianCloud& cloud);

// Index of the image whose embedding is nearest the mean of `images`: a
// typical appearance, the default for export.
int TypicalImage(const AppearanceModel& model, const std::vector<int>& images);

// The sun at an image's acquisition, as the catalog states it.
struct SunDirection {
  bool known = false;
  double elevation_deg = 0;
  double azimuth_deg = 0;  // clockwise from north
  SunDirection() = default;
  SunDirection(double elevation, double azimuth) : known(true), elevation_deg(elevation), azimuth_deg(azimuth) {}
  // Angle between the two directions toward the sun [deg].
  double AngleToDeg(const SunDirection& other) const;
};

// What a training image contributes to choosing the embedding of an image
// the model was not trained on.
struct EmbeddingSource {
  int image = 0;                 // column of AppearanceModel::image_embeddings
  std::string acquisition_time;  // ISO 8601 UTC, empty when unknown
  SunDirection sun;
};

// The embedding to render an image that has none of its own (a held-out
// view) with, from its acquisition metadata alone, never its pixels: the
// mean embedding of the training images taken the same UTC day (one pass of
// the satellite: the same light, shadows and cars); else of those whose sun
// stood nearest its own (within sun_tolerance_deg of the nearest: the
// shadows a date casts follow the sun); else, without dates or sun angles,
// the mean of all. `how` (optional) says which rule chose it.
Eigen::VectorXf EmbeddingForDate(const AppearanceModel& model, const std::vector<EmbeddingSource>& training,
                                 const std::string& acquisition_time, const SunDirection& sun,
                                 std::string* how = nullptr, double sun_tolerance_deg = 1.0);

}  // namespace skyfall
