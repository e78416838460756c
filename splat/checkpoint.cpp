#include "splat/optimizer_state.h"

#include <cstring>
#include <filesystem>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {
namespace {

// Version 2 adds the appearance model; version 1 files (without it) still load.
constexpr char kCheckpointMagic[8] = {'S', 'K', 'Y', 'C', 'K', 'P', 'T', '2'};
constexpr char kCheckpointMagicV1[8] = {'S', 'K', 'Y', 'C', 'K', 'P', 'T', '1'};

template <typename V>
void Put(std::string& s, const V& v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof(V));
}
template <typename V>
void PutVector(std::string& s, const std::vector<V>& v) {
  Put(s, static_cast<std::uint64_t>(v.size()));
  s.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(V));
}
void PutCloud(std::string& s, const GaussianCloud& c) {
  PutVector(s, c.means);
  PutVector(s, c.log_scales);
  PutVector(s, c.rotations);
  PutVector(s, c.opacity_logits);
  PutVector(s, c.sh);
}

template <typename M>
void PutMatrix(std::string& s, const M& x) {
  Put(s, static_cast<std::int64_t>(x.rows()));
  Put(s, static_cast<std::int64_t>(x.cols()));
  s.append(reinterpret_cast<const char*>(x.data()), static_cast<std::size_t>(x.size()) * sizeof(float));
}
void PutAppearance(std::string& s, const AppearanceModel& a) {
  for (const Eigen::MatrixXf* x : {&a.image_embeddings, &a.gaussian_embeddings, &a.w1, &a.w2, &a.w3}) PutMatrix(s, *x);
  for (const Eigen::VectorXf* x : {&a.b1, &a.b2, &a.b3}) PutMatrix(s, *x);
}

struct Reader {
  const std::string& s;
  std::size_t at = 0;
  std::string path;
  template <typename V>
  V Get() {
    if (at + sizeof(V) > s.size()) throw Error("train", path, "checkpoint is truncated");
    V v;
    std::memcpy(&v, s.data() + at, sizeof(V));
    at += sizeof(V);
    return v;
  }
  template <typename V>
  std::vector<V> GetVector() {
    const auto n = Get<std::uint64_t>();
    if (at + n * sizeof(V) > s.size()) throw Error("train", path, "checkpoint is truncated");
    std::vector<V> v(n);
    std::memcpy(static_cast<void*>(v.data()), s.data() + at, n * sizeof(V));  // Eigen fixed-size vectors are plain arrays
    at += n * sizeof(V);
    return v;
  }
  template <typename M>
  M GetMatrix() {
    const auto rows = Get<std::int64_t>(), cols = Get<std::int64_t>();
    const std::size_t bytes = static_cast<std::size_t>(rows * cols) * sizeof(float);
    if (rows < 0 || cols < 0 || at + bytes > s.size()) throw Error("train", path, "checkpoint is truncated");
    M x(rows, cols);
    std::memcpy(x.data(), s.data() + at, bytes);
    at += bytes;
    return x;
  }
  AppearanceModel GetAppearance() {
    AppearanceModel a;
    for (Eigen::MatrixXf* x : {&a.image_embeddings, &a.gaussian_embeddings, &a.w1, &a.w2, &a.w3})
      *x = GetMatrix<Eigen::MatrixXf>();
    for (Eigen::VectorXf* x : {&a.b1, &a.b2, &a.b3}) *x = GetMatrix<Eigen::VectorXf>();
    return a;
  }
  GaussianCloud GetCloud() {
    GaussianCloud c;
    c.means = GetVector<Eigen::Vector3f>();
    c.log_scales = GetVector<Eigen::Vector3f>();
    c.rotations = GetVector<Eigen::Vector4f>();
    c.opacity_logits = GetVector<float>();
    c.sh = GetVector<std::array<float, 12>>();
    return c;
  }
};

}  // namespace

void SaveCheckpoint(const std::string& path, const Checkpoint& ck) {
  std::string s(kCheckpointMagic, sizeof(kCheckpointMagic));
  Put(s, static_cast<std::int64_t>(ck.iteration));
  Put(s, static_cast<std::int64_t>(ck.adam.step));
  PutCloud(s, ck.cloud);
  PutCloud(s, ck.adam.m);
  PutCloud(s, ck.adam.v);
  PutVector(s, std::vector<char>(ck.rng_state.begin(), ck.rng_state.end()));
  PutVector(s, ck.series);
  PutVector(s, ck.stats.grad_sum);
  PutVector(s, ck.stats.seen);
  Put(s, ck.loss_sum);
  Put(s, ck.loss_count);
  Put(s, static_cast<std::uint8_t>(ck.appearance.enabled));
  if (ck.appearance.enabled) {
    for (const AppearanceModel* a : {&ck.appearance.model, &ck.appearance.m, &ck.appearance.v}) PutAppearance(s, *a);
  }
  WriteFileAtomic(path, s);
}

Checkpoint LoadCheckpoint(const std::string& path) {
  const std::string s = ReadTextFile(path);
  const bool v2 = s.size() >= sizeof(kCheckpointMagic) && std::memcmp(s.data(), kCheckpointMagic, sizeof(kCheckpointMagic)) == 0;
  const bool v1 = s.size() >= sizeof(kCheckpointMagic) && std::memcmp(s.data(), kCheckpointMagicV1, sizeof(kCheckpointMagic)) == 0;
  if (!v1 && !v2) throw Error("train", path, "not a skyfall checkpoint");
  Reader r{s, sizeof(kCheckpointMagic), path};
  Checkpoint ck;
  ck.iteration = static_cast<int>(r.Get<std::int64_t>());
  ck.adam.step = static_cast<long>(r.Get<std::int64_t>());
  ck.cloud = r.GetCloud();
  ck.adam.m = r.GetCloud();
  ck.adam.v = r.GetCloud();
  const auto rng = r.GetVector<char>();
  ck.rng_state.assign(rng.begin(), rng.end());
  ck.series = r.GetVector<TrainSample>();
  ck.stats.grad_sum = r.GetVector<float>();
  ck.stats.seen = r.GetVector<int>();
  ck.loss_sum = r.Get<double>();
  ck.loss_count = r.Get<std::int64_t>();
  ck.appearance.enabled = v2 && r.Get<std::uint8_t>() != 0;
  if (ck.appearance.enabled) {
    ck.appearance.model = r.GetAppearance();
    ck.appearance.m = r.GetAppearance();
    ck.appearance.v = r.GetAppearance();
    if (static_cast<std::size_t>(ck.appearance.model.gaussian_embeddings.cols()) != ck.cloud.size() ||
        ck.appearance.m.gaussian_embeddings.cols() != ck.appearance.model.gaussian_embeddings.cols() ||
        ck.appearance.v.gaussian_embeddings.cols() != ck.appearance.model.gaussian_embeddings.cols()) {
      throw Error("train", path, "checkpoint is inconsistent (appearance embeddings size)");
    }
  }
  if (ck.stats.grad_sum.size() != ck.cloud.size() || ck.stats.seen.size() != ck.cloud.size()) {
    throw Error("train", path, "checkpoint is inconsistent (densification statistics size)");
  }
  if (ck.adam.m.size() != ck.cloud.size() || ck.adam.v.size() != ck.cloud.size()) {
    throw Error("train", path, "checkpoint is inconsistent (optimizer state size)");
  }
  return ck;
}

}  // namespace skyfall
