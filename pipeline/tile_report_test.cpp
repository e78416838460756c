#include "pipeline/tile_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/atomic_file.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

TileReport Sample() {
  TileReport r;
  r.tile = "SYN_001_c0_r0";
  r.status = StageStatus::kDegenerate;
  r.message = "too few tie points";
  r.options = {{"sfm", {{"ba_rounds", 2}}}};
  r.decisions = {{"dense", {{"ran", false}}}};
  r.images = 12;
  r.seconds = 41.5;
  r.metrics = {{"peak_rss_mb", 812.25}, {"psnr_db", std::nan("")}};
  StageReport sfm;
  sfm.stage = "sfm";
  sfm.status = StageStatus::kOk;
  sfm.seconds = 3.25;
  sfm.metrics = {{"tie_points", 3084}};
  sfm.warnings = {"one image left out"};
  r.stages = {sfm};
  return r;
}

TEST(TileReport, WhatIsWrittenIsReadBackAndANanFigureDoesNotMakeItUnreadable) {
  const fs::path dir = testing::ScratchDir("tile_report");
  const TileReport written = Sample();
  WriteTileReport(dir.string(), written);
  const std::optional<TileReport> read = ReadTileReport(dir.string());
  ASSERT_TRUE(read);
  EXPECT_EQ(read->tile, written.tile);
  EXPECT_EQ(read->status, StageStatus::kDegenerate);
  EXPECT_EQ(read->message, written.message);
  EXPECT_EQ(read->options, written.options);
  EXPECT_EQ(read->decisions, written.decisions);
  EXPECT_EQ(read->images, 12u);
  EXPECT_EQ(read->seconds, 41.5);
  EXPECT_EQ(read->PeakRssMb(), 812.25);
  EXPECT_TRUE(std::isnan(read->metrics.at("psnr_db")));  // written as null
  ASSERT_EQ(read->stages.size(), 1u);
  EXPECT_EQ(read->stages[0].metrics.at("tie_points"), 3084);
  EXPECT_EQ(read->stages[0].warnings, written.stages[0].warnings);
  // Written again, the same bytes: the city report copies stages through it.
  const std::string first = ReadTextFile(TileReportPath(dir.string()));
  WriteTileReport(dir.string(), *read);
  EXPECT_EQ(ReadTextFile(TileReportPath(dir.string())), first);
}

TEST(TileReport, MissingDamagedOrUnknownStatusMeansNotFinished) {
  const fs::path dir = testing::ScratchDir("tile_report_bad");
  EXPECT_FALSE(ReadTileReport(dir.string()));
  std::ofstream(TileReportPath(dir.string())) << "{\"tile\": \"t\", \"status\": \"ok\"";  // cut short
  EXPECT_FALSE(ReadTileReport(dir.string()));
  WriteTileReport(dir.string(), Sample());
  std::string text = ReadTextFile(TileReportPath(dir.string()));
  text.replace(text.find("\"degenerate\""), 12, "\"half-done\"");
  std::ofstream(TileReportPath(dir.string()), std::ios::trunc) << text;
  EXPECT_FALSE(ReadTileReport(dir.string()));
  EXPECT_EQ(StageStatusFromString("skipped"), StageStatus::kSkipped);
  EXPECT_FALSE(StageStatusFromString("half-done"));
}

}  // namespace
}  // namespace skyfall
