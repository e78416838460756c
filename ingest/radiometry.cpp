#include "ingest/radiometry.h"

#include <gdal.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>

#include "core/error.h"
#include "core/format.h"
#include "core/stats.h"
#include "ingest/gdal_util.h"

namespace skyfall {
namespace {

// Band (1-based) whose colour interpretation or description names `colour`; 0 if none.
int FindBand(GDALDatasetH ds, GDALColorInterp interp, const std::string& name, const std::string& letter) {
  const int count = GDALGetRasterCount(ds);
  for (int b = 1; b <= count; ++b) {
    if (GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, b)) == interp) return b;
  }
  for (int b = 1; b <= count; ++b) {
    const std::string d = ToLower(GDALGetDescription(GDALGetRasterBand(ds, b)));
    if (d == name || d == letter) return b;
  }
  return 0;
}

std::array<int, 3> ChooseBands(GDALDatasetH ds) {
  const int red = FindBand(ds, GCI_RedBand, "red", "r"), green = FindBand(ds, GCI_GreenBand, "green", "g"),
            blue = FindBand(ds, GCI_BlueBand, "blue", "b");
  if (red && green && blue) return {red, green, blue};
  // Without names: the first three bands that are not alpha, else grey.
  std::vector<int> colour;
  for (int b = 1; b <= GDALGetRasterCount(ds); ++b) {
    if (GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, b)) != GCI_AlphaBand) colour.push_back(b);
  }
  if (colour.size() >= 3) return {colour[0], colour[1], colour[2]};
  const int grey = colour.empty() ? 1 : colour[0];
  return {grey, grey, grey};
}

// The three chosen bands, raw, interleaved by pixel; out_w x out_h samples of
// the full image (GDAL averages nothing: nearest sampling keeps raw values).
std::vector<float> ReadBands(GDALDatasetH ds, const std::array<int, 3>& bands, int out_w, int out_h,
                             const std::string& path) {
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  std::vector<float> out(3 * static_cast<std::size_t>(out_w) * out_h);
  gdal::QuietErrors quiet;
  for (int c = 0; c < 3; ++c) {
    if (c > 0 && bands[c] == bands[c - 1]) {  // grey: copy the previous channel
      for (std::size_t k = 0; k < out.size() / 3; ++k) out[3 * k + c] = out[3 * k + c - 1];
      continue;
    }
    GDALRasterBandH band = GDALGetRasterBand(ds, bands[c]);
    if (GDALRasterIO(band, GF_Read, 0, 0, w, h, out.data() + c, out_w, out_h, GDT_Float32, 3 * sizeof(float),
                     3 * sizeof(float) * static_cast<GSpacing>(out_w)) != CE_None) {
      throw Error("radiometry", path,
                  "pixel data of band " + std::to_string(bands[c]) + " unreadable: " + quiet.LastMessage());
    }
  }
  return out;
}

// Valid pixels: finite, not nodata, and not part of a zero fill reaching the
// image border (the black margins of orthorectified or cropped scenes).
std::vector<std::uint8_t> ValidMask(const std::vector<float>& rgb, int w, int h, const Radiometry& r) {
  const std::size_t n = static_cast<std::size_t>(w) * h;
  std::vector<std::uint8_t> valid(n, 1);
  std::vector<std::uint8_t> zero(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const float* p = &rgb[3 * k];
    bool ok = true, all_zero = true;
    for (int c = 0; c < 3; ++c) {
      ok = ok && std::isfinite(p[c]) && !(r.has_nodata && p[c] == static_cast<float>(r.nodata));
      all_zero = all_zero && p[c] == 0.0f;
    }
    valid[k] = ok;
    zero[k] = all_zero;
  }
  std::deque<std::size_t> queue;
  auto seed = [&](int x, int y) {
    const std::size_t k = static_cast<std::size_t>(y) * w + x;
    if (zero[k] && valid[k]) {
      valid[k] = 0;
      queue.push_back(k);
    }
  };
  for (int x = 0; x < w; ++x) seed(x, 0), seed(x, h - 1);
  for (int y = 0; y < h; ++y) seed(0, y), seed(w - 1, y);
  while (!queue.empty()) {
    const std::size_t k = queue.front();
    queue.pop_front();
    const int x = static_cast<int>(k % w), y = static_cast<int>(k / w);
    if (x > 0) seed(x - 1, y);
    if (x + 1 < w) seed(x + 1, y);
    if (y > 0) seed(x, y - 1);
    if (y + 1 < h) seed(x, y + 1);
  }
  return valid;
}

}  // namespace

void RadiometryOptions::Check() const {
  CheckOptionRanges(*this, "radiometry");
  if (!(low_percentile < high_percentile)) {
    throw Error("radiometry", "low_percentile", "needs low_percentile < high_percentile, got " +
                                                    FormatDouble(low_percentile) + " and " + FormatDouble(high_percentile));
  }
}

std::size_t NormalizedImage::ValidCount() const {
  return static_cast<std::size_t>(std::count(valid.begin(), valid.end(), std::uint8_t{1}));
}

Radiometry MeasureRadiometry(const std::string& path, const RadiometryOptions& options) {
  options.Check();
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  Radiometry r;
  r.bands = ChooseBands(ds.handle);
  int has_nodata = 0;
  r.nodata = GDALGetRasterNoDataValue(GDALGetRasterBand(ds.handle, r.bands[0]), &has_nodata);
  r.has_nodata = has_nodata != 0;
  const GDALDataType type = GDALGetRasterDataType(GDALGetRasterBand(ds.handle, r.bands[0]));
  const int w = GDALGetRasterXSize(ds.handle), h = GDALGetRasterYSize(ds.handle);
  const double step = std::max(1.0, std::sqrt(static_cast<double>(w) * h / options.max_sample_px));
  const int sw = std::max(1, static_cast<int>(w / step)), sh = std::max(1, static_cast<int>(h / step));
  const std::vector<float> rgb = ReadBands(ds.handle, r.bands, sw, sh, path);
  const std::vector<std::uint8_t> valid = ValidMask(rgb, sw, sh, r);
  std::vector<float> values;
  values.reserve(rgb.size());
  for (std::size_t k = 0; k < valid.size(); ++k) {
    if (!valid[k]) continue;
    for (int c = 0; c < 3; ++c) values.push_back(rgb[3 * k + c]);
  }
  if (values.empty()) throw Error("radiometry", path, "has no valid pixel (all nodata, NaN or zero fill)");
  if (type == GDT_Byte && !options.stretch_byte) {  // display-scaled already: keep its range
    r.method = "type_range";
    r.low = 0;
    r.high = 255;
    return r;
  }
  r.method = "percentile";
  r.low = Quantile(values, options.low_percentile);
  r.high = Quantile(values, options.high_percentile);
  if (!(r.high > r.low)) r.high = r.low + 1.0;  // a constant image: any scale, it carries no texture
  return r;
}

NormalizedImage ReadNormalizedImage(const std::string& path, const Radiometry& radiometry) {
  const Radiometry r = radiometry.Measured() ? radiometry : MeasureRadiometry(path, RadiometryOptions{});
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  for (int b : r.bands) {
    if (b < 1 || b > GDALGetRasterCount(ds.handle))
      throw Error("radiometry", path, "has no band " + std::to_string(b) + " (the catalog's radiometry.bands)");
  }
  NormalizedImage out;
  out.width_px = GDALGetRasterXSize(ds.handle);
  out.height_px = GDALGetRasterYSize(ds.handle);
  out.rgb = ReadBands(ds.handle, r.bands, out.width_px, out.height_px, path);
  out.valid = ValidMask(out.rgb, out.width_px, out.height_px, r);
  const float low = static_cast<float>(r.low), scale = static_cast<float>(1.0 / (r.high - r.low));
  for (std::size_t k = 0; k < out.valid.size(); ++k) {
    for (int c = 0; c < 3; ++c) {
      float& v = out.rgb[3 * k + c];
      v = out.valid[k] ? std::clamp((v - low) * scale, 0.0f, 1.0f) : 0.0f;
    }
  }
  return out;
}

}  // namespace skyfall
