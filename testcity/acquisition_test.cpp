#include "testcity/acquisition.h"

#include <gtest/gtest.h>

#include <cmath>

namespace skyfall::synth {
namespace {

struct CivilDate {
  int y, m, d;
};

CivilDate Civil(long days) {
  CivilDate c{};
  CivilFromDays(days, &c.y, &c.m, &c.d);
  return c;
}

TEST(Acquisition, CivilDatesAcrossEpochsAndLeapDays) {
  const struct {
    long days;
    CivilDate want;
  } cases[] = {{0, {1970, 1, 1}},     {-1, {1969, 12, 31}},  {16450, {2015, 1, 15}},
               {11016, {2000, 2, 29}}, {11017, {2000, 3, 1}}, {-25508, {1900, 3, 1}}};
  for (const auto& c : cases) {
    const CivilDate got = Civil(c.days);
    EXPECT_EQ(got.y, c.want.y) << c.days;
    EXPECT_EQ(got.m, c.want.m) << c.days;
    EXPECT_EQ(got.d, c.want.d) << c.days;
  }
}

TEST(Acquisition, PassesAreDatedAndTimedAsDocumented) {
  const Acquisition first = MakeAcquisition(0, 0, -81.6637);
  EXPECT_EQ(first.compact, "20150115155500");
  EXPECT_EQ(first.iso, "2015-01-15T15:55:00Z");
  EXPECT_EQ(first.day_of_year, 15);
  // The third shot of a pass is 22 s later; the next date is 41 days on and 7 minutes later.
  EXPECT_EQ(MakeAcquisition(0, 2, -81.6637).iso, "2015-01-15T15:55:22Z");
  EXPECT_EQ(MakeAcquisition(1, 0, -81.6637).iso, "2015-02-25T16:02:00Z");
}

TEST(Acquisition, EveryLongitudeIsImagedInTheLateMorning) {
  // Local mean solar time stays where it is at the reference longitude
  // (15:55-16:24 UTC at -81.6637 deg: 628.345-657.345 minutes after local
  // midnight) wherever the city is, the pass carrying into the previous or
  // next UTC day where it must. Dates 0-29 cover every minute offset.
  constexpr double kFirstLocalMin = 15 * 60 + 55 - 81.6637 * 4, kLastLocalMin = kFirstLocalMin + 29;
  constexpr double kRoundingMin = 0.5;  // the 4 minutes per degree are rounded to a minute
  for (double lon_deg : {-179.9, -81.6637, 0.0, 98.3363, 179.9}) {
    for (int date = 0; date < 30; ++date) {
      const Acquisition a = MakeAcquisition(date, 0, lon_deg);
      const double local_min = std::fmod(60 * a.utc_hours + 4 * lon_deg + 2 * 1440.0, 1440.0);
      EXPECT_GE(local_min, kFirstLocalMin - kRoundingMin) << lon_deg << " " << a.iso;
      EXPECT_LE(local_min, kLastLocalMin + kRoundingMin) << lon_deg << " " << a.iso;
    }
  }
  // 180 degrees east of the reference: 12 hours earlier in UTC, same day.
  EXPECT_EQ(MakeAcquisition(0, 0, 98.3363).iso, "2015-01-15T03:55:00Z");
}

TEST(Acquisition, SunPositionAtNoonAndInTheMorning) {
  // The model has no equation of time and a cosine declination, good to
  // about 1 degree; 1.5 degrees of tolerance.
  constexpr double kSunToleranceDeg = 1.5;
  Acquisition equinox;
  equinox.day_of_year = 80;  // about 21 March: declination near 0
  equinox.utc_hours = 12.0;
  double el = 0, az = 0;
  SunPosition(0.0, 0.0, equinox, &el, &az);
  EXPECT_NEAR(el, 90.0, kSunToleranceDeg);
  // At 45 N on the equinox's noon the sun stands 45 degrees high, due south.
  SunPosition(45.0, 0.0, equinox, &el, &az);
  EXPECT_NEAR(el, 45.0, kSunToleranceDeg);
  EXPECT_NEAR(az, 180.0, kSunToleranceDeg);
  // Mid-morning: south-east and lower.
  Acquisition morning = equinox;
  morning.utc_hours = 9.0;
  SunPosition(45.0, 0.0, morning, &el, &az);
  EXPECT_GT(az, 90.0);
  EXPECT_LT(az, 180.0);
  EXPECT_GT(el, 0.0);
  EXPECT_LT(el, 45.0);
  // Mid-winter at the default city: the low January sun stays below 40 degrees.
  SunPosition(30.3488, -81.6637, MakeAcquisition(0, 0, -81.6637), &el, &az);
  EXPECT_GT(el, 20.0);
  EXPECT_LT(el, 40.0);
}

}  // namespace
}  // namespace skyfall::synth
