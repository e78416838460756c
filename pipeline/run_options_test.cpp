#include "pipeline/run_options.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/error.h"

namespace skyfall {
namespace {

using json = nlohmann::json;

// The message of the Error `f` throws ("" when it throws none).
template <class F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(RunOptions, DefaultsPassTheirCheckAndAreTheStagesOwnDefaults) {
  const RunOptions o;
  EXPECT_NO_THROW(o.Check());
  // One place per default: the run's sections are the stages' own structs.
  EXPECT_EQ(o.dense.sgm_p2, DenseOptions{}.sgm_p2);
  EXPECT_EQ(o.train.optimizer.iterations, TrainOptions{}.iterations);
  EXPECT_EQ(o.tiling.tile_m, TilingOptions{}.tile_m);
  const json doc = json::parse(RunOptionsToJson(o));
  EXPECT_EQ(doc["schema"], "skyfall.run_options/1");
  for (const char* section : {"ingest", "tiling", "sfm", "dense", "train", "merge", "dsm", "executor"})
    EXPECT_TRUE(doc.contains(section)) << section;
  EXPECT_EQ(doc["train"]["raster"]["background"].size(), 3u);
}

TEST(RunOptions, JsonRoundTripKeepsEveryChangedField) {
  RunOptions o;
  o.tiling.tile_m = 300;
  o.sfm.features.max_features = 1234;
  o.dense.visibility_pass = false;
  o.train.optimizer.appearance.hidden = 64;
  o.train.optimizer.raster.background = Eigen::Vector3d(0.25, 0.5, 1);
  o.train.optimizer.seed = 18446744073709551615ull;  // the largest seed survives JSON
  o.train.depth_prior = "cmd:my_depth {in} {out}";
  o.merge.lod.min_gaussians = 7;
  o.dsm.export_options.median_depth = false;
  o.executor.kind = "inline";
  const std::string text = RunOptionsToJson(o);
  const RunOptions back = RunOptionsFromJson(text, "test.json");
  EXPECT_EQ(RunOptionsToJson(back), text);
  EXPECT_EQ(back.train.optimizer.seed, o.train.optimizer.seed);
  EXPECT_EQ(back.train.optimizer.raster.background, o.train.optimizer.raster.background);
  EXPECT_FALSE(back.dsm.export_options.median_depth);
}

TEST(RunOptions, MissingFieldsKeepTheirDefaults) {
  const RunOptions o = RunOptionsFromJson(R"({"dense": {"sgm_p2": 1.5}})", "partial.json");
  EXPECT_EQ(o.dense.sgm_p2, 1.5);
  EXPECT_EQ(o.dense.cell_m, DenseOptions{}.cell_m);
  EXPECT_EQ(RunOptionsToJson(RunOptionsFromJson("{}", "empty.json")), RunOptionsToJson(RunOptions{}));
}

TEST(RunOptions, ReadingNamesTheFileAndTheFieldOfEveryMistake) {
  auto read = [](const std::string& text) { return ErrorOf([&] { RunOptionsFromJson(text, "run.json"); }); };
  const std::string unknown = read(R"({"dense": {"sgm_p3": 1}})");
  EXPECT_NE(unknown.find("run.json"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("dense.sgm_p3"), std::string::npos) << unknown;
  EXPECT_NE(read(R"({"denser": {}})").find("denser"), std::string::npos);
  const std::string type = read(R"({"train": {"iterations": "many"}})");
  EXPECT_NE(type.find("train.iterations"), std::string::npos) << type;
  EXPECT_NE(read(R"({"train": {"iterations": 1.5}})").find("whole number"), std::string::npos);
  EXPECT_NE(read(R"({"train": {"seed": -1}})").find("negative"), std::string::npos);
  EXPECT_NE(read(R"({"dense": {"visibility_pass": 1}})").find("true or false"), std::string::npos);
  EXPECT_NE(read(R"({"train": {"raster": {"background": [0, 0]}}})").find("3 numbers"), std::string::npos);
  EXPECT_NE(read(R"({"dense": 3})").find("dense"), std::string::npos);
  EXPECT_NE(read(R"({"schema": "skyfall.run_options/2"})").find("skyfall.run_options/2"), std::string::npos);
  EXPECT_NE(read("{not json").find("not valid JSON"), std::string::npos);
  EXPECT_NE(read("[1, 2]").find("JSON object"), std::string::npos);
}

TEST(RunOptions, CheckNamesTheSectionAndFieldOfABadValue) {
  auto check = [](auto change) {
    RunOptions o;
    change(o);
    return ErrorOf([&] { o.Check(); });
  };
  const std::string mode = check([](RunOptions& o) { o.train.init_points = "dnse"; });
  EXPECT_NE(mode.find("train.init_points"), std::string::npos) << mode;
  EXPECT_NE(mode.find("dnse"), std::string::npos) << mode;
  EXPECT_NE(check([](RunOptions& o) { o.train.appearance = "sometimes"; }).find("train.appearance"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.densify = ""; }).find("train.densify"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.depth_prior = "lidar"; }).find("train.depth_prior"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.depth_prior = "cmd:"; }).find("train.depth_prior"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.downscale = 0; }).find("train.downscale"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.anchor.step_weight = 1.5; }).find("train.surface_step_weight"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.anchor.step_reach_m = -1; }).find("train.surface_step_reach_m"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.anchor.step_min_m = 0; }).find("train.surface_step_min_m"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.optimizer.iterations = 0; }).find("train.iterations"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.dense.cell_m = -1; }).find("dense.cell_m"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.tiling.tile_m = 8; }).find("tiling."), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.merge.lod.min_reduction = 2; }).find("merge.lod.min_reduction"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.dsm.compare.pyramid_levels = 0; }).find("dsm.compare.pyramid_levels"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.dsm.source = "idu"; }).find("dsm.source"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.dsm.export_options.min_alpha = 1; }).find("dsm.export.min_alpha"),
            std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.executor.kind = "cloud"; }).find("executor.kind"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.executor.jobs = -2; }).find("executor.jobs"), std::string::npos);
}

TEST(RunOptions, SetReachesAnyFieldByItsPath) {
  RunOptions o;
  SetRunOption(&o, "dense.sgm_p2=1.5");
  SetRunOption(&o, "train.depth_prior=none");           // a string needs no quotes
  SetRunOption(&o, "train.appearance_model.hidden=64");
  SetRunOption(&o, "merge.lod.max_levels=3");
  SetRunOption(&o, "train.raster.background=[1,1,1]");
  EXPECT_EQ(o.dense.sgm_p2, 1.5);
  EXPECT_EQ(o.train.depth_prior, "none");
  EXPECT_EQ(o.train.optimizer.appearance.hidden, 64);
  EXPECT_EQ(o.merge.lod.max_levels, 3);
  EXPECT_EQ(o.train.optimizer.raster.background, Eigen::Vector3d::Ones());
  EXPECT_NE(ErrorOf([&] { SetRunOption(&o, "dense.sgm_p9=1"); }).find("dense.sgm_p9"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { SetRunOption(&o, "dense=1"); }).find("section"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { SetRunOption(&o, "dense.cell_m"); }).find("SECTION.FIELD=VALUE"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { SetRunOption(&o, "train.iterations=lots"); }).find("train.iterations"), std::string::npos);
  EXPECT_EQ(o.train.optimizer.iterations, TrainOptions{}.iterations);  // a failed --set changes nothing
}

TEST(RunOptions, TileOptionsFollowWhatDecidesATilesProducts) {
  const RunOptions base;
  RunOptions trained = base, dense = base, executed = base, merged = base;
  trained.train.optimizer.iterations += 1;
  dense.dense.sgm_p1 *= 2;
  executed.executor.jobs = 7;
  merged.merge.stitch.voxel_m = 2;
  EXPECT_NE(TileOptionsJson(trained), TileOptionsJson(base));
  EXPECT_NE(TileOptionsJson(dense), TileOptionsJson(base));
  EXPECT_EQ(TileOptionsJson(executed), TileOptionsJson(base));  // how tiles run does not change them
  EXPECT_EQ(TileOptionsJson(merged), TileOptionsJson(base));
  EXPECT_EQ(json::parse(DenseOptionsJson(base.dense))["cell_m"], base.dense.cell_m);
}

}  // namespace
}  // namespace skyfall
