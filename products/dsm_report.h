// Products of a DSM comparison: report.json and report.csv (metrics), the
// error map as a GeoTIFF and as a coloured PNG with a legend, and a PNG
// histogram of the signed errors.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "products/dsm.h"

namespace skyfall {

struct DsmReportInputs {
  std::string prediction_path;
  std::string truth_path;
  std::string cls_path;  // may be empty
};

// {"by_class": [...], "building_rims": {...}, "building_edge_profile": {...}}:
// the breakdown as report.json has it.
nlohmann::json DsmBreakdownJson(const DsmBreakdown& breakdown);

// report.json (with the breakdown when the truth came with classes, and then
// also report_by_class.csv), report.csv, the error map and the histogram.
void WriteDsmComparison(const DsmComparison& result, const DsmGrid& truth_grid, const DsmCompareOptions& options,
                        const DsmReportInputs& inputs, const std::string& out_dir);

}  // namespace skyfall
