#include "products/report_page.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"
#include "products/city_report.h"
#include "products/point_cloud.h"
#include "products/run_report.h"
#include "products/stac.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr const char* kStyle = R"(
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; margin: .5em 0 1.2em; } td, th { border: 1px solid #ddd; padding: 3px 8px; }
th { background: #f3f3f3; text-align: left; } td.n { text-align: right; font-variant-numeric: tabular-nums; }
.ok { color: #1a7f37; } .failed { color: #c62828; font-weight: bold; } .degenerate, .skipped { color: #9a6700; }
img { max-width: 100%; border: 1px solid #ddd; } .pair { display: flex; gap: 1em; flex-wrap: wrap; }
.pair img { width: 100%; image-rendering: pixelated; }
.pair figure { margin: 0; flex: 1 1 45%; } figcaption { color: #555; font-size: .9em; }
.muted { color: #666; }
)";

std::string Fixed(double v, int decimals) { return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "–"; }

std::string Number(const json& j, const char* key, int decimals, double factor = 1.0) {
  if (!j.contains(key) || !j.at(key).is_number()) return "–";
  return Fixed(j.at(key).get<double>() * factor, decimals);
}

std::string Cell(const std::string& text, bool numeric = false) {
  return std::string(numeric ? "<td class=n>" : "<td>") + text + "</td>";
}

std::string ReadBinary(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// An <img> with the PNG embedded, or a note when the file is missing.
std::string EmbeddedPng(const fs::path& png, const std::string& alt) {
  if (!fs::exists(png)) return "<p class=muted>(" + HtmlEscape(alt) + ": not written)</p>";
  return "<img alt=\"" + HtmlEscape(alt) + "\" src=\"data:image/png;base64," + Base64(ReadBinary(png)) + "\">";
}

std::string Link(const fs::path& target, const fs::path& out_dir, const std::string& text) {
  if (!fs::exists(target)) return "";
  const std::string href = fs::relative(fs::absolute(target), fs::absolute(out_dir)).generic_string();
  return "<a href=\"" + HtmlEscape(UrlPath(href)) + "\">" + HtmlEscape(text) + "</a> ";
}

// A point cloud (an AOI's "points", a city's "points_city") in whichever
// encoding the run wrote.
std::string PointCloudLinks(const fs::path& dir, const fs::path& out_dir, const std::string& stem = "points",
                            const std::string& text = "point cloud") {
  std::string html;
  for (const auto& [encoding, name] : EnumNames<PointCloudEncoding>::kNames) {
    html += Link(dir / PointCloudFileName(encoding, stem), out_dir, text + " (" + name + ")");
  }
  return html;
}

std::string DsmTable(const CityReport& report) {
  std::string html =
      "<table><tr><th>AOI</th><th>MAE [m]</th><th>RMSE [m]</th><th>median |e| [m]</th><th>NMAD [m]</th>"
      "<th>completeness</th><th>within 1 m</th><th>dense alone: MAE [m]</th><th>dense: completeness</th>"
      "<th>filled cells</th></tr>";
  for (const json& d : report.dsm) {
    const json dense = d.value("dense", json::object());
    html += "<tr>" + Cell(HtmlEscape(d.value("aoi", "?"))) + Cell(Number(d, "mae_m", 2), true) +
            Cell(Number(d, "rmse_m", 2), true) + Cell(Number(d, "median_abs_m", 2), true) +
            Cell(Number(d, "nmad_m", 2), true) + Cell(Number(d, "completeness", 1, 100) + " %", true) +
            Cell(Number(d, "within_1m", 1, 100) + " %", true) + Cell(Number(dense, "mae_m", 2), true) +
            Cell(Number(dense, "completeness", 1, 100) + " %", true) +
            Cell(Number(dense, "filled_cell_fraction", 1, 100) + " %", true) + "</tr>";
  }
  return html + "</table>";
}

// A string field of a report object, or `fallback` when it is missing or not a string.
std::string TextField(const json& j, const char* key, const std::string& fallback = "") {
  return j.is_object() && j.contains(key) && j.at(key).is_string() ? j.at(key).get<std::string>() : fallback;
}

// Where an AOI's error comes from (present when its truth has classes): each
// class and each band along building outlines, trained beside dense alone.
std::string BreakdownTable(const json& d) {
  if (!d.contains("by_class") || !d.at("by_class").is_array()) return "";
  const json dense = d.value("dense", json::object());
  // The dense figures of the same group, matched by name.
  const auto dense_group = [&](const std::string& name) {
    if (name.empty()) return json::object();
    for (const json& g : dense.value("by_class", json::array()))
      if (TextField(g, "name") == name) return g;
    const json rims = dense.value("building_rims", json::object());
    const json rim = rims.is_object() ? rims.value(name, json::object()) : json::object();
    return rim.is_object() ? rim : json::object();
  };
  std::string html =
      "<table><tr><th>where</th><th>share of cells</th><th>MAE [m]</th><th>mean error [m]</th>"
      "<th>part of the MAE [m]</th><th>dense alone: MAE [m]</th><th>dense: part [m]</th></tr>";
  const auto row = [&](const json& g, const std::string& label) {
    if (!g.is_object() || !g.contains("cells") || !g.at("cells").is_number()) return;
    if (g.at("cells").get<double>() == 0) return;  // a rim band of an AOI without buildings
    const json o = dense_group(TextField(g, "name"));
    html += "<tr>" + Cell(HtmlEscape(label)) + Cell(Number(g, "share", 1, 100) + " %", true) +
            Cell(Number(g, "mae_m", 2), true) + Cell(Number(g, "bias_m", 2), true) +
            Cell(Number(g, "mae_part_m", 3), true) + Cell(Number(o, "mae_m", 2), true) +
            Cell(Number(o, "mae_part_m", 3), true) + "</tr>";
  };
  for (const json& g : d.at("by_class")) row(g, "class: " + TextField(g, "name", "?"));
  const json rims = d.contains("building_rims") && d.at("building_rims").is_object() ? d.at("building_rims") : json::object();
  const std::string width = Number(rims, "rim_width_m", 1);
  if (rims.contains("roof_rim")) row(rims.at("roof_rim"), "roof rim (building, within " + width + " m of its edge)");
  if (rims.contains("beside_buildings")) {
    row(rims.at("beside_buildings"), "beside buildings (within " + width + " m of a roof edge)");
  }
  return html + "</table><p class=muted>The parts of the classes add up to the MAE; the rim bands overlap the "
                "classes. At a roof edge one misplaced cell costs the building's height.</p>";
}

std::string Decisions(const json& decisions) {
  std::string text;
  for (const auto& [name, d] : decisions.items()) {
    if (!d.is_object()) {
      text += "<b>" + HtmlEscape(name) + "</b>: " + HtmlEscape(d.is_string() ? d.get<std::string>() : d.dump()) +
              "<br>";
      continue;
    }
    std::string value = d.contains("on") ? (d.at("on").get<bool>() ? "on" : "off")
                        : d.contains("levels") ? std::to_string(d.at("levels").get<int>()) + " levels"
                        : d.contains("source") && d.at("source").is_string() ? d.at("source").get<std::string>()
                                                                              : "";
    std::string why = d.value("why", "");
    for (const char* figure : {"facade_ratio", "measured_fraction"}) {
      if (d.contains(figure) && d.at(figure).is_number()) why += fmt::format("; {} {:.3f}", figure, d.at(figure).get<double>());
    }
    text += "<b>" + HtmlEscape(name) + "</b> " + HtmlEscape(value) + (why.empty() ? "" : " <span class=muted>(" +
            HtmlEscape(why) + ")</span>") + "<br>";
  }
  return text;
}

// A tile's held-out views: each one's PSNR with links to its render, its
// image and their difference (splat/heldout/); empty without any.
std::string HeldOutViews(const fs::path& splat_dir, const fs::path& out_dir) {
  const fs::path train_report = splat_dir / "train_report.json";
  if (!fs::exists(train_report)) return "";
  json report;
  try {
    report = json::parse(std::ifstream(train_report));
  } catch (const json::exception&) {
    return "<span class=muted>(unreadable train_report.json)</span>";
  }
  std::string html;
  try {  // a report of another version: what cannot be read is left out, the page stands
    for (const json& v : report.value("held_out", json::array())) {
      html += HtmlEscape(v.value("name", "?")) + ": " + Number(v, "psnr_db", 1) + " dB ";
      const json images = v.value("images", json::array());
      const char* labels[] = {"render", "image", "difference"};
      for (std::size_t k = 0; k < images.size() && k < 3; ++k)
        if (images[k].is_string()) html += Link(splat_dir / images[k].get<std::string>(), out_dir, labels[k]);
      html += "<br>";
    }
  } catch (const json::exception&) {
    html += "<span class=muted>(unexpected held_out in train_report.json)</span>";
  }
  return html;
}

// What a tile's stages warned of (an image left out, the limits of a
// stereo pair), one line each.
std::string StageWarnings(const json& tile) {
  std::string html;
  for (const json& s : tile.value("stages", json::array()))
    for (const json& w : s.value("warnings", json::array()))
      if (w.is_string()) html += (html.empty() ? "" : "<br>") + HtmlEscape(w.get<std::string>());
  return html;
}

std::string TileTable(const CityReport& report, const fs::path& city_dir, const fs::path& out_dir) {
  std::string html =
      "<table><tr><th>tile</th><th>status</th><th>time [s]</th><th>peak memory [MB]</th><th>decisions</th>"
      "<th>held-out views (PSNR)</th><th>warnings</th></tr>";
  for (const json& t : report.tiles) {
    const std::string status = t.value("status", "failed");
    const std::string tile = t.value("tile", "?");
    html += "<tr>" + Cell(HtmlEscape(tile)) + "<td class=" + HtmlEscape(status) + ">" +
            HtmlEscape(status) + (t.value("message", "").empty() ? "" : ": " + HtmlEscape(t.value("message", ""))) +
            "</td>" + Cell(Number(t, "seconds", 1), true) + Cell(Number(t, "peak_rss_mb", 0), true) +
            Cell(Decisions(t.value("decisions", json::object()))) +
            Cell(HeldOutViews(city_dir / "tiles" / tile / "splat", out_dir)) + Cell(StageWarnings(t)) + "</tr>";
  }
  return html + "</table>";
}

// The classes against the truth's: accuracy and each class's IoU.
std::string ClassesTable(const json& comparison) {
  const json lc = comparison.value("land_cover", json::object());
  if (lc.empty()) return "";
  auto iou = [&](const char* kind) { return Cell(Number(lc.value(kind, json::object()), "iou", 3), true); };
  return "<table><tr><th>classes vs truth: accuracy</th><th>IoU building</th><th>IoU vegetation</th>"
         "<th>IoU ground</th><th>cells</th></tr><tr>" +
         Cell(Number(lc, "overall_accuracy", 3), true) + iou("building") + iou("vegetation") + iou("ground") +
         Cell(Number(lc, "cells", 0), true) + "</tr></table>";
}

// The orthophoto against the synthetic city's exact one (every cell), where
// the truth has one.
std::string OrthoTruthTable(const json& dsm) {
  if (!dsm.contains("ortho_truth")) return "";
  const json& exact = dsm["ortho_truth"];
  return "<table><tr><th>ortho vs exact orthophoto: PSNR [dB]</th><th>SSIM</th><th>cells</th></tr><tr>" +
         Cell(Number(exact, "psnr_db", 2), true) + Cell(Number(exact, "ssim", 3), true) +
         Cell(Number(exact, "cells", 0), true) + "</tr></table>";
}

// Per AOI: the GIS products, their previews side by side (the orthophoto
// beside the DSM and the quality layers), and their figures against the
// truth (DTM on ground, nDSM on buildings, ortho against the nadir image).
std::string ProductsSection(const CityReport& report, const fs::path& out_dir) {
  std::map<std::string, json> truth;
  for (const json& d : report.dsm) truth[d.value("aoi", "")] = d;
  std::string html;
  for (const json& p : report.products) {
    const std::string aoi = p.value("aoi", "?");
    const fs::path dir = out_dir / aoi, previews = dir / "previews";
    html += "<h4>" + HtmlEscape(aoi) + ": GIS products</h4><p>Heights above the " +
            HtmlEscape(p.value("vertical_datum_description", "?")) + ". " +
            Link(dir / "dsm.tif", out_dir, "DSM") + Link(dir / "dtm.tif", out_dir, "DTM") +
            Link(dir / "ndsm.tif", out_dir, "nDSM") + Link(dir / "quality.tif", out_dir, "quality layers") +
            Link(dir / "ortho.tif", out_dir, "orthophoto") + Link(dir / "classes.tif", out_dir, "classes") +
            PointCloudLinks(dir, out_dir) + "</p>";
    json left_out = p.value("left_out", json::array());
    if (p.contains("classes") && p["classes"].contains("left_out")) left_out.push_back(p["classes"]["left_out"]);
    for (const json& why : left_out)
      html += "<p class=muted>Left out: " + HtmlEscape(why.get<std::string>()) + "</p>";
    if (truth.count(aoi)) {
      const json terrain = truth[aoi].value("terrain", json::object()), ortho = truth[aoi].value("ortho", json::object());
      html += "<table><tr><th>DTM on ground: MAE [m]</th><th>bias [m]</th><th>nDSM on buildings: MAE [m]</th>"
              "<th>bias [m]</th><th>ortho vs " + HtmlEscape(ortho.value("image", "nadir image")) +
              ": PSNR [dB]</th><th>SSIM</th><th>ground cells</th></tr><tr>" +
              Cell(Number(terrain, "dtm_mae_ground_m", 2), true) + Cell(Number(terrain, "dtm_bias_ground_m", 2), true) +
              Cell(Number(terrain, "ndsm_mae_building_m", 2), true) +
              Cell(Number(terrain, "ndsm_bias_building_m", 2), true) + Cell(Number(ortho, "psnr_db", 2), true) +
              Cell(Number(ortho, "ssim", 3), true) + Cell(Number(ortho, "ground_cells", 0), true) + "</tr></table>" +
              OrthoTruthTable(truth[aoi]) + ClassesTable(truth[aoi]);
    }
    html += "<div class=pair>";
    const char* figures[][2] = {{"ortho.png", "Orthophoto (nadir render, no lean)"},
                                {"dsm.png", "DSM (dark low, light high)"},
                                {"views.png", "Views that see each cell (dark few)"},
                                {"fill_rule.png", "How each cell got its height (codes in docs/outputs.md)"},
                                {"classes.png", "Classes: ground (tan), building (red), vegetation (green), above "
                                                "ground untold (violet)"}};
    for (const auto& [file, caption] : figures)
      if (fs::exists(previews / file))
        html += "<figure>" + EmbeddedPng(previews / file, aoi + " " + caption) + "<figcaption>" + caption +
                "</figcaption></figure>";
    html += "</div>";
  }
  return html;
}

std::string StageTable(const CityReport& report) {
  std::string html = "<table><tr><th>stage</th><th>status</th><th>time [s]</th></tr>";
  for (const json& s : report.stages) {
    const std::string status = s.value("status", "?");
    html += "<tr>" + Cell(HtmlEscape(s.value("stage", "?"))) + "<td class=" + HtmlEscape(status) + ">" +
            HtmlEscape(status) + "</td>" + Cell(Number(s, "seconds", 1), true) + "</tr>";
  }
  return html + "</table>";
}

// How many of the city's tiles an earlier run finished (their entries' `reused`).
int ReusedTiles(const CityReport& report) {
  int n = 0;
  for (const json& t : report.tiles) n += t.value("reused", false);
  return n;
}

std::string CitySection(const CityReport& report, const fs::path& out_dir, std::vector<ScenePoint>* points) {
  const std::string& city = report.city;
  const fs::path city_dir = out_dir / city;
  const int reused = ReusedTiles(report);
  std::string html = "<h2 id=\"" + HtmlEscape(city) + "\">City " + HtmlEscape(city) + "</h2>";
  html += fmt::format("<p>{} AOI(s), {} tile(s), {} s in all; peak tile memory {} MB.", report.aois.size(),
                      report.tiles.size(), Fixed(report.seconds, 0), Fixed(report.peak_tile_rss_mb, 0));
  if (reused > 0)
    html += fmt::format(" {} of the tiles were finished by an earlier run and reused: the time is this run's, "
                        "without theirs (each tile's own time is in the table of tiles).", reused);
  html += "</p>";
  html += "<p>Products: " + Link(city_dir / "scene" / "scene.ply", out_dir, "scene (PLY)") +
          Link(city_dir / "scene" / "lod.json", out_dir, "LOD levels") +
          Link(city_dir / "scene" / "dsm_city.tif", out_dir, "city DSM") +
          PointCloudLinks(city_dir, out_dir, "points_city", "city point cloud") +
          Link(city_dir / "3dtiles" / "tileset.json", out_dir, "3D Tiles") +
          Link(city_dir / "collection.json", out_dir, "STAC collection") +
          Link(CityReportPath(city_dir), out_dir, "run report (JSON)") + "</p>";
  if (!report.scene) html += "<p class=failed>No scene was made; see the stages below.</p>";
  html += "<h3>DSM against the truth</h3>" + DsmTable(report);
  for (const json& d : report.dsm) {
    const std::string aoi = d.value("aoi", "?");
    const fs::path compare = out_dir / aoi / "dsm_compare";
    html += "<h4>" + HtmlEscape(aoi) + "</h4><p>" + Link(out_dir / aoi / "dsm.tif", out_dir, "DSM (GeoTIFF)") +
            Link(compare / "report.json", out_dir, "comparison (JSON)") +
            Link(compare / "error_map.tif", out_dir, "error map (GeoTIFF)") +
            Link(compare / "report_by_class.csv", out_dir, "error by class (CSV)") +
            Link(compare / "report_edge_profile.csv", out_dir, "error by distance from building outlines (CSV)") +
            "</p>" + BreakdownTable(d) +
            "<div class=pair><figure>" +
            EmbeddedPng(compare / "error_map.png", aoi + " error map") +
            "<figcaption>Error map: DSM minus truth (blue low, red high)</figcaption></figure><figure>" +
            EmbeddedPng(compare / "error_histogram.png", aoi + " error histogram") +
            "<figcaption>Error histogram</figcaption></figure></div>";
    const json dense = d.value("dense", json::object());
    points->push_back({aoi + (reused > 0 ? " *" : ""), report.seconds, d.value("mae_m", NAN),
                       dense.is_object() ? dense.value("mae_m", NAN) : NAN, false});
  }
  html += "<h3>GIS products</h3>" + ProductsSection(report, out_dir);
  html += "<h3>Automatic decisions of the city</h3><p>" + Decisions(report.decisions.is_object() ? report.decisions : json::object()) + "</p>";
  html += "<h3>Stages</h3>" + StageTable(report);
  html += "<h3>Tiles</h3>" + TileTable(report, city_dir, out_dir);
  return html;
}

}  // namespace

std::string UrlPath(const std::string& path) {
  std::string out;
  for (const unsigned char ch : path) {
    const bool unreserved = (ch >= 'A' && ch <= 'Z') || (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') ||
                            ch == '-' || ch == '.' || ch == '_' || ch == '~' || ch == '/';
    out += unreserved ? std::string(1, static_cast<char>(ch)) : fmt::format("%{:02X}", ch);
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += kAlphabet[(v >> s) & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) | (static_cast<unsigned char>(bytes[i + 1]) << 8);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

std::string HtmlEscape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string WriteRunReportPage(const std::string& out_dir) {
  const fs::path out(out_dir);
  const fs::path summary_path = out / "run_summary.json";
  json summary;
  try {
    summary = json::parse(ReadTextFile(summary_path.string()));
  } catch (const json::exception& e) {
    throw Error("report", summary_path.string(), std::string("not valid JSON: ") + e.what());
  }
  std::string sections, toc;
  std::vector<ScenePoint> points;
  for (const json& c : summary.value("cities", json::array())) {
    const std::string report_path = c.value("report", "");
    if (report_path.empty() || !fs::exists(report_path)) {
      sections += "<h2>City " + HtmlEscape(c.value("city", "?")) + "</h2><p class=failed>" +
                  HtmlEscape(c.value("error", "no run report")) + "</p>";
      continue;
    }
    std::string why;
    const std::optional<CityReport> report = ReadCityReport(report_path, &why);
    if (!report) throw Error("report", report_path, "is not a readable run report: " + why);
    toc += "<li><a href=\"#" + HtmlEscape(report->city) + "\">" + HtmlEscape(report->city) +
           "</a>" + (c.value("unchanged", false) ? " <span class=muted>(unchanged since its last run)</span>" : "") +
           "</li>";
    sections += CitySection(*report, out, &points);
  }
  std::string plot = "<p class=muted>(no AOI with truth: no error to plot)</p>";
  if (!points.empty()) {
    const fs::path png = out / "report_error_vs_time.png";
    WriteScenesPlot(points, png.string());
    plot = EmbeddedPng(png, "DSM error against run time");
  }
  const int exit_code = summary.value("exit_code", -1);
  const std::string html =
      "<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>skyfall run report</title><style>" +
      std::string(kStyle) + "</style></head><body><h1>skyfall run report</h1>" +
      fmt::format("<p>Input <code>{}</code>, written {}; {} s; exit code {} ({}).</p>",
                  HtmlEscape(summary.value("root", "?")), UtcNowIso(), Number(summary, "seconds", 0), exit_code,
                  exit_code == 0 ? "success" : exit_code == 5 ? "partial failure" : "nothing processed") +
      "<ul>" + toc + "</ul><h2>DSM error against run time</h2>" + plot +
      "<p class=muted>Each AOI: its city's run time and the DSM MAE of the trained scene (filled) and of the dense "
      "heights alone (open). * marks a city whose tiles an earlier run finished: this run's time leaves theirs out."
      "</p>" +
      sections + "</body></html>\n";
  const std::string path = (out / "report.html").string();
  WriteFileAtomic(path, html);
  return path;
}

}  // namespace skyfall
