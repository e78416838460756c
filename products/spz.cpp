#include "products/spz.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.h"

namespace skyfall {
namespace {

constexpr int kHeaderBytes = 16;
constexpr int kShDegree = 1;
constexpr int kShRestCoeffs = 3;   // degree-1 coefficients per channel
constexpr int kSh1BucketBits = 5;  // SPZ keeps 5 of 8 bits for degree-1 SH (its reference encoder's choice)
constexpr double kLogScaleOffset = 10.0, kLogScaleStep = 16.0;

std::uint8_t ToByte(double x) { return static_cast<std::uint8_t>(std::clamp(std::round(x), 0.0, 255.0)); }

std::uint8_t QuantizeSh(double x) {
  constexpr int bucket = 1 << (8 - kSh1BucketBits);
  int q = static_cast<int>(std::round(x * 128.0) + 128.0);
  q = (q + bucket / 2) / bucket * bucket;
  return static_cast<std::uint8_t>(std::clamp(q, 0, 255));
}

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

void PutU32(std::vector<std::uint8_t>* out, std::uint32_t v) {
  for (int b = 0; b < 4; ++b) out->push_back(static_cast<std::uint8_t>(v >> (8 * b)));
}

std::uint32_t GetU32(const std::uint8_t* p) { return p[0] | (p[1] << 8) | (p[2] << 16) | (std::uint32_t(p[3]) << 24); }

std::vector<std::uint8_t> Gzip(const std::vector<std::uint8_t>& raw) {
  z_stream s{};
  if (deflateInit2(&s, Z_BEST_COMPRESSION, Z_DEFLATED, 16 + MAX_WBITS, 9, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw Error("spz", "gzip", "deflateInit2 failed");
  }
  std::vector<std::uint8_t> out(deflateBound(&s, raw.size()) + 64);
  s.next_in = const_cast<Bytef*>(raw.data());
  s.avail_in = static_cast<uInt>(raw.size());
  s.next_out = out.data();
  s.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&s, Z_FINISH);
  const std::size_t written = out.size() - s.avail_out;
  deflateEnd(&s);
  if (rc != Z_STREAM_END) throw Error("spz", "gzip", "deflate did not finish");
  out.resize(written);
  return out;
}

std::vector<std::uint8_t> Gunzip(const std::vector<std::uint8_t>& packed, const std::string& subject) {
  z_stream s{};
  if (inflateInit2(&s, 16 + MAX_WBITS) != Z_OK) throw Error("spz", subject, "inflateInit2 failed");
  s.next_in = const_cast<Bytef*>(packed.data());
  s.avail_in = static_cast<uInt>(packed.size());
  std::vector<std::uint8_t> out;
  std::uint8_t buffer[1 << 15];
  int rc = Z_OK;
  while (rc == Z_OK) {
    s.next_out = buffer;
    s.avail_out = sizeof buffer;
    rc = inflate(&s, Z_NO_FLUSH);
    out.insert(out.end(), buffer, buffer + (sizeof buffer - s.avail_out));
  }
  inflateEnd(&s);
  if (rc != Z_STREAM_END) throw Error("spz", subject, "not a complete gzip stream");
  return out;
}

}  // namespace

int SpzFractionalBits(const GaussianCloud& cloud, int max_bits) {
  double largest = 0;
  for (const auto& m : cloud.means) largest = std::max(largest, static_cast<double>(m.cwiseAbs().maxCoeff()));
  constexpr double kLimit = (1 << 23) - 1;  // 24-bit signed
  int bits = max_bits;
  while (bits > 0 && largest * std::ldexp(1.0, bits) >= kLimit) --bits;
  return bits;
}

std::vector<std::uint8_t> EncodeSpz(const GaussianCloud& cloud, int fractional_bits) {
  const std::size_t n = cloud.size();
  std::vector<std::uint8_t> raw;
  raw.reserve(kHeaderBytes + n * (9 + 1 + 3 + 3 + 3 + 9));
  PutU32(&raw, kSpzMagic);
  PutU32(&raw, kSpzVersion);
  PutU32(&raw, static_cast<std::uint32_t>(n));
  raw.push_back(kShDegree);
  raw.push_back(static_cast<std::uint8_t>(fractional_bits));
  raw.push_back(0);  // flags: no antialiasing filter in training
  raw.push_back(0);
  const double scale = std::ldexp(1.0, fractional_bits);
  constexpr double kLimit = (1 << 23) - 1;
  for (const auto& m : cloud.means) {
    for (int a = 0; a < 3; ++a) {
      const double fixed = std::round(m[a] * scale);
      if (!(std::abs(fixed) <= kLimit)) {
        throw Error("spz", "position", "coordinate " + std::to_string(m[a]) + " m does not fit 24 bits at " +
                                           std::to_string(fractional_bits) + " fractional bits");
      }
      const auto v = static_cast<std::int32_t>(fixed);
      for (int b = 0; b < 3; ++b) raw.push_back(static_cast<std::uint8_t>((v >> (8 * b)) & 0xff));
    }
  }
  for (float logit : cloud.opacity_logits) raw.push_back(ToByte(Sigmoid(logit) * 255.0));
  for (const auto& sh : cloud.sh) {
    for (int c = 0; c < 3; ++c) raw.push_back(ToByte(sh[c * kShCoeffsPerChannel] * (kSpzColourScale * 255.0) + 127.5));
  }
  for (const auto& s : cloud.log_scales) {
    for (int a = 0; a < 3; ++a) raw.push_back(ToByte((s[a] + kLogScaleOffset) * kLogScaleStep));
  }
  for (const auto& q : cloud.rotations) {  // (w, x, y, z), any norm
    Eigen::Vector4d u = q.cast<double>();
    const double norm = u.norm();
    u = norm > 0 ? Eigen::Vector4d(u / norm) : Eigen::Vector4d(1, 0, 0, 0);
    if (u[0] < 0) u = -u;  // q and -q are one rotation: keep w >= 0, so it need not be stored
    for (int a = 1; a <= 3; ++a) raw.push_back(ToByte(u[a] * 127.5 + 127.5));
  }
  for (const auto& sh : cloud.sh) {
    for (int k = 1; k <= kShRestCoeffs; ++k) {
      for (int c = 0; c < 3; ++c) raw.push_back(QuantizeSh(sh[c * kShCoeffsPerChannel + k]));
    }
  }
  return Gzip(raw);
}

GaussianCloud DecodeSpz(const std::vector<std::uint8_t>& bytes, const std::string& subject, int* fractional_bits) {
  const std::vector<std::uint8_t> raw = Gunzip(bytes, subject);
  if (raw.size() < kHeaderBytes || GetU32(raw.data()) != kSpzMagic) throw Error("spz", subject, "no SPZ header");
  if (GetU32(raw.data() + 4) != kSpzVersion) {
    throw Error("spz", subject, "version " + std::to_string(GetU32(raw.data() + 4)) + " (only 2 is read)");
  }
  const std::size_t n = GetU32(raw.data() + 8);
  const int degree = raw[12], bits = raw[13];
  if (degree > 1) throw Error("spz", subject, "SH degree " + std::to_string(degree) + " (at most 1 is read)");
  const std::size_t sh_bytes = degree == 1 ? 9 : 0;
  if (raw.size() != kHeaderBytes + n * (9 + 1 + 3 + 3 + 3 + sh_bytes)) {
    throw Error("spz", subject, "size " + std::to_string(raw.size()) + " does not match " + std::to_string(n) + " points");
  }
  if (fractional_bits) *fractional_bits = bits;
  GaussianCloud cloud;
  cloud.resize(n);
  const std::uint8_t* p = raw.data() + kHeaderBytes;
  const double step = std::ldexp(1.0, -bits);
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a, p += 3) {
      std::int32_t v = p[0] | (p[1] << 8) | (p[2] << 16);
      if (v & 0x800000) v |= ~0xffffff;  // sign extension
      cloud.means[i][a] = static_cast<float>(v * step);
    }
  }
  for (std::size_t i = 0; i < n; ++i, ++p) {
    const double alpha = std::clamp(*p / 255.0, 1e-6, 1 - 1e-6);
    cloud.opacity_logits[i] = static_cast<float>(std::log(alpha / (1 - alpha)));
  }
  for (std::size_t i = 0; i < n; ++i) {
    cloud.sh[i].fill(0.0f);
    for (int c = 0; c < 3; ++c, ++p) {
      cloud.sh[i][c * kShCoeffsPerChannel] = static_cast<float>((*p - 127.5) / (kSpzColourScale * 255.0));
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a, ++p) cloud.log_scales[i][a] = static_cast<float>(*p / kLogScaleStep - kLogScaleOffset);
  }
  for (std::size_t i = 0; i < n; ++i, p += 3) {
    const Eigen::Vector3d xyz(p[0] / 127.5 - 1, p[1] / 127.5 - 1, p[2] / 127.5 - 1);
    const double w = std::sqrt(std::max(0.0, 1.0 - xyz.squaredNorm()));
    cloud.rotations[i] = Eigen::Vector4f(static_cast<float>(w), static_cast<float>(xyz.x()),
                                         static_cast<float>(xyz.y()), static_cast<float>(xyz.z()));
  }
  for (std::size_t i = 0; i < n && degree == 1; ++i) {
    for (int k = 1; k <= kShRestCoeffs; ++k) {
      for (int c = 0; c < 3; ++c, ++p) cloud.sh[i][c * kShCoeffsPerChannel + k] = static_cast<float>((*p - 128.0) / 128.0);
    }
  }
  return cloud;
}

}  // namespace skyfall
