#include "testcity/acquisition.h"

#include <cmath>
#include <cstdio>

namespace skyfall::synth {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Sun-synchronous imaging satellites (WorldView-3 among them) pass at about
// 10:30 local solar time. The passes of every date fall at 10:28-10:57 local
// mean solar time: 15:55-16:24 UTC at the default longitude (Jacksonville,
// as the DFC2019 scenes), earlier or later elsewhere, so that a city far
// east or west is not imaged at night.
constexpr double kPassReferenceLonDeg = -81.6637;

}  // namespace

// Howard Hinnant's days-to-civil algorithm.
void CivilFromDays(long z, int* y, int* m, int* d) {
  z += 719468;
  const long era = (z >= 0 ? z : z - 146096) / 146097;
  const long doe = z - era * 146097;
  const long yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const long doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const long mp = (5 * doy + 2) / 153;
  *d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  *m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  *y = static_cast<int>(yoe + era * 400 + (*m <= 2));
}

Acquisition MakeAcquisition(int date_index, int shot_in_pass, double lon_deg) {
  const long days_2015_01_15 = 16450;  // 2015-01-15
  constexpr long kMinutesPerDay = 24 * 60;
  const long minute_at_reference = 15 * 60 + 55 + (date_index * 7) % 30;
  // The sun's local time advances 4 minutes per degree of longitude east.
  // Counted in minutes since 1970 (always positive here), the pass carries
  // into the day before or after by plain division.
  const long utc_minutes = (days_2015_01_15 + 41L * date_index) * kMinutesPerDay + minute_at_reference -
                           std::lround(4.0 * (lon_deg - kPassReferenceLonDeg));
  const long day = utc_minutes / kMinutesPerDay, utc_minute = utc_minutes % kMinutesPerDay;
  int y, m, d;
  CivilFromDays(day, &y, &m, &d);
  const int second = 11 * shot_in_pass;
  const int hh = static_cast<int>(utc_minute / 60), mm = static_cast<int>(utc_minute % 60);
  char compact[64], iso[64];
  std::snprintf(compact, sizeof(compact), "%04d%02d%02d%02d%02d%02d", y, m, d, hh, mm, second);
  std::snprintf(iso, sizeof(iso), "%04d-%02d-%02dT%02d:%02d:%02dZ", y, m, d, hh, mm, second);
  Acquisition a;
  a.compact = compact;
  a.iso = iso;
  a.day_of_year = static_cast<int>((day - 16436) % 365) + 1;  // 16436 = 2015-01-01; leap days ignored
  a.utc_hours = hh + mm / 60.0 + second / 3600.0;
  return a;
}

void SunPosition(double lat_deg, double lon_deg, const Acquisition& a, double* elevation_deg,
                 double* azimuth_deg) {
  const double decl = -23.44 * kDegToRad * std::cos(2 * M_PI / 365.0 * (a.day_of_year + 10));
  const double solar_hours = a.utc_hours + lon_deg / 15.0;
  const double hour_angle = 15.0 * (solar_hours - 12.0) * kDegToRad;
  const double lat = lat_deg * kDegToRad;
  const double sin_el = std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(hour_angle);
  *elevation_deg = std::asin(sin_el) / kDegToRad;
  double az = std::atan2(-std::sin(hour_angle),
                         std::tan(decl) * std::cos(lat) - std::sin(lat) * std::cos(hour_angle));
  az = az / kDegToRad;
  *azimuth_deg = az < 0 ? az + 360 : az;
}

}  // namespace skyfall::synth
