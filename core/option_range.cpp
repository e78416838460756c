#include "core/option_range.h"

#include <algorithm>
#include <cmath>

#include "core/format.h"

namespace skyfall {

void ThrowOutOfRange(const std::string& component, const std::string& path, double value, const OptionRange& range) {
  throw Error(component, path, FormatDouble(value) + " must be " + range.Text());
}

bool OptionRange::Declared() const {
  return std::isfinite(min) || std::isfinite(max) || !values.empty() || odd;
}

bool OptionRange::Contains(double v) const {
  if (!std::isfinite(v)) return false;
  if (also && v == *also) return true;
  if (!values.empty()) return std::find(values.begin(), values.end(), v) != values.end();
  if (odd && std::fmod(std::abs(v), 2.0) != 1.0) return false;
  return (min_open ? v > min : v >= min) && (max_open ? v < max : v <= max);
}

std::string OptionRange::Text() const {
  std::string text;
  if (!values.empty()) {
    for (std::size_t k = 0; k < values.size(); ++k)
      text += (k == 0 ? "" : k + 1 == values.size() ? " or " : ", ") + FormatDouble(values[k]);
    return text;
  }
  if (odd) text = "odd, ";
  if (std::isfinite(min) && std::isfinite(max)) {
    text += "in " + std::string(min_open ? "(" : "[") + FormatDouble(min) + ", " + FormatDouble(max) +
            (max_open ? ")" : "]");
  } else if (std::isfinite(min)) {
    text += (min_open ? "> " : ">= ") + FormatDouble(min);
  } else if (std::isfinite(max)) {
    text += (max_open ? "< " : "<= ") + FormatDouble(max);
  } else {
    text += "finite";
  }
  if (also) text += ", or " + FormatDouble(*also) + (also_means.empty() ? "" : " (" + also_means + ")");
  return text;
}

namespace range {
namespace {
OptionRange Interval(double min, bool min_open, double max, bool max_open) {
  OptionRange r;
  r.min = min;
  r.max = max;
  r.min_open = min_open;
  r.max_open = max_open;
  return r;
}
}  // namespace
constexpr double kInf = std::numeric_limits<double>::infinity();
OptionRange AtLeast(double min) { return Interval(min, false, kInf, false); }
OptionRange Above(double min) { return Interval(min, true, kInf, false); }
OptionRange In(double min, double max) { return Interval(min, false, max, false); }
OptionRange Inside(double min, double max) { return Interval(min, true, max, true); }
OptionRange AboveUpTo(double min, double max) { return Interval(min, true, max, false); }
OptionRange FromBelow(double min, double max) { return Interval(min, false, max, true); }
OptionRange OneOf(std::vector<double> values) {
  OptionRange r;
  r.values = std::move(values);
  return r;
}
OptionRange Odd(OptionRange r) {
  r.odd = true;
  return r;
}
OptionRange Or(OptionRange r, double also, const char* means) {
  r.also = also;
  r.also_means = means;
  return r;
}
}  // namespace range

}  // namespace skyfall
