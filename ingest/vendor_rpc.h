// The vendors' own RPC files, read directly (not as GDAL sidecars): Airbus
// DIMAP RPC_*.XML (Pleiades, SPOT 6/7), DigitalGlobe/Maxar product XML (its
// <RPB> element), EnMAP METADATA.XML; and the choice of a reader by a file's
// content. Every reader returns the model in the convention of core/rpc.h
// (first pixel centre at (0, 0)), validates it, and names the file and the
// XML element on error.
#pragma once

#include <string>

#include "core/rpc.h"

namespace skyfall {

enum class RpcFileFormat {
  kSatNerfJson,      // Sat-NeRF camera JSON ({"rpc": {...}})
  kRpbText,          // DigitalGlobe .RPB ("lineOffset = ...;")
  kKeyValueText,     // "LINE_OFF: ..." text: _RPC.TXT of IKONOS, GeoEye, SkySat, PlanetScope
  kDimapXml,         // DIMAP RPC_*.XML (Rational_Function_Model)
  kDigitalGlobeXml,  // DigitalGlobe/Maxar product XML (<isd> with <RPB>)
  kEnmapXml,         // EnMAP METADATA.XML (<level_X>, one model per band)
  kGdalDataset,      // a raster or VRT: GDAL's RPC metadata domain
  kUnknownText,      // text of none of the above (GDAL is still tried)
};

// The name recorded as an image's rpc_source: "satnerf_json", "rpb",
// "rpc_text", "dimap_xml", "digitalglobe_xml", "enmap_xml", "gdal_metadata".
const char* RpcFileFormatName(RpcFileFormat format);

// Decides by the file's first 64 KiB, whatever its name. Throws Error naming
// the file when it is missing or empty.
RpcFileFormat DetectRpcFileFormat(const std::string& path);

// DIMAP v2 (Global_RFM/Inverse_Model, the ground-to-image polynomials) and v3
// (GroundtoImage_Values). DIMAP counts pixels from the first pixel's centre
// at FIRST_ROW/FIRST_COL of ImagetoGround_Validity_Domain, 1 when absent
// (all DIMAP v2 products): that origin is subtracted from LINE_OFF/SAMP_OFF,
// as GDAL's DIMAP reader and rpcm do.
RpcModel ReadDimapRpcXml(const std::string& path);

// The <RPB><IMAGE> element of a DigitalGlobe/Maxar product XML; RPC00B
// convention, offsets taken as written (as GDAL and rpcm do).
RpcModel ReadDigitalGlobeXml(const std::string& path);

// EnMAP metadata holds one RPC model per spectral band (<bandID number="N">
// under product/navigation/RPC): the 91 VNIR bands share one model, each SWIR
// band has its own. Band 1 (the VNIR model) unless another is asked for.
// Offsets are taken as written, as rpcm does.
inline constexpr int kEnmapDefaultBand = 1;
RpcModel ReadEnmapRpc(const std::string& path, int band = kEnmapDefaultBand);

// An RPC file beside an image that GDAL does not attach to it but these
// readers know: RPC_<stem>.XML or <stem>_RPC.XML (and lower-case variants;
// GDAL takes a DIMAP RPC_*.XML only beside a DIM_*.XML or an IMG_*_R<r>C<c>
// tile name), and for an IMG_<id> image RPC_<id>.XML. Returns the first that
// exists, or an empty string.
std::string FindOwnRpcSidecar(const std::string& image_path);

}  // namespace skyfall
