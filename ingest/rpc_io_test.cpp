#include "ingest/rpc_io.h"

#include <gdal_utils.h>
#include <gtest/gtest.h>

#include <fstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"
#include "tests/test_rpc_fixture.h"
#include "tests/test_support.h"
#include "ingest/gdal_rpc_check.h"
#include "ingest/raster.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

// The bound for agreement with GDAL's RPC transformer.
constexpr double kGdalAgreementTolPx = 1e-3;

std::vector<fs::path> Jax068Images() {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(Dfc2019Root() / "Track3-RGB-crops" / "JAX_068"))
    out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(RpcIo, AgreesWithGdalTransformerOnAllJax068Crops) {
  SKYFALL_REQUIRE_DFC2019();
  const auto images = Jax068Images();
  ASSERT_EQ(images.size(), 19u);
  double worst_project = 0, worst_localize = 0;
  for (const auto& path : images) {
    const RasterInfo info = ReadRasterInfo(path);
    // Whole image, whole RPC height range (HEIGHT_OFF +- HEIGHT_SCALE, about -520..480 m).
    const RpcAgreement a = CompareWithGdal(path, ReadRpcFromRaster(path), info.width_px, info.height_px);
    EXPECT_EQ(a.points, 21 * 21 * 11);
    EXPECT_LT(a.max_project_diff_px, kGdalAgreementTolPx) << path;
    EXPECT_LT(a.max_localize_diff_px, kGdalAgreementTolPx) << path;
    worst_project = std::max(worst_project, a.max_project_diff_px);
    worst_localize = std::max(worst_localize, a.max_localize_diff_px);
  }
  std::printf("[figures] GDAL agreement over 19 crops: max project diff %.3g px, "
              "max localize diff %.3g px\n", worst_project, worst_localize);
}

TEST(RpcIo, SatNerfJsonCamerasEqualTheTiffRpcs) {
  SKYFALL_REQUIRE_DFC2019();
  for (const auto& path : Jax068Images()) {
    const fs::path json = Dfc2019Root() / "satnerf-rpcs" / "JAX_068" / (path.stem().string() + ".json");
    const SatNerfCamera cam = ReadSatNerfCamera(json);
    const RpcModel tif = ReadRpcFromRaster(path);
    const RasterInfo info = ReadRasterInfo(path);
    EXPECT_EQ(cam.width_px, info.width_px);
    EXPECT_EQ(cam.height_px, info.height_px);
    EXPECT_TRUE(cam.sun_elevation_deg.has_value());
    // Same term order and normalization: identical projections.
    for (double h : {-30.0, 0.0, 30.0}) {
      const Eigen::Vector2d ll = Localize(tif, info.width_px / 2.0, info.height_px / 2.0, h);
      EXPECT_LT((cam.rpc.Project(ll.x(), ll.y(), h) - tif.Project(ll.x(), ll.y(), h)).norm(), 1e-6)
          << json;
    }
  }
}

TEST(RpcIo, CroppedModelMatchesWhatGdalWritesForASubWindow) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("rpc_crop");
  const fs::path src = Jax068Image("001"), dst = dir / "crop.tif";
  char* argv[] = {const_cast<char*>("-srcwin"), const_cast<char*>("100"), const_cast<char*>("50"),
                  const_cast<char*>("200"), const_cast<char*>("150"), nullptr};
  GDALAllRegister();
  GDALTranslateOptions* opts = GDALTranslateOptionsNew(argv, nullptr);
  GDALDatasetH in = GDALOpen(src.c_str(), GA_ReadOnly);
  GDALDatasetH out = GDALTranslate(dst.c_str(), in, opts, nullptr);
  ASSERT_NE(out, nullptr);
  GDALClose(out);
  GDALClose(in);
  GDALTranslateOptionsFree(opts);

  const RpcModel ours = ReadRpcFromRaster(src).Cropped(100, 50);
  const RpcModel gdal = ReadRpcFromRaster(dst);
  EXPECT_NEAR(ours.samp_off, gdal.samp_off, 1e-9);
  EXPECT_NEAR(ours.line_off, gdal.line_off, 1e-9);
  const RpcAgreement a = CompareWithGdal(dst, ours, 200, 150);
  EXPECT_LT(a.max_project_diff_px, kGdalAgreementTolPx);
}

// An RPC whose values fit the fixed-width NITF RPC00B fields.
std::map<std::string, std::string> Rpc00bRepresentableKeys() {
  RpcModel rpc = MakeTestRpc();
  rpc.samp_off = 15391;
  rpc.line_off = 8155;
  return RpcToGdalMetadata(rpc);
}

TEST(RpcIo, ReadsNitfRpc00b) {
  const fs::path dir = ScratchDir("rpc_nitf");
  const fs::path path = dir / "image.ntf";
  WriteTestRaster(path, "NITF", 64, 48, 1, Rpc00bRepresentableKeys());
  fs::remove(dir / "image.ntf.aux.xml");  // the RPC must come from the TRE itself
  {
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
    ASSERT_NE(ds, nullptr);
    ASSERT_NE(GDALGetMetadataItem(ds, "RPC00B", "TRE"), nullptr) << "GDAL wrote no RPC00B TRE";
    GDALClose(ds);
  }
  const RpcModel rpc = ReadRpcFromRaster(path);
  EXPECT_EQ(rpc.line_off, 8155);
  EXPECT_NEAR(rpc.lat_scale, 0.0686, 1e-12);
  const RpcAgreement a = CompareWithGdal(path, rpc, 64, 48);
  EXPECT_LT(a.max_project_diff_px, kGdalAgreementTolPx);
  EXPECT_LT(a.max_localize_diff_px, kGdalAgreementTolPx);
}

std::string RpbText() {
  const RpcModel rpc = MakeTestRpc();
  std::string s = "satId = \"WV03\";\nBEGIN_GROUP = IMAGE\n";
  const auto keys = RpcToGdalMetadata(rpc);
  const std::pair<const char*, const char*> scalars[] = {
      {"lineOffset", "LINE_OFF"},   {"sampOffset", "SAMP_OFF"},     {"latOffset", "LAT_OFF"},
      {"longOffset", "LONG_OFF"},   {"heightOffset", "HEIGHT_OFF"}, {"lineScale", "LINE_SCALE"},
      {"sampScale", "SAMP_SCALE"},  {"latScale", "LAT_SCALE"},      {"longScale", "LONG_SCALE"},
      {"heightScale", "HEIGHT_SCALE"}};
  for (const auto& [rpb, gdal] : scalars) s += std::string("\t") + rpb + " = " + keys.at(gdal) + ";\n";
  const std::pair<const char*, const std::array<double, 20>*> lists[] = {
      {"lineNumCoef", &rpc.line_num}, {"lineDenCoef", &rpc.line_den},
      {"sampNumCoef", &rpc.samp_num}, {"sampDenCoef", &rpc.samp_den}};
  for (const auto& [name, c] : lists) {
    s += std::string("\t") + name + " = (\n";
    for (int i = 0; i < 20; ++i) s += "\t\t\t" + FormatDouble((*c)[i]) + (i < 19 ? ",\n" : ");\n");
  }
  return s + "END_GROUP = IMAGE\nEND;\n";
}

TEST(RpcIo, ReadsRpbFileAndRpbSidecar) {
  const fs::path dir = ScratchDir("rpc_rpb");
  std::ofstream(dir / "image.RPB") << RpbText();
  const RpcModel direct = ReadRpbFile((dir / "image.RPB").string());
  EXPECT_EQ(direct.line_num, MakeTestRpc().line_num);
  // GDAL attaches a same-named .RPB sidecar to the raster's RPC domain.
  WriteTestRaster(dir / "image.tif", "GTiff", 32, 32, 1);
  const RpcModel sidecar = ReadRpcFromRaster((dir / "image.tif").string());
  EXPECT_EQ(sidecar.samp_den, MakeTestRpc().samp_den);
  std::string source;
  ReadRpcAny((dir / "image.RPB").string(), &source);
  EXPECT_EQ(source, "rpb");
}

TEST(RpcIo, MissingAndCorruptRastersNameTheFile) {
  const fs::path dir = ScratchDir("rpc_bad_files");
  const std::string missing = (dir / "nope.tif").string();
  EXPECT_NE(ErrorText([&] { ReadRpcFromRaster(missing); }).find(missing + ": file does not exist"),
            std::string::npos);
  const fs::path corrupt = dir / "corrupt.tif";
  std::ofstream(corrupt, std::ios::binary) << std::string("II*\0\x08\0\0\0garbage", 15);
  const std::string msg = ErrorText([&] { ReadRasterInfo(corrupt.string()); });
  EXPECT_NE(msg.find(corrupt.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a readable raster"), std::string::npos) << msg;
}

TEST(RpcIo, TruncatedTiffIsCaughtByPixelVerification) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("rpc_truncated");
  const fs::path path = dir / "truncated.tif";
  fs::copy_file(Jax068Image("003"), path);
  fs::resize_file(path, fs::file_size(path) * 6 / 10);
  const std::string msg = ErrorText([&] { VerifyRasterPixels(path.string()); });
  EXPECT_NE(msg.find(path.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("band"), std::string::npos) << msg;
}

TEST(RpcIo, RasterWithoutRpcSaysSo) {
  const fs::path dir = ScratchDir("rpc_none");
  WriteTestRaster(dir / "plain.tif", "GTiff", 16, 16, 3);
  const std::string msg = ErrorText([&] { ReadRpcFromRaster((dir / "plain.tif").string()); });
  EXPECT_NE(msg.find("plain.tif: no RPC metadata"), std::string::npos) << msg;
}

TEST(RpcIo, NanCoefficientAndZeroDenominatorInTiffNameFileAndField) {
  const fs::path dir = ScratchDir("rpc_nan");
  auto keys = RpcToGdalMetadata(MakeTestRpc());
  keys["LINE_NUM_COEFF"] = "0.1 1 0.2 nan 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
  WriteTestRaster(dir / "nan.tif", "GTiff", 16, 16, 1, keys);
  std::string msg = ErrorText([&] { ReadRpcFromRaster((dir / "nan.tif").string()); });
  EXPECT_NE(msg.find("nan.tif: LINE_NUM_COEFF[3]"), std::string::npos) << msg;

  keys = RpcToGdalMetadata(MakeTestRpc());
  keys["SAMP_DEN_COEFF"] = "0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
  WriteTestRaster(dir / "zero.tif", "GTiff", 16, 16, 1, keys);
  msg = ErrorText([&] { ReadRpcFromRaster((dir / "zero.tif").string()); });
  EXPECT_NE(msg.find("zero.tif: SAMP_DEN_COEFF"), std::string::npos) << msg;
  EXPECT_NE(msg.find("zero denominator"), std::string::npos) << msg;
}

TEST(RpcIo, SatNerfJsonErrorsNameTheJsonField) {
  SKYFALL_REQUIRE_DFC2019();
  const std::string text =
      ReadTextFile((Dfc2019Root() / "satnerf-rpcs" / "JAX_068" / "JAX_068_001_RGB.json").string());
  std::string with_null = text;
  const auto pos = with_null.find("\"row_num\": [") + std::string("\"row_num\": [").size();
  const auto comma = with_null.find(',', pos);
  const auto second = with_null.find(',', comma + 1);
  with_null.replace(comma + 1, second - comma - 1, " null");  // row_num[1] -> null (JSON's NaN)
  std::string msg = ErrorText([&] { ParseSatNerfCamera(with_null, "cam.json"); });
  EXPECT_NE(msg.find("cam.json: rpc.row_num[1]"), std::string::npos) << msg;

  std::string missing = text;
  missing.replace(missing.find("\"lat_scale\""), 11, "\"lat_scalX\"");
  msg = ErrorText([&] { ParseSatNerfCamera(missing, "cam.json"); });
  EXPECT_NE(msg.find("'lat_scale' is missing"), std::string::npos) << msg;

  msg = ErrorText([&] { ParseSatNerfCamera("{not json", "cam.json"); });
  EXPECT_NE(msg.find("cam.json: not valid JSON"), std::string::npos) << msg;
}

TEST(RpcIo, IsoTimeFromNitfDate) {
  EXPECT_EQ(IsoTimeFromCompact("20141005160138"), "2014-10-05T16:01:38Z");
  EXPECT_EQ(IsoTimeFromCompact("2014-10"), "");
}

}  // namespace
}  // namespace skyfall
