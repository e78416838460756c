#include "splat/ply.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

GaussianCloud TwoGaussians() {
  GaussianCloud c;
  c.resize(2);
  for (int i = 0; i < 2; ++i) {
    c.means[i] = Eigen::Vector3f(1.5f + i, -2.25f, 30.125f);
    c.log_scales[i] = Eigen::Vector3f(-1.0f, -2.0f, -3.0f * (i + 1));
    c.rotations[i] = Eigen::Vector4f(0.9f, 0.1f, -0.2f, 0.3f * i);
    c.opacity_logits[i] = 0.7f - i;
    for (int k = 0; k < 12; ++k) c.sh[i][k] = 0.01f * k - 0.05f * i;
  }
  return c;
}

TEST(Ply, RoundTripsTheInriaLayout) {
  const fs::path dir = ScratchDir("ply");
  const GaussianCloud c = TwoGaussians();
  WriteGaussiansPly((dir / "scene.ply").string(), c);
  const std::string text = ReadTextFile((dir / "scene.ply").string());
  // Viewers look for exactly these names.
  for (const char* p : {"property float f_dc_0", "property float f_rest_8", "property float opacity",
                        "property float scale_2", "property float rot_3", "element vertex 2"})
    EXPECT_NE(text.find(p), std::string::npos) << p;
  const GaussianCloud back = ReadGaussiansPly((dir / "scene.ply").string());
  ASSERT_EQ(back.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(back.means[i], c.means[i]);
    EXPECT_EQ(back.log_scales[i], c.log_scales[i]);
    EXPECT_EQ(back.rotations[i], c.rotations[i]);
    EXPECT_EQ(back.opacity_logits[i], c.opacity_logits[i]);
    EXPECT_EQ(back.sh[i], c.sh[i]);
  }
}

TEST(Ply, ReadsDegreeThreeFilesAndKeepsDegreeOne) {
  // A degree-3 file (45 f_rest) as written by the 3DGS reference code, ASCII here.
  const fs::path dir = ScratchDir("ply3");
  std::ofstream f(dir / "deg3.ply");
  f << "ply\nformat ascii 1.0\nelement vertex 1\n";
  for (const char* n : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"}) f << "property float " << n << "\n";
  for (int k = 0; k < 45; ++k) f << "property float f_rest_" << k << "\n";
  f << "property float opacity\nproperty float scale_0\nproperty float scale_1\nproperty float scale_2\n"
       "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n";
  f << "1 2 3 0 0 0 0.1 0.2 0.3";
  for (int k = 0; k < 45; ++k) f << " " << k;
  f << " 0.5 -1 -1 -1 1 0 0 0\n";
  f.close();
  const GaussianCloud c = ReadGaussiansPly((dir / "deg3.ply").string());
  ASSERT_EQ(c.size(), 1u);
  // Channel-major f_rest: red uses 0..14, green 15..29, blue 30..44.
  EXPECT_EQ(c.sh[0][1], 0.0f);
  EXPECT_EQ(c.sh[0][3], 2.0f);
  EXPECT_EQ(c.sh[0][5], 15.0f);
  EXPECT_EQ(c.sh[0][9], 30.0f);
  EXPECT_EQ(c.sh[0][8], 0.3f);
}

TEST(Ply, BadFilesNameTheProblem) {
  const fs::path dir = ScratchDir("plybad");
  std::ofstream(dir / "points.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n1 2 3\n";
  std::string msg = ErrorText([&] { ReadGaussiansPly((dir / "points.ply").string()); });
  EXPECT_NE(msg.find("property 'f_dc_0' is missing"), std::string::npos) << msg;
  const std::string good = GaussiansToPly(TwoGaussians());
  std::ofstream(dir / "cut.ply", std::ios::binary) << good.substr(0, good.size() - 10);
  msg = ErrorText([&] { ReadGaussiansPly((dir / "cut.ply").string()); });
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
  std::ofstream(dir / "text.ply") << "hello";
  EXPECT_NE(ErrorText([&] { ReadGaussiansPly((dir / "text.ply").string()); }).find("not a PLY"), std::string::npos);
}

TEST(Ply, AFilteredReadKeepsWhatTheFilterTakesInFileOrder) {
  // More vertices than one read chunk (65,536), so chunk borders are crossed.
  const fs::path dir = ScratchDir("plyfilter");
  GaussianCloud c;
  constexpr std::size_t kCount = 150001;
  c.resize(kCount);
  for (std::size_t i = 0; i < kCount; ++i) {
    c.means[i] = Eigen::Vector3f(static_cast<float>(i % 1000), static_cast<float>(i / 1000), 0.5f);
    c.log_scales[i] = Eigen::Vector3f(-1.0f, -1.0f, static_cast<float>(i % 7) - 3.0f);
    c.rotations[i] = Eigen::Vector4f(1.0f, 0.0f, 0.0f, 0.0f);
    c.opacity_logits[i] = static_cast<float>(i % 13);
    c.sh[i].fill(static_cast<float>(i % 17));
  }
  WriteGaussiansPly((dir / "big.ply").string(), c);
  const GaussianCloud all = ReadGaussiansPly((dir / "big.ply").string());
  ASSERT_EQ(all.size(), kCount);
  EXPECT_EQ(all.means.back(), c.means.back());
  EXPECT_EQ(all.sh[70000], c.sh[70000]);
  const GaussianCloud band = ReadGaussiansPly((dir / "big.ply").string(), [](const Eigen::Vector3f& m,
                                                                           const Eigen::Vector3f& s) {
    return m.y() >= 60.0f && m.y() < 80.0f && s.z() > 0.0f;  // rows 60-79, i % 7 in {4, 5, 6}
  });
  std::vector<std::size_t> expected;
  for (std::size_t i = 60000; i < 80000; ++i)
    if (i % 7 >= 4) expected.push_back(i);
  ASSERT_EQ(band.size(), expected.size());
  for (std::size_t k = 0; k < expected.size(); k += 997) {
    const std::size_t i = expected[k];
    EXPECT_EQ(band.means[k], c.means[i]) << i;
    EXPECT_EQ(band.log_scales[k], c.log_scales[i]) << i;
    EXPECT_EQ(band.opacity_logits[k], c.opacity_logits[i]) << i;
    EXPECT_EQ(band.sh[k], c.sh[i]) << i;
  }
}

TEST(Ply, AChunkedReadHandsEveryGaussianOnceInFileOrder) {
  const fs::path dir = ScratchDir("plychunks");
  GaussianCloud c;
  constexpr std::size_t kCount = 140000;  // two full chunks of 65,536 and a partial one
  c.resize(kCount);
  for (std::size_t i = 0; i < kCount; ++i) {
    c.means[i] = Eigen::Vector3f(static_cast<float>(i), -1.0f, 2.0f);
    c.log_scales[i] = Eigen::Vector3f(-1.0f, -2.0f, -3.0f);
    c.rotations[i] = Eigen::Vector4f(1.0f, 0.0f, 0.0f, 0.0f);
    c.opacity_logits[i] = static_cast<float>(i % 11);
    c.sh[i].fill(static_cast<float>(i % 5));
  }
  WriteGaussiansPly((dir / "big.ply").string(), c);
  std::vector<std::size_t> chunk_sizes;
  GaussianCloud joined;
  ForEachGaussiansPlyChunk((dir / "big.ply").string(), [&](const GaussianCloud& chunk) {
    chunk_sizes.push_back(chunk.size());
    for (std::size_t i = 0; i < chunk.size(); ++i) joined.Append(chunk, i);
  });
  EXPECT_EQ(chunk_sizes, (std::vector<std::size_t>{65536, 65536, kCount - 2 * 65536}));
  ASSERT_EQ(joined.size(), kCount);
  for (std::size_t i = 0; i < kCount; i += 4999) {
    EXPECT_EQ(joined.means[i], c.means[i]) << i;
    EXPECT_EQ(joined.opacity_logits[i], c.opacity_logits[i]) << i;
    EXPECT_EQ(joined.sh[i], c.sh[i]) << i;
  }
  const std::string error = ErrorText([&] { ForEachGaussiansPlyChunk((dir / "none.ply").string(), {}); });
  EXPECT_NE(error.find("none.ply"), std::string::npos) << error;
}

TEST(Ply, AStreamedWriteEqualsTheWholeWriteByteForByte) {
  const fs::path dir = ScratchDir("plystream");
  GaussianCloud c;
  constexpr std::size_t kCount = 50000;  // 4.8 MB of records: past the writer's 4 MB buffer
  c.resize(kCount);
  for (std::size_t i = 0; i < kCount; ++i) {
    c.means[i] = Eigen::Vector3f(0.25f * i, -1.0f * (i % 7), 2.0f);
    c.log_scales[i] = Eigen::Vector3f(-1.0f, -2.0f, -0.001f * i);
    c.rotations[i] = Eigen::Vector4f(1.0f, 0.1f, 0.0f, 0.0f);
    c.opacity_logits[i] = static_cast<float>(i % 13) - 6;
    for (int k = 0; k < 12; ++k) c.sh[i][k] = 0.001f * k * (i % 17);
  }
  for (int degree : {0, 1}) {
    const std::string whole = (dir / "whole.ply").string(), streamed = (dir / "streamed.ply").string();
    WriteGaussiansPly(whole, c, degree);
    fs::remove(streamed);
    {
      GaussiansPlyWriter writer(streamed, degree);
      for (std::size_t i = 0; i < 3; ++i) writer.Add(c, i);
      GaussianCloud rest;
      for (std::size_t i = 3; i < kCount; ++i) rest.Append(c, i);
      writer.AddAll(rest);
      EXPECT_EQ(writer.count(), kCount);
      EXPECT_FALSE(fs::exists(streamed));  // nothing shows before Finish
      writer.Finish();
    }
    EXPECT_EQ(ReadTextFile(streamed), ReadTextFile(whole)) << "degree " << degree;
  }
  // Dropped unfinished: the earlier file stays, and no temporary file is left.
  const std::string before = ReadTextFile((dir / "streamed.ply").string());
  {
    GaussiansPlyWriter writer((dir / "streamed.ply").string());
    writer.Add(c, 0);
  }
  EXPECT_EQ(ReadTextFile((dir / "streamed.ply").string()), before);
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 2);
  // An empty cloud is a valid PLY.
  GaussiansPlyWriter empty((dir / "empty.ply").string());
  empty.Finish();
  EXPECT_EQ(ReadGaussiansPly((dir / "empty.ply").string()).size(), 0u);
  EXPECT_THROW(empty.Add(c, 0), Error);
}

}  // namespace
}  // namespace skyfall
