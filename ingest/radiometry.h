// Radiometry of any sensor: which bands are red, green and blue, how raw
// values map to [0, 1], and which pixels hold no data. Measured once per
// image at ingestion (recorded in the catalog) and applied identically by
// every stage that reads pixels.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/aoi.h"
#include "core/option_range.h"

namespace skyfall {

struct RadiometryOptions {
  double low_percentile = 0.005;   // raw value at this fraction of valid pixels maps to 0
  double high_percentile = 0.995;  // ... and at this one to 1
  // Byte imagery is a display product already scaled to 0-255; other types
  // (UInt16 and Int16 with 11-14 bit DN, UInt32, Float32 reflectance) carry
  // sensor values whose range has to be measured. True stretches Byte
  // images between their percentiles as well.
  bool stretch_byte = false;
  int max_sample_px = 1 << 20;     // percentiles from a decimated read of at most this many pixels
  void Check() const;              // throws Error("radiometry", field, ...)
};
template <class IO> void Visit(IO& io, RadiometryOptions& o) {
  io("low_percentile", o.low_percentile,
     "The raw value at this fraction of an image's valid pixels maps to 0", range::In(0, 1));
  io("high_percentile", o.high_percentile,
     "The raw value at this fraction of an image's valid pixels maps to 1", range::In(0, 1));
  io("stretch_byte", o.stretch_byte,
     "Also stretch Byte images between the percentiles (off: their 0-255 values map to 0-1 as they are; other data "
     "types are always stretched)");
  io("max_sample_px", o.max_sample_px,
     "The percentiles come from a decimated read of at most this many pixels", range::AtLeast(1024));
}

// Chooses the bands (colour interpretation red/green/blue, else band
// descriptions "red"/"green"/"blue" or "r"/"g"/"b", else the first three; one
// band, or fewer than three, gives grey from band 1; alpha bands are never
// colour) and measures the value range over the valid pixels. Throws Error
// naming the file when it cannot be read or holds no valid pixel.
Radiometry MeasureRadiometry(const std::string& path, const RadiometryOptions& options);

// An image in the common radiometry: 3 values per pixel in [0, 1] (grey
// images repeat one), and a mask of the pixels that hold data.
struct NormalizedImage {
  int width_px = 0;
  int height_px = 0;
  std::vector<float> rgb;            // 3 per pixel, row-major; 0 where not valid
  std::vector<std::uint8_t> valid;   // 1 per pixel: 0 for nodata, NaN, or zero fill connected to the border
  std::size_t ValidCount() const;
};

// Reads `path` with `radiometry` (measured with default options first when
// it was not measured, e.g. a catalog written before it was recorded).
NormalizedImage ReadNormalizedImage(const std::string& path, const Radiometry& radiometry);

}  // namespace skyfall
