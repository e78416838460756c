#include "products/tiles3d.h"

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "products/spz.h"
#include "splat/ply.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// One Gaussian with the given parameters (SH: dc and degree-1 per channel).
void AddGaussian(GaussianCloud* cloud, Eigen::Vector3f mean, Eigen::Vector3f log_scale, Eigen::Vector4f wxyz,
                 float logit, std::array<float, 12> sh) {
  cloud->means.push_back(mean);
  cloud->log_scales.push_back(log_scale);
  cloud->rotations.push_back(wxyz);
  cloud->opacity_logits.push_back(logit);
  cloud->sh.push_back(sh);
}

// Quantization steps of SPZ v2, the tolerances of the round trip:
constexpr double kAlphaStep = 1.0 / 255;               // opacity byte
constexpr double kLogScaleStep = 1.0 / 16;             // log-scale byte
constexpr double kDcStep = 1.0 / (0.15 * 255);         // DC colour byte
constexpr double kSh1Step = 8.0 / 128;                 // degree-1 SH keeps 5 bits of 8
constexpr double kQuatStep = 1.0 / 127.5;              // x, y, z bytes

TEST(Spz, KnownValuesSurviveTheRoundTrip) {
  GaussianCloud cloud;
  // An unnormalized quaternion with negative w: stored as the same rotation with w >= 0.
  AddGaussian(&cloud, {1.5f, -2.25f, 10.0f}, {std::log(2.0f), std::log(0.5f), -3.0f}, {-2.0f, 1.0f, 1.0f, 1.0f},
              0.0f, {1.0f, 0.1f, -0.2f, 0.3f, -0.5f, 0.0f, 0.0f, 0.0f, 0.25f, 0.4f, -0.4f, 0.05f});
  AddGaussian(&cloud, {-1000.0f, 700.5f, -3.0f}, {-1.0f, -1.0f, -1.0f}, {1.0f, 0.0f, 0.0f, 0.0f}, 4.0f, {});
  const int bits = SpzFractionalBits(cloud);
  EXPECT_EQ(bits, 13);  // 1000 m * 2^13 < 2^23 - 1 < 1000 m * 2^14
  int read_bits = 0;
  const GaussianCloud back = DecodeSpz(EncodeSpz(cloud, bits), "test", &read_bits);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(read_bits, bits);
  const double step = std::ldexp(1.0, -bits);
  for (std::size_t i = 0; i < 2; ++i) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(back.means[i][a], cloud.means[i][a], 0.5 * step + 1e-4);  // + float rounding at 1 km
      EXPECT_NEAR(back.log_scales[i][a], cloud.log_scales[i][a], 0.5 * kLogScaleStep);
    }
    const double alpha = 1 / (1 + std::exp(-cloud.opacity_logits[i]));
    EXPECT_NEAR(1 / (1 + std::exp(-back.opacity_logits[i])), alpha, 0.5 * kAlphaStep + 1e-6);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(back.sh[i][c * 4], cloud.sh[i][c * 4], 0.5 * kDcStep + 1e-6);
      for (int k = 1; k < 4; ++k) EXPECT_NEAR(back.sh[i][c * 4 + k], cloud.sh[i][c * 4 + k], 0.5 * kSh1Step + 1e-6);
    }
  }
  // (-2, 1, 1, 1) / sqrt(7) becomes (2, -1, -1, -1) / sqrt(7).
  const Eigen::Vector4d expected = Eigen::Vector4d(2, -1, -1, -1) / std::sqrt(7.0);
  for (int a = 0; a < 4; ++a) EXPECT_NEAR(back.rotations[0][a], expected[a], 2 * kQuatStep) << a;
  EXPECT_NEAR(std::exp(back.log_scales[0][0]), 2.0, 2.0 * 0.5 * kLogScaleStep);
}

TEST(Spz, RefusesWhatItCannotHold) {
  GaussianCloud far;
  AddGaussian(&far, {9000.0f, 0, 0}, {0, 0, 0}, {1, 0, 0, 0}, 0, {});
  EXPECT_THROW(EncodeSpz(far, 12), Error);  // 9000 m needs 2^25 steps of 1/4096 m
  EXPECT_EQ(SpzFractionalBits(far), 9);
  EXPECT_THROW(DecodeSpz({1, 2, 3}, "junk", nullptr), Error);
}

std::vector<std::uint8_t> Slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::uint32_t U32(const std::vector<std::uint8_t>& b, std::size_t at) {
  return b[at] | (b[at + 1] << 8) | (b[at + 2] << 16) | (std::uint32_t(b[at + 3]) << 24);
}

// The GLB's JSON and the SPZ stream of its buffer view.
std::pair<json, std::vector<std::uint8_t>> SplitGlb(const std::vector<std::uint8_t>& glb) {
  EXPECT_EQ(U32(glb, 0), 0x46546c67u);  // "glTF"
  EXPECT_EQ(U32(glb, 8), glb.size());
  const std::uint32_t json_length = U32(glb, 12);
  const json gltf = json::parse(std::string(glb.begin() + 20, glb.begin() + 20 + json_length));
  const std::size_t bin = 20 + json_length;
  const std::size_t spz_length = gltf["bufferViews"][0]["byteLength"];
  return {gltf, std::vector<std::uint8_t>(glb.begin() + bin + 8, glb.begin() + bin + 8 + spz_length)};
}

TEST(Tiles3d, GlbCarriesTheSplatsAsSpz) {
  GaussianCloud cloud;
  AddGaussian(&cloud, {1, 2, 3}, {0, 0, 0}, {1, 0, 0, 0}, 0, {});
  AddGaussian(&cloud, {-4, 5, -6}, {0, 0, 0}, {1, 0, 0, 0}, 0, {});
  const auto [gltf, spz] = SplitGlb(SplatGlb(cloud, 12));
  const json& primitive = gltf["meshes"][0]["primitives"][0];
  EXPECT_EQ(primitive["mode"], 0);
  EXPECT_EQ(primitive["extensions"]["KHR_gaussian_splatting"]["extensions"]
                     ["KHR_gaussian_splatting_compression_spz_2"]["bufferView"], 0);
  EXPECT_EQ(gltf["extensionsRequired"].size(), 2u);
  EXPECT_EQ(gltf["accessors"][primitive["attributes"]["POSITION"].get<int>()]["min"], json({-4, 2, -6}));
  EXPECT_EQ(gltf["accessors"][0]["count"], 2);
  // z-up content: the node maps (x, y, z) to (x, z, -y).
  EXPECT_EQ(gltf["nodes"][0]["matrix"], json({1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1}));
  const GaussianCloud back = DecodeSpz(spz, "glb", nullptr);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_FLOAT_EQ(back.means[1].z(), -6.0f);
}

// A scene folder as the merge writes it: frame.json, lod.json, lod_<k>.ply.
void WriteScene(const fs::path& dir, int per_side) {
  fs::create_directories(dir);
  std::ofstream(dir / "frame.json") << R"({"city": "T", "enu_origin": {"lon_deg": -81.66, "lat_deg": 30.35,
      "height_m": -20.0}, "epsg": 32617})";
  json levels = json::array();
  for (int level = 0; level < 3; ++level) {
    GaussianCloud cloud;
    const int n = per_side >> level;
    const float spacing = 300.0f / n;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        AddGaussian(&cloud, {(i + 0.5f) * spacing - 150, (j + 0.5f) * spacing - 150, 0.1f * i},
                    Eigen::Vector3f::Constant(std::log(0.5f * spacing)), {1, 0, 0, 0}, 2, {});
    const std::string file = "lod_" + std::to_string(level) + ".ply";
    WriteGaussiansPly((dir / file).string(), cloud);
    levels.push_back({{"level", level}, {"file", file}, {"count", cloud.size()}, {"geometric_error_m", level * 2.5}});
  }
  std::ofstream(dir / "lod.json") << json{{"levels", levels}}.dump();
}

void CheckNode(const json& node, const std::string& dir, std::size_t* leaf_gaussians, int* leaves) {
  if (node.contains("children")) {
    for (const json& child : node["children"]) {
      EXPECT_LE(child["geometricError"].get<double>(), node["geometricError"].get<double>());
      CheckNode(child, dir, leaf_gaussians, leaves);
    }
    return;
  }
  ++*leaves;
  EXPECT_EQ(node["geometricError"], 0.0);
  const auto [gltf, spz] = SplitGlb(Slurp(fs::path(dir) / node["content"]["uri"].get<std::string>()));
  *leaf_gaussians += gltf["accessors"][0]["count"].get<std::size_t>();
}

TEST(Tiles3d, QuadtreeOfLevelsWithTheCityFrameAsRootTransform) {
  const fs::path dir = testing::ScratchDir("tiles3d");
  WriteScene(dir / "scene", 64);
  NullProgress progress;
  Tiles3dOptions options;
  options.leaf_m = 100;  // 300 m -> 150 m -> 75 m: two splits, leaves of level 0
  const Tiles3dSummary s = Export3dTiles((dir / "scene").string(), (dir / "out").string(), options, progress);
  const json tileset = json::parse(std::ifstream(s.tileset_path));
  EXPECT_EQ(tileset["asset"]["version"], "1.1");
  const json& root = tileset["root"];
  EXPECT_EQ(root["refine"], "REPLACE");
  EXPECT_EQ(root["geometricError"], 5.0);  // the coarsest level's
  EXPECT_GE(tileset["geometricError"].get<double>(), root["geometricError"].get<double>());
  EXPECT_EQ(root["children"].size(), 4u);
  EXPECT_EQ(root["children"][0]["children"].size(), 4u);
  std::size_t leaf_gaussians = 0;
  int leaves = 0;
  CheckNode(root, (dir / "out").string(), &leaf_gaussians, &leaves);
  EXPECT_EQ(leaves, 16);
  EXPECT_EQ(leaf_gaussians, 64u * 64u);  // every finest Gaussian in exactly one leaf
  // The root transform takes ENU to ECEF as GeographicLib does, at the corners.
  const std::vector<double> m = root["transform"];
  const GeographicLib::LocalCartesian enu(30.35, -81.66, -20.0, GeographicLib::Geocentric::WGS84());
  for (const auto& [e, n] : {std::pair{-150.0, -150.0}, {150.0, -150.0}, {150.0, 150.0}, {-150.0, 150.0}}) {
    double lat, lon, h, x, y, z;
    enu.Reverse(e, n, 30.0, lat, lon, h);
    GeographicLib::Geocentric::WGS84().Forward(lat, lon, h, x, y, z);
    const Eigen::Vector3d ecef(m[0] * e + m[4] * n + m[8] * 30 + m[12], m[1] * e + m[5] * n + m[9] * 30 + m[13],
                               m[2] * e + m[6] * n + m[10] * 30 + m[14]);
    EXPECT_LT((ecef - Eigen::Vector3d(x, y, z)).norm(), 1e-6);  // [m]: both exact to rounding
  }
  EXPECT_EQ(m[3], 0.0);
  EXPECT_EQ(m[15], 1.0);
}

// Every file under `dir`, by relative path, with its bytes.
std::map<std::string, std::vector<std::uint8_t>> FilesUnder(const fs::path& dir) {
  std::map<std::string, std::vector<std::uint8_t>> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) files[fs::relative(entry.path(), dir).string()] = Slurp(entry.path());
  return files;
}

// Each node's Gaussians have their centres inside its box (horizontally),
// which is what the streamed bucketing must give.
void CheckContentInsideBoxes(const json& node, const fs::path& dir, std::size_t* checked) {
  if (node.contains("content")) {
    const std::vector<double> box = node["boundingVolume"]["box"];
    const auto [gltf, spz] = SplitGlb(Slurp(dir / node["content"]["uri"].get<std::string>()));
    const GaussianCloud cloud = DecodeSpz(spz, "glb", nullptr);
    constexpr double kSpzStepM = 1e-3;  // far above the SPZ position step, far below the boxes' 75 m
    for (const Eigen::Vector3f& m : cloud.means) {
      EXPECT_LE(std::abs(m.x() - box[0]), box[3] + kSpzStepM);
      EXPECT_LE(std::abs(m.y() - box[1]), box[7] + kSpzStepM);
      ++*checked;
    }
  }
  if (node.contains("children"))
    for (const json& child : node["children"]) CheckContentInsideBoxes(child, dir, checked);
}

TEST(Tiles3d, StreamedThroughATinySpillTheTilesetIsTheSameByteForByte) {
  const fs::path dir = testing::ScratchDir("tiles3d");
  WriteScene(dir / "scene", 64);
  NullProgress progress;
  Tiles3dOptions options;
  options.leaf_m = 100;
  options.spill_buffer_mb = 1e3;  // everything buffered, one write per tile
  const Tiles3dSummary whole = Export3dTiles((dir / "scene").string(), (dir / "whole").string(), options, progress);
  options.spill_buffer_mb = 1e-4;  // 100 bytes: a write for about every Gaussian
  const Tiles3dSummary tiny = Export3dTiles((dir / "scene").string(), (dir / "tiny").string(), options, progress);
  EXPECT_EQ(whole.tiles, tiny.tiles);
  EXPECT_EQ(whole.gaussians, tiny.gaussians);
  const auto a = FilesUnder(dir / "whole"), b = FilesUnder(dir / "tiny");
  ASSERT_EQ(a.size(), static_cast<std::size_t>(whole.contents) + 1);  // the GLBs and tileset.json; no spill left
  EXPECT_TRUE(a == b);
  EXPECT_FALSE(fs::exists(dir / "tiny" / ".spill"));
  std::size_t checked = 0;
  CheckContentInsideBoxes(json::parse(std::string(a.at("tileset.json").begin(), a.at("tileset.json").end()))["root"], dir / "tiny", &checked);
  EXPECT_EQ(checked, whole.gaussians);
}

TEST(Tiles3d, MissingLodIsANamedError) {
  const fs::path dir = testing::ScratchDir("tiles3d");
  NullProgress progress;
  const std::string error = testing::ErrorText(
      [&] { Export3dTiles((dir / "nothing").string(), (dir / "out").string(), Tiles3dOptions{}, progress); });
  EXPECT_NE(error.find("lod.json"), std::string::npos) << error;
}

}  // namespace
}  // namespace skyfall
