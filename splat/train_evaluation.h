// How a training run scores the scene against its views (not a public
// header): the held-out views' PSNR (by the nearest training date's
// embedding), their renders for the report, and the training views' PSNR.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/gaussians.h"
#include "splat/optimizer_state.h"
#include "splat/trainer.h"

namespace skyfall {

// The mean PSNR of the held-out views (NaN: none), each rendered by
// RenderHeldOut and scored over its pixels with data.
double HeldOutPsnr(const GaussianCloud& c, const std::vector<TrainView>& views, const RasterOptions& raster,
                   const AppearanceState& appearance, const std::vector<int>& train_ids, bool by_date = true);

// Every held-out view rendered with the embedding its date chooses, with
// its PSNR, its PSNR with colours fitted on its left half (HalfFittedPsnr:
// what is left once the held-out date's radiometry, which no model trained
// on other dates can know, is taken out) and, with the appearance model,
// its best PSNR under Sat-NeRF's protocol (BestTrainingEmbedding).
std::vector<HeldOutRender> HeldOutRenders(const GaussianCloud& c, const std::vector<TrainView>& views,
                                          const RasterOptions& raster, const AppearanceState& appearance,
                                          const std::vector<int>& train_ids);

// The mean of one figure over the held-out renders (NaN: none).
double MeanOverHeldOut(const std::vector<HeldOutRender>& renders, double HeldOutRender::*figure);

// How many held-out views each rule of EmbeddingForDate chose for, by
// report metric name.
std::map<std::string, double> HeldOutEmbeddingRules(const std::vector<TrainView>& views,
                                                    const AppearanceState& appearance,
                                                    const std::vector<int>& train_ids);

// Mean PSNR of the training views, each rendered with its own embedding:
// how well the model fits what it was trained on.
double TrainingPsnr(const GaussianCloud& c, const std::vector<TrainView>& views, const RasterOptions& raster,
                    const AppearanceState& appearance, const std::vector<int>& train_ids);

}  // namespace skyfall
