#include "splat/optimizer_state.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace skyfall {
namespace {

constexpr double kAdamBeta1 = 0.9, kAdamBeta2 = 0.999, kAdamEps = 1e-15;

// Adam's bias corrections at one step, folded into float constants so the
// update itself runs in float (it vectorizes; in double it was most of the
// optimizer phase).
struct AdamStepScale {
  float step_per_lr;  // 1 / (1 - beta1^t)
  float inv_sqrt_bc2;  // 1 / sqrt(1 - beta2^t)
};
AdamStepScale ScaleAtStep(long step) {
  const double bc1 = 1 - std::pow(kAdamBeta1, step), bc2 = 1 - std::pow(kAdamBeta2, step);
  return {static_cast<float>(1.0 / bc1), static_cast<float>(1.0 / std::sqrt(bc2))};
}

// `step_of(k)`: the learning rate of value k times AdamStepScale::step_per_lr.
template <typename StepOf>
void AdamLoop(float* p, float* m, float* v, const float* g, std::size_t n, float inv_sqrt_bc2, StepOf step_of) {
  constexpr float b1 = static_cast<float>(kAdamBeta1), b2 = static_cast<float>(kAdamBeta2);
  constexpr float eps = static_cast<float>(kAdamEps);
  for (std::size_t k = 0; k < n; ++k) {
    m[k] = b1 * m[k] + (1.0f - b1) * g[k];
    v[k] = b2 * v[k] + (1.0f - b2) * g[k] * g[k];
    p[k] -= step_of(k) * m[k] / (std::sqrt(v[k]) * inv_sqrt_bc2 + eps);
  }
}

// AdamLoop over n values in parallel chunks: each value's update is
// independent, so the result does not depend on the chunking. `step_of`
// takes the index into the whole array.
template <typename StepOf>
void AdamParallel(float* p, float* m, float* v, const float* g, std::size_t n, float inv_sqrt_bc2, StepOf step_of) {
  constexpr std::size_t kChunk = 16384;
  tbb::parallel_for(std::size_t{0}, (n + kChunk - 1) / kChunk, [&](std::size_t c) {
    const std::size_t a = c * kChunk;
    AdamLoop(p + a, m + a, v + a, g + a, std::min(kChunk, n - a), inv_sqrt_bc2,
             [&](std::size_t k) { return step_of(a + k); });
  });
}

void AdamUpdate(float* p, float* m, float* v, const float* g, std::size_t n, double lr, const AdamStepScale& s) {
  const float step = static_cast<float>(lr) * s.step_per_lr;
  AdamParallel(p, m, v, g, n, s.inv_sqrt_bc2, [step](std::size_t) { return step; });
}

// The values of one field of every Gaussian (contiguous in the cloud) as one array.
template <typename Field>
float* Flat(std::vector<Field>& f) {
  static_assert(sizeof(Field) % sizeof(float) == 0, "a field is whole floats");
  return reinterpret_cast<float*>(f.data());
}
template <typename Field>
const float* Flat(const std::vector<Field>& f) {
  return reinterpret_cast<const float*>(f.data());
}
template <typename Field>
std::size_t FlatSize(const std::vector<Field>& f) {
  return f.size() * sizeof(Field) / sizeof(float);
}

template <typename Field>
void AdamField(std::vector<Field>& p, std::vector<Field>& m, std::vector<Field>& v, const std::vector<Field>& g,
               double lr, const AdamStepScale& s) {
  AdamUpdate(Flat(p), Flat(m), Flat(v), Flat(g), FlatSize(p), lr, s);
}


// The model's parameter blocks with their learning rates, in a fixed order.
struct ParamBlock {
  float* data;
  std::size_t size;
  double lr;
};
std::vector<ParamBlock> Blocks(AppearanceModel& x, const AppearanceOptions& o) {
  auto block = [](auto& e, double lr) { return ParamBlock{e.data(), static_cast<std::size_t>(e.size()), lr}; };
  return {block(x.image_embeddings, o.lr_image), block(x.gaussian_embeddings, o.lr_gaussian), block(x.w1, o.lr_mlp),
          block(x.w2, o.lr_mlp), block(x.w3, o.lr_mlp), block(x.b1, o.lr_mlp), block(x.b2, o.lr_mlp),
          block(x.b3, o.lr_mlp)};
}

}  // namespace

void AdamStepAppearance(AppearanceState& a, AppearanceModel& grad, long step, const AppearanceOptions& o) {
  const AdamStepScale scale = ScaleAtStep(step);
  const auto p = Blocks(a.model, o), m = Blocks(a.m, o), v = Blocks(a.v, o), g = Blocks(grad, o);
  for (std::size_t k = 0; k < p.size(); ++k) AdamUpdate(p[k].data, m[k].data, v[k].data, g[k].data, p[k].size, p[k].lr, scale);
}

void AdamStep(GaussianCloud& c, Adam& adam, const GaussianCloud& g, const TrainOptions& o, double lr_mean) {
  ++adam.step;
  const AdamStepScale scale = ScaleAtStep(adam.step);
  AdamField(c.means, adam.m.means, adam.v.means, g.means, lr_mean, scale);
  const bool late = o.lr.scale_late > 0 && static_cast<double>(adam.step) > o.lr.scale_late_from * o.iterations;
  AdamField(c.log_scales, adam.m.log_scales, adam.v.log_scales, g.log_scales, late ? o.lr.scale_late : o.lr.scale,
            scale);
  AdamField(c.rotations, adam.m.rotations, adam.v.rotations, g.rotations, o.lr.rotation, scale);
  AdamField(c.opacity_logits, adam.m.opacity_logits, adam.v.opacity_logits, g.opacity_logits, o.lr.opacity, scale);
  // SH: per channel, 4 coefficients, the degree-0 one at its own rate.
  static_assert(kShCoeffsPerChannel == 4, "the rate pattern below has period 4");
  const float step_dc = static_cast<float>(o.lr.sh_dc) * scale.step_per_lr;
  const float step_rest = static_cast<float>(o.lr.sh_rest) * scale.step_per_lr;
  AdamParallel(Flat(c.sh), Flat(adam.m.sh), Flat(adam.v.sh), Flat(g.sh), FlatSize(c.sh), scale.inv_sqrt_bc2,
               [step_dc, step_rest](std::size_t j) { return j % 4 == 0 ? step_dc : step_rest; });
}

}  // namespace skyfall
