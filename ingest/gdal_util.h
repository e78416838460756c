// Private GDAL helpers shared by the sources that read and write rasters (not a public header).
#pragma once

#include <cpl_error.h>
#include <gdal.h>

#include <map>
#include <string>

namespace skyfall::gdal {

// Registers GDAL's drivers once, thread-safely.
void EnsureRegistered();

// Silences GDAL's console output for the current thread while alive, and
// remembers the last message so it can go into our own Error text.
class QuietErrors {
 public:
  QuietErrors();
  ~QuietErrors();
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;
  std::string LastMessage() const;
};

// Metadata list of a domain as a map ("KEY=VALUE" entries).
std::map<std::string, std::string> MetadataMap(GDALMajorObjectH object, const char* domain);

// RAII dataset handle.
struct Dataset {
  GDALDatasetH handle = nullptr;
  explicit Dataset(GDALDatasetH h) : handle(h) {}
  ~Dataset() {
    if (handle) GDALClose(handle);
  }
  Dataset(const Dataset&) = delete;
  Dataset& operator=(const Dataset&) = delete;
};

// Opens read-only or throws Error("raster", path, reason).
GDALDatasetH OpenOrThrow(const std::string& path);

}  // namespace skyfall::gdal
