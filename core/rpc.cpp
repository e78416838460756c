#include "core/rpc.h"

#include <Eigen/LU>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <regex>
#include <sstream>

#include "core/error.h"
#include "core/format.h"
#include "core/rpc_terms.h"

namespace skyfall {
namespace {

using rpc_terms::Dot;
using rpc_terms::Monomials;
using rpc_terms::Terms;

// Partial derivatives of the monomials with respect to L and P.
Terms MonomialsDL(double L, double P, double H) {
  return {0.0, 1.0,   0.0, 0.0,       P,   H,         0.0, 2 * L,     0.0, 0.0,
          P * H, 3 * L * L, P * P, H * H, 2 * L * P, 0.0, 0.0, 2 * L * H, 0.0, 0.0};
}
Terms MonomialsDP(double L, double P, double H) {
  return {0.0, 0.0,   1.0, 0.0,   L,         0.0,       H,     0.0,       2 * P, 0.0,
          L * H, 0.0, 2 * L * P, 0.0, L * L, 3 * P * P, H * H, 0.0, 2 * P * H, 0.0};
}

// A denominator this small (relative to the usual ~1) means a pole: the model
// is undefined there.
constexpr double kMinAbsDenominator = 1e-8;

struct ScalarField {
  const char* gdal_key;
  double RpcModel::*member;
  bool must_be_nonzero;
};
const ScalarField kScalarFields[] = {
    {"LINE_OFF", &RpcModel::line_off, false},       {"SAMP_OFF", &RpcModel::samp_off, false},
    {"LAT_OFF", &RpcModel::lat_off, false},         {"LONG_OFF", &RpcModel::lon_off, false},
    {"HEIGHT_OFF", &RpcModel::height_off, false},   {"LINE_SCALE", &RpcModel::line_scale, true},
    {"SAMP_SCALE", &RpcModel::samp_scale, true},    {"LAT_SCALE", &RpcModel::lat_scale, true},
    {"LONG_SCALE", &RpcModel::lon_scale, true},     {"HEIGHT_SCALE", &RpcModel::height_scale, true},
};
struct CoeffField {
  const char* gdal_key;
  Terms RpcModel::*member;
};
const CoeffField kCoeffFields[] = {
    {"LINE_NUM_COEFF", &RpcModel::line_num},
    {"LINE_DEN_COEFF", &RpcModel::line_den},
    {"SAMP_NUM_COEFF", &RpcModel::samp_num},
    {"SAMP_DEN_COEFF", &RpcModel::samp_den},
};

void CheckDenominator(const Terms& den, const char* key) {
  bool all_zero = true;
  for (double c : den) all_zero = all_zero && c == 0.0;
  if (all_zero) throw Error("rpc", key, "all 20 coefficients are zero (zero denominator)");
  // A valid RPC denominator keeps one sign over the validity cube; a sign
  // change or a near-zero value is a pole inside the image.
  const double center = den[0];
  if (std::abs(center) < kMinAbsDenominator) {
    throw Error("rpc", std::string(key) + "[0]",
                "denominator is zero at the normalization centre (value " + FormatDouble(center) +
                    ")");
  }
  constexpr int kSteps = 5;
  for (int i = 0; i < kSteps; ++i) {
    for (int j = 0; j < kSteps; ++j) {
      for (int k = 0; k < kSteps; ++k) {
        const double L = -1.0 + 2.0 * i / (kSteps - 1);
        const double P = -1.0 + 2.0 * j / (kSteps - 1);
        const double H = -1.0 + 2.0 * k / (kSteps - 1);
        const double d = Dot(den, Monomials(L, P, H));
        if (std::abs(d) < kMinAbsDenominator || (d > 0) != (center > 0)) {
          throw Error("rpc", key,
                      "denominator vanishes inside the validity cube (value " + FormatDouble(d) +
                          " at normalized L=" + FormatDouble(L) + " P=" + FormatDouble(P) +
                          " H=" + FormatDouble(H) + ")");
        }
      }
    }
  }
}

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
bool IsLetter(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

// A number, optionally followed by one unit word: IKONOS/GeoEye _rpc.txt files
// write "LINE_OFF: +005124.00 pixels", and GDAL (CPLAtof) reads such values by
// ignoring whatever follows the number. Anything else after the number is
// refused, so that "12,5" or "1.5.3" is not silently read as 12 or 1.5.
double ParseNumber(const std::string& text, const std::string& field) {
  const char* begin = text.c_str();
  while (*begin == ' ' || *begin == '\t') ++begin;
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin) throw Error("rpc", field, "is not a number: '" + text + "'");
  const char* rest = end;
  while (IsBlank(*rest)) ++rest;
  if (rest > end && IsLetter(*rest)) {  // the unit word, apart from the number
    while (IsLetter(*rest)) ++rest;
    while (IsBlank(*rest)) ++rest;
  }
  if (*rest != '\0') throw Error("rpc", field, "has trailing text: '" + text + "'");
  return v;
}

Terms ParseCoefficients(const std::string& text, const std::string& field) {
  std::istringstream in(text);
  Terms out{};
  std::string token;
  int n = 0;
  while (in >> token) {
    if (n == 20) throw Error("rpc", field, "has more than 20 coefficients");
    out[n] = ParseNumber(token, field + "[" + std::to_string(n) + "]");
    ++n;
  }
  if (n != 20) {
    throw Error("rpc", field, "has " + std::to_string(n) + " coefficients, expected 20");
  }
  return out;
}

}  // namespace

void RpcModel::Validate() const {
  for (const auto& f : kScalarFields) {
    const double v = this->*f.member;
    if (!std::isfinite(v)) throw Error("rpc", f.gdal_key, "is not finite (" + FormatDouble(v) + ")");
    if (f.must_be_nonzero && v == 0.0) throw Error("rpc", f.gdal_key, "is zero (a scale must not be)");
  }
  for (const auto& f : kCoeffFields) {
    const Terms& c = this->*f.member;
    for (int i = 0; i < 20; ++i) {
      if (!std::isfinite(c[i])) {
        throw Error("rpc", std::string(f.gdal_key) + "[" + std::to_string(i) + "]",
                    "is not finite (" + FormatDouble(c[i]) + ")");
      }
    }
  }
  CheckDenominator(line_den, "LINE_DEN_COEFF");
  CheckDenominator(samp_den, "SAMP_DEN_COEFF");
}

Eigen::Vector2d RpcModel::Project(double lon_deg, double lat_deg, double height_m) const {
  return Project(lon_deg, lat_deg, height_m, nullptr);
}

double LongitudeDeltaDeg(double lon_deg, double ref_deg) {
  const double d = lon_deg - ref_deg;
  if (d >= -180.0 && d < 180.0) return d;  // the usual case, left exact
  const double m = std::fmod(d + 180.0, 360.0);
  return (m < 0 ? m + 360.0 : m) - 180.0;
}

double WrapLongitudeDeg(double lon_deg) { return LongitudeDeltaDeg(lon_deg, 0.0); }

Eigen::Vector2d RpcModel::Project(double lon_deg, double lat_deg, double height_m,
                                  Eigen::Matrix2d* d_colrow_d_lonlat) const {
  const double L = LongitudeDeltaDeg(lon_deg, lon_off) / lon_scale;
  const double P = (lat_deg - lat_off) / lat_scale;
  const double H = (height_m - height_off) / height_scale;
  const Terms m = Monomials(L, P, H);
  const double ln = Dot(line_num, m), ld = Dot(line_den, m);
  const double sn = Dot(samp_num, m), sd = Dot(samp_den, m);
  if (std::abs(ld) < kMinAbsDenominator || std::abs(sd) < kMinAbsDenominator) {
    throw Error("rpc", std::abs(ld) < kMinAbsDenominator ? "LINE_DEN_COEFF" : "SAMP_DEN_COEFF",
                "denominator is zero at lon=" + FormatDouble(lon_deg) + " lat=" +
                    FormatDouble(lat_deg) + " height=" + FormatDouble(height_m));
  }
  const Eigen::Vector2d colrow(sn / sd * samp_scale + samp_off, ln / ld * line_scale + line_off);
  if (d_colrow_d_lonlat) {
    const Terms mL = MonomialsDL(L, P, H), mP = MonomialsDP(L, P, H);
    // Quotient rule, then chain rule through the normalization.
    auto d_ratio = [](double num, double den, double dnum, double dden) {
      return (dnum * den - num * dden) / (den * den);
    };
    Eigen::Matrix2d J;
    J(0, 0) = d_ratio(sn, sd, Dot(samp_num, mL), Dot(samp_den, mL)) * samp_scale / lon_scale;
    J(0, 1) = d_ratio(sn, sd, Dot(samp_num, mP), Dot(samp_den, mP)) * samp_scale / lat_scale;
    J(1, 0) = d_ratio(ln, ld, Dot(line_num, mL), Dot(line_den, mL)) * line_scale / lon_scale;
    J(1, 1) = d_ratio(ln, ld, Dot(line_num, mP), Dot(line_den, mP)) * line_scale / lat_scale;
    *d_colrow_d_lonlat = J;
  }
  return colrow;
}

RpcModel RpcModel::Cropped(double col0, double row0) const {
  RpcModel out = *this;
  out.samp_off -= col0;
  out.line_off -= row0;
  return out;
}

Eigen::Vector2d Localize(const RpcModel& rpc, double col, double row, double height_m,
                         const LocalizeOptions& options) {
  const Eigen::Vector2d target(col, row);
  // Start at the normalization centre: the RPC is close to affine, so Newton
  // reaches machine precision in a handful of steps from there.
  Eigen::Vector2d lonlat(rpc.lon_off, rpc.lat_off);
  Eigen::Matrix2d J;
  Eigen::Vector2d residual = rpc.Project(lonlat.x(), lonlat.y(), height_m, &J) - target;
  auto fail = [&](const std::string& why) {
    return Error("rpc", "localize",
                 why + " at col=" + FormatDouble(col) + " row=" + FormatDouble(row) +
                     " height=" + FormatDouble(height_m) + " (residual " +
                     FormatDouble(residual.norm()) + " px)");
  };
  for (int it = 0; it < options.max_iterations; ++it) {
    if (residual.norm() <= options.tolerance_px) return lonlat;
    const Eigen::FullPivLU<Eigen::Matrix2d> lu(J);
    if (!lu.isInvertible()) throw fail("singular Jacobian");
    const Eigen::Vector2d step = lu.solve(-residual);
    // Backtracking keeps the iteration from overshooting where the
    // polynomial bends (far from the offsets or at extreme heights).
    double t = 1.0;
    Eigen::Vector2d next = lonlat;
    Eigen::Vector2d next_residual = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Matrix2d next_J = J;
    for (int halvings = 0; halvings < 30; ++halvings, t *= 0.5) {
      next = lonlat + t * step;
      const double L = LongitudeDeltaDeg(next.x(), rpc.lon_off) / rpc.lon_scale;
      const double P = (next.y() - rpc.lat_off) / rpc.lat_scale;
      if (std::abs(L) > options.max_normalized || std::abs(P) > options.max_normalized) continue;
      next_residual = rpc.Project(next.x(), next.y(), height_m, &next_J) - target;
      if (next_residual.norm() < residual.norm()) break;
    }
    if (!(next_residual.norm() < residual.norm())) {
      // No step improves: either converged to round-off or diverging.
      if (residual.norm() <= 1e3 * options.tolerance_px) return lonlat;
      throw fail("Newton iteration stalled");
    }
    lonlat = next;
    residual = next_residual;
    J = next_J;
  }
  if (residual.norm() <= options.tolerance_px) return lonlat;
  throw fail("no convergence after " + std::to_string(options.max_iterations) + " iterations");
}

RpcModel RpcFromGdalMetadata(const std::map<std::string, std::string>& keys) {
  RpcModel rpc;
  auto get = [&](const char* key) -> const std::string& {
    const auto it = keys.find(key);
    if (it == keys.end()) throw Error("rpc", key, "is missing");
    return it->second;
  };
  for (const auto& f : kScalarFields) rpc.*f.member = ParseNumber(get(f.gdal_key), f.gdal_key);
  for (const auto& f : kCoeffFields) rpc.*f.member = ParseCoefficients(get(f.gdal_key), f.gdal_key);
  if (keys.count("ERR_BIAS")) rpc.err_bias_m = ParseNumber(keys.at("ERR_BIAS"), "ERR_BIAS");
  if (keys.count("ERR_RAND")) rpc.err_rand_m = ParseNumber(keys.at("ERR_RAND"), "ERR_RAND");
  rpc.Validate();
  return rpc;
}

std::map<std::string, std::string> RpcToGdalMetadata(const RpcModel& rpc) {
  std::map<std::string, std::string> keys;
  for (const auto& f : kScalarFields) keys[f.gdal_key] = FormatDouble(rpc.*f.member);
  for (const auto& f : kCoeffFields) {
    std::string s;
    for (double c : rpc.*f.member) s += (s.empty() ? "" : " ") + FormatDouble(c);
    keys[f.gdal_key] = s;
  }
  keys["ERR_BIAS"] = FormatDouble(rpc.err_bias_m);
  keys["ERR_RAND"] = FormatDouble(rpc.err_rand_m);
  return keys;
}

RpcModel RpcFromRpbText(const std::string& text) {
  // Collect `name = value;` and `name = ( v, v, ... );` pairs; group markers
  // (BEGIN_GROUP/END_GROUP/END) are ignored.
  static const std::map<std::string, std::string> kRpbToGdal = {
      {"lineOffset", "LINE_OFF"},     {"sampOffset", "SAMP_OFF"},     {"latOffset", "LAT_OFF"},
      {"longOffset", "LONG_OFF"},     {"heightOffset", "HEIGHT_OFF"}, {"lineScale", "LINE_SCALE"},
      {"sampScale", "SAMP_SCALE"},    {"latScale", "LAT_SCALE"},      {"longScale", "LONG_SCALE"},
      {"heightScale", "HEIGHT_SCALE"}, {"lineNumCoef", "LINE_NUM_COEFF"},
      {"lineDenCoef", "LINE_DEN_COEFF"}, {"sampNumCoef", "SAMP_NUM_COEFF"},
      {"sampDenCoef", "SAMP_DEN_COEFF"}, {"errBias", "ERR_BIAS"},     {"errRand", "ERR_RAND"},
  };
  // Scalars sit on one line; coefficient lists span lines inside ( ).
  static const std::regex kAssign(R"(([A-Za-z_]+)[ \t]*=[ \t]*(\([^)]*\)|[^;\n]*);)");
  std::map<std::string, std::string> keys;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kAssign);
       it != std::sregex_iterator(); ++it) {
    const auto found = kRpbToGdal.find((*it)[1].str());
    if (found == kRpbToGdal.end()) continue;
    std::string value = (*it)[2].str();
    for (char& ch : value) {
      if (ch == '(' || ch == ')' || ch == ',' || ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
    }
    keys[found->second] = value;
  }
  try {
    return RpcFromGdalMetadata(keys);
  } catch (const Error& e) {
    // Name the field the way the .RPB file spells it.
    std::string rpb_name = e.subject();
    for (const auto& [rpb, gdal] : kRpbToGdal) {
      if (rpb_name.rfind(gdal, 0) == 0) {
        rpb_name = rpb + rpb_name.substr(gdal.size());
        break;
      }
    }
    throw Error("rpc", rpb_name, e.detail());
  }
}

RpcModel RpcFromKeyValueText(const std::string& text) {
  // One "KEY: value" per line (GDAL's own reader of these files, GDALLoadRPCFile,
  // also takes "KEY=value"); the first of repeated keys counts, as in GDAL.
  std::map<std::string, std::string> values;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    const size_t sep = line.find_first_of(":=");
    if (sep == std::string::npos) continue;
    size_t a = 0, b = sep;
    while (a < b && IsBlank(line[a])) ++a;
    while (b > a && IsBlank(line[b - 1])) --b;
    if (b > a) values.emplace(line.substr(a, b - a), line.substr(sep + 1));
  }
  auto get = [&](const std::string& key) -> const std::string& {
    const auto it = values.find(key);
    if (it == values.end()) throw Error("rpc", key, "is missing");
    return it->second;
  };
  RpcModel rpc;
  for (const auto& f : kScalarFields) rpc.*f.member = ParseNumber(get(f.gdal_key), f.gdal_key);
  // Each polynomial is written one term a line, KEY_1 .. KEY_20.
  for (const auto& f : kCoeffFields) {
    for (int i = 0; i < 20; ++i) {
      const std::string key = std::string(f.gdal_key) + "_" + std::to_string(i + 1);
      (rpc.*f.member)[i] = ParseNumber(get(key), key);
    }
  }
  if (values.count("ERR_BIAS")) rpc.err_bias_m = ParseNumber(values.at("ERR_BIAS"), "ERR_BIAS");
  if (values.count("ERR_RAND")) rpc.err_rand_m = ParseNumber(values.at("ERR_RAND"), "ERR_RAND");
  try {
    rpc.Validate();
  } catch (const Error& e) {
    // Validate names the term 0-based, "LINE_NUM_COEFF[3]"; the file says LINE_NUM_COEFF_4.
    std::smatch m;
    static const std::regex kIndexed(R"(^([A-Z_]+)\[(\d+)\]$)");
    if (std::regex_match(e.subject(), m, kIndexed)) {
      throw Error("rpc", m[1].str() + "_" + std::to_string(std::stoi(m[2].str()) + 1), e.detail());
    }
    throw;
  }
  return rpc;
}

}  // namespace skyfall
