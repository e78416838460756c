// What a rerun reads back to resume: the run configuration, a tile's report
// and the Slurm jobs record (files in a scratch folder, as a rerun finds them).
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "fuzz/fuzz_target.h"
#include "pipeline/run_options.h"
#include "pipeline/slurm.h"
#include "pipeline/tile_run.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace skyfall;
  namespace fs = std::filesystem;
  const std::string text = fuzz::Text(data, size);
  fuzz::Expect([&] { RunOptionsFromJson(text, "run_config.json"); });
  static const fs::path dir = fs::temp_directory_path() / ("skyfall_fuzz_reports_" + std::to_string(getpid()));
  fs::create_directories(dir / "slurm");
  std::ofstream(dir / "tile_report.json", std::ios::binary | std::ios::trunc) << text;
  std::ofstream(dir / "slurm" / "jobs.json", std::ios::binary | std::ios::trunc) << text;
  fuzz::Expect([&] { TileOutcomeFromReport(dir.string()); });
  fuzz::Expect([&] { TileFinished(dir.string(), RunOptions{}); });
  fuzz::Expect([&] {
    SlurmCityJobs jobs;
    ReadSlurmJobs(dir.string(), &jobs);
  });
  return 0;
}
