// Little-endian byte writing for the binary formats products/ writes by hand
// (LAS/LAZ headers, records and chunks).
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>

namespace skyfall {

// Appends `value`'s bytes, least significant first.
template <typename T>
void PutLe(std::string* out, T value) {
  static_assert(std::is_unsigned_v<T>);
  for (std::size_t b = 0; b < sizeof(T); ++b) out->push_back(static_cast<char>((value >> (8 * b)) & 0xff));
}

// An IEEE double as its 8 bytes, least significant first.
inline void PutLe(std::string* out, double value) {
  std::uint64_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  PutLe(out, bits);
}

}  // namespace skyfall
