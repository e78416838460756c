// skyfall report --run DIR [--aoi aoi.json]
#include <spdlog/spdlog.h>

#include <cmath>

#include "apps/commands.h"
#include "catalogs/aoi_catalog.h"
#include "merge/run_report.h"

namespace skyfall::cli {

void AddReportCommand(CLI::App& app, Runner* runner) {
  auto run = std::make_shared<std::string>(), aoi = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Error against run time: held-out PSNR from train_report.json and DSM MAE of the run's snapshots");
  cmd->add_option("--run", *run, "A `skyfall splat train` output folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--aoi", *aoi, "aoi.json with the truth grid (DSM MAE needs it and `--snapshots` in training)");
  cmd->add_option("--out", *out, "Output folder (default: the run folder)");
  cmd->callback([runner, run, aoi, out] {
    *runner = [run, aoi, out] {
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
