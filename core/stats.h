// Order statistics shared by the stages (robust thresholds, error reports).
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace skyfall {

// The element of rank floor(p * n) (0 <= p < 1) of `values` (by value: the
// copy is partially reordered); T{} for an empty sample.
template <typename T>
T Quantile(std::vector<T> values, double p) {
  if (values.empty()) return T{};
  const std::size_t k = std::min(values.size() - 1, static_cast<std::size_t>(p * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// The upper median (rank n / 2); T{} for an empty sample.
template <typename T>
T Median(std::vector<T> values) {
  return Quantile(std::move(values), 0.5);
}

}  // namespace skyfall
