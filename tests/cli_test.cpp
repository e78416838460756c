// End-to-end checks of the `skyfall` binary as a user runs it.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <tuple>
#include <numeric>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include <signal.h>
#include <unistd.h>

#include "core/atomic_file.h"
#include "core/sha256.h"
#include "splat/ply.h"
#include "tests/test_support.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

TEST(Cli, VersionAndHelpOnEveryCommand) {
  const fs::path dir = ScratchDir("cli");
  const CommandResult v = RunCommand(Skyfall() + " --version", dir);
  EXPECT_EQ(v.exit_code, 0);
  EXPECT_EQ(v.out.rfind("skyfall 0.", 0), 0u) << v.out;
  for (const char* cmd : {"", "ingest", "rpc", "rpc project", "rpc localize", "rpc check", "synth", "sfm", "dense", "splat train", "splat render", "dsm export", "dsm compare", "report", "tile", "run-tile", "merge", "run"}) {
    const CommandResult h = RunCommand(Skyfall() + " " + cmd + " --help", dir);
    EXPECT_EQ(h.exit_code, 0) << cmd;
    EXPECT_NE(h.out.find("Usage"), std::string::npos) << cmd << ": " << h.out;
  }
  const CommandResult none = RunCommand(Skyfall(), dir);
  EXPECT_NE(none.exit_code, 0);
}

TEST(Cli, RpcProjectAndLocalizeRoundTripAtFullPrecision) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("cli");
  const std::string image = Jax068Image("010").string();  // the most oblique view (~32 deg)
  const CommandResult p =
      RunCommand(Skyfall() + " rpc project " + image + " -81.66377836684407 30.3487524532743 12.5", dir);
  ASSERT_EQ(p.exit_code, 0) << p.err;
  double col = 0, row = 0;
  std::istringstream(p.out) >> col >> row;
  EXPECT_GT(col, 0);
  EXPECT_GT(row, 0);
  // Printed with 17 significant digits, so localizing the printed pixel
  // gives back the point to ~1e-13 deg (~1e-8 m).
  EXPECT_GE(p.out.size(), 30u) << p.out;
  char cmd[512];
  std::snprintf(cmd, sizeof(cmd), "%s rpc localize %s %.17g %.17g 12.5", Skyfall().c_str(),
                image.c_str(), col, row);
  const CommandResult l = RunCommand(cmd, dir);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  double lon = 0, lat = 0;
  std::istringstream(l.out) >> lon >> lat;
  EXPECT_NEAR(lon, -81.66377836684407, 1e-12);
  EXPECT_NEAR(lat, 30.3487524532743, 1e-12);

  // The Sat-NeRF JSON of the same image gives the same pixel.
  const std::string json =
      (Dfc2019Root() / "satnerf-rpcs" / "JAX_068" / "JAX_068_010_RGB.json").string();
  const CommandResult pj =
      RunCommand(Skyfall() + " rpc project " + json + " -81.66377836684407 30.3487524532743 12.5", dir);
  double col_j = 0, row_j = 0;
  std::istringstream(pj.out) >> col_j >> row_j;
  EXPECT_NEAR(col_j, col, 1e-6);
  EXPECT_NEAR(row_j, row, 1e-6);
}

TEST(Cli, RpcErrorsNameTheFile) {
  const fs::path dir = ScratchDir("cli");
  const std::string missing = (dir / "missing.tif").string();
  const CommandResult r = RunCommand(Skyfall() + " rpc project " + missing + " 0 0 0", dir);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty());  // nothing half-printed on stdout
}

TEST(Cli, IngestJsonSummaryOnTheSharedSample) {
  SKYFALL_REQUIRE_DFC2019();
  const fs::path dir = ScratchDir("cli");
  const CommandResult r = RunCommand(
      Skyfall() + " ingest " + Dfc2019Root().string() + " --out " + (dir / "out").string() +
          " --aoi JAX_068 --json", dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["ingested"], 1);
  EXPECT_EQ(summary["failed"], 0);
  EXPECT_EQ(summary["aois"][0]["aoi"], "JAX_068");
  EXPECT_EQ(summary["aois"][0]["images"], 19);
  EXPECT_TRUE(fs::exists(dir / "out" / "JAX_068" / "aoi.json"));
  EXPECT_NE(r.err.find("[ingest JAX_068] done: 19/19"), std::string::npos) << r.err;  // progress
}

TEST(Cli, IngestExitsNonZeroOnlyWhenNothingWasIngested) {
  const fs::path dir = ScratchDir("cli");
  const fs::path root = dir / "root";
  fs::create_directories(root / "Track3-RGB-crops" / "BAD_001");
  std::ofstream(root / "Track3-RGB-crops" / "BAD_001" / "BAD_001_001_RGB.tif") << "garbage";
  const CommandResult r = RunCommand(
      Skyfall() + " ingest " + root.string() + " --out " + (dir / "out").string() + " --json", dir);
  EXPECT_EQ(r.exit_code, 1);
  const auto summary = nlohmann::json::parse(r.out);
  EXPECT_EQ(summary["ingested"], 0);
  EXPECT_EQ(summary["aois"][0]["status"], "failed");
  EXPECT_NE(r.err.find("BAD_001_001_RGB.tif"), std::string::npos) << r.err;

  if (!fs::exists(Dfc2019Root() / "Track3-Truth")) return;
  // One good AOI next to the bad one: success, and the bad one is listed.
  fs::create_directories(root / "Track3-RGB-crops" / "JAX_068");
  fs::create_symlink(Jax068Image("001"), root / "Track3-RGB-crops" / "JAX_068" / "JAX_068_001_RGB.tif");
  const CommandResult mixed = RunCommand(
      Skyfall() + " ingest " + root.string() + " --out " + (dir / "out").string() + " --json", dir);
  EXPECT_EQ(mixed.exit_code, 0) << mixed.err;
  EXPECT_EQ(nlohmann::json::parse(mixed.out)["failed"], 1);
}

// The bad-input corpus (scripts/make_bad_inputs.sh): one `skyfall run` over
// a tree of broken AOIs and images processes the sound AOIs and names every
// defect, with its file and value, in run_summary.json. The table in
// docs/reliability.md lists the same cases.
TEST(Cli, BadInputCorpusNamesEveryDefect) {
  const fs::path dir = ScratchDir("cli_bad_inputs");
  const fs::path tree = dir / "tree", out = dir / "out";
  const CommandResult made = RunCommand("bash " + std::string(SKYFALL_SOURCE_DIR) + "/scripts/make_bad_inputs.sh " +
                                            tree.string() + " " + Skyfall(), dir);
  ASSERT_EQ(made.exit_code, 0) << made.err;
  const CommandResult run = RunCommand(Skyfall() + " --quiet run " + tree.string() + " --out " + out.string() +
                                           " --tile-m 64 --iterations 30 --init-max-scale 0 --idu off",
                                       dir);
  EXPECT_EQ(run.exit_code, 5) << "partial: some AOIs failed, the others finished\n" << run.err;
  const auto summary = nlohmann::json::parse(ReadTextFile((out / "run_summary.json").string()));

  std::map<std::string, nlohmann::json> aois;
  for (const auto& a : summary["aois"]) aois[a["aoi"]] = a;
  ASSERT_EQ(aois.size(), 10u) << summary.dump(1);  // the empty folder is listed too
  const fs::path truth = tree / "Track3-Truth";
  // AOI-level defects: the AOI fails at ingest; the error names the file and the value.
  const std::vector<std::tuple<std::string, std::string, std::string>> aoi_cases = {
      {"EMPTY_001", (tree / "Track3-RGB-crops" / "EMPTY_001").string(), "holds no image"},
      {"TXTFIELDS_001", (truth / "TXTFIELDS_001_DSM.txt").string(), "found 3"},
      {"TXTNEG_001", (truth / "TXTNEG_001_DSM.txt").string(), "-128 is not a positive"},
      {"TXTTEXT_001", (truth / "TXTTEXT_001_DSM.txt").string(), "'easting'"},
      {"TRUTHSIZE_001", (truth / "TRUTHSIZE_001_DSM.tif").string(), "64x64 px"},
      {"APART_001", "APART_001", "no common area"},
  };
  for (const auto& [aoi, file, value] : aoi_cases) {
    ASSERT_TRUE(aois.count(aoi)) << aoi;
    EXPECT_EQ(aois[aoi]["ingest"], "failed") << aoi;
    const std::string error = aois[aoi]["error"];
    EXPECT_NE(error.find(file), std::string::npos) << aoi << ": " << error;
    EXPECT_NE(error.find(value), std::string::npos) << aoi << ": " << error;
  }
  EXPECT_EQ(summary["aois_failed"], aoi_cases.size());

  // Image-level defects: the image is left out with its reason; its AOI goes on.
  const nlohmann::json& images = aois["IMAGES_001"];
  EXPECT_EQ(images["ingest"], "ok");
  EXPECT_EQ(images["images"], 3);
  std::map<std::string, std::string> reasons;
  for (const auto& s : images["skipped_images"])
    reasons[fs::path(s["file"].get<std::string>()).filename().string()] = s["reason"];
  const std::vector<std::pair<std::string, std::string>> image_cases = {
      {"IMAGES_001_004_RGB.tif", "truncated or corrupt"},           // truncated TIFF
      {"IMAGES_001_005_RGB.tif", "not a readable raster"},          // wrong magic
      {"IMAGES_001_006_RGB.tif", "HEIGHT_OFF: is not finite (nan)"},
      {"IMAGES_001_007_RGB.tif", "LONG_SCALE: is zero"},
      {"IMAGES_001_008_RGB.tif", "LINE_DEN_COEFF[0]: denominator is zero"},
      {"IMAGES_001_009_RGB.tif", "duplicate of " + (tree / "Track3-RGB-crops" / "IMAGES_001" / "IMAGES_001_001_RGB.tif").string()},
      {"IMAGES_001_010_RGB.tif", "image is 1x1 px"},
      {"IMAGES_001_011_RGB.tif", "has no valid pixel"},
      {"IMAGES_001_012_RGB.vrt", "outside its RPC's reach"},        // 40000 x 40000 sparse VRT
  };
  EXPECT_EQ(reasons.size(), image_cases.size());
  for (const auto& [file, reason] : image_cases) {
    ASSERT_TRUE(reasons.count(file)) << file << " was not reported";
    EXPECT_NE(reasons[file].find(reason), std::string::npos) << file << ": " << reasons[file];
    EXPECT_NE(reasons[file].find(file), std::string::npos) << "the reason names the file: " << reasons[file];
  }

  // Cities: the sound AOIs, the one left with three good images and the AOI
  // on a UTM zone boundary are reconstructed and compared; one image is not enough.
  std::map<std::string, nlohmann::json> cities;
  for (const auto& c : summary["cities"]) cities[c["city"]] = c;
  for (const std::string aoi : {"GOOD_001", "IMAGES_001", "ZONE_001"}) {
    ASSERT_TRUE(cities.count(aoi)) << aoi;
    EXPECT_TRUE(cities[aoi]["scene"].get<bool>()) << aoi << ": " << cities[aoi]["error"];
    EXPECT_TRUE(fs::exists(out / aoi / "dsm.tif")) << aoi;
  }
  ASSERT_TRUE(cities.count("ONE_001"));
  EXPECT_FALSE(cities["ONE_001"]["scene"].get<bool>());
  EXPECT_NE(cities["ONE_001"]["error"].get<std::string>().find("fewer than 2 images"), std::string::npos)
      << cities["ONE_001"]["error"];
  // The zone-boundary AOI lands where its truth is (18 zones apart would be kilometres off).
  const auto zone_report = nlohmann::json::parse(ReadTextFile((out / "ZONE_001" / "run_report.json").string()));
  EXPECT_LT(zone_report["dsm"][0]["mae_m"].get<double>(), 1.0) << zone_report["dsm"].dump();

  // An output folder that cannot be created: a bad-input exit naming it, nothing written.
  std::ofstream(dir / "a_file") << "x";
  const std::string unwritable = (dir / "a_file" / "out").string();
  const CommandResult refused = RunCommand(Skyfall() + " run " + tree.string() + " --out " + unwritable, dir);
  EXPECT_EQ(refused.exit_code, 1) << refused.err;
  EXPECT_NE(refused.err.find(unwritable), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("Not a directory"), std::string::npos) << refused.err;
  EXPECT_EQ(ReadTextFile((dir / "a_file").string()), "x");
}

TEST(Cli, SynthIngestSfmChain) {
  const fs::path dir = ScratchDir("cli");
  const std::string root = (dir / "city").string(), cat = (dir / "catalogs").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 96 --views 3 --seed 5", dir).exit_code, 0);
  ASSERT_EQ(RunCommand(Skyfall() + " ingest " + root + " --out " + cat, dir).exit_code, 0);
  const std::string aoi = cat + "/SYN_001/aoi.json";
  const CommandResult sfm = RunCommand(Skyfall() + " sfm --aoi " + aoi + " --out " + (dir / "sfm").string(), dir);
  ASSERT_EQ(sfm.exit_code, 0) << sfm.err;
  for (const char* f : {"cameras.json", "points.ply", "sfm_report.json", "colmap/images.txt"})
    EXPECT_TRUE(fs::exists(dir / "sfm" / f)) << f;
  const auto report = nlohmann::json::parse(std::ifstream(dir / "sfm" / "sfm_report.json"));
  EXPECT_EQ(report["status"], "ok");
  EXPECT_EQ(report["num_images_used"], 3);

  // Dense heights; an SfM folder without its files is named in the error.
  const CommandResult dense = RunCommand(Skyfall() + " dense --sfm " + (dir / "sfm").string(), dir);
  ASSERT_EQ(dense.exit_code, 0) << dense.err;
  const auto dense_report = nlohmann::json::parse(std::ifstream(dir / "sfm" / "dense_report.json"));
  EXPECT_EQ(dense_report["status"], "ok");
  EXPECT_GT(dense_report["metrics"]["valid_fraction"].get<double>(), 0.3);
  EXPECT_TRUE(fs::exists(dir / "sfm" / "dense.ply"));
  // The report records what produced the heights, so that run-tile reuses them only for the same settings.
  EXPECT_TRUE(dense_report["extent_enu_m"].is_null());
  EXPECT_EQ(dense_report["options"]["visibility_pass"], true);
  EXPECT_EQ(dense_report["options"]["cell_m"], 0.0);   // automatic: follows the imagery
  EXPECT_EQ(dense_report["metrics"]["cell_m"], 0.5);   // 0.5 m synthetic imagery keeps 0.5 m cells
  fs::create_directories(dir / "empty_sfm");
  const CommandResult no_sfm = RunCommand(Skyfall() + " dense --sfm " + (dir / "empty_sfm").string(), dir);
  EXPECT_EQ(no_sfm.exit_code, 1);
  EXPECT_NE(no_sfm.err.find("cameras.json"), std::string::npos) << no_sfm.err;

  // Training and rendering on the SfM result. 30 steps cannot grow 1 m
  // Gaussians over the gaps between this small scene's tie points, so the
  // initial size is left uncapped (the DSM check below needs coverage).
  const std::string splat = (dir / "splat").string();
  const CommandResult train = RunCommand(Skyfall() + " splat train --sfm " + (dir / "sfm").string() + " --out " + splat +
                                             " --iterations 30 --resolution 2 --snapshots --checkpoint-every 15"
                                             " --init-max-scale 0",
                                         dir);
  ASSERT_EQ(train.exit_code, 0) << train.err;
  // stderr is a file here, as in cron: progress comes every 5 % of the steps
  // (or 10 s), not once per step: at most 20 lines for the 30 steps + start/end.
  const auto progress_lines = [&] {
    std::size_t n = 0;
    for (std::size_t at = train.err.find("[splat train]"); at != std::string::npos;
         at = train.err.find("[splat train]", at + 1)) ++n;
    return n;
  }();
  EXPECT_LE(progress_lines, 22u) << train.err;
  const auto train_report = nlohmann::json::parse(std::ifstream(dir / "splat" / "train_report.json"));
  EXPECT_EQ(train_report["series"].back()["iteration"], 30);
  EXPECT_TRUE(fs::exists(dir / "splat" / "checkpoints" / "checkpoint.bin"));
  // dense.ply is there, so training started from it, without densification (--densify auto).
  const auto settings = nlohmann::json::parse(std::ifstream(dir / "splat" / "checkpoints" / "settings.json"));
  EXPECT_EQ(settings["init_points"], "dense");
  EXPECT_EQ(settings["densify"], false);
  const CommandResult bad_densify = RunCommand(Skyfall() + " splat train --sfm " + (dir / "sfm").string() + " --out " +
                                                   (dir / "splat_bad").string() + " --densify maybe", dir);
  EXPECT_NE(bad_densify.exit_code, 0);  // refused while parsing (a CLI11 exit code), before any stage
  EXPECT_FALSE(fs::exists(dir / "splat_bad"));
  EXPECT_NE(bad_densify.err.find("--densify"), std::string::npos) << bad_densify.err;
  // A checkpoint resumes only under the same training options: a rerun that
  // only checkpoints at other steps resumes, one with another loss weight
  // (an option the checkpoint's stamp once left out) starts again.
  const fs::path rerun = dir / "splat_rerun";
  fs::copy(splat, rerun, fs::copy_options::recursive);
  const std::string retrain = Skyfall() + " splat train --sfm " + (dir / "sfm").string() + " --out " + rerun.string() +
                              " --iterations 30 --resolution 2 --init-max-scale 0";
  const CommandResult same = RunCommand(retrain + " --checkpoint-every 10", dir);
  ASSERT_EQ(same.exit_code, 0) << same.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(rerun / "train_report.json"))["resumed_from_iteration"], 30);
  const CommandResult other = RunCommand(retrain + " --lambda-opacity 5", dir);
  ASSERT_EQ(other.exit_code, 0) << other.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(rerun / "train_report.json"))["resumed_from_iteration"], 0);
  EXPECT_NE(other.err.find("other settings"), std::string::npos) << other.err;
  EXPECT_TRUE(fs::exists(rerun / "checkpoints" / "checkpoint.bin.stale"));
  const CommandResult render = RunCommand(Skyfall() + " splat render --scene " + splat + "/scene.ply --cameras " +
                                              (dir / "sfm" / "cameras.json").string() + " --out " +
                                              (dir / "render").string() + " --resolution 2", dir);
  ASSERT_EQ(render.exit_code, 0) << render.err;
  EXPECT_TRUE(fs::exists(dir / "render" / "SYN_001_001_RGB_rgb.png"));
  EXPECT_TRUE(fs::exists(dir / "render" / "SYN_001_001_RGB_depth.tif"));

  // DSM of the trained scene on the AOI's truth grid, compared with the truth.
  const std::string dsm = (dir / "dsm.tif").string();
  const CommandResult exported = RunCommand(Skyfall() + " dsm export --scene " + splat + "/scene.ply --frame " + aoi +
                                                " --out " + dsm, dir);
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  const std::string truth = root + "/Track3-Truth/SYN_001";
  const CommandResult compared = RunCommand(Skyfall() + " dsm compare --pred " + dsm + " --gt " + truth + "_DSM.tif --gt-txt " +
                                                truth + "_DSM.txt --epsg 32617 --cls " + truth + "_CLS.tif --out " +
                                                (dir / "cmp").string(), dir);
  ASSERT_EQ(compared.exit_code, 0) << compared.err;
  const auto cmp = nlohmann::json::parse(std::ifstream(dir / "cmp" / "report.json"));
  EXPECT_GT(cmp["completeness"].get<double>(), 0.5);
  EXPECT_TRUE(std::isfinite(cmp["mae_m"].get<double>()));

  // Error against run time from the snapshots at iterations 15 and 30.
  const CommandResult run_report = RunCommand(Skyfall() + " report --run " + splat + " --aoi " + aoi, dir);
  ASSERT_EQ(run_report.exit_code, 0) << run_report.err;
  std::ifstream csv(dir / "splat" / "error_vs_time.csv");
  std::string header, line;
  std::getline(csv, header);
  EXPECT_EQ(header, "iteration,elapsed_s,loss,psnr_test_db,gaussians,dsm_mae_m,dsm_rmse_m");
  int with_mae = 0, rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    const double mae = std::stod(line.substr(line.rfind(',', line.rfind(',') - 1) + 1));
    with_mae += std::isfinite(mae);
  }
  EXPECT_EQ(rows, 2);      // iterations 0 and 30 (eval every 250, and the last)
  EXPECT_EQ(with_mae, 1);  // the snapshot at 30 (15 is not in the series)
  EXPECT_TRUE(fs::exists(dir / "splat" / "error_vs_time.png"));

  // One image only: a degenerate status with its own exit code, and a report.
  auto catalog = nlohmann::json::parse(std::ifstream(aoi));
  catalog["images"] = nlohmann::json::array({catalog["images"][0]});
  std::ofstream(dir / "one.json") << catalog.dump();
  const CommandResult one = RunCommand(
      Skyfall() + " sfm --aoi " + (dir / "one.json").string() + " --out " + (dir / "sfm1").string(), dir);
  EXPECT_EQ(one.exit_code, 4) << one.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(dir / "sfm1" / "sfm_report.json"))["status"], "degenerate");
}


// The run configuration: flags over --set over a --config file over the
// defaults, checked before any stage, and handed to the tile processes. (The
// pipeline itself is tested through the library in pipeline/city_run_test.)
TEST(Cli, RunConfigurationFromFileSetAndFlagsReachesTheTileProcesses) {
  const fs::path dir = ScratchDir("run");
  const CommandResult defaults = RunCommand(Skyfall() + " run --print-config", dir);
  ASSERT_EQ(defaults.exit_code, 0) << defaults.err;
  const auto printed = nlohmann::json::parse(defaults.out);
  EXPECT_EQ(printed["schema"], "skyfall.run_options/1");
  EXPECT_EQ(printed["train"]["init_points"], "auto");

  auto config = printed;
  config["train"]["iterations"] = 9;
  config["train"]["densify"] = "on";
  std::ofstream(dir / "run.json") << config.dump();
  const CommandResult merged = RunCommand(Skyfall() + " run --print-config --config " + (dir / "run.json").string() +
                                              " --set dense.sgm_p2=1.5 --set train.densify=off --iterations 11", dir);
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  const auto effective = nlohmann::json::parse(merged.out);
  EXPECT_EQ(effective["train"]["iterations"], 11);    // the flag wins over the file
  EXPECT_EQ(effective["train"]["densify"], "off");    // --set wins over the file
  EXPECT_EQ(effective["dense"]["sgm_p2"], 1.5);
  EXPECT_EQ(effective["tiling"], printed["tiling"]);  // the rest stays

  // A mistyped mode stops the run before anything is read or written,
  // whether it comes as a flag or in the file.
  const std::string out = (dir / "out").string(), root = (dir / "city").string();
  fs::create_directories(root);
  const CommandResult typo = RunCommand(Skyfall() + " run " + root + " --out " + out + " --init-points dnse", dir);
  EXPECT_NE(typo.exit_code, 0);
  EXPECT_NE(typo.err.find("--init-points"), std::string::npos) << typo.err;
  config["train"]["init_points"] = "dnse";
  std::ofstream(dir / "bad.json") << config.dump();
  const CommandResult bad = RunCommand(Skyfall() + " run " + root + " --out " + out + " --config " +
                                           (dir / "bad.json").string(), dir);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("train.init_points"), std::string::npos) << bad.err;
  config = printed;
  config["dense"]["sgm_p3"] = 1;
  std::ofstream(dir / "unknown.json") << config.dump();
  const CommandResult unknown = RunCommand(Skyfall() + " run " + root + " --out " + out + " --config " +
                                               (dir / "unknown.json").string(), dir);
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.err.find("dense.sgm_p3"), std::string::npos) << unknown.err;
  EXPECT_FALSE(fs::exists(out));

  // The printed configuration, piped back in, runs a small city with tile
  // processes that read it; the city records exactly that configuration.
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 64 --views 3 --seed 4", dir).exit_code, 0);
  const std::string flags = " --tile-m 64 --iterations 30 --init-max-scale 0 --idu on --set idu.orbit.episodes=2"
                            " --set idu.orbit.grid=1 --set idu.orbit.width_px=32 --set idu.orbit.height_px=32"
                            " --set idu.iterations_per_episode=5";
  const CommandResult print = RunCommand(Skyfall() + " run --print-config" + flags, dir);
  ASSERT_EQ(print.exit_code, 0) << print.err;
  const CommandResult run = RunCommand(Skyfall() + " run --print-config" + flags + " | " + Skyfall() +
                                           " run --config /dev/stdin " + root + " --out " + out, dir);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const fs::path city = fs::path(out) / "SYN_001";
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(city / "run_config.json")), nlohmann::json::parse(print.out));
  const auto report = nlohmann::json::parse(std::ifstream(city / "run_report.json"));
  ASSERT_EQ(report["tiles"].size(), 1u);
  EXPECT_EQ(report["tiles"][0]["status"], "ok") << report.dump();
  const fs::path tile = city / "tiles" / report["tiles"][0]["tile"].get<std::string>();
  EXPECT_TRUE(fs::exists(tile / "run.log"));  // it ran as its own process
  EXPECT_GT(report["peak_tile_rss_mb"].get<double>(), 10.0);
  EXPECT_TRUE(fs::exists(city / "scene" / "scene.ply"));
  EXPECT_TRUE(fs::exists(city / "dsm.tif"));  // a one-AOI city is named after its AOI
  // The synthesis stage ran in the tile process, and the report says why.
  EXPECT_EQ(report["tiles"][0]["decisions"]["idu"]["on"], true) << report.dump();
  EXPECT_TRUE(fs::exists(tile / "idu" / "scene.ply"));
  EXPECT_TRUE(fs::exists(tile / "idu" / "episode_1" / "episode.json"));
  // The same configuration given to run-tile finds the tile done.
  const CommandResult again = RunCommand(Skyfall() + " run-tile " + tile.string() + " --config " +
                                             (city / "run_config.json").string(), dir);
  EXPECT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.err.find("already done"), std::string::npos) << again.err;
}

TEST(Cli, ReportPlotsErrorAgainstRunTimeAcrossScenes) {
  const fs::path dir = ScratchDir("report");
  std::ofstream(dir / "bench_accuracy.json") << R"({"schema": "skyfall.bench_accuracy/1", "scenes": [
      {"scene": "a", "mae_m": 1.2, "dense_mae_m": 1.4, "seconds": 300.0, "tuned_on": true},
      {"scene": "b", "mae_m": 0.8, "dense_mae_m": null, "seconds": 120.0}]})";
  const CommandResult r = RunCommand(Skyfall() + " report --scenes " + (dir / "bench_accuracy.json").string(), dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GT(fs::file_size(dir / "bench_accuracy.png"), 1000u);
  std::ofstream(dir / "broken.json") << "{";
  const CommandResult bad = RunCommand(Skyfall() + " report --scenes " + (dir / "broken.json").string(), dir);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("broken.json"), std::string::npos) << bad.err;
}

// `synth --draw N` makes the same drawn scene every time, records its
// options, and refuses the scene options it draws itself.
TEST(Cli, SynthDrawRecordsItsOptionsAndRefusesTheOnesItDraws) {
  const fs::path dir = ScratchDir("synth_draw");
  auto options_of = [&](const std::string& name) {
    const std::string root = (dir / name).string();
    const CommandResult r = RunCommand(Skyfall() + " synth --out " + root + " --size-m 32 --draw 5", dir);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return nlohmann::json::parse(std::ifstream(root + "/synth_report.json")).at("options");
  };
  const nlohmann::json a = options_of("a"), b = options_of("b");
  EXPECT_EQ(a, b);
  EXPECT_GE(a.at("seed").get<std::uint64_t>(), 1000000u);
  EXPECT_EQ(a.at("size_m").get<double>(), 32.0);
  for (const char* drawn : {"--seed 3", "--lat 10", "--views 4", "--bands 1", "--relief-m 20"}) {
    const CommandResult clash =
        RunCommand(Skyfall() + " synth --out " + (dir / "c").string() + " --draw 5 " + drawn, dir);
    EXPECT_NE(clash.exit_code, 0) << drawn;
    EXPECT_NE(clash.err.find("--draw"), std::string::npos) << clash.err;
  }
  const CommandResult zero = RunCommand(Skyfall() + " synth --out " + (dir / "z").string() + " --draw 0", dir);
  EXPECT_NE(zero.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir / "z" / "synth_report.json"));
}

TEST(Cli, TileWithoutImagesIsSkippedNotFatal) {
  const fs::path dir = ScratchDir("run");
  const std::string root = (dir / "city").string(), cat = (dir / "catalogs").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 64 --views 3 --seed 2", dir).exit_code, 0);
  ASSERT_EQ(RunCommand(Skyfall() + " ingest " + root + " --out " + cat, dir).exit_code, 0);
  // Images cropped to their western quarter see only the western tiles.
  auto catalog = nlohmann::json::parse(std::ifstream(cat + "/SYN_001/aoi.json"));
  for (auto& im : catalog["images"]) im["width_px"] = im["width_px"].get<int>() / 4;
  std::ofstream(dir / "narrow.json") << catalog.dump();
  const CommandResult tiled = RunCommand(Skyfall() + " tile --aoi " + (dir / "narrow.json").string() + " --out " +
                                             (dir / "tiles").string() + " --tile-m 32 --overlap-m 4", dir);
  ASSERT_EQ(tiled.exit_code, 0) << tiled.err;
  const auto index = nlohmann::json::parse(std::ifstream(dir / "tiles" / "tiles.json"));
  std::string empty_tile;
  for (const auto& t : index["tiles"]) {
    if (t["status"] == "no_images") empty_tile = t["id"];
  }
  ASSERT_FALSE(empty_tile.empty()) << index.dump();
  EXPECT_NE(tiled.err.find(empty_tile + ": fewer than 2 images see it"), std::string::npos) << tiled.err;
  const CommandResult r = RunCommand(Skyfall() + " run-tile " + (dir / "tiles" / empty_tile).string(), dir);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("nothing to reconstruct"), std::string::npos) << r.err;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(dir / "tiles" / empty_tile / "tile_report.json"))["status"], "skipped");
  // Merging tiles none of which finished is a clear error naming the folder.
  const CommandResult m = RunCommand(Skyfall() + " merge --tiles " + (dir / "tiles").string() + " --out " +
                                         (dir / "scene").string(), dir);
  EXPECT_EQ(m.exit_code, 1);
  EXPECT_NE(m.err.find("no finished tile to merge"), std::string::npos) << m.err;
}

}  // namespace
}  // namespace skyfall
