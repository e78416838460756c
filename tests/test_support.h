// Helpers shared by the tests: where the shared data is, scratch folders,
// running the CLI, and writing small rasters with GDAL.
#pragma once

#include <gdal.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "core/error.h"

namespace skyfall::testing {

namespace fs = std::filesystem;

inline fs::path SharedData() { return fs::path(SKYFALL_SHARED_DATA); }
inline fs::path Dfc2019Root() { return SharedData() / "dfc2019"; }
// A Pleiades 1A triplet laid out as a user's own-data folder (its README).
inline fs::path PleiadesMrsRoot() { return SharedData() / "pleiades-mrs"; }
// The official output schemas kept beside the data (see its README).
inline fs::path SharedSchemas() { return SharedData().parent_path() / "schemas"; }
inline fs::path Jax068Image(const std::string& nnn) {
  return Dfc2019Root() / "Track3-RGB-crops" / "JAX_068" / ("JAX_068_" + nnn + "_RGB.tif");
}

// Skips the test (loudly) when the shared DFC2019 sample is not beside the
// repository; CI always has it.
#define SKYFALL_REQUIRE_DFC2019()                                                       \
  do {                                                                                  \
    if (!std::filesystem::exists(::skyfall::testing::Dfc2019Root() / "Track3-Truth")) \
      GTEST_SKIP() << "shared DFC2019 data not found at "                               \
                   << ::skyfall::testing::Dfc2019Root();                                \
  } while (0)

#define SKYFALL_REQUIRE_PLEIADES_MRS()                                                   \
  do {                                                                                   \
    if (!std::filesystem::exists(::skyfall::testing::PleiadesMrsRoot() / "img_01.tif"))  \
      GTEST_SKIP() << "shared Pleiades data not found at "                               \
                   << ::skyfall::testing::PleiadesMrsRoot();                             \
  } while (0)

// A fresh, empty scratch folder, unique to the running test so that tests
// can run in parallel (ctest -j).
inline fs::path ScratchDir(const std::string& name) {
  const char* base = std::getenv("SKYFALL_TEST_TMP");
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test = info ? std::string(info->test_suite_name()) + "." + info->name() : "global";
  const fs::path dir = fs::path(base ? base : fs::temp_directory_path().string()) / test / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

struct CommandResult {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

// Runs a shell command, capturing stdout and stderr separately.
inline CommandResult RunCommand(const std::string& command, const fs::path& scratch) {
  const fs::path out = scratch / "cmd.stdout", err = scratch / "cmd.stderr";
  const std::string full = command + " >" + out.string() + " 2>" + err.string();
  const int status = std::system(full.c_str());
  auto slurp = [](const fs::path& p) {
    std::string s;
    if (FILE* f = std::fopen(p.c_str(), "rb")) {
      std::array<char, 4096> buf;
      size_t n;
      while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) s.append(buf.data(), n);
      std::fclose(f);
    }
    return s;
  };
  CommandResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

// The message of the skyfall::Error that `f` throws, or "<no error>".
inline std::string ErrorText(const std::function<void()>& f) {
  try {
    f();
  } catch (const ::skyfall::Error& e) {
    return e.what();
  }
  return "<no error>";
}

inline std::string Skyfall() { return SKYFALL_BINARY; }

// Writes a small Byte raster with the given driver, optional metadata in the
// default domain and optional RPC-domain metadata.
inline void WriteTestRaster(const fs::path& path, const char* driver, int width, int height,
                            int bands, const std::map<std::string, std::string>& rpc = {},
                            const std::map<std::string, std::string>& metadata = {}) {
  GDALAllRegister();
  GDALDriverH mem = GDALGetDriverByName("MEM");
  GDALDatasetH src = GDALCreate(mem, "", width, height, bands, GDT_Byte, nullptr);
  for (int b = 1; b <= bands; ++b) GDALFillRaster(GDALGetRasterBand(src, b), 40.0 * b, 0.0);
  for (const auto& [k, v] : metadata) GDALSetMetadataItem(src, k.c_str(), v.c_str(), nullptr);
  for (const auto& [k, v] : rpc) GDALSetMetadataItem(src, k.c_str(), v.c_str(), "RPC");
  GDALDatasetH dst =
      GDALCreateCopy(GDALGetDriverByName(driver), path.c_str(), src, FALSE, nullptr, nullptr, nullptr);
  ASSERT_NE(dst, nullptr) << "could not write " << path;
  GDALClose(dst);
  GDALClose(src);
}

}  // namespace skyfall::testing
