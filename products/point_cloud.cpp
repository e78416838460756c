#include "products/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <limits>
#include <type_traits>
#include <utility>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {
namespace {

constexpr std::uint16_t kHeaderBytes = 375;  // LAS 1.4 public header block
constexpr std::uint16_t kVlrHeaderBytes = 54;
constexpr std::uint8_t kPointFormat = 7;
constexpr std::uint16_t kPointBytes = 36;  // format 7
constexpr std::uint16_t kGlobalEncodingWkt = 1 << 4;
constexpr char kProjectionUserId[] = "LASF_Projection";
constexpr std::uint16_t kWktRecordId = 2112;

// --- Writing -----------------------------------------------------------------

template <typename T>
void PutLe(std::string* out, T value) {
  static_assert(std::is_unsigned_v<T>);
  for (std::size_t b = 0; b < sizeof(T); ++b) out->push_back(static_cast<char>((value >> (8 * b)) & 0xff));
}

void PutLe(std::string* out, std::int32_t value) { PutLe(out, static_cast<std::uint32_t>(value)); }

void PutLe(std::string* out, double value) {
  std::uint64_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  PutLe(out, bits);
}

// A fixed-size char field, null-padded.
void PutText(std::string* out, const std::string& text, std::size_t size) {
  out->append(text.substr(0, size));
  out->append(size - std::min(text.size(), size), '\0');
}

constexpr const char* kAxes[] = {"easting", "northing", "height"};

struct Quantized {
  std::vector<std::array<std::int32_t, 3>> xyz;
  std::array<double, 3> offset{}, min{}, max{};
};

// Integer coordinates at kLasScaleM above each axis' offset (its minimum,
// rounded down to a whole metre, so that every integer is >= 0).
Quantized Quantize(const std::string& path, const std::vector<LasPoint>& points) {
  Quantized q;
  if (points.empty()) return q;
  std::array<double, 3> lowest;
  lowest.fill(std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::array<double, 3> p = {points[i].easting_m, points[i].northing_m, points[i].height_m};
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(p[a])) {
        throw Error("las", path, "point " + std::to_string(i) + ": " + kAxes[a] + " " + std::to_string(p[a]) +
                                     " is not finite");
      }
      lowest[a] = std::min(lowest[a], p[a]);
    }
  }
  for (int a = 0; a < 3; ++a) q.offset[a] = std::floor(lowest[a]);
  std::array<std::int32_t, 3> qmin, qmax;
  qmin.fill(std::numeric_limits<std::int32_t>::max());
  qmax.fill(std::numeric_limits<std::int32_t>::min());
  q.xyz.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::array<double, 3> p = {points[i].easting_m, points[i].northing_m, points[i].height_m};
    std::array<std::int32_t, 3> n;
    for (int a = 0; a < 3; ++a) {
      const double steps = std::round((p[a] - q.offset[a]) / kLasScaleM);
      if (steps > std::numeric_limits<std::int32_t>::max()) {
        throw Error("las", path, "point " + std::to_string(i) + ": " + kAxes[a] +
                                     " more than 2147 km above the cloud's minimum");
      }
      n[a] = static_cast<std::int32_t>(steps);
      qmin[a] = std::min(qmin[a], n[a]);
      qmax[a] = std::max(qmax[a], n[a]);
    }
    q.xyz.push_back(n);
  }
  for (int a = 0; a < 3; ++a) {
    q.min[a] = qmin[a] * kLasScaleM + q.offset[a];
    q.max[a] = qmax[a] * kLasScaleM + q.offset[a];
  }
  return q;
}

void PutHeader(std::string* out, const Quantized& q, std::uint64_t count, std::uint32_t point_offset) {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  out->append("LASF");
  PutLe<std::uint16_t>(out, 0);  // file source ID: none assigned
  PutLe(out, kGlobalEncodingWkt);
  out->append(16, '\0');  // project GUID
  out->push_back(1);
  out->push_back(4);
  PutText(out, "OTHER", 32);  // system identifier: the spec's word for data from neither a sensor nor a merge
  PutText(out, "skyfall", 32);
  PutLe(out, static_cast<std::uint16_t>(utc.tm_yday + 1));
  PutLe(out, static_cast<std::uint16_t>(utc.tm_year + 1900));
  PutLe(out, kHeaderBytes);
  PutLe(out, point_offset);
  PutLe<std::uint32_t>(out, 1);  // VLRs
  out->push_back(static_cast<char>(kPointFormat));
  PutLe(out, kPointBytes);
  // Legacy point counts (4 + 5 x 4 bytes): R15 wants them zero for formats 6 and up.
  out->append(24, '\0');
  for (int a = 0; a < 3; ++a) PutLe(out, kLasScaleM);
  for (int a = 0; a < 3; ++a) PutLe(out, q.offset[a]);
  for (int a = 0; a < 3; ++a) {
    PutLe(out, q.max[a]);
    PutLe(out, q.min[a]);
  }
  PutLe<std::uint64_t>(out, 0);  // waveform data packets: none
  PutLe<std::uint64_t>(out, 0);  // first EVLR: none
  PutLe<std::uint32_t>(out, 0);  // EVLRs
  PutLe(out, count);
  PutLe(out, count);  // every point is return 1 of 1
  out->append(14 * 8, '\0');
}

void PutWktVlr(std::string* out, const std::string& crs_wkt) {
  PutLe<std::uint16_t>(out, 0);  // reserved
  PutText(out, kProjectionUserId, 16);
  PutLe(out, kWktRecordId);
  PutLe(out, static_cast<std::uint16_t>(crs_wkt.size() + 1));
  PutText(out, "OGC coordinate system WKT", 32);
  out->append(crs_wkt);
  out->push_back('\0');
}

void PutPoint(std::string* out, const std::array<std::int32_t, 3>& xyz, const LasPoint& p) {
  for (int a = 0; a < 3; ++a) PutLe(out, xyz[a]);
  PutLe<std::uint16_t>(out, 0);  // intensity: none from imagery
  out->push_back(0x11);          // return 1 of 1
  out->push_back(0);             // classification flags, scanner channel, scan direction, edge of flight line
  out->push_back(static_cast<char>(p.classification));
  out->push_back(0);             // user data
  PutLe<std::uint16_t>(out, 0);  // scan angle
  PutLe<std::uint16_t>(out, 0);  // point source ID
  PutLe(out, 0.0);               // GPS time
  PutLe(out, p.red);
  PutLe(out, p.green);
  PutLe(out, p.blue);
}

// --- Reading (shares nothing with the writing above) -------------------------

class Bytes {
 public:
  Bytes(std::string data, const std::string& path) : data_(std::move(data)), path_(path) {}
  std::size_t size() const { return data_.size(); }
  void Need(std::uint64_t end, const std::string& what) const {
    if (end > data_.size()) {
      throw Error("las", path_, "truncated: needs " + std::to_string(end) + " bytes for " + what + ", has " +
                                    std::to_string(data_.size()));
    }
  }
  template <typename T>
  T Get(std::size_t at) const {
    static_assert(std::is_unsigned_v<T>);
    Need(at + sizeof(T), "a field");
    T value = 0;
    for (std::size_t b = 0; b < sizeof(T); ++b) value |= T(static_cast<unsigned char>(data_[at + b])) << (8 * b);
    return value;
  }
  double GetDouble(std::size_t at) const {
    const auto bits = Get<std::uint64_t>(at);
    double value;
    std::memcpy(&value, &bits, sizeof value);
    return value;
  }
  std::string GetText(std::size_t at, std::size_t size) const {
    Need(at + size, "a text field");
    const std::string field = data_.substr(at, size);
    return field.substr(0, field.find('\0'));
  }

 private:
  std::string data_;
  std::string path_;
};

// Smallest record of each point data record format 0..10 (LAS 1.4 R15).
constexpr std::array<std::uint16_t, 11> kMinRecordBytes = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

}  // namespace

void WriteLas(const std::string& path, const std::vector<LasPoint>& points, const std::string& crs_wkt) {
  if (crs_wkt.empty()) throw Error("las", path, "no CRS WKT given");
  if (crs_wkt.size() + 1 > std::numeric_limits<std::uint16_t>::max()) {
    throw Error("las", path, "CRS WKT of " + std::to_string(crs_wkt.size()) + " bytes does not fit a VLR");
  }
  const Quantized q = Quantize(path, points);
  const auto point_offset = static_cast<std::uint32_t>(kHeaderBytes + kVlrHeaderBytes + crs_wkt.size() + 1);
  std::string out;
  out.reserve(point_offset + points.size() * kPointBytes);
  PutHeader(&out, q, points.size(), point_offset);
  PutWktVlr(&out, crs_wkt);
  for (std::size_t i = 0; i < points.size(); ++i) PutPoint(&out, q.xyz[i], points[i]);
  WriteFileAtomic(path, out);
}

LasHeaderInfo ReadLasHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("las", path, "cannot open");
  std::string data(std::istreambuf_iterator<char>(in), {});
  const Bytes bytes(std::move(data), path);
  if (bytes.size() < 4 || bytes.GetText(0, 4) != "LASF") {
    throw Error("las", path, "not a LAS file (no LASF signature)");
  }

  LasHeaderInfo info;
  info.version_major = bytes.Get<std::uint8_t>(24);
  info.version_minor = bytes.Get<std::uint8_t>(25);
  const auto header_size = bytes.Get<std::uint16_t>(94);
  bytes.Need(header_size, "the public header block");
  const auto point_offset = bytes.Get<std::uint32_t>(96);
  const auto vlr_count = bytes.Get<std::uint32_t>(100);
  info.point_format = bytes.Get<std::uint8_t>(104);
  const auto record_bytes = bytes.Get<std::uint16_t>(105);
  if (info.point_format >= static_cast<int>(kMinRecordBytes.size())) {
    throw Error("las", path, "point data record format " + std::to_string(info.point_format) + " is not known");
  }
  if (record_bytes < kMinRecordBytes[info.point_format]) {
    throw Error("las", path, "point records of " + std::to_string(record_bytes) + " bytes are too short for format " +
                                 std::to_string(info.point_format));
  }
  const bool v14 = info.version_major == 1 && info.version_minor >= 4;
  info.point_count = v14 ? bytes.Get<std::uint64_t>(247) : bytes.Get<std::uint32_t>(107);
  double* const fields[] = {&info.scale_x, &info.scale_y, &info.scale_z, &info.offset_x, &info.offset_y,
                            &info.offset_z, &info.max_x,   &info.min_x,   &info.max_y,    &info.min_y,
                            &info.max_z,   &info.min_z};
  for (std::size_t f = 0; f < std::size(fields); ++f) *fields[f] = bytes.GetDouble(131 + 8 * f);

  std::uint64_t at = header_size;
  for (std::uint32_t v = 0; v < vlr_count; ++v) {
    bytes.Need(at + kVlrHeaderBytes, "VLR " + std::to_string(v));
    const auto length = bytes.Get<std::uint16_t>(at + 20);
    bytes.Need(at + kVlrHeaderBytes + length, "VLR " + std::to_string(v));
    if (bytes.GetText(at + 2, 16) == kProjectionUserId && bytes.Get<std::uint16_t>(at + 18) == kWktRecordId) {
      info.crs_wkt = bytes.GetText(at + kVlrHeaderBytes, length);
    }
    at += kVlrHeaderBytes + length;
  }

  // Compared by division: a corrupt count must not overflow the product.
  if (point_offset > bytes.size() || info.point_count > (bytes.size() - point_offset) / record_bytes) {
    throw Error("las", path, "truncated: " + std::to_string(info.point_count) + " point records of " +
                                 std::to_string(record_bytes) + " bytes from byte " + std::to_string(point_offset) +
                                 " do not fit in " + std::to_string(bytes.size()));
  }
  // Formats 6-10 hold an 8-bit class at byte 16, the older ones 5 bits at byte 15.
  const bool wide_class = info.point_format >= 6;
  for (std::uint64_t i = 0; i < info.point_count; ++i) {
    const std::size_t record = point_offset + i * record_bytes;
    const unsigned cls =
        wide_class ? bytes.Get<std::uint8_t>(record + 16) : bytes.Get<std::uint8_t>(record + 15) & 0x1f;
    if (cls < info.points_by_class.size()) ++info.points_by_class[cls];
  }
  return info;
}

}  // namespace skyfall
