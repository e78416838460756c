// Modes as enums with one string codec each. A mode's names are listed once,
// beside its enum, as a specialization of EnumNames; the option registry
// writes and reads them, the CLI offers them, and code compares enums, never
// strings.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace skyfall {

// Specialize for each mode: static constexpr std::array<std::pair<E, const
// char*>, N> kNames = {...};
template <class E>
struct EnumNames;

template <class E>
const char* EnumName(E value) {
  for (const auto& [e, name] : EnumNames<E>::kNames)
    if (e == value) return name;
  return "?";
}

template <class E>
std::optional<E> EnumFromName(std::string_view name) {
  for (const auto& [e, n] : EnumNames<E>::kNames)
    if (name == n) return e;
  return std::nullopt;
}

template <class E>
std::vector<std::string> EnumNameList() {
  std::vector<std::string> names;
  for (const auto& entry : EnumNames<E>::kNames) names.emplace_back(entry.second);
  return names;
}

// "'auto', 'on' or 'off'", for messages and help.
template <class E>
std::string EnumChoices() {
  const std::vector<std::string> names = EnumNameList<E>();
  std::string out;
  for (std::size_t k = 0; k < names.size(); ++k)
    out += (k == 0 ? "" : k + 1 == names.size() ? " or " : ", ") + ("'" + names[k] + "'");
  return out;
}

// The mode of a stage that can be asked for or left to the data.
enum class Switch { kAuto, kOn, kOff };
template <>
struct EnumNames<Switch> {
  static constexpr std::array<std::pair<Switch, const char*>, 3> kNames = {
      {{Switch::kAuto, "auto"}, {Switch::kOn, "on"}, {Switch::kOff, "off"}}};
};

}  // namespace skyfall
