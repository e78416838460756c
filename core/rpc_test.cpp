#include "core/rpc.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"
#include "tests/test_rpc_fixture.h"

namespace skyfall {
namespace {

using testing::MakeTestRpc;

// Newton localization is asked for 1e-9 px; allow three orders of magnitude
// for round-off in the normalization of ~1e4-pixel offsets.
constexpr double kRoundTripTolPx = 1e-6;

// Sweeps the whole normalized validity cube, corners included.
template <typename F>
void ForEachCubePoint(const RpcModel& rpc, int steps, F&& f) {
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < steps; ++j)
      for (int k = 0; k < steps; ++k) {
        const double u = -1.0 + 2.0 * i / (steps - 1);
        const double v = -1.0 + 2.0 * j / (steps - 1);
        const double w = -1.0 + 2.0 * k / (steps - 1);
        f(rpc.lon_off + u * rpc.lon_scale, rpc.lat_off + v * rpc.lat_scale,
          rpc.height_off + w * rpc.height_scale);
      }
}

TEST(Rpc, FixtureIsValid) { EXPECT_NO_THROW(MakeTestRpc().Validate()); }

TEST(Rpc, ProjectAtOffsetsGivesConstantTerms) {
  const RpcModel rpc = MakeTestRpc();
  const Eigen::Vector2d p = rpc.Project(rpc.lon_off, rpc.lat_off, rpc.height_off);
  EXPECT_DOUBLE_EQ(p.x(), rpc.samp_num[0] / rpc.samp_den[0] * rpc.samp_scale + rpc.samp_off);
  EXPECT_DOUBLE_EQ(p.y(), rpc.line_num[0] / rpc.line_den[0] * rpc.line_scale + rpc.line_off);
}

TEST(Rpc, JacobianMatchesFiniteDifferences) {
  const RpcModel rpc = MakeTestRpc();
  ForEachCubePoint(rpc, 3, [&](double lon, double lat, double h) {
    Eigen::Matrix2d J;
    rpc.Project(lon, lat, h, &J);
    const double step_deg = 1e-7;  // ~1 cm: central differences exact to ~1e-9 relative
    for (int c = 0; c < 2; ++c) {
      const double dl = c == 0 ? step_deg : 0.0, dp = c == 1 ? step_deg : 0.0;
      const Eigen::Vector2d fd =
          (rpc.Project(lon + dl, lat + dp, h) - rpc.Project(lon - dl, lat - dp, h)) /
          (2 * step_deg);
      for (int r = 0; r < 2; ++r) {
        EXPECT_NEAR(J(r, c), fd(r), 1e-6 * std::abs(fd(r)) + 1e-3) << "entry " << r << "," << c;
      }
    }
  });
}

TEST(Rpc, LocalizeInvertsProjectOverTheWholeValidityCube) {
  const RpcModel rpc = MakeTestRpc();
  int checked = 0;
  ForEachCubePoint(rpc, 7, [&](double lon, double lat, double h) {
    const Eigen::Vector2d px = rpc.Project(lon, lat, h);
    const Eigen::Vector2d ll = Localize(rpc, px.x(), px.y(), h);
    EXPECT_LT((rpc.Project(ll.x(), ll.y(), h) - px).norm(), kRoundTripTolPx);
    EXPECT_NEAR(ll.x(), lon, 1e-10);
    EXPECT_NEAR(ll.y(), lat, 1e-10);
    ++checked;
  });
  EXPECT_EQ(checked, 343);
}

TEST(Rpc, LocalizeReportsNonConvergenceInsteadOfAWrongPoint) {
  RpcModel rpc = MakeTestRpc();
  // Columns no longer depend on lon/lat: the Jacobian is singular.
  rpc.samp_num = {};
  rpc.samp_num[0] = 0.1;
  rpc.samp_num[3] = 1.0;
  try {
    Localize(rpc, 100.0, 200.0, 0.0);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("col=100"), std::string::npos) << e.what();
  }
  // A pixel far outside the validity domain also fails loudly.
  const RpcModel good = MakeTestRpc();
  EXPECT_THROW(Localize(good, 1e9, -1e9, 0.0), Error);
}

// Astride the antimeridian a longitude may arrive as 179.9999 or -180.0001:
// both are the same meridian, and the model must say so.
TEST(Rpc, LongitudesAreTakenModulo360AroundTheOffset) {
  EXPECT_EQ(LongitudeDeltaDeg(-81.5, -81.6), -81.5 - -81.6);  // the usual case is left exact
  EXPECT_NEAR(LongitudeDeltaDeg(-179.9999, 179.9999), 0.0002, 1e-12);
  EXPECT_NEAR(LongitudeDeltaDeg(179.9999, -179.9999), -0.0002, 1e-12);
  EXPECT_NEAR(LongitudeDeltaDeg(540.5, 0.0), -179.5, 1e-12);
  EXPECT_NEAR(WrapLongitudeDeg(180.0002), -179.9998, 1e-12);
  EXPECT_EQ(WrapLongitudeDeg(-180.0), -180.0);
  RpcModel rpc = MakeTestRpc();
  const double lon = rpc.lon_off + 0.3 * rpc.lon_scale, lat = rpc.lat_off - 0.2 * rpc.lat_scale;
  const Eigen::Vector2d p = rpc.Project(lon, lat, rpc.height_off);
  // A whole turn added rounds the longitude at ~6e-14 deg (the ulp of 280),
  // a few 1e-7 px at this fixture's scales: 1e-6 px bounds it.
  EXPECT_NEAR((rpc.Project(lon + 360.0, lat, rpc.height_off) - p).norm(), 0.0, 1e-6);
  EXPECT_NEAR((rpc.Project(lon - 720.0, lat, rpc.height_off) - p).norm(), 0.0, 1e-6);
}

TEST(Rpc, CroppedModelIsAnExactShift) {
  const RpcModel rpc = MakeTestRpc();
  const RpcModel crop = rpc.Cropped(1234.0, -567.5);
  ForEachCubePoint(rpc, 3, [&](double lon, double lat, double h) {
    const Eigen::Vector2d full = rpc.Project(lon, lat, h);
    const Eigen::Vector2d sub = crop.Project(lon, lat, h);
    EXPECT_DOUBLE_EQ(sub.x(), full.x() - 1234.0);
    EXPECT_DOUBLE_EQ(sub.y(), full.y() + 567.5);
  });
}

TEST(Rpc, ValidateNamesNonFiniteCoefficient) {
  RpcModel rpc = MakeTestRpc();
  rpc.samp_num[7] = std::numeric_limits<double>::quiet_NaN();
  try {
    rpc.Validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "SAMP_NUM_COEFF[7]");
    EXPECT_NE(std::string(e.what()).find("nan"), std::string::npos) << e.what();
  }
  rpc = MakeTestRpc();
  rpc.lat_off = std::numeric_limits<double>::infinity();
  EXPECT_THROW(rpc.Validate(), Error);
}

TEST(Rpc, ValidateRejectsZeroScaleAndZeroDenominators) {
  RpcModel rpc = MakeTestRpc();
  rpc.lon_scale = 0.0;
  try {
    rpc.Validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "LONG_SCALE");
  }
  rpc = MakeTestRpc();
  rpc.line_den = {};
  try {
    rpc.Validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "LINE_DEN_COEFF");
  }
  rpc = MakeTestRpc();
  rpc.samp_den[0] = 0.0;
  try {
    rpc.Validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "SAMP_DEN_COEFF[0]");
  }
  // A pole inside the cube: 1 + 2L changes sign at L = -0.5.
  rpc = MakeTestRpc();
  rpc.line_den = {};
  rpc.line_den[0] = 1.0;
  rpc.line_den[1] = 2.0;
  try {
    rpc.Validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "LINE_DEN_COEFF");
    EXPECT_NE(std::string(e.what()).find("vanishes"), std::string::npos) << e.what();
  }
}

TEST(Rpc, GdalMetadataRoundTripIsExact) {
  const RpcModel rpc = MakeTestRpc();
  const RpcModel back = RpcFromGdalMetadata(RpcToGdalMetadata(rpc));
  EXPECT_EQ(back.line_num, rpc.line_num);
  EXPECT_EQ(back.samp_den, rpc.samp_den);
  EXPECT_EQ(back.line_off, rpc.line_off);
  EXPECT_EQ(back.height_scale, rpc.height_scale);
}

TEST(Rpc, GdalMetadataErrorsNameTheKey) {
  auto keys = RpcToGdalMetadata(MakeTestRpc());
  auto expect_subject = [](const std::map<std::string, std::string>& k, const std::string& subject) {
    try {
      RpcFromGdalMetadata(k);
      FAIL() << "expected error about " << subject;
    } catch (const Error& e) {
      EXPECT_EQ(e.subject(), subject) << e.what();
    }
  };
  auto missing = keys;
  missing.erase("LAT_SCALE");
  expect_subject(missing, "LAT_SCALE");
  auto bad = keys;
  bad["LINE_OFF"] = "12x";
  expect_subject(bad, "LINE_OFF");
  auto short_list = keys;
  short_list["SAMP_NUM_COEFF"] = "1 2 3";
  expect_subject(short_list, "SAMP_NUM_COEFF");
  auto nan = keys;
  nan["LINE_DEN_COEFF"] = "1 nan 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
  expect_subject(nan, "LINE_DEN_COEFF[1]");
}

std::string MakeRpb(const RpcModel& rpc) {
  auto list = [](const std::array<double, 20>& c) {
    std::string s = "(\n";
    for (int i = 0; i < 20; ++i) s += "\t\t\t" + std::to_string(c[i]) + (i < 19 ? ",\n" : ");\n");
    return s;
  };
  char head[1024];
  std::snprintf(head, sizeof(head),
                "satId = \"WV03\";\nbandId = \"P\";\nSpecId = \"RPC00B\";\nBEGIN_GROUP = IMAGE\n"
                "\terrBias = 1.5;\n\terrRand = 0.2;\n\tlineOffset = %.10f;\n\tsampOffset = %.10f;\n"
                "\tlatOffset = %.10f;\n\tlongOffset = %.10f;\n\theightOffset = %.10f;\n"
                "\tlineScale = %.10f;\n\tsampScale = %.10f;\n\tlatScale = %.10f;\n"
                "\tlongScale = %.10f;\n\theightScale = %.10f;\n",
                rpc.line_off, rpc.samp_off, rpc.lat_off, rpc.lon_off, rpc.height_off,
                rpc.line_scale, rpc.samp_scale, rpc.lat_scale, rpc.lon_scale, rpc.height_scale);
  return std::string(head) + "\tlineNumCoef = " + list(rpc.line_num) +
         "\tlineDenCoef = " + list(rpc.line_den) + "\tsampNumCoef = " + list(rpc.samp_num) +
         "\tsampDenCoef = " + list(rpc.samp_den) + "END_GROUP = IMAGE\nEND;\n";
}

TEST(Rpc, ReadsDigitalGlobeRpb) {
  const RpcModel rpc = MakeTestRpc();
  const RpcModel back = RpcFromRpbText(MakeRpb(rpc));
  EXPECT_DOUBLE_EQ(back.lat_off, rpc.lat_off);
  EXPECT_DOUBLE_EQ(back.samp_off, rpc.samp_off);
  EXPECT_DOUBLE_EQ(back.err_bias_m, 1.5);
  for (int i = 0; i < 20; ++i) EXPECT_NEAR(back.line_num[i], rpc.line_num[i], 1e-6);
}

TEST(Rpc, RpbErrorsUseRpbFieldNames) {
  std::string text = MakeRpb(MakeTestRpc());
  const auto pos = text.find("\tlatScale");
  text.erase(pos, text.find('\n', pos) - pos);
  try {
    RpcFromRpbText(text);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.subject(), "latScale") << e.what();
  }
}

}  // namespace
}  // namespace skyfall
