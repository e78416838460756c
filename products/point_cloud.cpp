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
#include "products/copc.h"
#include "products/laz_encoder.h"
#include "products/little_endian.h"

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

// Where the header's pointers lead: the point records (or LAZ chunks), how
// many VLRs precede them, and the EVLRs after them.
struct Layout {
  std::uint32_t point_offset = 0;
  std::uint32_t vlr_count = 0;
  std::uint8_t point_format = kPointFormat;  // with kLazFormatBit when compressed
  std::uint64_t first_evlr = 0;
  std::uint32_t evlr_count = 0;
};

void PutHeader(std::string* out, const Quantized& q, std::uint64_t count, const Layout& layout) {
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
  PutLe(out, layout.point_offset);
  PutLe(out, layout.vlr_count);
  out->push_back(static_cast<char>(layout.point_format));
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
  PutLe(out, layout.first_evlr);
  PutLe(out, layout.evlr_count);
  PutLe(out, count);
  PutLe(out, count);  // every point is return 1 of 1
  out->append(14 * 8, '\0');
}

void PutVlr(std::string* out, const std::string& user_id, std::uint16_t record_id, const std::string& description,
            const std::string& payload) {
  PutLe<std::uint16_t>(out, 0);  // reserved
  PutText(out, user_id, 16);
  PutLe(out, record_id);
  PutLe(out, static_cast<std::uint16_t>(payload.size()));
  PutText(out, description, 32);
  out->append(payload);
}

void PutWktVlr(std::string* out, const std::string& crs_wkt) {
  PutVlr(out, kProjectionUserId, kWktRecordId, "OGC coordinate system WKT", crs_wkt + std::string(1, '\0'));
}

void PutLaszipVlr(std::string* out, std::uint32_t chunk_points) {
  PutVlr(out, kLaszipUserId, kLaszipRecordId, "skyfall LAZ 1.4 layered chunks", LaszipVlrPayload(chunk_points));
}

constexpr std::size_t kEvlrHeaderBytes = 60;
constexpr char kCopcUserId[] = "copc";
constexpr std::uint16_t kCopcInfoRecordId = 1;
constexpr std::uint16_t kCopcHierarchyRecordId = 1000;
constexpr std::size_t kCopcInfoBytes = 160;
constexpr std::size_t kCopcEntryBytes = 32;

// COPC's info VLR: the octree's cube, the root's point spacing and where the
// hierarchy page lies (known once the chunks are laid out).
std::string CopcInfoPayload(const CopcCube& cube, std::uint64_t hierarchy_offset, std::uint64_t hierarchy_bytes) {
  std::string out;
  for (int a = 0; a < 3; ++a) PutLe(&out, cube.center[a]);
  PutLe(&out, cube.halfsize);
  PutLe(&out, 2 * cube.halfsize / kCopcGridCells);  // spacing of the root node
  PutLe(&out, hierarchy_offset);
  PutLe(&out, hierarchy_bytes);
  PutLe(&out, 0.0);  // GPS time range: none recorded
  PutLe(&out, 0.0);
  out.append(11 * 8, '\0');  // reserved
  return out;
}

LazRecord Record(const std::array<std::int32_t, 3>& xyz, const LasPoint& p) {
  LazRecord r;
  r.xyz = xyz;
  r.classification = p.classification;
  r.rgb = {p.red, p.green, p.blue};
  return r;
}

void CheckCrs(const std::string& path, const std::string& crs_wkt) {
  if (crs_wkt.empty()) throw Error("las", path, "no CRS WKT given");
  if (crs_wkt.size() + 1 > std::numeric_limits<std::uint16_t>::max()) {
    throw Error("las", path, "CRS WKT of " + std::to_string(crs_wkt.size()) + " bytes does not fit a VLR");
  }
}

std::string LasBytes(const std::string& crs_wkt, const Quantized& q, const std::vector<LasPoint>& points) {
  Layout layout;
  layout.point_offset = static_cast<std::uint32_t>(kHeaderBytes + kVlrHeaderBytes + crs_wkt.size() + 1);
  layout.vlr_count = 1;
  std::string out;
  out.reserve(layout.point_offset + points.size() * kPointBytes);
  PutHeader(&out, q, points.size(), layout);
  PutWktVlr(&out, crs_wkt);
  for (std::size_t i = 0; i < points.size(); ++i) out += RawRecord7(Record(q.xyz[i], points[i]));
  return out;
}

// The points as LAZ chunks, one per group, in the groups' order; returns the
// chunks' bytes and fills `table` with each chunk's points and bytes.
std::string LazChunks(const Quantized& q, const std::vector<LasPoint>& points,
                      const std::vector<std::vector<std::uint32_t>>& groups, std::vector<LazChunkEntry>* table) {
  std::string out;
  for (const auto& group : groups) {
    std::vector<LazRecord> records;
    records.reserve(group.size());
    for (std::uint32_t i : group) records.push_back(Record(q.xyz[i], points[i]));
    const std::string chunk = EncodeLazChunk(records);
    table->push_back({static_cast<std::uint32_t>(group.size()), static_cast<std::uint32_t>(chunk.size())});
    out += chunk;
  }
  return out;
}

std::vector<std::array<double, 3>> StoredCoordinates(const Quantized& q) {
  std::vector<std::array<double, 3>> xyz(q.xyz.size());
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    for (int a = 0; a < 3; ++a) xyz[i][a] = q.xyz[i][a] * kLasScaleM + q.offset[a];
  }
  return xyz;
}

// Plain LAZ: fixed chunks of LASzip's default 50,000 points, taken along a
// Morton curve over the cloud's cube so that neighbours share a chunk.
std::string LazBytes(const std::string& crs_wkt, const Quantized& q, const std::vector<LasPoint>& points) {
  constexpr std::size_t kChunkPoints = kLazFixedChunkPoints;
  const auto xyz = StoredCoordinates(q);
  const std::vector<std::uint32_t> order = MortonOrder(xyz, CopcCubeAround(xyz, kLasScaleM));
  std::vector<std::vector<std::uint32_t>> groups;
  for (std::size_t start = 0; start < order.size(); start += kChunkPoints) {
    groups.emplace_back(order.begin() + start, order.begin() + std::min(order.size(), start + kChunkPoints));
  }
  Layout layout;
  layout.point_offset = static_cast<std::uint32_t>(kHeaderBytes + 2 * kVlrHeaderBytes + crs_wkt.size() + 1 +
                                                   LaszipVlrPayload(kChunkPoints).size());
  layout.vlr_count = 2;
  layout.point_format = kPointFormat | kLazFormatBit;
  std::string out;
  PutHeader(&out, q, points.size(), layout);
  PutWktVlr(&out, crs_wkt);
  PutLaszipVlr(&out, kChunkPoints);
  std::vector<LazChunkEntry> table;
  const std::string chunks = LazChunks(q, points, groups, &table);
  PutLe<std::uint64_t>(&out, layout.point_offset + 8 + chunks.size());  // where the chunk table starts
  out += chunks;
  out += EncodeLazChunkTable(table, /*variable_size=*/false);
  return out;
}

// COPC: the LAZ file above with one chunk per octree node, the info VLR
// first, and the hierarchy (one page, every node) as an EVLR after the chunk
// table.
std::string CopcBytes(const std::string& crs_wkt, const Quantized& q, const std::vector<LasPoint>& points) {
  const auto xyz = StoredCoordinates(q);
  const CopcCube cube = CopcCubeAround(xyz, kLasScaleM);
  const std::vector<CopcNode> nodes = BuildCopcOctree(xyz, cube);
  std::vector<std::vector<std::uint32_t>> groups;
  for (const CopcNode& node : nodes) groups.push_back(node.points);

  Layout layout;
  layout.point_offset = static_cast<std::uint32_t>(kHeaderBytes + 3 * kVlrHeaderBytes + kCopcInfoBytes +
                                                   LaszipVlrPayload(kLazVariableChunks).size() + crs_wkt.size() + 1);
  layout.vlr_count = 3;
  layout.point_format = kPointFormat | kLazFormatBit;
  std::vector<LazChunkEntry> table;
  const std::string chunks = LazChunks(q, points, groups, &table);
  const std::uint64_t chunks_start = layout.point_offset + 8;
  const std::string chunk_table = EncodeLazChunkTable(table, /*variable_size=*/true);
  layout.first_evlr = chunks_start + chunks.size() + chunk_table.size();
  layout.evlr_count = 1;

  std::string page;
  if (nodes.empty()) {  // an empty cloud: the root, with no points, so that the page is not empty
    page.append(kCopcEntryBytes, '\0');
  }
  std::uint64_t at = chunks_start;
  for (std::size_t n = 0; n < nodes.size(); ++n) {
    for (int k = 0; k < 4; ++k) PutLe(&page, static_cast<std::uint32_t>(nodes[n].key[k]));
    PutLe(&page, at);
    PutLe(&page, table[n].bytes);
    PutLe(&page, table[n].points);
    at += table[n].bytes;
  }

  std::string out;
  PutHeader(&out, q, points.size(), layout);
  PutVlr(&out, kCopcUserId, kCopcInfoRecordId, "COPC info",
         CopcInfoPayload(cube, layout.first_evlr + kEvlrHeaderBytes, page.size()));
  PutLaszipVlr(&out, kLazVariableChunks);
  PutWktVlr(&out, crs_wkt);
  PutLe<std::uint64_t>(&out, layout.first_evlr - chunk_table.size());  // where the chunk table starts
  out += chunks;
  out += chunk_table;
  PutLe<std::uint16_t>(&out, 0);  // EVLR: reserved
  PutText(&out, kCopcUserId, 16);
  PutLe(&out, kCopcHierarchyRecordId);
  PutLe(&out, static_cast<std::uint64_t>(page.size()));
  PutText(&out, "COPC hierarchy", 32);
  out += page;
  return out;
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

void WriteLas(const std::string& path, const std::vector<LasPoint>& points, const std::string& crs_wkt,
              PointCloudEncoding encoding) {
  CheckCrs(path, crs_wkt);
  const Quantized q = Quantize(path, points);
  switch (encoding) {
    case PointCloudEncoding::kLas:
      WriteFileAtomic(path, LasBytes(crs_wkt, q, points));
      return;
    case PointCloudEncoding::kLaz:
      WriteFileAtomic(path, LazBytes(crs_wkt, q, points));
      return;
    case PointCloudEncoding::kCopc:
      WriteFileAtomic(path, CopcBytes(crs_wkt, q, points));
      return;
  }
}

namespace {

// Each encoding's file suffix (COPC's own for COPC) and media type.
struct PointCloudFile {
  PointCloudEncoding encoding;
  const char* suffix;
  const char* media_type;
};
constexpr PointCloudFile kPointCloudFiles[] = {
    {PointCloudEncoding::kLas, ".las", "application/vnd.las"},
    {PointCloudEncoding::kLaz, ".laz", "application/vnd.laszip"},
    {PointCloudEncoding::kCopc, ".copc.laz", "application/vnd.laszip+copc"},
};

const PointCloudFile& FileOf(PointCloudEncoding encoding) {
  for (const PointCloudFile& f : kPointCloudFiles)
    if (f.encoding == encoding) return f;
  return kPointCloudFiles[0];
}

}  // namespace

std::string PointCloudFileName(PointCloudEncoding encoding, const std::string& stem) {
  return stem + FileOf(encoding).suffix;
}

std::string PointCloudMediaType(PointCloudEncoding encoding) { return FileOf(encoding).media_type; }

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
  const auto format_byte = bytes.Get<std::uint8_t>(104);
  // LASzip marks compressed records with bit 7 (and some writers bit 6).
  info.point_format = format_byte & 0x3f;
  const bool laz_bit = (format_byte & 0x80) != 0;
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
    const std::string user_id = bytes.GetText(at + 2, 16);
    const auto record_id = bytes.Get<std::uint16_t>(at + 18);
    if (user_id == kProjectionUserId && record_id == kWktRecordId) {
      info.crs_wkt = bytes.GetText(at + kVlrHeaderBytes, length);
    }
    if (user_id == kLaszipUserId && record_id == kLaszipRecordId) info.compressed = true;
    if (v == 0 && user_id == kCopcUserId && record_id == kCopcInfoRecordId) info.copc = true;
    at += kVlrHeaderBytes + length;
  }

  if (laz_bit != info.compressed) {
    throw Error("las", path, laz_bit ? "point format marked compressed but no \"laszip encoded\" VLR"
                                     : "a \"laszip encoded\" VLR but the point format is not marked compressed");
  }
  if (info.compressed) return info;  // records are LAZ chunks: for a LAZ decoder
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
