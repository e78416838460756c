// Number formatting shared by messages and text outputs.
#pragma once

#include <string>

namespace skyfall {

// Shortest text that reads back to exactly the same double ("%.17g"), so
// coordinates printed by the CLI or written to metadata lose nothing.
std::string FormatDouble(double value);

}  // namespace skyfall
