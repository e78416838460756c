// When the test city's images are taken and where the sun stands then:
// dates, times of day and solar angles of the synthetic passes.
#pragma once

#include <string>

namespace skyfall::synth {

struct Acquisition {
  std::string compact;     // YYYYMMDDhhmmss (NITF IDATIM), UTC
  std::string iso;         // YYYY-MM-DDThh:mm:ssZ
  int day_of_year = 1;     // 1-based; leap days ignored
  double utc_hours = 16.0;
};

// Days since 1970-01-01 -> proleptic Gregorian civil date.
void CivilFromDays(long days, int* year, int* month, int* day);

// Shot `shot_in_pass` (0-based, 11 s apart) of the pass on date
// `date_index` (0-based, 41 days apart from 2015-01-15) over longitude
// `lon_deg`: sun-synchronous passes at 10:28-10:57 local mean solar time.
Acquisition MakeAcquisition(int date_index, int shot_in_pass, double lon_deg);

// Approximate solar elevation and azimuth (clockwise from north) [deg], from
// declination and hour angle without the equation of time: good to a degree
// or two, plenty for plausible shadows.
void SunPosition(double lat_deg, double lon_deg, const Acquisition& a, double* elevation_deg, double* azimuth_deg);

}  // namespace skyfall::synth
