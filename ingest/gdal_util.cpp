#include "ingest/gdal_util.h"

#include <filesystem>
#include <mutex>

#include "core/error.h"

namespace skyfall::gdal {

void EnsureRegistered() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

QuietErrors::QuietErrors() {
  CPLPushErrorHandler(CPLQuietErrorHandler);
  CPLErrorReset();
}
QuietErrors::~QuietErrors() { CPLPopErrorHandler(); }
std::string QuietErrors::LastMessage() const {
  const char* msg = CPLGetLastErrorMsg();
  return msg && *msg ? std::string(msg) : std::string();
}

std::map<std::string, std::string> MetadataMap(GDALMajorObjectH object, const char* domain) {
  std::map<std::string, std::string> out;
  char** list = GDALGetMetadata(object, domain);
  for (int i = 0; list && list[i]; ++i) {
    const std::string entry = list[i];
    const auto eq = entry.find('=');
    if (eq == std::string::npos) continue;
    out[entry.substr(0, eq)] = entry.substr(eq + 1);
  }
  return out;
}

GDALDatasetH OpenOrThrow(const std::string& path) {
  EnsureRegistered();
  if (!std::filesystem::exists(path)) throw Error("raster", path, "file does not exist");
  QuietErrors quiet;
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  if (!ds) {
    const std::string why = quiet.LastMessage();
    throw Error("raster", path,
                "not a readable raster (corrupt or unsupported)" + (why.empty() ? "" : ": " + why));
  }
  return ds;
}

}  // namespace skyfall::gdal
