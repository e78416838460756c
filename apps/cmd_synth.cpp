// skyfall synth --out ROOT [...]: the built-in synthetic city.
#include <spdlog/spdlog.h>

#include <cstdint>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/console.h"
#include "core/error.h"
#include "splat/dataset.h"
#include "testcity/testcity.h"

namespace skyfall::cli {

namespace {

// What the command line fills in.
struct SynthArgs {
  synth::SynthOptions opts;
  std::string out, render_cameras, render_out;
  int lighting_view = 0;
  std::uint64_t draw = 0;
};

// The scene's options, in --help order. Those --draw chooses go to `drawn`.
void AddSceneOptions(CLI::App* cmd, synth::SynthOptions* opts, std::vector<CLI::Option*>* drawn) {
  auto drawn_option = [&](const std::string& name, auto& value, const std::string& help) {
    drawn->push_back(cmd->add_option(name, value, help)->capture_default_str());
  };
  cmd->add_option("--aoi", opts->aoi, "AOI name, NAME_NNN")->capture_default_str();
  drawn_option("--seed", opts->seed, "Random seed; equal seeds give identical output");
  cmd->add_option("--size-m", opts->size_m, "AOI side [m]")->capture_default_str();
  cmd->add_option("--gsd-m", opts->gsd_m, "Ground sampling distance [m]")->capture_default_str();
  drawn_option("--views", opts->views, "Images per AOI");
  drawn_option("--lat", opts->lat_deg, "City centre latitude [deg]");
  drawn_option("--lon", opts->lon_deg, "City centre longitude [deg]");
  cmd->add_option("--blocks-x", opts->blocks_x, "Adjacent AOIs along east")->capture_default_str();
  cmd->add_option("--blocks-y", opts->blocks_y, "Adjacent AOIs along north")->capture_default_str();
  drawn_option("--min-off-nadir", opts->min_off_nadir_deg, "Smallest off-nadir angle of the views [deg]");
  drawn_option("--max-off-nadir", opts->max_off_nadir_deg, "Largest off-nadir angle of the views [deg]");
  drawn_option("--views-per-date", opts->views_per_date, "Images taken on one pass (same light)");
  drawn_option("--bit-depth", opts->bit_depth, "8 (Byte) or 11..16 (UInt16 digital numbers)");
  drawn_option("--bands", opts->bands, "3 (RGB) or 1 (panchromatic)");
  drawn_option("--max-building-m", opts->max_building_m, "Tallest building above ground [m]");
  drawn_option("--relief-m", opts->relief_m, "Hills under the city, peak to peak [m] (slopes up to relief*pi/1000)");
  cmd->add_option("--rpc-height-offset-m", opts->rpc_height_offset_m,
                  "Put the RPCs' HEIGHT_OFF this far from the scene (a stiff case) [m]")
      ->capture_default_str();
  cmd->add_option("--ground-height-m", opts->ground_height_m,
                  "Mean ground height above the WGS84 ellipsoid [m] (a city in the mountains: 2300, 4000)")
      ->capture_default_str();
  cmd->add_option("--rpc-bias-px", opts->rpc_bias_px,
                  "Per-acquisition RPC pointing bias, the same in every AOI's crop of it: a shift of up to this many "
                  "pixels, less the part a shift of the whole city would explain, recorded in synth_report.json [px]")
      ->capture_default_str();
  cmd->add_option("--rpc-bias-rotation-deg", opts->rpc_bias_rotation_deg,
                  "Per-image RPC pointing bias: a rotation about the image centre of up to this angle (<= 0.1) [deg]")
      ->capture_default_str();
  cmd->add_option("--views-per-aoi", opts->views_per_aoi,
                  "Each AOI of a city keeps its own seeded choice of this many of the --views acquisitions "
                  "(0: all), as the AOIs of a DFC2019 tree hold different passes")
      ->capture_default_str();
  cmd->add_option("--along-track-deg", opts->along_track_deg,
                  "A three-line camera: the views on one orbit track, off-nadir from -A (forward) to +A (backward), "
                  "one pass (ZY-3: --views 3 --views-per-date 3 --along-track-deg 22) [deg]")
      ->capture_default_str();
  drawn_option("--date-contrast", opts->date_contrast, "Radiometric change between dates (1 default, 3 strong)");
  cmd->add_option("--haze", opts->haze,
                  "Atmospheric haze: the share of each pixel's light that is path radiance, lowering contrast and "
                  "colour (0 clear; 0.7 as grey as the DFC2019 crops' trees) [0, 0.9]")
      ->capture_default_str();
  cmd->add_option("--noise-dn", opts->noise_dn,
                  "Sensor noise: Gaussian, this standard deviation in DN of the 8-bit scale per band and pixel, on "
                  "top of the +-1 DN every image has (real satellite images: a few DN) [0, 20]")
      ->capture_default_str();
  cmd->add_option("--blur-px", opts->blur_px,
                  "Sensor blur: each image's optics as a Gaussian point-spread function of this standard deviation, "
                  "before the detector's noise (real crops are softer than the default sharp views) [px, 0..3]")
      ->capture_default_str();
  cmd->add_option("--clouds", opts->clouds,
                  "Cumulus 1 km above the tallest roof over every second date (dates 1, 3, ...): the share of the "
                  "sky their puffs cover before overlaps; they hide the ground and shade it [0, 0.8]")
      ->capture_default_str();
}

int RunSynthCommand(SynthArgs& a) {
  ConsoleProgress progress;
  synth::SynthOptions& opts = a.opts;
  if (a.draw > 0) {
    opts = synth::DrawSceneOptions(a.draw, opts);
    spdlog::info(
        "synth: draw {}: seed {}, lat {} lon {}, off-nadir {}-{} deg, {} views ({} per date), {} band(s) of {} "
        "bits, relief {} m, buildings up to {} m, date contrast {}",
        a.draw, opts.seed, opts.lat_deg, opts.lon_deg, opts.min_off_nadir_deg, opts.max_off_nadir_deg, opts.views,
        opts.views_per_date, opts.bands, opts.bit_depth, opts.relief_m, opts.max_building_m, opts.date_contrast);
  }
  if (!a.render_cameras.empty()) {
    if (a.render_out.empty()) throw Error("synth", "--render-out", "is needed with --render-cameras");
    const int n = synth::RenderTruthViews(opts, ReadCameras(a.render_cameras), ReadCamerasFrameOrigin(a.render_cameras),
                                          a.lighting_view, a.render_out, progress);
    spdlog::info("synth: {} truth images in {}", n, a.render_out);
    return 0;
  }
  if (a.out.empty()) throw Error("synth", "--out", "is needed (the root folder of the tree to write)");
  const synth::SynthResult r = synth::RunSynth(opts, a.out, progress);
  spdlog::info("synth: {} AOI(s), {} images, {} buildings, RPC fit max residual {:.2e} px, {:.1f} s", r.aois.size(),
               r.report.metrics.at("images"), r.city.buildings.size(), r.report.metrics.at("rpc_fit_max_residual_px"),
               r.report.seconds);
  spdlog::info("synth: wrote {} (report: {}/synth_report.json)", a.out, a.out);
  return 0;
}

}  // namespace

void AddSynthCommand(CLI::App& app, Runner* runner) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "Write a procedural satellite city as a DFC2019-style tree (RGB crops with RPCs, truth "
      "DSM/CLS, Sat-NeRF JSONs) that `skyfall ingest` reads like real data");
  cmd->add_option("--out", args->out, "Root folder of the tree to write");
  cmd->add_option("--render-cameras", args->render_cameras,
                  "Instead of the tree: truth images of the same city for the cameras of this cameras.json "
                  "(e.g. orbit views), into --render-out");
  cmd->add_option("--render-out", args->render_out, "Folder for the truth images (<name>.png, <name>_mask.png)");
  cmd->add_option("--lighting-view", args->lighting_view,
                  "Truth images are lit as this image (0-based) of the first AOI")
      ->capture_default_str();
  std::vector<CLI::Option*> drawn;  // the options --draw chooses, refused beside it
  AddSceneOptions(cmd, &args->opts, &drawn);
  CLI::Option* draw_option = cmd->add_option(
      "--draw", args->draw,
      "Draw the scene at random instead (N >= 1; equal N, equal scene): seed, latitude, longitude, "
      "off-nadir range, views, views per date, bands, bit depth, relief, tallest building and date contrast, "
      "recorded in synth_report.json's options; for accuracy checks on scenes no setting was chosen on")
      ->check(CLI::PositiveNumber);
  for (CLI::Option* o : drawn) draw_option->excludes(o);
  cmd->callback([runner, args] { *runner = [args] { return RunSynthCommand(*args); }; });
}

}  // namespace skyfall::cli
