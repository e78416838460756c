// The real vendor RPC files of ../shared/data/rpc-formats, read directly
// (ReadRpcAny) and as the sidecars GDAL attaches to an image
// (ReadRpcFromRaster), each checked against an evaluation of the file's own
// numbers that shares no code with the product: the numbers are taken from
// the text by regular expressions and the RPC00B polynomial is written out
// here.
#include "ingest/vendor_rpc.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/stage.h"
#include "tests/test_rpc_fixture.h"
#include "tests/test_support.h"
#include "ingest/dfc2019.h"
#include "ingest/rpc_io.h"

namespace skyfall {
namespace {

using namespace skyfall::testing;

fs::path RpcFormatsRoot() { return SharedData() / "rpc-formats"; }

#define SKYFALL_REQUIRE_RPC_FORMATS()                                              \
  do {                                                                             \
    if (!fs::exists(RpcFormatsRoot() / "rpc_IKONOS.txt"))                          \
      GTEST_SKIP() << "shared vendor RPC files not found at " << RpcFormatsRoot(); \
  } while (0)

// The issue's bound between the product and the independent evaluation.
constexpr double kAgreementTolPx = 1e-6;

// ---- The independent evaluation ------------------------------------------------

struct TextRpc {
  double line_off = 0, samp_off = 0, lat_off = 0, lon_off = 0, height_off = 0;
  double line_scale = 0, samp_scale = 0, lat_scale = 0, lon_scale = 0, height_scale = 0;
  std::vector<double> line_num, line_den, samp_num, samp_den;

  // RPC00B: term order 1 L P H LP LH PH L2 P2 H2 PLH L3 LP2 LH2 L2P P3 PH2 L2H P2H H3,
  // L = longitude, P = latitude, H = height, all normalized.
  static double Poly(const std::vector<double>& c, double L, double P, double H) {
    const double t[20] = {1,         L,         P,         H,         L * P,
                          L * H,     P * H,     L * L,     P * P,     H * H,
                          P * L * H, L * L * L, L * P * P, L * H * H, L * L * P,
                          P * P * P, P * H * H, L * L * H, P * P * H, H * H * H};
    double s = 0;
    for (int i = 0; i < 20; ++i) s += c.at(i) * t[i];
    return s;
  }
  Eigen::Vector2d Project(double lon_deg, double lat_deg, double height_m) const {
    const double L = (lon_deg - lon_off) / lon_scale, P = (lat_deg - lat_off) / lat_scale,
                 H = (height_m - height_off) / height_scale;
    return {Poly(samp_num, L, P, H) / Poly(samp_den, L, P, H) * samp_scale + samp_off,
            Poly(line_num, L, P, H) / Poly(line_den, L, P, H) * line_scale + line_off};
  }
};

const char* const kNumber = R"(([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?))";

// The first number that follows `pattern` in `text`.
double NumberAfter(const std::string& text, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(pattern + R"(\s*)" + kNumber)))
    throw std::runtime_error("test: no number after /" + pattern + "/");
  return std::stod(m[1].str());
}

std::vector<double> Numbers(const std::string& text) {
  std::vector<double> out;
  const std::regex number(kNumber);
  for (auto it = std::sregex_iterator(text.begin(), text.end(), number);
       it != std::sregex_iterator(); ++it)
    out.push_back(std::stod((*it)[1].str()));
  return out;
}

// The text between the first `open` and the following `close`.
std::string Between(const std::string& text, const std::string& open, const std::string& close) {
  const size_t a = text.find(open);
  const size_t b = a == std::string::npos ? a : text.find(close, a + open.size());
  if (b == std::string::npos) throw std::runtime_error("test: no " + open + " ... " + close);
  return text.substr(a + open.size(), b - a - open.size());
}

// 20 terms spelt <prefix><n>: "LINE_NUM_COEFF_" "7" ":" or "<ROW_NUM_" "07" ">".
std::vector<double> NumberedTerms(const std::string& text, const std::string& prefix,
                                  const std::string& suffix, bool two_digits) {
  std::vector<double> out;
  for (int i = 1; i <= 20; ++i) {
    const std::string n = (two_digits && i < 10 ? "0" : "") + std::to_string(i);
    out.push_back(NumberAfter(text, prefix + n + suffix));
  }
  return out;
}

// "KEY: value" text (IKONOS, SkySat, PlanetScope).
TextRpc FromKeyValueText(const std::string& t) {
  auto key = [&](const std::string& k) { return NumberAfter(t, "(?:^|\\n)" + k + R"(:)"); };
  TextRpc r;
  r.line_off = key("LINE_OFF"), r.samp_off = key("SAMP_OFF"), r.lat_off = key("LAT_OFF");
  r.lon_off = key("LONG_OFF"), r.height_off = key("HEIGHT_OFF"), r.line_scale = key("LINE_SCALE");
  r.samp_scale = key("SAMP_SCALE"), r.lat_scale = key("LAT_SCALE"), r.lon_scale = key("LONG_SCALE");
  r.height_scale = key("HEIGHT_SCALE");
  r.line_num = NumberedTerms(t, "\\nLINE_NUM_COEFF_", ":", false);
  r.line_den = NumberedTerms(t, "\\nLINE_DEN_COEFF_", ":", false);
  r.samp_num = NumberedTerms(t, "\\nSAMP_NUM_COEFF_", ":", false);
  r.samp_den = NumberedTerms(t, "\\nSAMP_DEN_COEFF_", ":", false);
  return r;
}

// DIMAP: Inverse_Model polynomials, RFM_Validity normalization, first pixel
// centre at (1, 1).
TextRpc FromDimap(const std::string& t) {
  const std::string inv = Between(t, "<Inverse_Model>", "</Inverse_Model>");
  const std::string v = Between(t, "<RFM_Validity>", "</RFM_Validity>");
  auto tag = [&](const std::string& k) { return NumberAfter(v, "<" + k + ">"); };
  TextRpc r;
  r.line_off = tag("LINE_OFF") - 1, r.samp_off = tag("SAMP_OFF") - 1;
  r.lat_off = tag("LAT_OFF"), r.lon_off = tag("LONG_OFF"), r.height_off = tag("HEIGHT_OFF");
  r.line_scale = tag("LINE_SCALE"), r.samp_scale = tag("SAMP_SCALE"),
  r.lat_scale = tag("LAT_SCALE");
  r.lon_scale = tag("LONG_SCALE"), r.height_scale = tag("HEIGHT_SCALE");
  r.line_num = NumberedTerms(inv, "<LINE_NUM_COEFF_", ">", false);
  r.line_den = NumberedTerms(inv, "<LINE_DEN_COEFF_", ">", false);
  r.samp_num = NumberedTerms(inv, "<SAMP_NUM_COEFF_", ">", false);
  r.samp_den = NumberedTerms(inv, "<SAMP_DEN_COEFF_", ">", false);
  return r;
}

// DigitalGlobe product XML: the <RPB> element at the end of the file.
TextRpc FromDigitalGlobe(const std::string& t) {
  const std::string rpb = Between(t, "<RPB>", "</RPB>");
  auto tag = [&](const std::string& k) { return NumberAfter(rpb, "<" + k + ">"); };
  auto list = [&](const std::string& k) {
    return Numbers(Between(rpb, "<" + k + ">", "</" + k + ">"));
  };
  TextRpc r;
  r.line_off = tag("LINEOFFSET"), r.samp_off = tag("SAMPOFFSET"), r.lat_off = tag("LATOFFSET");
  r.lon_off = tag("LONGOFFSET"), r.height_off = tag("HEIGHTOFFSET"),
  r.line_scale = tag("LINESCALE");
  r.samp_scale = tag("SAMPSCALE"), r.lat_scale = tag("LATSCALE"), r.lon_scale = tag("LONGSCALE");
  r.height_scale = tag("HEIGHTSCALE");
  r.line_num = list("LINENUMCOEF"), r.line_den = list("LINEDENCOEF");
  r.samp_num = list("SAMPNUMCOEF"), r.samp_den = list("SAMPDENCOEF");
  return r;
}

// EnMAP: the <bandID number="N"> model, ROW = line, COL = sample.
TextRpc FromEnmap(const std::string& t, int band) {
  // (bandID elements elsewhere in the file describe the bands, not their RPC)
  const std::string rpc = Between(t, "<RPC>", "</RPC>");
  const std::string m =
      Between(rpc, "<bandID number=\"" + std::to_string(band) + "\">", "</bandID>");
  auto tag = [&](const std::string& k) { return NumberAfter(m, "<" + k + ">"); };
  TextRpc r;
  r.line_off = tag("ROW_OFF"), r.samp_off = tag("COL_OFF"), r.lat_off = tag("LAT_OFF");
  r.lon_off = tag("LONG_OFF"), r.height_off = tag("HEIGHT_OFF"), r.line_scale = tag("ROW_SCALE");
  r.samp_scale = tag("COL_SCALE"), r.lat_scale = tag("LAT_SCALE"), r.lon_scale = tag("LONG_SCALE");
  r.height_scale = tag("HEIGHT_SCALE");
  r.line_num = NumberedTerms(m, "<ROW_NUM_", ">", true);
  r.line_den = NumberedTerms(m, "<ROW_DEN_", ">", true);
  r.samp_num = NumberedTerms(m, "<COL_NUM_", ">", true);
  r.samp_den = NumberedTerms(m, "<COL_DEN_", ">", true);
  return r;
}

// Sat-NeRF JSON: "rpc": {"row_offset": ..., "row_num": [...]}.
TextRpc FromSatNerfJson(const std::string& t) {
  auto key = [&](const std::string& k) { return NumberAfter(t, "\"" + k + R"("\s*:)"); };
  auto list = [&](const std::string& k) { return Numbers(Between(t, "\"" + k + "\"", "]")); };
  TextRpc r;
  r.line_off = key("row_offset"), r.samp_off = key("col_offset"), r.lat_off = key("lat_offset");
  r.lon_off = key("lon_offset"), r.height_off = key("alt_offset"), r.line_scale = key("row_scale");
  r.samp_scale = key("col_scale"), r.lat_scale = key("lat_scale"), r.lon_scale = key("lon_scale");
  r.height_scale = key("alt_scale");
  r.line_num = list("row_num"), r.line_den = list("row_den");
  r.samp_num = list("col_num"), r.samp_den = list("col_den");
  return r;
}

// GDAL VRT: <MDI key="LINE_OFF">675</MDI> in the RPC metadata domain.
TextRpc FromVrt(const std::string& t) {
  auto mdi = [&](const std::string& k) { return Between(t, "<MDI key=\"" + k + "\">", "</MDI>"); };
  auto one = [&](const std::string& k) { return Numbers(mdi(k)).at(0); };
  TextRpc r;
  r.line_off = one("LINE_OFF"), r.samp_off = one("SAMP_OFF"), r.lat_off = one("LAT_OFF");
  r.lon_off = one("LONG_OFF"), r.height_off = one("HEIGHT_OFF"), r.line_scale = one("LINE_SCALE");
  r.samp_scale = one("SAMP_SCALE"), r.lat_scale = one("LAT_SCALE"), r.lon_scale = one("LONG_SCALE");
  r.height_scale = one("HEIGHT_SCALE");
  r.line_num = Numbers(mdi("LINE_NUM_COEFF")), r.line_den = Numbers(mdi("LINE_DEN_COEFF"));
  r.samp_num = Numbers(mdi("SAMP_NUM_COEFF")), r.samp_den = Numbers(mdi("SAMP_DEN_COEFF"));
  return r;
}

// ---- The files ---------------------------------------------------------------------

enum class Kind { kKeyValue, kDimap, kDigitalGlobe, kEnmap, kSatNerf, kVrt };

struct VendorFile {
  const char* name;
  Kind kind;
  const char* source;         // what ReadRpcAny reports
  const char* sidecar_image;  // GDAL sidecar route: the image name, or nullptr
  const char* sidecar_name;   // and the name GDAL looks for beside it
};

const VendorFile kFiles[] = {
    {"rpc_IKONOS.txt", Kind::kKeyValue, "rpc_text", "po_2619900.tif", "po_2619900_rpc.txt"},
    {"20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT", Kind::kKeyValue, "rpc_text",
     "skysat.tif", "skysat_RPC.TXT"},
    {"rpc_PLANET_L1A.txt", Kind::kKeyValue, "rpc_text", "planet.tif", "planet_RPC.TXT"},
    {"rpc_PLANET_L1B.txt", Kind::kKeyValue, "rpc_text", "planet.tif", "planet_rpc.txt"},
    // GDAL's DIMAP reader wants an IMG_<id>_R<r>C<c> tile name beside RPC_<id>.XML.
    {"rpc_PLEIADES.xml", Kind::kDimap, "dimap_xml", "IMG_PHR1A_P_001_R1C1.tif",
     "RPC_PHR1A_P_001.XML"},
    {"rpc_SPOT6.xml", Kind::kDimap, "dimap_xml", "IMG_SPOT6_P_001_R1C1.tif",
     "RPC_SPOT6_P_001_R1C1.XML"},
    {"rpc_WV1.xml", Kind::kDigitalGlobe, "digitalglobe_xml", "wv1.tif", "wv1.XML"},
    {"rpc_WV2.xml", Kind::kDigitalGlobe, "digitalglobe_xml", "wv2.tif", "wv2.xml"},
    {"rpc_WV3.xml", Kind::kDigitalGlobe, "digitalglobe_xml", "wv3.tif", "wv3.XML"},
    {"ENMAP01-____L1B-DT0000001011_20220609T081225Z_001_V010111_20230119T143357Z-METADATA.XML",
     Kind::kEnmap, "enmap_xml", nullptr, nullptr},
    {"JAX_068_001_RGB.json", Kind::kSatNerf, "satnerf_json", nullptr, nullptr},
    {"rpc_unsupported.xml", Kind::kVrt, "gdal_metadata", nullptr, nullptr},
};

TextRpc Independent(const VendorFile& f, int enmap_band = 1) {
  const std::string text = ReadTextFile((RpcFormatsRoot() / f.name).string());
  switch (f.kind) {
    case Kind::kKeyValue: return FromKeyValueText(text);
    case Kind::kDimap: return FromDimap(text);
    case Kind::kDigitalGlobe: return FromDigitalGlobe(text);
    case Kind::kEnmap: return FromEnmap(text, enmap_band);
    case Kind::kSatNerf: return FromSatNerfJson(text);
    case Kind::kVrt: return FromVrt(text);
  }
  throw std::runtime_error("test: unknown kind");
}

// The worst disagreement over the validity cube: projection of ground points
// at normalized (L, P, H) in {-1, 0, 1}^3, and localization of image points
// at normalized (sample, line) in {-1, 0, 1}^2 and heights at -1/2, 0, 1/2
// (checked back through the independent projection).
struct Disagreement {
  double project_px = 0, localize_px = 0;
};
Disagreement Compare(const RpcModel& product, const TextRpc& own) {
  Disagreement d;
  for (double a : {-1.0, 0.0, 1.0}) {
    for (double b : {-1.0, 0.0, 1.0}) {
      for (double c : {-1.0, 0.0, 1.0}) {
        const double lon = own.lon_off + a * own.lon_scale, lat = own.lat_off + b * own.lat_scale;
        const double h = own.height_off + c * own.height_scale;
        d.project_px = std::max(d.project_px,
                                (product.Project(lon, lat, h) - own.Project(lon, lat, h)).norm());
        const Eigen::Vector2d px(own.samp_off + a * own.samp_scale,
                                 own.line_off + b * own.line_scale);
        const double h_loc = own.height_off + 0.5 * c * own.height_scale;
        const Eigen::Vector2d ll = Localize(product, px.x(), px.y(), h_loc);
        d.localize_px = std::max(d.localize_px, (own.Project(ll.x(), ll.y(), h_loc) - px).norm());
      }
    }
  }
  return d;
}

void ExpectSameModel(const RpcModel& a, const RpcModel& b, const std::string& label) {
  auto near = [&](double x, double y, const char* what) {
    EXPECT_NEAR(x, y, 1e-12 * std::max(1.0, std::abs(x))) << label << " " << what;
  };
  near(a.line_off, b.line_off, "LINE_OFF");
  near(a.samp_off, b.samp_off, "SAMP_OFF");
  near(a.lat_off, b.lat_off, "LAT_OFF");
  near(a.lon_off, b.lon_off, "LONG_OFF");
  near(a.height_off, b.height_off, "HEIGHT_OFF");
  near(a.line_scale, b.line_scale, "LINE_SCALE");
  near(a.samp_scale, b.samp_scale, "SAMP_SCALE");
  near(a.lat_scale, b.lat_scale, "LAT_SCALE");
  near(a.lon_scale, b.lon_scale, "LONG_SCALE");
  near(a.height_scale, b.height_scale, "HEIGHT_SCALE");
  for (int i = 0; i < 20; ++i) {
    near(a.line_num[i], b.line_num[i], "LINE_NUM_COEFF");
    near(a.line_den[i], b.line_den[i], "LINE_DEN_COEFF");
    near(a.samp_num[i], b.samp_num[i], "SAMP_NUM_COEFF");
    near(a.samp_den[i], b.samp_den[i], "SAMP_DEN_COEFF");
  }
}

TEST(VendorRpc, EveryFileReadDirectlyAgreesWithItsOwnNumbers) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  Disagreement worst;
  for (const VendorFile& f : kFiles) {
    const std::string path = (RpcFormatsRoot() / f.name).string();
    std::string source;
    RpcModel rpc;
    ASSERT_NO_THROW(rpc = ReadRpcAny(path, &source)) << ErrorText([&] { ReadRpcAny(path); });
    EXPECT_EQ(source, f.source) << f.name;
    const Disagreement d = Compare(rpc, Independent(f));
    EXPECT_LT(d.project_px, kAgreementTolPx) << f.name;
    EXPECT_LT(d.localize_px, kAgreementTolPx) << f.name;
    std::printf("[figures] %s: max project diff %.3g px, max localize diff %.3g px\n", f.name,
                d.project_px, d.localize_px);
    worst.project_px = std::max(worst.project_px, d.project_px);
    worst.localize_px = std::max(worst.localize_px, d.localize_px);
  }
  std::printf(
      "[figures] all %zu vendor files: max project diff %.3g px, max localize diff %.3g px\n",
      std::size(kFiles), worst.project_px, worst.localize_px);
}

TEST(VendorRpc, DimapOffsetsBecomeZeroBased) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  // RFM_Validity says LINE_OFF 18088.5, SAMP_OFF 20000.5 with the first pixel centre at (1, 1).
  const RpcModel rpc = ReadRpcAny((RpcFormatsRoot() / "rpc_PLEIADES.xml").string());
  EXPECT_EQ(rpc.line_off, 18087.5);
  EXPECT_EQ(rpc.samp_off, 19999.5);
}

TEST(VendorRpc, EnmapBandsCanBeChosen) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  const VendorFile& enmap = kFiles[9];
  ASSERT_EQ(enmap.kind, Kind::kEnmap);
  const std::string path = (RpcFormatsRoot() / enmap.name).string();
  // The 91 VNIR bands share band 1's model; each SWIR band (92..224) has its own.
  for (int band : {1, 91, 92, 150, 224}) {
    RpcReadOptions options;
    options.band = band;
    const Disagreement d = Compare(ReadRpcAny(path, nullptr, options), Independent(enmap, band));
    EXPECT_LT(d.project_px, kAgreementTolPx) << "band " << band;
    EXPECT_LT(d.localize_px, kAgreementTolPx) << "band " << band;
  }
  RpcReadOptions options;
  options.band = 225;
  std::string msg = ErrorText([&] { ReadRpcAny(path, nullptr, options); });
  EXPECT_NE(msg.find(enmap.name), std::string::npos) << msg;
  EXPECT_NE(msg.find("no model for band 225 (224 bandID models"), std::string::npos) << msg;
  options.band = 2;
  msg =
      ErrorText([&] { ReadRpcAny((RpcFormatsRoot() / "rpc_WV2.xml").string(), nullptr, options); });
  EXPECT_NE(msg.find("rpc_WV2.xml: holds one RPC model"), std::string::npos) << msg;
}

// DigitalGlobe .RPB text written from rpc_WV2.xml's own numbers (the folder
// holds no .RPB file).
std::string RpbTextOf(const TextRpc& r) {
  std::ostringstream s;
  s.precision(17);
  s << "satId = \"WV02\";\nbandId = \"RGB\";\nSpecId = \"RPC00B\";\nBEGIN_GROUP = IMAGE\n"
    << "\terrBias = 26.68;\n\terrRand = 0.14;\n"
    << "\tlineOffset = " << r.line_off << ";\n\tsampOffset = " << r.samp_off << ";\n"
    << "\tlatOffset = " << r.lat_off << ";\n\tlongOffset = " << r.lon_off << ";\n"
    << "\theightOffset = " << r.height_off << ";\n\tlineScale = " << r.line_scale << ";\n"
    << "\tsampScale = " << r.samp_scale << ";\n\tlatScale = " << r.lat_scale << ";\n"
    << "\tlongScale = " << r.lon_scale << ";\n\theightScale = " << r.height_scale << ";\n";
  const std::pair<const char*, const std::vector<double>*> lists[] = {{"lineNumCoef", &r.line_num},
                                                                      {"lineDenCoef", &r.line_den},
                                                                      {"sampNumCoef", &r.samp_num},
                                                                      {"sampDenCoef", &r.samp_den}};
  for (const auto& [name, c] : lists) {
    s << "\t" << name << " = (";
    for (size_t i = 0; i < c->size(); ++i)
      s << "\n\t\t\t" << (*c)[i] << (i + 1 < c->size() ? "," : ");\n");
  }
  s << "END_GROUP = IMAGE\nEND;\n";
  return s.str();
}

TEST(VendorRpc, SidecarsGdalFindsGiveTheSameModelAsTheFileReadDirectly) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  for (const VendorFile& f : kFiles) {
    if (!f.sidecar_image) continue;
    const fs::path dir = ScratchDir(fs::path(f.name).stem().string());
    WriteTestRaster(dir / f.sidecar_image, "GTiff", 64, 64, 1);  // no RPC of its own
    fs::copy_file(RpcFormatsRoot() / f.name, dir / f.sidecar_name);
    const RpcModel direct = ReadRpcAny((RpcFormatsRoot() / f.name).string());
    RpcModel sidecar;
    ASSERT_NO_THROW(sidecar = ReadRpcFromRaster((dir / f.sidecar_image).string()))
        << f.name << ": "
        << ErrorText([&] { ReadRpcFromRaster((dir / f.sidecar_image).string()); });
    ExpectSameModel(sidecar, direct, f.name);
    const Disagreement d = Compare(sidecar, Independent(f));
    EXPECT_LT(d.project_px, kAgreementTolPx) << f.name;
  }
  // .RPB, read directly and as GDAL's sidecar.
  const VendorFile& wv2 = kFiles[7];
  ASSERT_EQ(std::string(wv2.name), "rpc_WV2.xml");
  const fs::path dir = ScratchDir("rpb");
  std::ofstream(dir / "wv2.RPB") << RpbTextOf(Independent(wv2));
  std::ofstream(dir / "named_anyhow.txt") << RpbTextOf(Independent(wv2));
  WriteTestRaster(dir / "wv2.tif", "GTiff", 64, 64, 1);
  std::string source;
  const RpcModel direct = ReadRpcAny((dir / "named_anyhow.txt").string(), &source);
  EXPECT_EQ(source, "rpb");
  ExpectSameModel(ReadRpcFromRaster((dir / "wv2.tif").string()), direct, "wv2.RPB");
  const Disagreement d = Compare(direct, Independent(wv2));
  EXPECT_LT(d.project_px, kAgreementTolPx);
  EXPECT_LT(d.localize_px, kAgreementTolPx);
}

TEST(VendorRpc, ContentNotNameDecidesTheReader) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  const fs::path dir = ScratchDir("renamed");
  const std::pair<const char*, const char*> renames[] = {{"rpc_IKONOS.txt", "ikonos.dat"},
                                                         {"rpc_PLEIADES.xml", "pleiades.txt"},
                                                         {"rpc_WV3.xml", "wv3"},
                                                         {"JAX_068_001_RGB.json", "camera.txt"}};
  for (const auto& [name, renamed] : renames) {
    fs::copy_file(RpcFormatsRoot() / name, dir / renamed);
    ExpectSameModel(ReadRpcAny((dir / renamed).string()),
                    ReadRpcAny((RpcFormatsRoot() / name).string()), renamed);
  }
}

TEST(VendorRpc, FilesWithoutAnRpcAreRefusedNamingTheFile) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  const fs::path dir = ScratchDir("refused");
  auto write = [&](const char* name, const std::string& text) {
    std::ofstream(dir / name, std::ios::binary) << text;
    return (dir / name).string();
  };
  struct Case {
    std::string path;
    std::string expected;
  };
  const Case cases[] = {
      {(RpcFormatsRoot() / "README.md").string(), "holds no RPC"},
      {(RpcFormatsRoot() / "LICENSE.rpcm").string(), "holds no RPC"},
      {write("empty.xml", ""), "is empty"},
      {write("blank.txt", " \n\t\n"), "holds only blanks"},
      {write("catalog.xml", "<?xml version=\"1.0\"?>\n<catalog><book id=\"1\"/></catalog>\n"),
       "holds no RPC"},
      {write("isd.xml", "<?xml version=\"1.0\"?>\n<isd><IMD><SATID>WV02</SATID></IMD></isd>\n"),
       "isd.RPB.IMAGE: is missing"},
      {write("dimap.xml", "<Dimap_Document><Rational_Function_Model/></Dimap_Document>"),
       "Dimap_Document.Rational_Function_Model.Global_RFM: is missing"},
      {write("enmap.xml", "<level_X><product><navigation/></product></level_X>"),
       "level_X.product.navigation.RPC: is missing"},
      {write("broken.xml", "<isd><RPB>"), "is not well-formed XML"},
      {(dir / "nope.RPB").string(), "file does not exist"},
  };
  for (const Case& c : cases) {
    const std::string msg = ErrorText([&] { ReadRpcAny(c.path); });
    EXPECT_NE(msg.find(c.path), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.expected), std::string::npos) << msg;
  }
}

TEST(VendorRpc, BadFieldsAreNamedAsTheFileSpellsThem) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  const fs::path dir = ScratchDir("bad_fields");
  auto edited = [&](const char* name, const std::string& from, const std::string& to) {
    std::string text = ReadTextFile((RpcFormatsRoot() / name).string());
    const size_t at = text.find(from);
    if (at == std::string::npos) throw std::runtime_error("test: no " + from);
    text.replace(at, from.size(), to);
    const fs::path out = dir / name;
    std::ofstream(out, std::ios::binary) << text;
    return out.string();
  };
  struct Case {
    std::string path;
    std::string expected;
  };
  const Case cases[] = {
      {edited("rpc_IKONOS.txt", "LINE_NUM_COEFF_7:", "LINE_NUM_COEFF_7x:"),
       "LINE_NUM_COEFF_7: is missing"},
      {edited("rpc_PLANET_L1A.txt", "LAT_SCALE: -0.0234", "LAT_SCALE: -0,0234"),
       "LAT_SCALE: has trailing text: ' -0,0234'"},
      {edited("rpc_PLEIADES.xml",
              "<LINE_DEN_COEFF_1>1</LINE_DEN_COEFF_1>\n        "
              "<LINE_DEN_COEFF_2>-0.0003567797330998679",
              "<LINE_DEN_COEFF_1>1</LINE_DEN_COEFF_1>\n        <LINE_DEN_COEFF_2>abc"),
       "Global_RFM.Inverse_Model.LINE_DEN_COEFF_2: is not a number: 'abc'"},
      {edited("rpc_SPOT6.xml", "<LONG_SCALE>0.17163418</LONG_SCALE>",
              "<LONG_SCALX>0.17163418</LONG_SCALX>"),
       "Global_RFM.RFM_Validity.LONG_SCALE: is missing"},
      {edited("rpc_WV2.xml", "<SAMPSCALE>14264</SAMPSCALE>", "<SAMPSCALE>0</SAMPSCALE>"),
       "isd.RPB.IMAGE.SAMPSCALE: is zero"},
      {edited("rpc_WV1.xml", "<LINEDENCOEF>1.000000000000000e+00 ", "<LINEDENCOEF>nan "),
       "isd.RPB.IMAGE.LINEDENCOEFList.LINEDENCOEF[0]: is not finite"},
  };
  for (const Case& c : cases) {
    const std::string msg = ErrorText([&] { ReadRpcAny(c.path); });
    EXPECT_NE(msg.find(c.path), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.expected), std::string::npos) << msg;
  }
}

TEST(VendorRpc, UnitWordsPassButOtherTrailingTextDoesNot) {
  auto keys = RpcToGdalMetadata(MakeTestRpc());
  keys["LINE_OFF"] = "+005124.00 pixels";
  keys["LAT_OFF"] = "-34.90300000 degrees\r\n";
  EXPECT_EQ(RpcFromGdalMetadata(keys).line_off, 5124.0);
  EXPECT_EQ(RpcFromGdalRpcDomain(keys).lat_off, -34.903);
  keys["LINE_OFF"] = "5124.00pixels";
  EXPECT_NE(ErrorText([&] { RpcFromGdalRpcDomain(keys); }).find("LINE_OFF: has trailing text"),
            std::string::npos);
  keys["LINE_OFF"] = "5124 pixels 7";
  EXPECT_NE(ErrorText([&] { RpcFromGdalMetadata(keys); }).find("LINE_OFF: has trailing text"),
            std::string::npos);
  keys.erase("LINE_OFF");  // GDAL alone would read a missing offset as 0
  EXPECT_NE(ErrorText([&] { RpcFromGdalRpcDomain(keys); }).find("LINE_OFF: is missing"),
            std::string::npos);
}

// A plain folder of one image and its RPC file, ingested: the image's
// rpc_source, or the reason it was skipped or the AOI failed.
std::string IngestedRpcSource(const fs::path& root, const char* image, const char* rpc_file,
                              const char* rpc_name) {
  fs::create_directories(root);
  WriteTestRaster(root / image, "GTiff", 64, 64, 1);
  fs::copy_file(RpcFormatsRoot() / rpc_file, root / rpc_name);
  NullProgress progress;
  const IngestResult r =
      RunIngest(IngestOptions{}, root.string(), (root.parent_path() / "out").string(), progress);
  if (r.aois.size() != 1) return "aois: " + std::to_string(r.aois.size());
  const AoiIngestResult& aoi = r.aois[0];
  for (const Skipped& s : aoi.skipped_images) return "skipped: " + s.reason;
  if (aoi.catalog.images.size() != 1)
    return "images: " + std::to_string(aoi.catalog.images.size()) + " " + aoi.report.message;
  return aoi.catalog.images[0].rpc_source;
}

// An RPC in a sidecar GDAL does not attach (RPC_<stem>.XML without a DIM_
// file or tile name) is found by our own readers; an IKONOS _rpc.txt (unit
// words) by GDAL.
TEST(VendorRpc, IngestReadsOwnSidecarsAndUnitWords) {
  SKYFALL_REQUIRE_RPC_FORMATS();
  const fs::path dir = ScratchDir("ingest");
  EXPECT_EQ(IngestedRpcSource(dir / "pleiades", "scene.tif", "rpc_PLEIADES.xml", "RPC_scene.XML"),
            "dimap_xml");
  EXPECT_EQ(FindOwnRpcSidecar((dir / "pleiades" / "scene.tif").string()),
            (dir / "pleiades" / "RPC_scene.XML").string());
  EXPECT_EQ(
      IngestedRpcSource(dir / "ikonos", "po_2619900.tif", "rpc_IKONOS.txt", "po_2619900_rpc.txt"),
      "gdal_metadata");
  EXPECT_EQ(FindOwnRpcSidecar((dir / "ikonos" / "po_2619900.tif").string()), "");
}

}  // namespace
}  // namespace skyfall
