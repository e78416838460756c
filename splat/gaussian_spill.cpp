#include "splat/gaussian_spill.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <fstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

namespace fs = std::filesystem;

KeyedSpill::KeyedSpill(fs::path dir, std::size_t record_bytes, std::size_t budget_bytes)
    : dir_(std::move(dir)), record_bytes_(record_bytes), budget_bytes_(budget_bytes) {
  fs::remove_all(dir_);
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw Error("spill", dir_.string(), "cannot be created: " + ec.message());
}

KeyedSpill::~KeyedSpill() {
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

void KeyedSpill::Add(const std::string& key, const void* record) {
  keys_.insert(key);
  buffers_[key].append(static_cast<const char*>(record), record_bytes_);
  buffered_bytes_ += record_bytes_;
  if (buffered_bytes_ >= budget_bytes_) Flush();
}

void KeyedSpill::Flush() {
  for (const auto& [key, bytes] : buffers_) {
    const fs::path path = File(key);
    std::ofstream out(path, std::ios::binary | std::ios::app);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw Error("spill", path.string(), "cannot be written (disk full?)");
  }
  buffers_.clear();
  buffered_bytes_ = 0;
}

std::string KeyedSpill::Read(const std::string& key) {
  if (!keys_.count(key)) return {};
  std::string bytes;
  const fs::path path = File(key);
  if (fs::exists(path)) bytes = ReadTextFile(path.string());
  const auto buffered = buffers_.find(key);
  if (buffered != buffers_.end()) bytes += buffered->second;
  if (bytes.size() % record_bytes_ != 0) throw Error("spill", path.string(), "holds a partial record");
  return bytes;
}

void KeyedSpill::Remove(const std::string& key) {
  const auto buffered = buffers_.find(key);
  if (buffered != buffers_.end()) {
    buffered_bytes_ -= buffered->second.size();
    buffers_.erase(buffered);
  }
  std::error_code ec;
  fs::remove(File(key), ec);
  keys_.erase(key);
}

namespace {
constexpr std::size_t kFloats = 11 + 3 * kShCoeffsPerChannel;  // mean, log scale, rotation, logit, SH
static_assert(kSpilledGaussianBytes == kFloats * sizeof(float) + sizeof(std::uint64_t));
}  // namespace

void SpillGaussian(KeyedSpill& spill, const std::string& key, const GaussianCloud& cloud, std::size_t i,
                   std::uint64_t tag) {
  if (spill.record_bytes() != kSpilledGaussianBytes) throw Error("spill", key, "is not a spill of Gaussians");
  std::array<char, kSpilledGaussianBytes> record;
  std::array<float, kFloats> r;
  std::copy_n(cloud.means[i].data(), 3, r.begin());
  std::copy_n(cloud.log_scales[i].data(), 3, r.begin() + 3);
  std::copy_n(cloud.rotations[i].data(), 4, r.begin() + 6);
  r[10] = cloud.opacity_logits[i];
  std::copy(cloud.sh[i].begin(), cloud.sh[i].end(), r.begin() + 11);
  std::memcpy(record.data(), r.data(), sizeof(r));
  std::memcpy(record.data() + sizeof(r), &tag, sizeof(tag));
  spill.Add(key, record.data());
}

GaussianCloud ReadSpilledGaussians(KeyedSpill& spill, const std::string& key, std::vector<std::uint64_t>* tags) {
  if (spill.record_bytes() != kSpilledGaussianBytes) throw Error("spill", key, "is not a spill of Gaussians");
  const std::string bytes = spill.Read(key);
  const std::size_t n = bytes.size() / kSpilledGaussianBytes;
  GaussianCloud cloud;
  cloud.resize(n);
  if (tags) tags->resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const char* src = bytes.data() + i * kSpilledGaussianBytes;
    std::array<float, kFloats> r;
    std::memcpy(r.data(), src, sizeof(r));
    cloud.means[i] = Eigen::Vector3f(r[0], r[1], r[2]);
    cloud.log_scales[i] = Eigen::Vector3f(r[3], r[4], r[5]);
    cloud.rotations[i] = Eigen::Vector4f(r[6], r[7], r[8], r[9]);
    cloud.opacity_logits[i] = r[10];
    std::copy(r.begin() + 11, r.end(), cloud.sh[i].begin());
    if (tags) std::memcpy(&(*tags)[i], src + sizeof(r), sizeof(std::uint64_t));
  }
  return cloud;
}

}  // namespace skyfall
