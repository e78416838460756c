// skyfall export 3dtiles: a merged scene as a 3D Tiles 1.1 tileset of
// SPZ-compressed Gaussian splats for CesiumJS-style globes.
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "apps/console.h"
#include "merge/tiles3d.h"
#include "pipeline/exit_codes.h"

namespace skyfall::cli {

void AddExportCommand(CLI::App& app, Runner* runner) {
  CLI::App* exp = app.add_subcommand("export", "Export a merged scene to other formats");
  exp->require_subcommand(1);
  auto scene = std::make_shared<std::string>(), out = std::make_shared<std::string>();
  auto options = std::make_shared<Tiles3dOptions>();
  CLI::App* cmd = exp->add_subcommand(
      "3dtiles", "3D Tiles 1.1 tileset (quadtree, LOD levels, REPLACE) with glTF KHR_gaussian_splatting + SPZ content");
  cmd->add_option("--scene", *scene, "Merged scene folder OUT/<city>/scene (lod.json, lod_<k>.ply, frame.json)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", *out, "Output folder: tileset.json and content/*.glb")->required();
  cmd->add_option("--leaf-m", options->leaf_m, "Nodes split into quadrants while wider than this [m]")
      ->capture_default_str();
  cmd->callback([=] {
    *runner = [=] {
      ConsoleProgress progress;
      const Tiles3dSummary s = Export3dTiles(*scene, *out, *options, progress);
      spdlog::info("export 3dtiles: {} tiles, {} GLB, {} Gaussians, {} LOD levels -> {}", s.tiles, s.contents,
                   s.gaussians, s.levels, s.tileset_path);
      return kExitOk;
    };
  });
}

}  // namespace skyfall::cli
