// Products of a DSM comparison: report.json and report.csv (metrics), the
// error map as a GeoTIFF and as a coloured PNG with a legend, and a PNG
// histogram of the signed errors.
#pragma once

#include <string>

#include "merge/dsm.h"

namespace skyfall {

struct DsmReportInputs {
  std::string prediction_path;
  std::string truth_path;
  std::string cls_path;  // may be empty
};

void WriteDsmComparison(const DsmComparison& result, const DsmGrid& truth_grid, const DsmCompareOptions& options,
                        const DsmReportInputs& inputs, const std::string& out_dir);

}  // namespace skyfall
