// Vertical reference frames of height products: the CRS a GeoTIFF or point
// cloud states for its heights, what a reference raster states, and the
// conversion between ellipsoidal heights and heights above the EGM96 geoid
// (PROJ with the egm96_15.gtx grid of Debian's proj-data).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "core/dsm_grid.h"

namespace skyfall {

// OGC WKT2 of the CRS of values on UTM zone `epsg` measured from
// `reference`: the zone promoted to 3D (ellipsoidal heights), the compound
// EPSG:<epsg>+5773 (EGM96 heights), or the plain zone (no vertical CRS:
// heights above the terrain, or values that are not heights). For STAC's
// proj:wkt2 and the point cloud.
// `wkt1` gives OGC WKT1 (GDAL's dialect: a COMPD_CS with a VERT_CS), which
// the LAS 1.4 specification asks of a point cloud's CRS record.
std::string HeightCrsWkt(int epsg, std::optional<HeightReference> reference, bool wkt1 = false);

// The CRS a GeoTIFF gets: the compound CRS for EGM96 heights, else the
// plain zone. GDAL 3.6 cannot put a 3D projected CRS into GeoTIFF keys (it
// moves the whole CRS to a side file, and the COG alone would have none), so
// ellipsoidal heights state their reference in the HEIGHT_REFERENCE
// metadata item and the band description (decision D-114).
std::string GeoTiffCrsWkt(int epsg, std::optional<HeightReference> reference);

// The GDAL metadata item of every height raster the run writes: its value is
// the reference's name ("ellipsoid", "egm96", "above_terrain").
constexpr const char* kHeightReferenceItem = "HEIGHT_REFERENCE";

// A line for metadata and reports: "WGS84 ellipsoid (EPSG:4979)", ...
std::string HeightReferenceDescription(HeightReference reference);

// The EGM96 geoid's height above the WGS84 ellipsoid (the undulation N, so
// that an orthometric height is h - N) at each (longitude, latitude) in
// degrees. Throws Error when PROJ cannot use the egm96_15.gtx grid (it would
// otherwise fall back to a transformation without the geoid).
std::vector<double> Egm96UndulationsM(const std::vector<Eigen::Vector2d>& lon_lat_deg);

// Converts the heights of `grid` (UTM) to `to`, between kEllipsoid and
// kEgm96, with the undulation at each pixel centre. Throws Error naming
// `subject` for a conversion from or to kAboveTerrain.
void ConvertHeightReference(DsmGrid* grid, HeightReference to, const std::string& subject);

// The vertical reference a raster states: a compound CRS decides (kEgm96
// for EGM96 height, EPSG:5773; a tool that converted the heights changed
// the CRS, not always the metadata); else its HEIGHT_REFERENCE item (the
// run's own rasters); else kEllipsoid for a 3D CRS; nullopt when it states
// none. Throws Error naming `path` and
// the vertical CRS for any other (NAVD88, EGM2008...): the run cannot
// convert it.
std::optional<HeightReference> HeightReferenceOfRaster(const std::string& path);

}  // namespace skyfall
