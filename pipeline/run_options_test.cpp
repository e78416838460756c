#include "pipeline/run_options.h"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <algorithm>
#include <cmath>
#include <limits>
#include <new>
#include <set>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/format.h"

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
  EXPECT_EQ(o.dense.sgm.p2, DenseOptions{}.sgm.p2);
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
  o.dense.visibility.pass = false;
  o.train.optimizer.appearance.hidden = 64;
  o.train.optimizer.raster.background = Eigen::Vector3d(0.25, 0.5, 1);
  o.train.optimizer.seed = 18446744073709551615ull;  // the largest seed survives JSON
  o.train.depth_prior = "cmd:my_depth {in} {out}";
  o.merge.lod.min_gaussians = 7;
  o.dsm.export_options.median_depth = false;
  o.executor.kind = ExecutorKind::kInline;
  const std::string text = RunOptionsToJson(o);
  const RunOptions back = RunOptionsFromJson(text, "test.json");
  EXPECT_EQ(RunOptionsToJson(back), text);
  EXPECT_EQ(back.train.optimizer.seed, o.train.optimizer.seed);
  EXPECT_EQ(back.train.optimizer.raster.background, o.train.optimizer.raster.background);
  EXPECT_FALSE(back.dsm.export_options.median_depth);
}

TEST(RunOptions, MissingFieldsKeepTheirDefaults) {
  const RunOptions o = RunOptionsFromJson(R"({"dense": {"sgm_p2": 1.5}})", "partial.json");
  EXPECT_EQ(o.dense.sgm.p2, 1.5);
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
  // A mode is an enum: a name that is none of its values is refused where
  // it is read, naming the path and the choices.
  auto set = [](const std::string& assignment) {
    RunOptions o;
    return ErrorOf([&] { SetRunOption(&o, assignment); });
  };
  const std::string mode = set("train.init_points=dnse");
  EXPECT_NE(mode.find("train.init_points"), std::string::npos) << mode;
  EXPECT_NE(mode.find("dnse"), std::string::npos) << mode;
  EXPECT_NE(mode.find("'auto', 'dense' or 'sparse'"), std::string::npos) << mode;
  EXPECT_NE(set("train.appearance=sometimes").find("train.appearance"), std::string::npos);
  EXPECT_NE(set("train.densify=").find("train.densify"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.depth_prior = "lidar"; }).find("train.depth_prior"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.depth_prior = "cmd:"; }).find("train.depth_prior"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.train.downscale = -1; }).find("train.downscale"), std::string::npos);
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
  EXPECT_NE(set("dsm.source=idu").find("dsm.source"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.dsm.export_options.min_alpha = 1; }).find("dsm.export.min_alpha"),
            std::string::npos);
  EXPECT_NE(set("executor.kind=cloud").find("executor.kind"), std::string::npos);
  EXPECT_NE(check([](RunOptions& o) { o.executor.jobs = -2; }).find("executor.jobs"), std::string::npos);
}

TEST(RunOptions, SetReachesAnyFieldByItsPath) {
  RunOptions o;
  SetRunOption(&o, "dense.sgm_p2=1.5");
  SetRunOption(&o, "train.depth_prior=none");           // a string needs no quotes
  SetRunOption(&o, "train.appearance_model.hidden=64");
  SetRunOption(&o, "merge.lod.max_levels=3");
  SetRunOption(&o, "train.raster.background=[1,1,1]");
  EXPECT_EQ(o.dense.sgm.p2, 1.5);
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
  dense.dense.sgm.p1 *= 2;
  executed.executor.jobs = 7;
  merged.merge.stitch.voxel_m = 2;
  EXPECT_NE(TileOptionsJson(trained), TileOptionsJson(base));
  EXPECT_NE(TileOptionsJson(dense), TileOptionsJson(base));
  EXPECT_EQ(TileOptionsJson(executed), TileOptionsJson(base));  // how tiles run does not change them
  EXPECT_EQ(TileOptionsJson(merged), TileOptionsJson(base));
  EXPECT_EQ(json::parse(DenseOptionsJson(base.dense))["cell_m"], base.dense.cell_m);
}

TEST(RunOptions, TrainCheckpointStampHoldsEveryTrainingOption) {
  // A training option missing from the checkpoint's stamp would let a rerun
  // under another value resume the old run's checkpoint.
  const RunOptions base;
  RunOptions rate = base, weight = base, when = base;
  rate.train.optimizer.lr.mean_initial *= 0.25;
  weight.train.optimizer.surface.lambda_height = 0;
  when.train.optimizer.checkpoint_interval = 7;
  when.train.optimizer.eval_interval = 3;
  when.train.optimizer.keep_snapshots = true;
  EXPECT_NE(TrainCheckpointJson(rate.train), TrainCheckpointJson(base.train));
  EXPECT_NE(TrainCheckpointJson(weight.train), TrainCheckpointJson(base.train));
  EXPECT_EQ(TrainCheckpointJson(when.train), TrainCheckpointJson(base.train));  // when to save or score: no state
}

TEST(OptionRegistry, ListsEveryFieldOfTheRunOptions) {
  // A field added to an options struct but not to its Visit() would be left
  // out of the JSON form, --set, the docs and the resume stamps.
  const std::vector<std::string> gaps = RunOptionsRegistryGaps();
  std::string listing;
  for (const std::string& g : gaps) listing += g + "\n";
  EXPECT_TRUE(gaps.empty()) << "add these fields to their Visit() in pipeline/option_registry.h (or mark them "
                               "io.NotAnOption with the reason):\n"
                            << listing;
}

// The completeness check itself can fail: bytes an initializer wrote that no
// entry claims are found, padding is not.
struct RegistrySample {
  double listed = 1.5;
  bool forgotten = false;  // then 3 bytes of padding
  std::int32_t also_forgotten = 0;
  double other = 2.0;
};

TEST(OptionRegistry, AFieldLeftOutOfTheRegistryIsFoundAndPaddingIsNot) {
  static_assert(offsetof(RegistrySample, also_forgotten) == 12 && sizeof(RegistrySample) == 24, "layout assumed below");
  constexpr std::size_t n = sizeof(RegistrySample);
  alignas(RegistrySample) unsigned char buffer[n];
  std::vector<unsigned char> a(n), b(n);
  for (std::vector<unsigned char>* snapshot : {&a, &b}) {
    std::memset(buffer, snapshot == &a ? 0xA5 : 0x5A, n);
    new (buffer) RegistrySample;  // default-initialized: padding is left alone
    std::memcpy(snapshot->data(), buffer, n);
  }
  std::vector<bool> claimed(n, false);
  for (std::size_t k : {offsetof(RegistrySample, listed), offsetof(RegistrySample, other)})
    for (std::size_t j = 0; j < sizeof(double); ++j) claimed[k + j] = true;
  const auto ranges = UnclaimedFieldBytes(a, b, claimed);
  ASSERT_EQ(ranges.size(), 2u);
  EXPECT_EQ(ranges[0], std::make_pair(std::size_t{8}, std::size_t{9}));    // the bool
  EXPECT_EQ(ranges[1], std::make_pair(std::size_t{12}, std::size_t{16}));  // the int, after the padding
  for (std::size_t k = 0; k < n; ++k) claimed[k] = k < 8 || k >= 16 || k == 8 || (k >= 12 && k < 16);
  EXPECT_TRUE(UnclaimedFieldBytes(a, b, claimed).empty());
}

TEST(OptionRegistry, EveryListedOptionIsReachableBySetAndKeepsItsDefault) {
  const std::string defaults = RunOptionsToJson(RunOptions{});
  const std::vector<OptionDescription> rows = DescribeRunOptions();
  EXPECT_GT(rows.size(), 240u);
  for (const OptionDescription& row : rows) {
    RunOptions o;
    const json value = json::parse(row.default_json);
    SetRunOption(&o, row.path + "=" + (value.is_string() ? value.get<std::string>() : row.default_json));
    EXPECT_EQ(RunOptionsToJson(o), defaults) << row.path;
    EXPECT_EQ(DescribeRunOption(row.path).default_json, row.default_json);
  }
  EXPECT_NE(ErrorOf([] { DescribeRunOption("dense.no_such_field"); }).find("dense.no_such_field"), std::string::npos);
}

// Numbers the registry gives no range: any value is meaningful.
const std::set<std::string> kUnrangedNumbers = {"train.seed", "idu.seed"};
// Options whose own checks also compare them with another option: an end
// can be refused with the other at its default, so their ends are not
// tried for acceptance (values outside still are).
const std::set<std::string> kCrossChecked = {
    "ingest.radiometry.low_percentile", "ingest.radiometry.high_percentile", "sfm.features.stretch_low",
    "sfm.features.stretch_high", "tiling.overlap_m", "dense.min_pair_angle_deg", "dense.sgm_p1",
    "dense.fill_radius_m", "train.raster.min_alpha", "train.raster.max_alpha", "dense.max_pair_angle_deg",
    "dense.sgm_p2", "dense.max_fill_reach_m"};

TEST(OptionRegistry, EveryNumberHasARange) {
  for (const OptionDescription& row : DescribeRunOptions()) {
    const bool numeric = row.type == "integer" || row.type == "number" || row.type == "3 numbers";
    if (numeric && !kUnrangedNumbers.count(row.path)) EXPECT_TRUE(row.range.Declared()) << row.path;
    if (!numeric) EXPECT_FALSE(row.range.Declared()) << row.path;
  }
}

// The value `v` as --set takes it for the option (each of 3 numbers alike).
std::string Assignment(const OptionDescription& row, double v) {
  const std::string text = row.type == "integer" ? std::to_string(static_cast<long long>(v)) : FormatDouble(v);
  return row.path + "=" + (row.type == "3 numbers" ? "[" + text + "," + text + "," + text + "]" : text);
}

// Values just inside and just outside each end of a range.
struct RangeProbe {
  std::vector<double> inside, outside;
};
RangeProbe Probe(const OptionRange& r, bool integer) {
  RangeProbe p;
  auto step = [&](double end) { return integer ? 1.0 : std::max(1e-9, 1e-6 * std::max(1.0, std::abs(end))); };
  if (!r.values.empty()) {
    p.inside = r.values;
    p.outside = {*std::min_element(r.values.begin(), r.values.end()) - 1,
                 *std::max_element(r.values.begin(), r.values.end()) + 1};
    return p;
  }
  auto odd = [&](double v, double towards) { return r.odd && std::fmod(std::abs(v), 2.0) != 1.0 ? v + towards : v; };
  if (std::isfinite(r.min)) {
    p.inside.push_back(odd(r.min_open ? r.min + step(r.min) : r.min, 1));
    p.outside.push_back(r.min_open ? r.min : r.min - step(r.min));
  }
  if (std::isfinite(r.max)) {
    p.inside.push_back(odd(r.max_open ? r.max - step(r.max) : r.max, -1));
    p.outside.push_back(r.max_open ? r.max : r.max + step(r.max));
  }
  if (r.odd) p.outside.push_back(p.inside.front() + 1);
  if (r.also) {
    p.inside.push_back(*r.also);
    for (double& v : p.outside)
      if (v == *r.also) v -= step(v);  // the extra value is allowed: go one step further
  }
  return p;
}

// The declared ranges are what the run accepts: a value just outside an
// end is refused, naming the option, before any stage runs; an end itself
// (or the nearest value inside an open one) passes every check, the
// stages' own included, so no stage is stricter than what the
// documentation says.
TEST(OptionRegistry, EveryRangeIsWhatTheRunAccepts) {
  int probed = 0;
  for (const OptionDescription& row : DescribeRunOptions()) {
    if (!row.range.Declared()) continue;
    const RangeProbe p = Probe(row.range, row.type == "integer");
    for (double v : p.outside) {
      RunOptions o;
      const std::string why = ErrorOf([&] {
        SetRunOption(&o, Assignment(row, v));
        o.Check();
      });
      EXPECT_NE(why.find(row.path), std::string::npos) << Assignment(row, v) << ": " << why;
      ++probed;
    }
    if (kCrossChecked.count(row.path)) continue;
    for (double v : p.inside) {
      RunOptions o;
      const std::string why = ErrorOf([&] {
        SetRunOption(&o, Assignment(row, v));
        o.Check();
      });
      EXPECT_EQ(why, "") << Assignment(row, v) << " is within " << row.range.Text();
      ++probed;
    }
  }
  EXPECT_GT(probed, 400);
}

// A stage's own Check(), as a library caller runs it without the run's
// options around it, derives its ranges from the same Visit() the registry
// lists: a value the registry declares out of range fails there too, named.
TEST(OptionRegistry, StageChecksFollowTheDeclaredRanges) {
  auto fails_naming = [](const std::string& field, auto mutate) {
    return ErrorOf([&] { mutate(); }).find(field) != std::string::npos;
  };
  TrainOptions t;
  t.lambda_dssim = 1.5;
  EXPECT_TRUE(fails_naming("lambda_dssim", [&] { t.Check(); }));
  TrainOptions dense_start;
  dense_start.density.percent_dense = 0;  // once unchecked by the stage's hand-written checks
  EXPECT_TRUE(fails_naming("percent_dense", [&] { dense_start.Check(); }));
  DensityControlOptions d;
  d.max_gaussians = 0;
  EXPECT_TRUE(fails_naming("max_gaussians", [&] { d.Check(); }));
  IduOptions i;
  i.fill_voxel_m = 0;
  EXPECT_TRUE(fails_naming("fill_voxel_m", [&] { i.Check(); }));
  HoleFillOptions f;
  f.terrain_block_cells = 0;
  EXPECT_TRUE(fails_naming("fill_terrain_block_cells", [&] { f.Check(); }));
  HoleFillOptions reach;
  reach.max_reach_m = reach.radius_m / 2;  // two fields: the stage's own check
  EXPECT_TRUE(fails_naming("max_fill_reach_m", [&] { reach.Check(); }));
  DsmBreakdownOptions b;
  b.edge_bands = 101;
  EXPECT_TRUE(fails_naming("edge_bands", [&] { b.Check(); }));
  EXPECT_NO_THROW(TrainOptions{}.Check());
  EXPECT_NO_THROW(IduOptions{}.Check());
  EXPECT_NO_THROW(HoleFillOptions{}.Check());
  EXPECT_NO_THROW(DsmBreakdownOptions{}.Check());
}

TEST(OptionRegistry, RangesReadAsTheyAreMeant) {
  EXPECT_EQ(range::AtLeast(1).Text(), ">= 1");
  EXPECT_EQ(range::Above(0).Text(), "> 0");
  EXPECT_EQ(range::AboveUpTo(0, 1).Text(), "in (0, 1]");
  EXPECT_EQ(range::OneOf({8, 16}).Text(), "8 or 16");
  EXPECT_EQ(range::Odd(range::AtLeast(3)).Text(), "odd, >= 3");
  EXPECT_EQ(range::Or(range::AtLeast(16), 0, "automatic").Text(), ">= 16, or 0 (automatic)");
  EXPECT_FALSE(range::AtLeast(0).Contains(std::numeric_limits<double>::infinity()));
  EXPECT_FALSE(range::AtLeast(0).Contains(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_FALSE(range::Odd(range::AtLeast(3)).Contains(4));
  EXPECT_TRUE(range::Odd(range::AtLeast(3)).Contains(5));
  EXPECT_FALSE(OptionRange{}.Declared());
  const std::string why = ErrorOf([] {
    RunOptions o;
    SetRunOption(&o, "sfm.pinhole.grid_cols=2");
    o.Check();
  });
  EXPECT_NE(why.find("sfm.pinhole.grid_cols"), std::string::npos) << why;
  EXPECT_NE(why.find(">= 3"), std::string::npos) << why;
}

TEST(OptionRegistry, EveryOptionSaysWhatItDoes) {
  for (const OptionDescription& row : DescribeRunOptions()) EXPECT_GE(row.help.size(), 10u) << row.path;
}

TEST(OptionRegistry, DocsOutputsShowsTheDefaultConfiguration) {
  const std::string doc = ReadTextFile(std::string(SKYFALL_SOURCE_DIR) + "/docs/outputs.md");
  const std::size_t section = doc.find("## run_config.json");
  ASSERT_NE(section, std::string::npos);
  const std::size_t a = doc.find("```json\n", section), b = doc.find("```\n", a + 8);
  ASSERT_NE(a, std::string::npos);
  ASSERT_NE(b, std::string::npos);
  EXPECT_EQ(doc.substr(a + 8, b - a - 8), RunOptionsToJson(RunOptions{}))
      << "docs/outputs.md's run_config.json example is stale: paste `skyfall run --print-config`";
}

TEST(OptionRegistry, UnitsComeFromTheNamesSuffix) {
  EXPECT_EQ(UnitOfKey("cell_m"), "m");
  EXPECT_EQ(UnitOfKey("fov_deg"), "deg");
  EXPECT_EQ(UnitOfKey("floating_patch_max_m2"), "m²");
  EXPECT_EQ(UnitOfKey("poll_s"), "s");
  EXPECT_EQ(UnitOfKey("mem_mb"), "MB");
  EXPECT_EQ(UnitOfKey("ratio"), "");
  EXPECT_EQ(UnitOfKey("keep_snapshots"), "");
  EXPECT_EQ(DescribeRunOption("dense.cell_m").unit, "m");
}

TEST(OptionRegistry, DocsCliHoldsTheGeneratedReference) {
  const std::string doc = ReadTextFile(std::string(SKYFALL_SOURCE_DIR) + "/docs/cli.md");
  const std::string begin = "<!-- options:begin (generated: skyfall run --print-options-reference) -->\n";
  const std::string end = "<!-- options:end -->";
  const std::size_t a = doc.find(begin), b = doc.find(end);
  ASSERT_NE(a, std::string::npos) << "docs/cli.md lacks the options markers";
  ASSERT_NE(b, std::string::npos);
  const bool current = doc.substr(a + begin.size(), b - a - begin.size()) == RunOptionsReferenceMarkdown();
  EXPECT_TRUE(current) << "docs/cli.md's option tables are stale: run scripts/update_cli_docs.sh";
}

}  // namespace

TEST(RunOptions, RecordedSettingsHoldForNewOptionsAtTheirDefaultsOnly) {
  const std::string defaults = R"({"a": 1, "b": {"c": 2, "d": "x"}, "e": 0.5})";
  const std::string current = R"({"a": 1, "b": {"c": 2, "d": "x"}, "e": 0.5})";
  EXPECT_TRUE(SettingsStillHold(current, current, defaults));
  // Written before "e" and "b.d" existed: they are at their defaults now.
  EXPECT_TRUE(SettingsStillHold(R"({"a": 1, "b": {"c": 2}})", current, defaults));
  // A new option at another value, a changed value, a removed key: not the same run.
  EXPECT_FALSE(SettingsStillHold(R"({"a": 1, "b": {"c": 2}})", R"({"a": 1, "b": {"c": 2, "d": "y"}, "e": 0.5})",
                                 defaults));
  EXPECT_FALSE(SettingsStillHold(R"({"a": 2, "b": {"c": 2, "d": "x"}, "e": 0.5})", current, defaults));
  EXPECT_FALSE(SettingsStillHold(R"({"a": 1, "b": {"c": 2, "d": "x"}, "e": 0.5, "gone": 1})", current, defaults));
  // A key without a default (not an option: a decision, an input's hash) must be recorded.
  EXPECT_FALSE(SettingsStillHold(R"({"a": 1})", R"({"a": 1, "inputs": "abc"})", R"({"a": 1})"));
  // No record, or an unreadable one: nothing holds.
  EXPECT_FALSE(SettingsStillHold("", current, defaults));
  EXPECT_FALSE(SettingsStillHold("{not json", current, defaults));
  // The real stamps: the tile's options without one key, at its default.
  const RunOptions library;
  nlohmann::json older = nlohmann::json::parse(TileOptionsJson(library));
  older["train"].erase("init_step_reach_m");
  EXPECT_TRUE(SettingsStillHold(older.dump(), TileOptionsJson(library), TileOptionsJson(library)));
}

}  // namespace skyfall
