// skyfall export 3dtiles: a merged scene as a 3D Tiles 1.1 tileset of
// SPZ-compressed Gaussian splats for CesiumJS-style globes.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "apps/commands.h"
#include "apps/console.h"
#include "core/error.h"
#include "products/tiles3d.h"
#include "products/viewer.h"
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

namespace skyfall::cli {

// Where CesiumJS is: $SKYFALL_WEB_DIR, else the web/ folder of the source
// tree this binary was built from (where scripts/setup.sh installs it).
std::string CesiumDir() {
  const char* env = std::getenv("SKYFALL_WEB_DIR");
  const std::string web = env && *env ? env : SKYFALL_WEB_DIR;
  return web + "/node_modules/cesium/Build/Cesium";
}

void AddViewCommand(CLI::App& app, Runner* runner) {
  auto out = std::make_shared<std::string>(), city = std::make_shared<std::string>();
  auto port = std::make_shared<int>(8080);
  auto no_serve = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "view", "Serve a CesiumJS page of a run's 3D Tiles over its DSM on localhost (offline: no imagery, no token)");
  cmd->add_option("out", *out, "Output folder of `skyfall run --3dtiles`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--port", *port, "Port on 127.0.0.1")->capture_default_str()->check(CLI::Range(1, 65535));
  cmd->add_option("--city", *city, "City to show (default: the first with a tileset)");
  cmd->add_flag("--no-serve", *no_serve, "Write OUT/view/ and exit (serve OUT with any static file server)");
  cmd->callback([=] {
    *runner = [=] {
      const ViewPage page = WriteViewPage(*out, *city, CesiumDir());
      if (*no_serve) {
        spdlog::info("view: {} -> {}", page.city, page.index_html);
        return kExitOk;
      }
      const std::string url = fmt::format("http://127.0.0.1:{}/{}", *port, page.url_path);
      spdlog::info("view: {} at {} (Ctrl-C stops)", page.city, url);
      std::fflush(nullptr);
      // A static server for OUT: Python's, from Debian's python3.
      const std::string port_text = std::to_string(*port);
      execlp("python3", "python3", "-m", "http.server", port_text.c_str(), "--bind", "127.0.0.1", "--directory",
             out->c_str(), static_cast<char*>(nullptr));
      throw Error("view", "python3", std::string("cannot start the web server: ") + std::strerror(errno));
    };
  });
}

}  // namespace skyfall::cli
