#include "ingest/vertical_datum.h"

#include <cpl_conv.h>
#include <ogr_srs_api.h>
#include <proj.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "core/error.h"
#include "ingest/gdal_util.h"
#include "ingest/geo.h"

namespace skyfall {
namespace {

constexpr int kEgm96HeightEpsg = 5773;
constexpr int kWgs84Geographic3dEpsg = 4979;

struct SrsDeleter {
  void operator()(void* srs) const { OSRDestroySpatialReference(static_cast<OGRSpatialReferenceH>(srs)); }
};
using Srs = std::unique_ptr<void, SrsDeleter>;

Srs SrsFromUser(const std::string& definition) {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  if (OSRSetFromUserInput(srs, definition.c_str()) != OGRERR_NONE) {
    OSRDestroySpatialReference(srs);
    throw Error("datum", definition, "is not a CRS PROJ knows (is proj-data installed?)");
  }
  OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);  // longitude, latitude
  return Srs(srs);
}

std::string Wkt(OGRSpatialReferenceH srs, bool wkt1) {
  const char* options[] = {wkt1 ? "FORMAT=WKT1_GDAL" : "FORMAT=WKT2_2019", nullptr};
  char* wkt = nullptr;
  OSRExportToWktEx(srs, &wkt, options);
  std::string out = wkt ? wkt : "";
  CPLFree(wkt);
  return out;
}

}  // namespace

std::string HeightCrsWkt(int epsg, std::optional<HeightReference> reference, bool wkt1) {
  gdal::EnsureRegistered();
  if (reference == HeightReference::kEgm96)
    return Wkt(static_cast<OGRSpatialReferenceH>(
                   SrsFromUser("EPSG:" + std::to_string(epsg) + "+" + std::to_string(kEgm96HeightEpsg)).get()),
               wkt1);
  Srs srs = SrsFromUser("EPSG:" + std::to_string(epsg));
  if (reference == HeightReference::kEllipsoid && wkt1) {
    // WKT1 has no 3D projected CRS (PROJ refuses to write one): the zone
    // with a vertical CRS whose datum is the ellipsoid (OGC 01-009's
    // vertical datum type 2002, ellipsoidal), as LAS readers expect.
    const std::string zone = Wkt(static_cast<OGRSpatialReferenceH>(srs.get()), true);
    return "COMPD_CS[\"" + std::string(OSRGetName(static_cast<OGRSpatialReferenceH>(srs.get()))) +
           " + WGS 84 ellipsoidal height\"," + zone +
           ",VERT_CS[\"WGS 84 ellipsoidal height\",VERT_DATUM[\"WGS_1984\",2002],UNIT[\"metre\",1,"
           "AUTHORITY[\"EPSG\",\"9001\"]],AXIS[\"Ellipsoidal height\",UP]]]";
  }
  if (reference == HeightReference::kEllipsoid) OSRPromoteTo3D(static_cast<OGRSpatialReferenceH>(srs.get()), nullptr);
  return Wkt(static_cast<OGRSpatialReferenceH>(srs.get()), wkt1);
}

std::string GeoTiffCrsWkt(int epsg, std::optional<HeightReference> reference) {
  return HeightCrsWkt(epsg, reference == HeightReference::kEgm96 ? reference : std::nullopt);
}

std::string HeightReferenceDescription(HeightReference reference) {
  switch (reference) {
    case HeightReference::kEllipsoid: return "WGS84 ellipsoid (EPSG:4979)";
    case HeightReference::kEgm96: return "EGM96 geoid (EPSG:5773)";
    case HeightReference::kAboveTerrain: return "terrain model of the run (dtm.tif)";
  }
  return "?";
}

std::vector<double> Egm96UndulationsM(const std::vector<Eigen::Vector2d>& lon_lat_deg) {
  // PROJ's vertical grid shift with the grid named: a missing grid is an
  // error here, where a CRS-to-CRS transformation would fall back to one
  // without the geoid and leave heights unchanged. At h = 0 it gives N.
  PJ_CONTEXT* context = proj_context_create();
  PJ* shift = proj_create(context, "+proj=vgridshift +grids=egm96_15.gtx +multiplier=1");
  if (!shift) {
    proj_context_destroy(context);
    throw Error("datum", "egm96_15.gtx",
                "PROJ cannot open the EGM96 geoid grid (install Debian's proj-data, which ships it)");
  }
  std::vector<double> undulation(lon_lat_deg.size());
  for (std::size_t k = 0; k < lon_lat_deg.size(); ++k) {
    const PJ_COORD in = proj_coord(proj_torad(lon_lat_deg[k].x()), proj_torad(lon_lat_deg[k].y()), 0, 0);
    const PJ_COORD out = proj_trans(shift, PJ_FWD, in);
    if (!std::isfinite(out.xyz.z) || out.xyz.z == HUGE_VAL) {
      proj_destroy(shift);
      proj_context_destroy(context);
      throw Error("datum", "egm96_15.gtx",
                  "no EGM96 undulation at longitude " + std::to_string(lon_lat_deg[k].x()) + ", latitude " +
                      std::to_string(lon_lat_deg[k].y()));
    }
    undulation[k] = out.xyz.z;
  }
  proj_destroy(shift);
  proj_context_destroy(context);
  return undulation;
}

void ConvertHeightReference(DsmGrid* grid, HeightReference to, const std::string& subject) {
  if (grid->reference == to) return;
  if (to == HeightReference::kAboveTerrain || grid->reference == HeightReference::kAboveTerrain)
    throw Error("datum", subject,
                std::string("cannot convert heights ") + EnumName(grid->reference) + " to " + EnumName(to) +
                    " (heights above the terrain have no datum)");
  const UtmZone zone = UtmZoneFromEpsg(grid->epsg);
  // The geoid changes by centimetres over kilometres: its undulation on a
  // lattice of every kStridePx-th pixel, interpolated bilinearly, differs
  // from the per-pixel value by far less than the grid's own 1 mm steps.
  constexpr int kStridePx = 16;
  const int nx = grid->width_px / kStridePx + 2, ny = grid->height_px / kStridePx + 2;
  std::vector<Eigen::Vector2d> lattice;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Eigen::Vector2d ll = GeodeticFromUtm(zone, grid->upper_left_easting_m + (i * kStridePx + 0.5) * grid->gsd_m,
                                                 grid->upper_left_northing_m - (j * kStridePx + 0.5) * grid->gsd_m);
      lattice.emplace_back(ll.x(), ll.y());
    }
  const std::vector<double> n = Egm96UndulationsM(lattice);
  const double sign = to == HeightReference::kEgm96 ? -1.0 : 1.0;  // H = h - N, h = H + N
  for (int row = 0; row < grid->height_px; ++row)
    for (int col = 0; col < grid->width_px; ++col) {
      const double u = static_cast<double>(col) / kStridePx, v = static_cast<double>(row) / kStridePx;
      const int i = static_cast<int>(u), j = static_cast<int>(v);
      const double fu = u - i, fv = v - j;
      auto at = [&](int a, int b) { return n[static_cast<std::size_t>(b) * nx + a]; };
      const double undulation = (1 - fv) * ((1 - fu) * at(i, j) + fu * at(i + 1, j)) +
                                fv * ((1 - fu) * at(i, j + 1) + fu * at(i + 1, j + 1));
      float& h = grid->height_m[static_cast<std::size_t>(row) * grid->width_px + col];
      if (std::isfinite(h)) h = static_cast<float>(h + sign * undulation);
    }
  grid->reference = to;
}

std::optional<HeightReference> HeightReferenceOfRaster(const std::string& path) {
  gdal::Dataset ds(gdal::OpenOrThrow(path));
  OGRSpatialReferenceH srs = GDALGetSpatialRef(ds.handle);
  if (srs && OSRIsCompound(srs)) {
    const char* name = OSRGetAttrValue(srs, "VERT_CS", 0);
    const char* code = OSRGetAuthorityCode(srs, "VERT_CS");
    if ((code && std::atoi(code) == kEgm96HeightEpsg) || (name && std::strcmp(name, "EGM96 height") == 0))
      return HeightReference::kEgm96;
    throw Error("datum", path,
                std::string("states heights in ") + (name ? name : "an unnamed vertical CRS") +
                    "; the products are compared on heights above the WGS84 ellipsoid (the RPCs' frame) and "
                    "written above it or the EGM96 geoid, and the run converts neither to the other (convert it "
                    "with gdalwarp first)");
  }
  if (const char* item = GDALGetMetadataItem(ds.handle, kHeightReferenceItem, nullptr)) {
    if (const std::optional<HeightReference> stated = EnumFromName<HeightReference>(item)) return stated;
    throw Error("datum", path,
                std::string(kHeightReferenceItem) + " '" + item + "' is not " + EnumChoices<HeightReference>());
  }
  if (!srs) return std::nullopt;
  if (OSRGetAxesCount(srs) == 3) return HeightReference::kEllipsoid;
  return std::nullopt;
}

}  // namespace skyfall
