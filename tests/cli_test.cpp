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

namespace skyfall {
namespace {

using namespace skyfall::testing;

nlohmann::json ReadJsonFile(const fs::path& path) { return nlohmann::json::parse(std::ifstream(path)); }

fs::file_time_type TileReportTime(const fs::path& city_dir) {
  for (const auto& entry : fs::directory_iterator(city_dir / "tiles")) {
    if (fs::exists(entry.path() / "tile_report.json")) return fs::last_write_time(entry.path() / "tile_report.json");
  }
  return {};
}

CommandResult ValidateStac(const fs::path& out, const fs::path& scratch) {
  return RunCommand("/usr/bin/python3 " + std::string(SKYFALL_SOURCE_DIR) + "/tests/stac_validate.py " +
                        (out / "catalog.json").string() + " " + SharedSchemas().string(),
                    scratch);
}

// Two cities (one AOI each, far apart) run as a cron job would: a STAC
// catalog that validates, a second concurrent run refused by the lock, an
// unchanged rerun that recomputes nothing, and a changed image that redoes
// only its own city.
TEST(Cli, CronSafeIncrementalRunsWithAStacCatalog) {
  if (!fs::exists(SharedSchemas() / "stac-1.1.0")) GTEST_SKIP() << "no schemas at " << SharedSchemas();
  const fs::path dir = ScratchDir("cron");
  const std::string root = (dir / "tree").string(), out = (dir / "out").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --aoi SYN_001 --size-m 64 --views 3 --seed 4", dir)
                .exit_code, 0);
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --aoi SYN_002 --size-m 64 --views 3 --seed 5"
                                   " --lon -81.60",
                       dir).exit_code, 0);
  const std::string run = Skyfall() + " --log-json " + (dir / "events.jsonl").string() + " run " + root +
                          " --out " + out + " --tile-m 64 --iterations 30 --init-max-scale 0 --idu off";

  // The first run goes to the background; a second one on the same folder is
  // refused at once with the lock's exit code and names the holder.
  ASSERT_EQ(std::system(("(" + run + " >" + (dir / "first.log").string() + " 2>&1; echo $? >" +
                         (dir / "first.rc").string() + ") &").c_str()), 0);
  const fs::path lock_file = fs::path(out) / ".skyfall.lock";
  for (int i = 0; i < 600 && !(fs::exists(lock_file) && fs::file_size(lock_file) > 0); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const CommandResult refused = RunCommand(Skyfall() + " run " + root + " --out " + out, dir);
  EXPECT_EQ(refused.exit_code, 7) << refused.err;
  EXPECT_NE(refused.err.find("PID "), std::string::npos) << refused.err;
  for (int i = 0; i < 3000 && !fs::exists(dir / "first.rc"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::string rc;
  std::ifstream(dir / "first.rc") >> rc;
  ASSERT_EQ(rc, "0") << std::ifstream(dir / "first.log").rdbuf();

  // The catalog validates against the official schemas, checksums and gdalinfo.
  const CommandResult stac = ValidateStac(out, dir);
  EXPECT_EQ(stac.exit_code, 0) << stac.out << stac.err;
  EXPECT_NE(stac.out.find("2 collection(s)"), std::string::npos) << stac.out;
  const auto item = ReadJsonFile(fs::path(out) / "SYN_001" / "SYN_001.json");
  EXPECT_EQ(item["assets"]["dsm"]["roles"][0], "data");
  EXPECT_EQ(item["assets"]["dsm"]["unit"], "m");
  EXPECT_TRUE(item["assets"]["dsm"]["statistics"].contains("mean"));
  EXPECT_EQ(item["assets"]["dsm_report_by_class"]["type"], "text/csv") << item["assets"].dump();
  EXPECT_EQ(item["assets"]["dsm_report_edge_profile"]["type"], "text/csv") << item["assets"].dump();

  // Every line of the JSON log is an event; the DSM figures are there.
  std::ifstream events(dir / "events.jsonl");
  int dsm_events = 0;
  for (std::string line; std::getline(events, line);) {
    const auto event = nlohmann::json::parse(line);
    if (event.value("stage", "") == "dsm") {
      ++dsm_events;
      EXPECT_GT(event["figures"]["completeness"].get<double>(), 0.5) << line;
    }
  }
  EXPECT_EQ(dsm_events, 2);

  // Nothing changed: nothing is recomputed, in seconds.
  const auto first_001 = TileReportTime(fs::path(out) / "SYN_001");
  const auto first_002 = TileReportTime(fs::path(out) / "SYN_002");
  const auto start = std::chrono::steady_clock::now();
  const CommandResult again = RunCommand(run, dir);
  const double again_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_LT(again_s, 10.0);
  auto summary = ReadJsonFile(fs::path(out) / "run_summary.json");
  EXPECT_EQ(summary["cities"][0]["unchanged"], true) << summary.dump();
  EXPECT_EQ(summary["cities"][1]["unchanged"], true) << summary.dump();

  // One image of SYN_002 changes: only its city is redone.
  const fs::path image = fs::path(root) / "Track3-RGB-crops" / "SYN_002" / "SYN_002_001_RGB.tif";
  ASSERT_TRUE(fs::exists(image));
  fs::last_write_time(image, fs::last_write_time(image) + std::chrono::seconds(5));
  const CommandResult changed = RunCommand(run, dir);
  ASSERT_EQ(changed.exit_code, 0) << changed.err;
  summary = ReadJsonFile(fs::path(out) / "run_summary.json");
  EXPECT_EQ(summary["cities"][0]["unchanged"], true) << summary.dump();
  EXPECT_EQ(summary["cities"][1]["unchanged"], false) << summary.dump();
  EXPECT_GE(summary["cities"][1]["tiles_reset"].get<int>(), 1) << summary.dump();
  EXPECT_EQ(TileReportTime(fs::path(out) / "SYN_001"), first_001);
  EXPECT_NE(TileReportTime(fs::path(out) / "SYN_002"), first_002);
  const CommandResult stac_again = ValidateStac(out, dir);
  EXPECT_EQ(stac_again.exit_code, 0) << stac_again.out << stac_again.err;
  // The validator catches a product changed behind the catalog's back.
  std::ofstream(fs::path(out) / "SYN_001" / "dsm_compare" / "report.csv", std::ios::app) << "tampered\n";
  const CommandResult tampered = ValidateStac(out, dir);
  EXPECT_EQ(tampered.exit_code, 1) << tampered.out;
  EXPECT_NE(tampered.out.find("file:checksum does not match dsm_compare/report.csv"), std::string::npos)
      << tampered.out;

  // A mistyped flag is a usage error, told apart from bad input.
  EXPECT_EQ(RunCommand(Skyfall() + " run " + root + " --out " + out + " --no-such-flag", dir).exit_code, 2);
}

}  // namespace
}  // namespace skyfall

namespace skyfall {
namespace {

using namespace skyfall::testing;

// A single-node Slurm cluster for one test, stopped when it ends.
class LocalSlurm {
 public:
  explicit LocalSlurm(const fs::path& dir) : dir_(dir) {
    const std::string script = std::string(SKYFALL_SOURCE_DIR) + "/scripts/slurm_local.sh";
    const CommandResult r = RunCommand("bash " + script + " start " + dir.string(), dir.parent_path());
    exit_code_ = r.exit_code;
    message_ = r.out + r.err;
    stop_ = "bash " + script + " stop " + dir.string() + " >/dev/null 2>&1";
  }
  ~LocalSlurm() { [[maybe_unused]] const int rc = std::system(stop_.c_str()); }
  int exit_code() const { return exit_code_; }
  const std::string& message() const { return message_; }
  std::string Env() const { return "SLURM_CONF=" + (dir_ / "slurm.conf").string() + " "; }

 private:
  fs::path dir_;
  int exit_code_ = 0;
  std::string message_, stop_;
};

nlohmann::json DsmFigures(const fs::path& city) {
  const auto report = nlohmann::json::parse(std::ifstream(city / "run_report.json"));
  return report.at("dsm").at(0);
}

// A 2x2-tile city through sbatch (tile array + dependent merge job) gives the
// DSM figures of the local executor; status reads the jobs; a rerun submits
// only the tiles that did not finish.
TEST(Cli, SlurmExecutorRunsTheCityAsTheLocalOneDoes) {
  const fs::path dir = ScratchDir("slurm");
  LocalSlurm slurm(dir / "cluster");
  if (slurm.exit_code() == 77) GTEST_SKIP() << "Slurm cannot run on this machine: " << slurm.message();
  ASSERT_EQ(slurm.exit_code(), 0) << slurm.message();
  const std::string root = (dir / "tree").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 64 --views 3 --seed 4", dir).exit_code, 0);
  // One thread per tile in both executors, so both compute the same numbers.
  const std::string flags = " --tile-m 32 --overlap-m 4 --iterations 30 --init-max-scale 0 --idu off";
  const fs::path local = dir / "local", cluster = dir / "cluster_out";
  const CommandResult l = RunCommand(Skyfall() + " run " + root + " --out " + local.string() + flags + " --jobs 2", dir);
  ASSERT_EQ(l.exit_code, 0) << l.err;
  // A run that cannot finish must fail the test, not hang it.
  const std::string on_slurm = "timeout 300 env " + slurm.Env() + Skyfall() + " run " + root + " --out " + cluster.string() + flags +
                               " --executor slurm --slurm-cpus 1 --set executor.slurm.poll_s=0.5";
  const CommandResult s = RunCommand(on_slurm, dir);
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const fs::path city = cluster / "SYN_001";
  const auto jobs = nlohmann::json::parse(std::ifstream(city / "slurm" / "jobs.json"));
  EXPECT_EQ(jobs["tiles"].size(), 4u) << jobs.dump();
  EXPECT_FALSE(jobs["tiles_job"].get<std::string>().empty());
  EXPECT_TRUE(fs::exists(city / "slurm" / "finish.sbatch"));
  const auto want = DsmFigures(local / "SYN_001"), got = DsmFigures(city);
  for (const char* key : {"mae_m", "rmse_m", "completeness", "within_1m"}) {
    EXPECT_DOUBLE_EQ(got[key].get<double>(), want[key].get<double>()) << key;
  }

  const CommandResult status = RunCommand(slurm.Env() + Skyfall() + " status " + cluster.string() + " --json", dir);
  ASSERT_EQ(status.exit_code, 0) << status.err;
  const auto st = nlohmann::json::parse(status.out);
  EXPECT_EQ(st["cities"][0]["state"], "done") << st.dump();
  EXPECT_EQ(st["cities"][0]["tiles_done"], 4) << st.dump();
  EXPECT_EQ(st["cities"][0]["slurm"]["finish_job"], jobs["finish_job"]);

  // A tile that did not finish (and no city report): only it is resubmitted.
  const std::string first_tile = jobs["tiles"][0];
  fs::remove(fs::path(first_tile) / "tile_report.json");
  fs::remove(city / "run_report.json");
  const CommandResult again = RunCommand(on_slurm, dir);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const auto resubmitted = nlohmann::json::parse(std::ifstream(city / "slurm" / "jobs.json"));
  ASSERT_EQ(resubmitted["tiles"].size(), 1u) << resubmitted.dump();
  EXPECT_EQ(resubmitted["tiles"][0], first_tile);
  EXPECT_NE(resubmitted["finish_job"], jobs["finish_job"]);
  EXPECT_DOUBLE_EQ(DsmFigures(city)["mae_m"].get<double>(), want["mae_m"].get<double>());
}

}  // namespace
}  // namespace skyfall

namespace skyfall {
namespace {

using namespace skyfall::testing;

void CollectLeaves(const nlohmann::json& node, std::vector<std::string>* uris) {
  if (!node.contains("children")) {
    uris->push_back(node["content"]["uri"]);
    return;
  }
  for (const auto& child : node["children"]) CollectLeaves(child, uris);
}

// `skyfall run --3dtiles`: the tileset validates against the 3D Tiles 1.1
// schemas, every GLB passes the Khronos validator, and the SPZ streams,
// decoded by spz-loader (the decoder CesiumJS uses), give back the finest
// level's Gaussians: the same count, positions within half a quantization step.
TEST(Cli, ThreeDTilesExportPassesIndependentValidators) {
  const fs::path web = fs::path(SKYFALL_SOURCE_DIR) / "web";
  ASSERT_TRUE(fs::exists(web / "node_modules" / "gltf-validator")) << "run scripts/setup.sh (npm ci in web/)";
  ASSERT_TRUE(fs::exists(SharedSchemas() / "3d-tiles-1.1")) << "no schemas at " << SharedSchemas();
  const fs::path dir = ScratchDir("tiles3d");
  const std::string root = (dir / "tree").string(), out = (dir / "out").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 64 --views 3 --seed 4", dir).exit_code, 0);
  const CommandResult run = RunCommand(Skyfall() + " run " + root + " --out " + out +
                                           " --tile-m 64 --iterations 30 --init-max-scale 0 --idu off --3dtiles"
                                           " --set exports.tiles3d_options.leaf_m=32",
                                       dir);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const fs::path tiles = fs::path(out) / "SYN_001" / "3dtiles";
  const CommandResult schema = RunCommand("/usr/bin/python3 " + std::string(SKYFALL_SOURCE_DIR) +
                                              "/tests/tiles3d_validate.py " + (tiles / "tileset.json").string() +
                                              " " + SharedSchemas().string(), dir);
  EXPECT_EQ(schema.exit_code, 0) << schema.out << schema.err;

  const auto tileset = nlohmann::json::parse(std::ifstream(tiles / "tileset.json"));
  std::vector<std::string> leaves;
  CollectLeaves(tileset["root"], &leaves);
  ASSERT_GE(leaves.size(), 4u);  // 64 m city, 32 m leaves
  std::string files;
  for (const auto& uri : leaves) files += " " + (tiles / uri).string();
  const CommandResult checked = RunCommand("node " + (web / "check_splats.mjs").string() + files, dir);
  ASSERT_EQ(checked.exit_code, 0) << checked.err;

  // The finest level's Gaussians, sorted by x for the search below.
  const GaussianCloud finest = ReadGaussiansPly((fs::path(out) / "SYN_001" / "scene" / "lod_0.ply").string());
  std::vector<std::size_t> order(finest.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return finest.means[a].x() < finest.means[b].x(); });
  // What spz-loader gives back, against the PLY: the conversions of the export
  // (log-scale -> scale, logit -> opacity, (w, x, y, z) -> (x, y, z, w), SH
  // layout) checked on every Gaussian, within SPZ's quantization steps.
  constexpr double kEps = 1e-5;
  std::istringstream lines(checked.out);
  std::size_t decoded = 0, matched = 0;
  for (std::string line; std::getline(lines, line);) {
    const auto glb = nlohmann::json::parse(line);
    EXPECT_TRUE(glb["errors"].empty()) << glb["file"] << ": " << glb["errors"].dump();
    EXPECT_EQ(glb["version"], 2);
    const double half_step = 0.5 * std::ldexp(1.0, -glb["fractionalBits"].get<int>());
    const std::vector<double> p = glb["positions"], alphas = glb["alphas"], scales = glb["scales"],
                              rotations = glb["rotations"], colours = glb["colors"], sh = glb["sh"];
    ASSERT_EQ(p.size(), 3 * glb["numPoints"].get<std::size_t>());
    ASSERT_EQ(sh.size(), 9 * glb["numPoints"].get<std::size_t>());  // degree 1
    for (std::size_t n = 0; 3 * n < p.size(); ++n, ++decoded) {
      auto it = std::lower_bound(order.begin(), order.end(), p[3 * n] - half_step - kEps,
                                 [&](std::size_t s, double x) { return finest.means[s].x() < x; });
      for (; it != order.end() && finest.means[*it].x() <= p[3 * n] + half_step + kEps; ++it) {
        const Eigen::Vector3f& m = finest.means[*it];
        if (std::abs(m.y() - p[3 * n + 1]) > half_step + kEps || std::abs(m.z() - p[3 * n + 2]) > half_step + kEps) continue;
        ++matched;
        const std::size_t i = *it;
        EXPECT_NEAR(alphas[n], 1 / (1 + std::exp(-finest.opacity_logits[i])), 0.5 / 255 + kEps);
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(std::log(scales[3 * n + a]), finest.log_scales[i][a], 0.5 / 16 + kEps);
        Eigen::Vector4d q = finest.rotations[i].cast<double>().normalized();  // (w, x, y, z)
        if (q[0] < 0) q = -q;
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(rotations[4 * n + a], q[a + 1], 0.5 / 127.5 + kEps);
        for (int c = 0; c < 3; ++c) {
          // spz-loader turns the DC coefficient into colour with a rounded SH
          // constant (0.282 against 0.2820948): up to 2e-4 more for |dc| <= 2.
          constexpr double kLoaderShConstantSlack = 2e-4;
          EXPECT_NEAR(colours[3 * n + c], 0.5 + 0.28209479177387814 * finest.sh[i][c * 4],
                      0.28209479177387814 * 0.5 / (0.15 * 255) + kLoaderShConstantSlack);
          for (int k = 1; k < 4; ++k) {  // spz: coefficient-major, channel-minor
            EXPECT_NEAR(sh[9 * n + 3 * (k - 1) + c], std::clamp(finest.sh[i][c * 4 + k], -1.0f, 127.0f / 128),
                        4.0 / 128 + kEps);
          }
        }
        break;
      }
    }
  }
  EXPECT_EQ(decoded, finest.size());
  EXPECT_EQ(matched, decoded);
  const auto report = nlohmann::json::parse(std::ifstream(fs::path(out) / "SYN_001" / "run_report.json"));
  EXPECT_EQ(report["tiles3d"]["contents"].get<int>(), report["tiles3d"]["tiles"].get<int>()) << report["tiles3d"];

  // The run report page stands alone: figures, embedded plots and maps, tiles,
  // decisions, links to the products, and nothing fetched from the network.
  std::ifstream page_in(fs::path(out) / "report.html");
  const std::string page((std::istreambuf_iterator<char>(page_in)), {});
  for (const char* expected : {"MAE [m]", "within 1 m", "data:image/png;base64,", "SYN_001_c0_r0", "peak memory",
                               "appearance", "3dtiles/tileset.json", "SYN_001/dsm_compare/report.json", "part of the MAE",
                               "class: ground"}) {
    EXPECT_NE(page.find(expected), std::string::npos) << expected;
  }
  EXPECT_GE(std::count(page.begin(), page.end(), '<') , 100);
  EXPECT_EQ(page.find("http://"), std::string::npos);
  EXPECT_EQ(page.find("https://"), std::string::npos);

  // Both pages in a real browser (headless Chromium, WebGL by SwiftShader),
  // with every request off this machine refused: the report shows all its
  // images; the viewer, served by `skyfall view`, loads every visible tile.
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "run scripts/setup.sh (Debian's chromium)";
  const std::string check_page = "node " + (web / "check_page.mjs").string() + " ";
  const CommandResult shown = RunCommand(check_page + "file://" + (fs::path(out) / "report.html").string() + " " +
                                             (dir / "report.png").string(), dir);
  ASSERT_EQ(shown.exit_code, 0) << shown.err;
  const auto report_page = nlohmann::json::parse(shown.out);
  EXPECT_TRUE(report_page["external"].empty()) << shown.out;
  EXPECT_TRUE(report_page["errors"].empty()) << shown.out;
  ASSERT_GE(report_page["images"].size(), 3u) << shown.out;  // plot, error map, histogram
  for (const auto& image : report_page["images"]) EXPECT_GT(image["width"].get<int>(), 0) << image;

  const int port = 20000 + getpid() % 20000;
  const fs::path pid_file = dir / "view.pid";
  ASSERT_EQ(std::system((Skyfall() + " view " + out + " --port " + std::to_string(port) + " >" +
                         (dir / "view.log").string() + " 2>&1 & echo $! >" + pid_file.string()).c_str()), 0);
  std::this_thread::sleep_for(std::chrono::seconds(2));  // the server starts
  const CommandResult viewed = RunCommand(check_page + "http://127.0.0.1:" + std::to_string(port) +
                                              "/view/index.html " + (dir / "viewer.png").string() + " --viewer", dir);
  long server = 0;
  std::ifstream(pid_file) >> server;
  if (server > 0) kill(static_cast<pid_t>(server), SIGTERM);
  ASSERT_EQ(viewed.exit_code, 0) << viewed.err << std::ifstream(dir / "view.log").rdbuf();
  const auto viewer = nlohmann::json::parse(viewed.out);
  EXPECT_EQ(viewer["status"]["loaded"], true) << viewed.out;
  EXPECT_TRUE(viewer["status"]["errors"].empty()) << viewed.out;
  EXPECT_TRUE(viewer["external"].empty()) << viewed.out;
  EXPECT_TRUE(viewer["errors"].empty()) << viewed.out;
  EXPECT_GT(fs::file_size(dir / "viewer.png"), 10000u);
}

}  // namespace
}  // namespace skyfall

namespace skyfall {
namespace {

using namespace skyfall::testing;

// Every JSON file parses and every Gaussian PLY reads: nothing partial under a
// final name.
void ExpectWholeFiles(const fs::path& out, const std::string& point) {
  for (const auto& entry : fs::recursive_directory_iterator(out)) {
    if (!entry.is_regular_file()) continue;
    const fs::path& p = entry.path();
    if (p.extension() == ".json") {
      std::ifstream in(p);
      EXPECT_NO_THROW((void)nlohmann::json::parse(in)) << point << ": " << p;
    } else if (p.extension() == ".ply" && p.parent_path().filename() != "sfm") {  // Gaussian PLYs (sfm/ holds points)
      EXPECT_NO_THROW((void)ReadGaussiansPly(p.string())) << point << ": " << p;
    }
  }
}

// SIGKILL at named points of every stage (SKYFALL_CRASH_AT, core/crash_point.h;
// in a tile process the whole run dies), then a plain rerun: every rerun
// finishes, no file is ever partial under its final name, and the products
// are byte for byte those of an uninterrupted run (runs are deterministic at
// a given thread count; training resumes from its checkpoint, RNG included).
TEST(Cli, KilledRunsResumeToTheSameProducts) {
  const fs::path dir = ScratchDir("crash");
  const std::string root = (dir / "tree").string();
  ASSERT_EQ(RunCommand(Skyfall() + " synth --out " + root + " --size-m 64 --views 3 --seed 4", dir).exit_code, 0);
  const std::string flags = " --tile-m 64 --iterations 90 --init-max-scale 0 --idu off --jobs 1"
                            " --set train.checkpoint_interval=30";
  auto run = [&](const fs::path& out) { return Skyfall() + " -q run " + root + " --out " + out.string() + flags; };
  auto sums = [](const fs::path& out) {
    return std::make_pair(Sha256FileHex((out / "SYN_001" / "scene" / "scene.ply").string()),
                          Sha256FileHex((out / "SYN_001" / "dsm.tif").string()));
  };
  const CommandResult reference = RunCommand(run(dir / "reference"), dir);
  ASSERT_EQ(reference.exit_code, 0) << reference.err;
  const auto expected = sums(dir / "reference");
  for (const char* point : {"sfm", "dense", "train:10", "train:45", "train:75", "tile", "merge", "dsm",
                            "dsm_written", "report", "stac", "summary"}) {
    const fs::path out = dir / (std::string("killed_") + point);
    const CommandResult killed = RunCommand(std::string("SKYFALL_CRASH_AT=") + point + " " + run(out), dir);
    EXPECT_EQ(killed.exit_code, 128 + 9) << point << ": " << killed.err;  // SIGKILL, seen through the shell
    ExpectWholeFiles(out, point);
    const CommandResult rerun = RunCommand(run(out), dir);
    ASSERT_EQ(rerun.exit_code, 0) << point << ": " << rerun.err;
    EXPECT_EQ(sums(out), expected) << point;
  }

  // A full disk (here a 200 KB file-size limit): a clear error naming the file,
  // nothing already written is damaged, and a rerun with room finishes alike.
  const fs::path full = dir / "full";
  const CommandResult no_room = RunCommand("ulimit -f 200; " + run(full), dir);
  EXPECT_NE(no_room.exit_code, 0);
  EXPECT_NE(no_room.err.find("File too large"), std::string::npos) << no_room.err;
  ExpectWholeFiles(full, "file-size limit");
  ASSERT_EQ(RunCommand(run(full), dir).exit_code, 0);
  EXPECT_EQ(sums(full), expected);
}

}  // namespace
}  // namespace skyfall
