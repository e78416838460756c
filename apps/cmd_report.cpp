// skyfall report --run DIR [--aoi aoi.json]
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "catalogs/aoi_catalog.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "products/run_report.h"

namespace skyfall::cli {
namespace {

// bench_accuracy.json -> PNG of MAE against run time (beside it, or into out_dir).
int PlotScenes(const std::string& path, const std::string& out_dir) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(ReadTextFile(path));
  } catch (const nlohmann::json::exception& e) {
    throw Error("report", path, std::string("not valid JSON: ") + e.what());
  }
  auto number = [](const nlohmann::json& j, const char* key) {
    return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : NAN;
  };
  std::vector<ScenePoint> points;
  for (const auto& s : doc.at("scenes")) {
    points.push_back({s.value("scene", std::string("?")), number(s, "seconds"), number(s, "mae_m"),
                      number(s, "dense_mae_m"), s.value("tuned_on", false)});
  }
  const std::string png = (std::filesystem::path(out_dir.empty() ? std::filesystem::path(path).parent_path().string()
                                                                    : out_dir) /
                           "bench_accuracy.png")
                              .string();
  WriteScenesPlot(points, png);
  spdlog::info("report: {} scenes -> {}", points.size(), png);
  return 0;
}

}  // namespace

void AddReportCommand(CLI::App& app, Runner* runner) {
  auto run = std::make_shared<std::string>(), aoi = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto scenes = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Error against run time: of one training run (held-out PSNR, DSM MAE of its snapshots), or across "
                "the scenes of bench_accuracy.json");
  auto run_option = cmd->add_option("--run", *run, "A `skyfall splat train` output folder")->check(CLI::ExistingDirectory);
  cmd->add_option("--scenes", *scenes,
                  "bench_accuracy.json (scripts/bench_accuracy.sh): plot DSM MAE against run time per scene")
      ->check(CLI::ExistingFile)
      ->excludes(run_option);
  cmd->add_option("--aoi", *aoi, "aoi.json with the truth grid (DSM MAE needs it and `--snapshots` in training)");
  cmd->add_option("--out", *out, "Output folder (default: the run folder)");
  cmd->callback([runner, run, aoi, out, scenes] {
    *runner = [run, aoi, out, scenes] {
      if (!scenes->empty()) return PlotScenes(*scenes, *out);
      if (run->empty()) throw Error("report", "--run", "give a training run folder (or --scenes FILE)");
      AoiCatalog catalog;
      if (!aoi->empty()) catalog = ReadAoiCatalog(*aoi);
      const auto points = EvaluateRun(*run, catalog, DsmCompareOptions{});
      const std::string dest = out->empty() ? *run : *out;
      WriteRunReport(points, dest);
      for (const RunPoint& p : points) {
        spdlog::info("iteration {:6d}  {:8.1f} s  PSNR {:6.2f} dB  MAE {:6.3f} m  {:.0f} Gaussians", p.iteration,
                     p.elapsed_s, p.psnr_test_db, p.dsm_mae_m, p.gaussians);
      }
      spdlog::info("report: {}/error_vs_time.csv and error_vs_time.png", dest);
      return 0;
    };
  });
}

}  // namespace skyfall::cli
