// LAZ and COPC as products/point_cloud.h writes them, held to decoders that
// are not ours: laz-perf (whole-file LAZ, and COPC node by node through
// copc.js) and laz-rs (loaders.gl), all from npm, driven by
// web/check_points.mjs and web/check_las.mjs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>

#include "products/copc.h"
#include "products/laz_encoder.h"
#include "products/point_cloud.h"
#include "products/point_cloud_test_support.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::ErrorText;

constexpr double kHalfStep = 0.5 * kLasScaleM;  // quantization error of a stored coordinate

// A city block: a 200 x 100 m grid of 0.5 m cells, roofs and ground, grey
// and coloured cells, the classes the product writes.
std::vector<LasPoint> CityBlock() {
  std::vector<LasPoint> points;
  for (int row = 0; row < 200; ++row) {
    for (int col = 0; col < 400; ++col) {
      LasPoint p;
      p.easting_m = 440000.25 + 0.5 * col;
      p.northing_m = 3350000.25 + 0.5 * row;
      const bool roof = (col / 40) % 2 == 1 && (row / 50) % 2 == 0;
      p.height_m = 4.2 + 0.01 * col + (roof ? 12.5 : 0.0);
      p.classification = roof ? 6 : 2;
      const std::uint16_t grey = static_cast<std::uint16_t>(((col * 7 + row * 3) % 256) * 257);
      p.red = grey;
      p.green = roof ? grey : static_cast<std::uint16_t>(grey / 2);
      p.blue = grey;
      points.push_back(p);
    }
  }
  return points;
}

// The hard cases of the entropy coder: jumps across 2,000 km (coordinate
// differences of 31 bits), full 16-bit colours that are not grey, every
// class 0..255, repeated points.
std::vector<LasPoint> RaggedCloud(std::size_t n) {
  std::mt19937_64 rng(7);
  std::vector<LasPoint> points(n);
  for (std::size_t i = 0; i < n; ++i) {
    LasPoint& p = points[i];
    const bool jump = rng() % 7 == 0;
    p.easting_m = jump ? 100000.0 + static_cast<double>(rng() % 2000000000ull) * 1e-3
                       : 500000.0 + static_cast<double>(rng() % 1000) * 1e-3;
    p.northing_m = jump ? 3000000.0 + static_cast<double>(rng() % 2000000000ull) * 1e-3
                        : 4000000.0 + static_cast<double>(rng() % 1000) * 1e-3;
    p.height_m = jump ? -1000.0 + static_cast<double>(rng() % 2000000000ull) * 1e-3
                      : 10.0 + static_cast<double>(rng() % 100) * 1e-3;
    p.red = static_cast<std::uint16_t>(rng());
    p.green = rng() % 3 ? p.red : static_cast<std::uint16_t>(rng());
    p.blue = rng() % 5 ? p.green : static_cast<std::uint16_t>(rng());
    p.classification = static_cast<std::uint8_t>(rng() % 4 ? 2 : rng() % 256);
    if (i > 0 && rng() % 50 == 0) p = points[i - 1];
  }
  return points;
}

// web/check_points.mjs's report of `file`, or nothing when npm's decoders
// are not installed.
std::optional<json> Decode(const fs::path& file) {
  const fs::path web = fs::path(SKYFALL_SOURCE_DIR) / "web";
  const testing::CommandResult r =
      testing::RunCommand("node " + (web / "check_points.mjs").string() + " " + file.string(), file.parent_path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return std::nullopt;
  return json::parse(r.out);
}

bool DecodersInstalled(const fs::path& dir) {
  const fs::path modules = fs::path(SKYFALL_SOURCE_DIR) / "web" / "node_modules";
  return fs::exists(modules / "copc") && fs::exists(modules / "laz-perf") &&
         testing::RunCommand("node --version", dir).exit_code == 0;
}

// The three encodings of one cloud decode to the same records (compared as
// sorted sets: LAZ and COPC reorder points), with the header's count,
// bounds and CRS, and every COPC point inside its node's cube.
void ExpectEveryEncodingDecodesAlike(const std::vector<LasPoint>& points, const fs::path& dir, int min_nodes) {
  const std::string wkt = testing::Utm17nWithHeightWkt();
  const testing::Bounds truth = testing::TrueBounds(points);
  std::map<PointCloudEncoding, json> decoded;
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    const fs::path file = dir / PointCloudFileName(encoding);
    WriteLas(file.string(), points, wkt, encoding);
    const std::optional<json> d = Decode(file);
    ASSERT_TRUE(d) << name;
    EXPECT_EQ((*d)["format"], name);
    EXPECT_EQ((*d)["point_format"], 7) << name;
    EXPECT_EQ((*d)["count"].get<std::size_t>(), points.size()) << name;
    EXPECT_EQ((*d)["decoded"].get<std::size_t>(), points.size()) << name;
    EXPECT_EQ((*d)["crs_wkt"], wkt) << name;
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR((*d)["mins"][a].get<double>(), truth.min[a], kHalfStep) << name << " axis " << a;
      EXPECT_NEAR((*d)["maxs"][a].get<double>(), truth.max[a], kHalfStep) << name << " axis " << a;
      EXPECT_EQ((*d)["header_mins"][a], (*d)["mins"][a]) << name << " axis " << a;
      EXPECT_EQ((*d)["header_maxs"][a], (*d)["maxs"][a]) << name << " axis " << a;
    }
    decoded[encoding] = *d;
  }
  const json& las = decoded[PointCloudEncoding::kLas];
  EXPECT_EQ(decoded[PointCloudEncoding::kLaz]["records_sha256"], las["records_sha256"]);
  EXPECT_EQ(decoded[PointCloudEncoding::kCopc]["records_sha256"], las["records_sha256"]);
  EXPECT_EQ(decoded[PointCloudEncoding::kLaz]["classes"], las["classes"]);
  const json& copc = decoded[PointCloudEncoding::kCopc];
  EXPECT_EQ(copc["outside"], 0);
  EXPECT_EQ(copc["node_points"].get<std::size_t>(), points.size());
  EXPECT_GE(copc["nodes"].get<int>(), min_nodes);
}

TEST(Laz, EveryEncodingOfACityBlockDecodesToTheSameRecords) {
  const fs::path dir = testing::ScratchDir("laz_block");
  if (!DecodersInstalled(dir)) GTEST_SKIP() << "no node, or no copc / laz-perf in web/node_modules (npm ci in web/)";
  // 80,000 points: two LAZ chunks, and a COPC root with children.
  ExpectEveryEncodingDecodesAlike(CityBlock(), dir, /*min_nodes=*/3);
}

TEST(Laz, EveryEncodingOfExtremeInputDecodesToTheSameRecords) {
  const fs::path dir = testing::ScratchDir("laz_ragged");
  if (!DecodersInstalled(dir)) GTEST_SKIP() << "no node, or no copc / laz-perf in web/node_modules (npm ci in web/)";
  ExpectEveryEncodingDecodesAlike(RaggedCloud(60000), dir, /*min_nodes=*/2);
  // One point, and none: the smallest chunk and no chunk at all.
  ExpectEveryEncodingDecodesAlike(RaggedCloud(1), dir, /*min_nodes=*/1);
  const std::string wkt = testing::Utm17nWithHeightWkt();
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    const fs::path file = dir / ("empty_" + PointCloudFileName(encoding));
    WriteLas(file.string(), {}, wkt, encoding);
    const std::optional<json> d = Decode(file);
    ASSERT_TRUE(d) << name;
    EXPECT_EQ((*d)["decoded"], 0) << name;
  }
}

// laz-rs (through loaders.gl, as web/check_las.mjs drives it) reads plain
// LAZ, whose fixed 50,000-point chunks it knows, and finds the classes.
TEST(Laz, LazRsReadsTheFixedChunkLaz) {
  const fs::path web = fs::path(SKYFALL_SOURCE_DIR) / "web";
  const fs::path dir = testing::ScratchDir("laz_lazrs");
  if (!fs::exists(web / "node_modules" / "@loaders.gl" / "las") ||
      testing::RunCommand("node --version", dir).exit_code != 0) {
    GTEST_SKIP() << "no node, or no @loaders.gl/las in web/node_modules (npm ci in web/)";
  }
  const std::vector<LasPoint> points = CityBlock();
  const fs::path file = dir / "block.laz";
  WriteLas(file.string(), points, testing::Utm17nWithHeightWkt(), PointCloudEncoding::kLaz);
  const testing::CommandResult r =
      testing::RunCommand("node " + (web / "check_las.mjs").string() + " " + file.string(), dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json loaded = json::parse(r.out);
  EXPECT_EQ(loaded["count"].get<std::size_t>(), points.size());
  std::size_t roofs = 0;
  for (const LasPoint& p : points) roofs += p.classification == 6;
  EXPECT_EQ(loaded["classes"], json({{"2", points.size() - roofs}, {"6", roofs}}));
}

// Our own reader tells the encodings apart by the header's compression bit,
// the LASzip VLR and COPC's info VLR, and still finds the CRS.
TEST(Laz, ReaderTellsPlainLazAndCopcApart) {
  const fs::path dir = testing::ScratchDir("laz_reader");
  const std::string wkt = testing::Utm17nWithHeightWkt();
  const std::vector<LasPoint> points = CityBlock();
  std::map<PointCloudEncoding, std::uintmax_t> bytes;
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    const fs::path file = dir / PointCloudFileName(encoding);
    WriteLas(file.string(), points, wkt, encoding);
    bytes[encoding] = fs::file_size(file);
    const LasHeaderInfo info = ReadLasHeader(file.string());
    EXPECT_EQ(info.point_format, 7) << name;
    EXPECT_EQ(info.point_count, points.size()) << name;
    EXPECT_EQ(info.crs_wkt, wkt) << name;
    EXPECT_EQ(info.compressed, encoding != PointCloudEncoding::kLas) << name;
    EXPECT_EQ(info.copc, encoding == PointCloudEncoding::kCopc) << name;
  }
  // LASzip reaches 5-10x on surveyed clouds; a third is the floor below
  // which the coder would have stopped modelling the neighbours' differences.
  EXPECT_LT(bytes[PointCloudEncoding::kLaz] * 3, bytes[PointCloudEncoding::kLas]);
  EXPECT_LT(bytes[PointCloudEncoding::kCopc] * 3, bytes[PointCloudEncoding::kLas]);
}

TEST(Laz, ReaderRefusesACompressionBitWithoutTheLaszipRecord) {
  const fs::path dir = testing::ScratchDir("laz_reader");
  const std::string file = (dir / "marked.las").string();
  WriteLas(file, CityBlock(), testing::Utm17nWithHeightWkt(), PointCloudEncoding::kLas);
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(104);
  f.put(static_cast<char>(7 | kLazFormatBit));
  f.close();
  const std::string error = ErrorText([&] { ReadLasHeader(file); });
  EXPECT_NE(error.find(file), std::string::npos) << error;
  EXPECT_NE(error.find("laszip encoded"), std::string::npos) << error;
}

TEST(Laz, AChunkNeedsAPoint) {
  EXPECT_NE(ErrorText([] { EncodeLazChunk({}); }).find("at least one point"), std::string::npos);
}

// The first record of a chunk is stored raw and the layer sizes follow the
// count: a one-point chunk is the raw record, 1, then nine POINT14 layer
// sizes and one RGB14 size, where only X/Y and Z carry an encoder's flush.
TEST(Laz, AOnePointChunkIsTheRawRecordAndEmptyLayers) {
  LazRecord r;
  r.xyz = {-5, 7, 123456};
  r.classification = 6;
  r.rgb = {1, 2, 65535};
  const std::string chunk = EncodeLazChunk({r});
  ASSERT_GE(chunk.size(), 36u + 4 + 40);
  EXPECT_EQ(chunk.substr(0, 36), RawRecord7(r));
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (int b = 0; b < 4; ++b) v |= std::uint32_t(static_cast<unsigned char>(chunk[at + b])) << (8 * b);
    return v;
  };
  EXPECT_EQ(u32(36), 1u);
  const std::uint32_t xy = u32(40), z = u32(44);
  EXPECT_GT(xy, 0u);
  EXPECT_GT(z, 0u);
  for (int layer = 2; layer < 10; ++layer) EXPECT_EQ(u32(40 + 4 * layer), 0u) << "layer " << layer;
  EXPECT_EQ(chunk.size(), 36u + 4 + 40 + xy + z);
}

// Every point in exactly one node, inside that node's cube; a node's parent
// is in the tree; a node that kept all its points is within the leaf limit.
TEST(Copc, OctreeHoldsEveryPointOnceInsideItsNode) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> along(0.0, 1000.0), up(0.0, 60.0);
  std::vector<std::array<double, 3>> xyz(150000);
  for (auto& p : xyz) p = {500000.0 + along(rng), 4000000.0 + along(rng), up(rng)};
  const CopcCube cube = CopcCubeAround(xyz, kLasScaleM);
  const std::vector<CopcNode> nodes = BuildCopcOctree(xyz, cube);
  ASSERT_GT(nodes.size(), 1u);
  EXPECT_EQ(nodes.front().key, (std::array<std::int32_t, 4>{0, 0, 0, 0}));

  std::set<std::array<std::int32_t, 4>> keys;
  std::vector<int> seen(xyz.size(), 0);
  for (const CopcNode& node : nodes) {
    ASSERT_FALSE(node.points.empty());
    keys.insert(node.key);
    const double width = 2 * cube.halfsize / std::ldexp(1.0, node.key[0]);
    for (std::uint32_t i : node.points) {
      ++seen[i];
      for (int a = 0; a < 3; ++a) {
        const double lo = cube.center[a] - cube.halfsize + node.key[a + 1] * width;
        EXPECT_GE(xyz[i][a], lo - 1e-9) << "point " << i;
        EXPECT_LE(xyz[i][a], lo + width + 1e-9) << "point " << i;
      }
    }
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(xyz.size()));
  for (const CopcNode& node : nodes) {
    if (node.key[0] == 0) continue;
    EXPECT_TRUE(keys.count({node.key[0] - 1, node.key[1] / 2, node.key[2] / 2, node.key[3] / 2}))
        << "node " << node.key[0] << "-" << node.key[1] << "-" << node.key[2] << "-" << node.key[3];
    const bool has_children = std::any_of(nodes.begin(), nodes.end(), [&](const CopcNode& other) {
      return other.key[0] == node.key[0] + 1 && other.key[1] / 2 == node.key[1] && other.key[2] / 2 == node.key[2] &&
             other.key[3] / 2 == node.key[3];
    });
    if (!has_children) EXPECT_LE(node.points.size(), kCopcMaxNodePoints);
  }
}

}  // namespace
}  // namespace skyfall
