#include "ingest/vendor_rpc.h"

#include <cpl_minixml.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <vector>

#include "core/error.h"
#include "ingest/gdal_util.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

// ---- Format detection -------------------------------------------------------

constexpr size_t kDetectBytes = 64 * 1024;

std::string FileHead(const std::string& path) {
  if (!fs::exists(path)) throw Error("rpc", path, "file does not exist");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("rpc", path, "cannot be opened");
  std::string head(kDetectBytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  return head;
}

// The name of the first element of an XML text, past the declaration,
// comments and doctype ("" when there is none in `head`).
std::string XmlRootName(const std::string& head) {
  size_t pos = 0;
  while ((pos = head.find('<', pos)) != std::string::npos) {
    const char next = pos + 1 < head.size() ? head[pos + 1] : '\0';
    if (next == '?' || next == '!') {
      ++pos;
      continue;
    }
    size_t end = pos + 1;
    while (end < head.size() && !std::isspace(static_cast<unsigned char>(head[end])) &&
           head[end] != '>' && head[end] != '/')
      ++end;
    return head.substr(pos + 1, end - pos - 1);
  }
  return "";
}

RpcFileFormat XmlFormat(const std::string& head) {
  const std::string root = XmlRootName(head);
  // A DIM_*.XML product file is a Dimap_Document too, without the RPC: GDAL's
  // DIMAP driver opens it as the product's raster.
  if (root == "Dimap_Document")
    return head.find("<Rational_Function_Model") != std::string::npos ? RpcFileFormat::kDimapXml
                                                                      : RpcFileFormat::kGdalDataset;
  if (root == "isd") return RpcFileFormat::kDigitalGlobeXml;
  if (root == "level_X") return RpcFileFormat::kEnmapXml;
  if (root == "VRTDataset") return RpcFileFormat::kGdalDataset;
  return RpcFileFormat::kUnknownText;
}

// ---- XML access ---------------------------------------------------------------

struct XmlDeleter {
  void operator()(CPLXMLNode* node) const { CPLDestroyXMLNode(node); }
};
using XmlTree = std::unique_ptr<CPLXMLNode, XmlDeleter>;

XmlTree ParseXmlFile(const std::string& path) {
  gdal::QuietErrors quiet;
  XmlTree tree(CPLParseXMLFile(path.c_str()));
  if (!tree) throw Error("rpc", path, "is not well-formed XML: " + quiet.LastMessage());
  return tree;
}

// The document element: the first element of the top level that is not the
// <?xml ...?> declaration.
const CPLXMLNode* DocumentElement(const CPLXMLNode* tree, const std::string& path) {
  for (const CPLXMLNode* n = tree; n; n = n->psNext) {
    if (n->eType == CXT_Element && n->pszValue[0] != '?' && n->pszValue[0] != '!') return n;
  }
  throw Error("rpc", path, "holds no XML element");
}

const CPLXMLNode* ChildOrThrow(const CPLXMLNode* parent, const std::string& child_path,
                               const std::string& parent_path) {
  const CPLXMLNode* n = CPLGetXMLNode(parent, child_path.c_str());
  if (!n) throw Error("rpc", parent_path + "." + child_path, "is missing");
  return n;
}

// One RPC field as a vendor XML spells it, below the element of the model.
struct XmlField {
  const char* gdal_key;   // LINE_OFF, ..., SAMP_DEN_COEFF, ERR_BIAS
  std::string path;       // CPLGetXMLValue path; for numbered terms the prefix
  int number_digits = 0;  // > 0: 20 elements <path><n>, n = 1..20 zero-padded to this width
  bool optional = false;
};

std::string NumberedPath(const XmlField& f, int term) {
  std::string number = std::to_string(term);
  if (static_cast<int>(number.size()) < f.number_digits)
    number.insert(0, f.number_digits - number.size(), '0');
  return f.path + number;
}

// The XML element that a core/rpc.cpp error subject ("LINE_NUM_COEFF[3]",
// "LAT_SCALE") comes from.
std::string XmlSubject(const std::string& subject, const std::vector<XmlField>& fields,
                       const std::string& model_path) {
  const size_t bracket = subject.find('[');
  const std::string key = subject.substr(0, bracket);
  for (const XmlField& f : fields) {
    if (key != f.gdal_key) continue;
    if (bracket == std::string::npos) {  // the whole polynomial, or a scalar
      if (f.number_digits == 0) return model_path + "." + f.path;
      return model_path + "." + NumberedPath(f, 1) + ".." + NumberedPath(f, 20);
    }
    const int term = std::stoi(subject.substr(bracket + 1));
    return model_path + "." +
           (f.number_digits > 0 ? NumberedPath(f, term + 1) : f.path + subject.substr(bracket));
  }
  return model_path + ": " + subject;
}

// Gathers the fields of `model` into GDAL RPC keys and parses them with
// RpcFromGdalMetadata (numbers with an optional unit word, then validation);
// errors name the XML element (`model_path`.<field>).
RpcModel RpcFromXmlFields(const CPLXMLNode* model, const std::string& model_path,
                          const std::vector<XmlField>& fields) {
  std::map<std::string, std::string> keys;
  for (const XmlField& f : fields) {
    if (f.number_digits == 0) {
      const char* v = CPLGetXMLValue(model, f.path.c_str(), nullptr);
      if (v)
        keys[f.gdal_key] = v;
      else if (!f.optional)
        throw Error("rpc", model_path + "." + f.path, "is missing");
      continue;
    }
    std::string joined;
    for (int term = 1; term <= 20; ++term) {
      const std::string path = NumberedPath(f, term);
      const char* v = CPLGetXMLValue(model, path.c_str(), nullptr);
      if (!v) throw Error("rpc", model_path + "." + path, "is missing");
      // One number an element: a second token would shift every later term.
      static const std::regex kTwoTokens(R"(\S\s+\S)");
      if (std::regex_search(v, kTwoTokens)) {
        throw Error("rpc", model_path + "." + path,
                    std::string("holds more than one value: '") + v + "'");
      }
      joined += std::string(" ") + v;
    }
    keys[f.gdal_key] = joined;
  }
  try {
    return RpcFromGdalMetadata(keys);
  } catch (const Error& e) {
    throw Error("rpc", XmlSubject(e.subject(), fields, model_path), e.detail());
  }
}

// ---- DIMAP ----------------------------------------------------------------------

std::vector<XmlField> DimapFields(const std::string& polynomials) {
  std::vector<XmlField> f = {
      {"LINE_OFF", "RFM_Validity.LINE_OFF"},     {"SAMP_OFF", "RFM_Validity.SAMP_OFF"},
      {"LAT_OFF", "RFM_Validity.LAT_OFF"},       {"LONG_OFF", "RFM_Validity.LONG_OFF"},
      {"HEIGHT_OFF", "RFM_Validity.HEIGHT_OFF"}, {"LINE_SCALE", "RFM_Validity.LINE_SCALE"},
      {"SAMP_SCALE", "RFM_Validity.SAMP_SCALE"}, {"LAT_SCALE", "RFM_Validity.LAT_SCALE"},
      {"LONG_SCALE", "RFM_Validity.LONG_SCALE"}, {"HEIGHT_SCALE", "RFM_Validity.HEIGHT_SCALE"},
  };
  for (const char* key : {"LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"})
    f.push_back({key, polynomials + "." + key + "_", 1});
  return f;
}

// DIMAP's image coordinate of the first pixel centre (DIMAP v3 states it; v2
// products count from 1).
double DimapFirstPixel(const CPLXMLNode* doc, const char* axis) {
  const CPLXMLNode* domain = CPLSearchXMLNode(doc, "=ImagetoGround_Validity_Domain");
  const char* v = domain ? CPLGetXMLValue(domain, axis, nullptr) : nullptr;
  if (!v) return 1.0;
  char* end = nullptr;
  const double first = std::strtod(v, &end);
  if (end == v || *end != '\0') {
    throw Error("rpc", std::string("ImagetoGround_Validity_Domain.") + axis,
                std::string("is not a number: '") + v + "'");
  }
  return first;
}

// ---- EnMAP ----------------------------------------------------------------------

const std::vector<XmlField>& EnmapFields() {
  static const std::vector<XmlField> f = {
      {"LINE_OFF", "ROW_OFF"},
      {"SAMP_OFF", "COL_OFF"},
      {"LAT_OFF", "LAT_OFF"},
      {"LONG_OFF", "LONG_OFF"},
      {"HEIGHT_OFF", "HEIGHT_OFF"},
      {"LINE_SCALE", "ROW_SCALE"},
      {"SAMP_SCALE", "COL_SCALE"},
      {"LAT_SCALE", "LAT_SCALE"},
      {"LONG_SCALE", "LONG_SCALE"},
      {"HEIGHT_SCALE", "HEIGHT_SCALE"},
      {"LINE_NUM_COEFF", "ROW_NUM_", 2},
      {"LINE_DEN_COEFF", "ROW_DEN_", 2},
      {"SAMP_NUM_COEFF", "COL_NUM_", 2},
      {"SAMP_DEN_COEFF", "COL_DEN_", 2},
  };
  return f;
}

}  // namespace

const char* RpcFileFormatName(RpcFileFormat format) {
  switch (format) {
    case RpcFileFormat::kSatNerfJson: return "satnerf_json";
    case RpcFileFormat::kRpbText: return "rpb";
    case RpcFileFormat::kKeyValueText: return "rpc_text";
    case RpcFileFormat::kDimapXml: return "dimap_xml";
    case RpcFileFormat::kDigitalGlobeXml: return "digitalglobe_xml";
    case RpcFileFormat::kEnmapXml: return "enmap_xml";
    case RpcFileFormat::kGdalDataset: return "gdal_metadata";
    case RpcFileFormat::kUnknownText: return "unknown_text";
  }
  return "unknown";
}

RpcFileFormat DetectRpcFileFormat(const std::string& path) {
  const std::string head = FileHead(path);
  if (head.empty()) throw Error("rpc", path, "is empty (no RPC)");
  // Rasters (TIFF, NITF, JPEG 2000) are binary from their first bytes.
  if (head.find('\0') != std::string::npos) return RpcFileFormat::kGdalDataset;
  size_t start = head.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // UTF-8 byte order mark
  while (start < head.size() && std::isspace(static_cast<unsigned char>(head[start]))) ++start;
  if (start == head.size()) throw Error("rpc", path, "holds only blanks (no RPC)");
  if (head[start] == '{') return RpcFileFormat::kSatNerfJson;
  if (head[start] == '<') return XmlFormat(head);
  // A key at the start of a line, so that prose quoting one is not taken for it.
  static const std::regex kKeyValue(R"((^|\n)[ \t]*LINE_OFF[ \t]*[:=])");
  static const std::regex kRpb(R"((^|\n)[ \t]*lineOffset[ \t]*=)");
  if (std::regex_search(head, kKeyValue)) return RpcFileFormat::kKeyValueText;
  if (std::regex_search(head, kRpb)) return RpcFileFormat::kRpbText;
  return RpcFileFormat::kUnknownText;
}

RpcModel ReadDimapRpcXml(const std::string& path) {
  const XmlTree tree = ParseXmlFile(path);
  const CPLXMLNode* doc = DocumentElement(tree.get(), path);
  try {
    const std::string doc_path = doc->pszValue;
    const CPLXMLNode* rfm = ChildOrThrow(doc, "Rational_Function_Model.Global_RFM", doc_path);
    const std::string rfm_path = doc_path + ".Rational_Function_Model.Global_RFM";
    // v2 names the ground-to-image polynomials Inverse_Model, v3 GroundtoImage_Values.
    const char* polynomials = CPLGetXMLNode(rfm, "Inverse_Model")          ? "Inverse_Model"
                              : CPLGetXMLNode(rfm, "GroundtoImage_Values") ? "GroundtoImage_Values"
                                                                           : nullptr;
    if (!polynomials) {
      throw Error("rpc", rfm_path + ".Inverse_Model",
                  "is missing (and there is no DIMAP v3 GroundtoImage_Values either)");
    }
    RpcModel rpc = RpcFromXmlFields(rfm, rfm_path, DimapFields(polynomials));
    rpc.line_off -= DimapFirstPixel(doc, "FIRST_ROW");
    rpc.samp_off -= DimapFirstPixel(doc, "FIRST_COL");
    return rpc;
  } catch (const Error& e) {
    throw e.Within(path);
  }
}

RpcModel ReadDigitalGlobeXml(const std::string& path) {
  static const std::vector<XmlField> kFields = {
      {"LINE_OFF", "LINEOFFSET"},
      {"SAMP_OFF", "SAMPOFFSET"},
      {"LAT_OFF", "LATOFFSET"},
      {"LONG_OFF", "LONGOFFSET"},
      {"HEIGHT_OFF", "HEIGHTOFFSET"},
      {"LINE_SCALE", "LINESCALE"},
      {"SAMP_SCALE", "SAMPSCALE"},
      {"LAT_SCALE", "LATSCALE"},
      {"LONG_SCALE", "LONGSCALE"},
      {"HEIGHT_SCALE", "HEIGHTSCALE"},
      {"LINE_NUM_COEFF", "LINENUMCOEFList.LINENUMCOEF"},
      {"LINE_DEN_COEFF", "LINEDENCOEFList.LINEDENCOEF"},
      {"SAMP_NUM_COEFF", "SAMPNUMCOEFList.SAMPNUMCOEF"},
      {"SAMP_DEN_COEFF", "SAMPDENCOEFList.SAMPDENCOEF"},
      {"ERR_BIAS", "ERRBIAS", 0, true},
      {"ERR_RAND", "ERRRAND", 0, true},
  };
  const XmlTree tree = ParseXmlFile(path);
  const CPLXMLNode* doc = DocumentElement(tree.get(), path);
  try {
    const std::string doc_path = doc->pszValue;
    const CPLXMLNode* image = ChildOrThrow(doc, "RPB.IMAGE", doc_path);
    return RpcFromXmlFields(image, doc_path + ".RPB.IMAGE", kFields);
  } catch (const Error& e) {
    throw e.Within(path);
  }
}

RpcModel ReadEnmapRpc(const std::string& path, int band) {
  const XmlTree tree = ParseXmlFile(path);
  const CPLXMLNode* doc = DocumentElement(tree.get(), path);
  try {
    const std::string rpc_path = std::string(doc->pszValue) + ".product.navigation.RPC";
    const CPLXMLNode* models = ChildOrThrow(doc, "product.navigation.RPC", doc->pszValue);
    int count = 0;
    for (const CPLXMLNode* n = models->psChild; n; n = n->psNext) {
      if (n->eType != CXT_Element || std::string(n->pszValue) != "bandID") continue;
      ++count;
      const std::string number = CPLGetXMLValue(n, "number", "");
      if (number != std::to_string(band)) continue;
      return RpcFromXmlFields(n, rpc_path + ".bandID[number=" + number + "]", EnmapFields());
    }
    throw Error("rpc", rpc_path,
                "holds no model for band " + std::to_string(band) + " (" + std::to_string(count) +
                    " bandID models" + (count ? ", numbered from 1" : "") + ")");
  } catch (const Error& e) {
    throw e.Within(path);
  }
}

std::string FindOwnRpcSidecar(const std::string& image_path) {
  const fs::path image(image_path);
  const fs::path dir = image.parent_path();
  const std::string stem = image.stem().string();
  std::vector<std::string> names = {"RPC_" + stem + ".XML", "RPC_" + stem + ".xml",
                                    stem + "_RPC.XML", stem + "_rpc.xml"};
  if (stem.rfind("IMG_", 0) == 0) names.push_back("RPC_" + stem.substr(4) + ".XML");
  for (const std::string& name : names) {
    const fs::path candidate = dir / name;
    if (fs::is_regular_file(candidate)) return candidate.string();
  }
  return "";
}

}  // namespace skyfall
