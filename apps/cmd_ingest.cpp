// skyfall ingest ROOT --out DIR [--aoi ID ...] [--json]
#include <spdlog/spdlog.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "apps/console.h"
#include "ingest/dfc2019.h"

namespace skyfall::cli {
namespace {

struct IngestArgs {
  std::string root;
  std::string out;
  bool json = false;
  bool no_verify = false;
  IngestOptions options;
};

nlohmann::json Summary(const IngestArgs& args, const IngestResult& result) {
  nlohmann::json aois = nlohmann::json::array();
  for (const auto& a : result.aois) {
    nlohmann::json skipped = nlohmann::json::array();
    for (const auto& s : a.skipped_images) skipped.push_back({{"path", s.what}, {"reason", s.reason}});
    aois.push_back({{"aoi", a.aoi},
                    {"status", ToString(a.report.status)},
                    {"message", a.report.message},
                    {"catalog", a.catalog_path},
                    {"images", a.catalog.images.size()},
                    {"skipped_images", skipped},
                    {"seconds", a.report.seconds}});
  }
  const int ingested = result.NumIngested();
  return {{"root", args.root},
          {"out", args.out},
          {"ingested", ingested},
          {"failed", static_cast<int>(result.aois.size()) - ingested},
          {"aois", aois}};
}

int IngestAndReport(IngestArgs& args) {
  args.options.verify_pixels = !args.no_verify;
  ConsoleProgress progress;
  const IngestResult result = RunIngest(args.options, args.root, args.out, progress);
  for (const auto& a : result.aois) {
    if (a.report.status == StageStatus::kOk) {
      spdlog::info("{}: {} images ({} skipped) -> {}", a.aoi, a.catalog.images.size(),
                   a.skipped_images.size(), a.catalog_path);
    } else {
      spdlog::error("{}: failed: {}", a.aoi, a.report.message);
    }
  }
  const int ingested = result.NumIngested();
  spdlog::info("ingested {} of {} AOIs", ingested, result.aois.size());
  if (args.json) std::cout << Summary(args, result).dump(2) << std::endl;
  // Non-zero only when nothing could be ingested: a bulk run with a few bad
  // AOIs still succeeds, and the summary says which failed.
  return ingested > 0 ? 0 : 1;
}

}  // namespace

void AddIngestCommand(CLI::App& app, Runner* runner) {
  auto args = std::make_shared<IngestArgs>();
  CLI::App* cmd = app.add_subcommand(
      "ingest",
      "Scan a DFC2019 tree (Track3-RGB[-crops], Track3-Truth, satnerf-rpcs) and write one "
      "catalog per AOI: DIR/<AOI>/aoi.json");
  cmd->add_option("root", args->root, "DFC2019 root folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", args->out, "Output folder for the AOI catalogs")->required();
  cmd->add_option("--aoi", args->options.aois, "Only these AOIs (repeatable), e.g. JAX_068");
  cmd->add_flag("--json", args->json, "Print a machine-readable summary on stdout");
  cmd->add_flag("--no-verify-pixels", args->no_verify,
                "Skip reading every pixel (faster; corrupt rasters are then found later)");
  cmd->add_option("--height-margin-m", args->options.height_margin_m,
                  "Margin added to the truth/JSON height range [m]")
      ->capture_default_str();
  cmd->callback([runner, args] { *runner = [args] { return IngestAndReport(*args); }; });
}

}  // namespace skyfall::cli
