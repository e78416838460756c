// skyfall rpc project|localize|check: direct access to the RPC model of an
// image (GeoTIFF/NITF metadata and GDAL's sidecars) or of an RPC file given
// directly (.RPB, _RPC.TXT, DIMAP / DigitalGlobe / EnMAP XML, Sat-NeRF JSON).
#include <spdlog/spdlog.h>

#include <iostream>

#include "apps/commands.h"
#include "core/format.h"
#include "ingest/gdal_rpc_check.h"
#include "ingest/raster.h"
#include "ingest/rpc_io.h"

namespace skyfall::cli {
namespace {

struct RpcArgs {
  std::string image;
  double a = 0, b = 0, height_m = 0;
  RpcReadOptions read;
};

void AddPointCommand(CLI::App& rpc, const std::string& name, const std::string& help,
                     const std::string& a_name, const std::string& b_name,
                     std::function<int(const RpcArgs&)> run, Runner* runner) {
  auto args = std::make_shared<RpcArgs>();
  CLI::App* cmd = rpc.add_subcommand(name, help);
  cmd->add_option("image", args->image,
                  "Raster with RPC metadata, or an RPC file: .RPB, _RPC.TXT, DIMAP RPC_*.XML, "
                  "DigitalGlobe/Maxar .XML, EnMAP METADATA.XML, Sat-NeRF .json")
      ->required();
  cmd->add_option(a_name, args->a, a_name)->required();
  cmd->add_option(b_name, args->b, b_name)->required();
  cmd->add_option("alt", args->height_m, "Height above the WGS84 ellipsoid [m]")->required();
  cmd->add_option("--band", args->read.band,
                  "EnMAP metadata (one RPC model per band): the band, from 1 (default 1, the model "
                  "the 91 VNIR bands share)")
      ->check(CLI::PositiveNumber);
  cmd->callback([runner, args, run] { *runner = [args, run] { return run(*args); }; });
}

}  // namespace

void AddRpcCommand(CLI::App& app, Runner* runner) {
  CLI::App* rpc = app.add_subcommand("rpc", "Evaluate an image's RPC camera");
  rpc->require_subcommand(1);
  AddPointCommand(
      *rpc, "project", "Print 'col row' (pixel centres at integers) of a lon/lat/alt point",
      "lon", "lat",
      [](const RpcArgs& a) {
        const RpcModel rpc = ReadRpcAny(a.image, nullptr, a.read);
        const Eigen::Vector2d px = rpc.Project(a.a, a.b, a.height_m);
        std::cout << FormatDouble(px.x()) << " " << FormatDouble(px.y()) << std::endl;
        return 0;
      },
      runner);
  AddPointCommand(
      *rpc, "localize", "Print 'lon lat' of a pixel at a given height", "col", "row",
      [](const RpcArgs& a) {
        const RpcModel rpc = ReadRpcAny(a.image, nullptr, a.read);
        const Eigen::Vector2d ll = Localize(rpc, a.a, a.b, a.height_m);
        std::cout << FormatDouble(ll.x()) << " " << FormatDouble(ll.y()) << std::endl;
        return 0;
      },
      runner);

  auto image = std::make_shared<std::string>();
  CLI::App* check = rpc->add_subcommand(
      "check", "Compare our RPC evaluation with GDAL's RPC transformer over the whole image");
  check->add_option("image", *image, "Raster with RPC metadata")->required();
  check->callback([runner, image] {
    *runner = [image] {
      const RasterInfo info = ReadRasterInfo(*image);
      const RpcAgreement agreement =
          CompareWithGdal(*image, ReadRpcFromRaster(*image), info.width_px, info.height_px);
      std::cout << "points " << agreement.points << "\nmax_project_diff_px "
                << FormatDouble(agreement.max_project_diff_px) << "\nmax_localize_diff_px "
                << FormatDouble(agreement.max_localize_diff_px) << std::endl;
      return 0;
    };
  });
}

}  // namespace skyfall::cli
