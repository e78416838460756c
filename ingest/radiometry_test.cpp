#include "ingest/radiometry.h"

#include <gdal.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

constexpr int kW = 64, kH = 48;

// A GeoTIFF of `type` with `bands` bands whose band b holds value(b, x, y);
// `prepare` may set colour interpretations, descriptions or nodata.
std::string WriteTyped(const fs::path& path, GDALDataType type, int bands,
                       const std::function<double(int, int, int)>& value,
                       const std::function<void(GDALDatasetH)>& prepare = nullptr) {
  GDALAllRegister();
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", kW, kH, bands, type, nullptr);
  std::vector<double> row(kW);
  for (int b = 1; b <= bands; ++b) {
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) row[x] = value(b, x, y);
      EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(mem, b), GF_Write, 0, y, kW, 1, row.data(), kW, 1, GDT_Float64, 0, 0),
                CE_None);
    }
  }
  if (prepare) prepare(mem);
  GDALDatasetH out = GDALCreateCopy(GDALGetDriverByName("GTiff"), path.c_str(), mem, FALSE, nullptr, nullptr, nullptr);
  EXPECT_NE(out, nullptr);
  GDALClose(out);
  GDALClose(mem);
  return path.string();
}

// A ramp over the image: raw values from `lo` to `hi` along x, per band offset.
std::function<double(int, int, int)> Ramp(double lo, double hi) {
  return [=](int b, int x, int) { return lo + (hi - lo) * x / (kW - 1.0) + 0.0 * b; };
}

TEST(Radiometry, EveryDataTypeAndBandCountMapsToTheUnitRange) {
  const fs::path dir = ScratchDir("radiometry");
  struct Case {
    GDALDataType type;
    int bands;
    double lo, hi;  // raw range written
    const char* method;
  };
  // Byte keeps its type range; the others are stretched between percentiles.
  const Case cases[] = {{GDT_Byte, 3, 20, 200, "type_range"},   {GDT_Byte, 1, 0, 255, "type_range"},
                        {GDT_UInt16, 1, 150, 1900, "percentile"}, {GDT_UInt16, 4, 300, 3000, "percentile"},
                        {GDT_Int16, 3, -200, 800, "percentile"}, {GDT_UInt32, 8, 1000, 100000, "percentile"},
                        {GDT_Float32, 3, 0.02, 0.45, "percentile"}};
  for (const Case& c : cases) {
    const std::string name = std::string(GDALGetDataTypeName(c.type)) + "_" + std::to_string(c.bands);
    const std::string path = WriteTyped(dir / (name + ".tif"), c.type, c.bands, Ramp(c.lo, c.hi));
    const Radiometry r = MeasureRadiometry(path, RadiometryOptions{});
    EXPECT_EQ(r.method, c.method) << name;
    if (c.bands < 3) EXPECT_EQ(r.bands, (std::array<int, 3>{1, 1, 1})) << name;  // grey
    else EXPECT_EQ(r.bands, (std::array<int, 3>{1, 2, 3})) << name;              // the first three
    const NormalizedImage img = ReadNormalizedImage(path, r);
    ASSERT_EQ(img.rgb.size(), 3u * kW * kH) << name;
    float lo = 1, hi = 0;
    for (std::size_t k = 0; k < img.valid.size(); ++k)
      if (img.valid[k]) lo = std::min(lo, img.rgb[3 * k]), hi = std::max(hi, img.rgb[3 * k]);
    EXPECT_GE(lo, 0.0f) << name;
    EXPECT_LE(hi, 1.0f) << name;
    if (std::string(c.method) == "percentile") {
      // The ramp spans the range: 0.5% of the pixels at most clip at each end.
      EXPECT_NEAR(r.low, c.lo, 0.02 * (c.hi - c.lo)) << name;
      EXPECT_NEAR(r.high, c.hi, 0.02 * (c.hi - c.lo)) << name;
      EXPECT_EQ(lo, 0.0f) << name;
      EXPECT_EQ(hi, 1.0f) << name;
    } else {
      // Byte: value / 255 (tolerance: float rounding). A 0 column at the
      // border is zero fill, so the darkest valid value there is the next one.
      EXPECT_NEAR(hi, c.hi / 255.0, 1e-6) << name;
      EXPECT_GE(lo, c.lo / 255.0 - 1e-6) << name;
      EXPECT_LE(lo, (c.lo + 5) / 255.0) << name;
    }
  }
}

TEST(Radiometry, ColourBandsAreFoundByInterpretationOrDescription) {
  const fs::path dir = ScratchDir("radiometry");
  // 8 bands (a WorldView-3 multispectral order): red is band 5, green 3, blue 2.
  auto interp = [](GDALDatasetH ds) {
    const GDALColorInterp order[] = {GCI_Undefined, GCI_BlueBand, GCI_GreenBand, GCI_Undefined,
                                     GCI_RedBand,   GCI_Undefined, GCI_Undefined, GCI_Undefined};
    for (int b = 0; b < 8; ++b) GDALSetRasterColorInterpretation(GDALGetRasterBand(ds, b + 1), order[b]);
  };
  const auto by_band = [](int b, int x, int) { return 100.0 * b + x; };
  EXPECT_EQ(MeasureRadiometry(WriteTyped(dir / "ms8.tif", GDT_UInt16, 8, by_band, interp), {}).bands,
            (std::array<int, 3>{5, 3, 2}));
  auto described = [](GDALDatasetH ds) {
    const char* names[] = {"NIR", "Red", "Green", "Blue"};
    for (int b = 0; b < 4; ++b) GDALSetDescription(GDALGetRasterBand(ds, b + 1), names[b]);
  };
  EXPECT_EQ(MeasureRadiometry(WriteTyped(dir / "ms4.tif", GDT_UInt16, 4, by_band, described), {}).bands,
            (std::array<int, 3>{2, 3, 4}));
  // RGB + alpha: the alpha band is never colour; grey + alpha is grey.
  auto alpha_last = [](GDALDatasetH ds) {
    const int n = GDALGetRasterCount(ds);
    GDALSetRasterColorInterpretation(GDALGetRasterBand(ds, n), GCI_AlphaBand);
  };
  EXPECT_EQ(MeasureRadiometry(WriteTyped(dir / "ga.tif", GDT_Byte, 2, by_band, alpha_last), {}).bands,
            (std::array<int, 3>{1, 1, 1}));
}

TEST(Radiometry, NodataAndBorderZeroFillAreMaskedButInteriorZerosAreNot) {
  const fs::path dir = ScratchDir("radiometry");
  // UInt16: a zero-filled left margin of 10 columns, an interior black pixel
  // (a deep shadow) at (40, 20), and a nodata value 65535 at (30, 10).
  auto value = [](int, int x, int y) -> double {
    if (x < 10) return 0;
    if (x == 40 && y == 20) return 0;
    if (x == 30 && y == 10) return 65535;
    return 500 + 10 * x;
  };
  auto nodata = [](GDALDatasetH ds) { GDALSetRasterNoDataValue(GDALGetRasterBand(ds, 1), 65535); };
  const std::string path = WriteTyped(dir / "fill.tif", GDT_UInt16, 1, value, nodata);
  const Radiometry r = MeasureRadiometry(path, {});
  EXPECT_TRUE(r.has_nodata);
  // Neither the fill nor nodata moved the range: it is that of the data.
  EXPECT_GE(r.low, 500 + 10 * 10 - 1);
  EXPECT_LE(r.high, 500 + 10 * 63 + 1);
  const NormalizedImage img = ReadNormalizedImage(path, r);
  EXPECT_EQ(img.valid[5 * kW + 3], 0);     // margin
  EXPECT_EQ(img.valid[10 * kW + 30], 0);   // nodata
  EXPECT_EQ(img.valid[20 * kW + 40], 1);   // interior zero: a real dark pixel
  EXPECT_EQ(img.valid[20 * kW + 50], 1);
  EXPECT_EQ(img.ValidCount(), static_cast<std::size_t>(kW * kH - 10 * kH - 1));
  // An image with no valid pixel is an error naming it.
  const std::string empty = WriteTyped(dir / "empty.tif", GDT_UInt16, 1, [](int, int, int) { return 0.0; });
  EXPECT_NE(ErrorText([&] { MeasureRadiometry(empty, {}); }).find("empty.tif"), std::string::npos);
  // A catalog naming a band the file lacks is an error naming the file.
  Radiometry wrong = r;
  wrong.bands = {1, 2, 3};
  EXPECT_NE(ErrorText([&] { ReadNormalizedImage(path, wrong); }).find("no band 2"), std::string::npos);
}

TEST(Radiometry, StretchingByteImagesIsAnOptionAndBadPercentilesAreRefused) {
  const fs::path dir = ScratchDir("radiometry");
  const std::string path = WriteTyped(dir / "dim.tif", GDT_Byte, 3, Ramp(10, 60));
  RadiometryOptions o;
  o.stretch_byte = true;
  const Radiometry r = MeasureRadiometry(path, o);
  EXPECT_EQ(r.method, "percentile");
  EXPECT_NEAR(r.high, 60, 1);
  o.low_percentile = 0.9;
  o.high_percentile = 0.1;
  EXPECT_NE(ErrorText([&] { MeasureRadiometry(path, o); }).find("low_percentile"), std::string::npos);
}

}  // namespace
}  // namespace skyfall
