#include "splat/train_evaluation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>

#include "core/error.h"
#include "core/format.h"
#include "splat/losses.h"
#include "splat/rasterizer.h"

namespace skyfall {
namespace {

// `camera`'s render of `c` through the colour transforms of `embedding`;
// without the appearance model, the plain render (`embedding` unused).
RenderOutput<float> RenderWithEmbedding(const GaussianCloud& c, const PinholeCamera& camera,
                                        const RasterOptions& raster, const AppearanceState& appearance,
                                        const Eigen::VectorXf& embedding) {
  if (!appearance.enabled) return RenderGaussians<float>(c, camera, raster, nullptr);
  const std::vector<ColourAffine<float>> affine = EvaluateAppearance(appearance.model, embedding, c);
  return RenderGaussians(c, camera, raster, &affine);
}

double ViewPsnr(const GaussianCloud& c, const TrainView& v, const RasterOptions& raster,
                const AppearanceState& appearance, const Eigen::VectorXf& embedding) {
  return MaskedPsnr(RenderWithEmbedding(c, v.camera, raster, appearance, embedding).rgb, v.rgb, v.valid);
}

// The training views as EmbeddingForDate reads them.
std::vector<EmbeddingSource> EmbeddingSources(const std::vector<TrainView>& views, const std::vector<int>& train_ids) {
  std::vector<EmbeddingSource> sources;
  for (int j : train_ids) sources.push_back({j, views[j].acquisition_time, views[j].sun});
  return sources;
}

// Held-out views have no embedding of their own. With the appearance model
// a held-out view is rendered with the embedding its acquisition metadata
// choose (EmbeddingForDate: the same day's, else the nearest sun's), or
// with the mean training embedding (`by_date` false: the figure before that
// choice, kept for comparison).
RenderOutput<float> RenderHeldOut(const GaussianCloud& c, const TrainView& v, const RasterOptions& raster,
                                  const AppearanceState& appearance, const std::vector<EmbeddingSource>& sources,
                                  bool by_date) {
  if (!appearance.enabled) return RenderWithEmbedding(c, v.camera, raster, appearance, Eigen::VectorXf());
  // Without a date or sun, EmbeddingForDate gives the mean.
  const Eigen::VectorXf embedding = by_date ? EmbeddingForDate(appearance.model, sources, v.acquisition_time, v.sun)
                                            : EmbeddingForDate(appearance.model, sources, "", SunDirection());
  return RenderWithEmbedding(c, v.camera, raster, appearance, embedding);
}

// Sat-NeRF's test protocol: `v` rendered with every training view's
// embedding; the best PSNR and whose embedding gave it go into `r`.
void BestTrainingEmbedding(const GaussianCloud& c, const TrainView& v, const RasterOptions& raster,
                           const AppearanceState& appearance, const std::vector<TrainView>& views,
                           const std::vector<int>& train_ids, HeldOutRender* r) {
  r->best_embedding_psnr_db = std::numeric_limits<double>::quiet_NaN();
  for (int j : train_ids) {
    const double psnr = ViewPsnr(c, v, raster, appearance, appearance.model.image_embeddings.col(j));
    if (std::isnan(r->best_embedding_psnr_db) || psnr > r->best_embedding_psnr_db) {  // a NaN render never wins
      r->best_embedding_psnr_db = psnr;
      r->best_embedding_view = views[j].name;
    }
  }
}

}  // namespace

// The mean PSNR of the held-out views (NaN: none), each rendered by
// RenderHeldOut and scored over its pixels with data.
double HeldOutPsnr(const GaussianCloud& c, const std::vector<TrainView>& views, const RasterOptions& raster,
                   const AppearanceState& appearance, const std::vector<int>& train_ids, bool by_date) {
  const std::vector<EmbeddingSource> sources = EmbeddingSources(views, train_ids);
  double sum = 0;
  int n = 0;
  for (const TrainView& v : views) {
    if (!v.held_out) continue;
    sum += MaskedPsnr(RenderHeldOut(c, v, raster, appearance, sources, by_date).rgb, v.rgb, v.valid);
    ++n;
  }
  return n ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

// Every held-out view rendered with the embedding its date chooses, with
// its PSNR, its PSNR with colours fitted on its left half (HalfFittedPsnr:
// what is left once the held-out date's radiometry, which no model trained
// on other dates can know, is taken out) and, with the appearance model,
// its best PSNR under Sat-NeRF's protocol (BestTrainingEmbedding).
std::vector<HeldOutRender> HeldOutRenders(const GaussianCloud& c, const std::vector<TrainView>& views,
                                          const RasterOptions& raster, const AppearanceState& appearance,
                                          const std::vector<int>& train_ids) {
  const std::vector<EmbeddingSource> sources = EmbeddingSources(views, train_ids);
  std::vector<HeldOutRender> renders;
  for (const TrainView& v : views) {
    if (!v.held_out) continue;
    HeldOutRender r;
    r.name = v.name;
    r.width_px = v.camera.width_px;
    r.height_px = v.camera.height_px;
    r.rgb = RenderHeldOut(c, v, raster, appearance, sources, true).rgb;
    r.target = v.rgb;
    r.psnr_db = MaskedPsnr(r.rgb, v.rgb, v.valid);
    r.fitted_psnr_db = HalfFittedPsnr(r.rgb, v.rgb, v.camera.width_px, v.camera.height_px, v.valid);
    r.best_embedding_psnr_db = r.psnr_db;
    if (appearance.enabled) BestTrainingEmbedding(c, v, raster, appearance, views, train_ids, &r);
    renders.push_back(std::move(r));
  }
  return renders;
}

// The mean of one figure over the held-out renders (NaN: none).
double MeanOverHeldOut(const std::vector<HeldOutRender>& renders, double HeldOutRender::*figure) {
  if (renders.empty()) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0;
  for (const HeldOutRender& r : renders) sum += r.*figure;
  return sum / static_cast<double>(renders.size());
}

// How many held-out views each rule of EmbeddingForDate chose for, by
// report metric name.
std::map<std::string, double> HeldOutEmbeddingRules(const std::vector<TrainView>& views,
                                                    const AppearanceState& appearance,
                                                    const std::vector<int>& train_ids) {
  std::map<std::string, double> count;
  if (!appearance.enabled) return count;
  const std::vector<EmbeddingSource> sources = EmbeddingSources(views, train_ids);
  for (const TrainView& v : views) {
    if (!v.held_out) continue;
    std::string how;
    EmbeddingForDate(appearance.model, sources, v.acquisition_time, v.sun, &how);
    count["heldout_embedding_" + how] += 1;
  }
  return count;
}

// Mean PSNR of the training views, each rendered with its own embedding:
// how well the model fits what it was trained on.
double TrainingPsnr(const GaussianCloud& c, const std::vector<TrainView>& views, const RasterOptions& raster,
                    const AppearanceState& appearance, const std::vector<int>& train_ids) {
  double sum = 0;
  for (int j : train_ids) {
    const Eigen::VectorXf embedding = appearance.enabled ? appearance.model.image_embeddings.col(j) : Eigen::VectorXf();
    sum += ViewPsnr(c, views[j], raster, appearance, embedding);
  }
  return sum / static_cast<double>(train_ids.size());
}

std::size_t CoincidentGaussians(const GaussianCloud& cloud, double within_m) {
  if (!(within_m > 0)) throw Error("splat", "coincident radius", FormatDouble(within_m) + " m must be > 0");
  const CentreGrid grid(cloud, within_m);
  std::size_t coincident = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    bool found = false;
    grid.ForEachNear(i, [&found](std::size_t) { return !(found = true); });
    coincident += found;
  }
  return coincident;
}

}  // namespace skyfall
