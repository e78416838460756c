// The contract every fuzz target checks: a parser of outside input either
// returns or throws skyfall::Error (a message naming the file and field).
// Anything else (another exception, a crash, a sanitizer report, a hang,
// unbounded memory) is a bug that libFuzzer reports.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.h"

namespace skyfall::fuzz {

// Runs `parse` on the input; swallows only skyfall::Error.
template <class F>
void Expect(F&& parse) {
  try {
    parse();
  } catch (const skyfall::Error&) {
  }
}

inline std::string Text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace skyfall::fuzz
