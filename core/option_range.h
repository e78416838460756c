// What values an option may take, declared once beside the option in its
// struct's Visit(), and the range check every options struct derives from
// it. A Visit() names each field: io(key, field, help, range); the option
// registry (pipeline/option_registry.h) visits the same functions to write
// and read JSON, describe the options and prove itself complete.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "core/error.h"

namespace skyfall {

// The values a numeric option takes, declared with it in the registry: an
// interval whose ends may be open, or a set of values; optionally one more
// value outside the interval (0 = automatic) and odd integers only. A
// ranged value must also be finite. CheckOptionRanges() checks every value against
// its range, naming the option's dotted path; each struct's Check() calls it
// before its own checks (which keep what involves two fields).
struct OptionRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false, max_open = false;
  std::vector<double> values;  // when not empty: exactly one of these
  std::optional<double> also;  // accepted besides the interval
  std::string also_means;      // what `also` stands for, e.g. "automatic"
  bool odd = false;
  bool Declared() const;  // false for the default: any value
  bool Contains(double value) const;
  std::string Text() const;  // ">= 1", "in (0, 1]", "8 or 16", "odd, >= 3", ">= 16, or 0 (automatic)"
};
// Ranges as the registry writes them.
namespace range {
OptionRange AtLeast(double min);                // [min, inf)
OptionRange Above(double min);                  // (min, inf)
OptionRange In(double min, double max);         // [min, max]
OptionRange Inside(double min, double max);     // (min, max)
OptionRange AboveUpTo(double min, double max);  // (min, max]
OptionRange FromBelow(double min, double max);  // [min, max)
OptionRange OneOf(std::vector<double> values);
OptionRange Odd(OptionRange r);
OptionRange Or(OptionRange r, double also, const char* means);
}  // namespace range

// A field the visitors treat as one value, not as a section to descend into.
template <class T>
constexpr bool kIsOptionLeaf = std::is_arithmetic_v<T> || std::is_enum_v<T> || std::is_same_v<T, std::string> ||
                               std::is_same_v<T, Eigen::Vector3d>;

// Throws Error(component, dotted path, "<value> must be <range>") for the
// first numeric field of `options` (sections included) outside its declared
// range. `Visit(io, T&)` must be found by argument-dependent lookup.
[[noreturn]] void ThrowOutOfRange(const std::string& component, const std::string& path, double value,
                                  const OptionRange& range);

class OptionRangeChecker {
 public:
  OptionRangeChecker(std::string component, std::string path)
      : component_(std::move(component)), path_(std::move(path)) {}
  template <class T>
  void operator()(const char* key, T& value, const char* /*help*/ = nullptr, const OptionRange& range = {}) {
    const std::string path = path_.empty() ? key : path_ + "." + key;
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      Need(path, static_cast<double>(value), range);
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      for (int k = 0; k < 3; ++k) Need(path + "[" + std::to_string(k) + "]", value[k], range);
    } else if constexpr (!kIsOptionLeaf<T>) {
      OptionRangeChecker inner(component_, path);
      Visit(inner, value);
    }
  }
  template <class T>
  void NotAnOption(const T&) {}

 private:
  void Need(const std::string& path, double value, const OptionRange& range) const {
    if (range.Declared() && !range.Contains(value)) ThrowOutOfRange(component_, path, value, range);
  }
  std::string component_, path_;
};

// `path` is the dotted path of `options` inside its component's options
// ("orbit" for idu.orbit), put in front of the field's name.
template <class T>
void CheckOptionRanges(const T& options, const std::string& component, const std::string& path = "") {
  OptionRangeChecker checker(component, path);
  Visit(checker, const_cast<T&>(options));  // the checker only reads
}

}  // namespace skyfall
