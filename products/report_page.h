// OUT/report.html: the run for people who do not open a terminal. One
// self-contained page (CSS inline, images embedded as base64 PNG, no network)
// with, per city and AOI, the DSM figures against the truth (trained scene and
// dense heights alone), the error map and histogram, error against run time,
// every tile's status, time and peak memory, the automatic decisions of each
// stage with what decided them, and relative links to the products.
#pragma once

#include <string>

namespace skyfall {

// Builds the page from OUT/run_summary.json and the cities' run reports.
// Returns its path. Throws Error naming a report that cannot be read.
std::string WriteRunReportPage(const std::string& out_dir);

// Standard base64 (RFC 4648) of raw bytes.
std::string Base64(const std::string& bytes);

// Text made safe inside HTML elements and attribute values.
std::string HtmlEscape(const std::string& text);

// A relative path as a URL path: bytes other than RFC 3986's unreserved
// characters and '/' percent-encoded (users' image names may hold spaces,
// '#' or '%', which would end or garble a link).
std::string UrlPath(const std::string& path);

}  // namespace skyfall
