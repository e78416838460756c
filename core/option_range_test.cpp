#include "core/option_range.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace skyfall {
namespace {

struct InnerOptions {
  int window = 3;
  double weight = 0.5;
};
template <class IO> void Visit(IO& io, InnerOptions& o) {
  io("window", o.window, "odd window", range::Odd(range::AtLeast(3)));
  io("weight", o.weight, "a fraction", range::In(0, 1));
}
struct OuterOptions {
  double cell_m = 0;  // 0 = automatic
  Eigen::Vector3d colour{0.1, 0.2, 0.3};
  std::string name = "free";
  bool flag = true;
  InnerOptions inner;
  double unranged = -1e300;
};
template <class IO> void Visit(IO& io, OuterOptions& o) {
  io("cell_m", o.cell_m, "cell", range::Or(range::Above(0), 0, "automatic"));
  io("colour", o.colour, "rgb", range::In(0, 1));
  io("name", o.name, "any text");
  io("flag", o.flag, "a switch");
  io("inner", o.inner);
  io("unranged", o.unranged, "any finite or infinite number");
}

// The message of the Error CheckOptionRanges throws, or "" when it passes.
std::string RangeError(const OuterOptions& o, const std::string& path = "") {
  try {
    CheckOptionRanges(o, "test", path);
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return "";
}

TEST(OptionRange, DefaultsPassAndTheAlsoValueIsAccepted) {
  OuterOptions o;
  EXPECT_EQ(RangeError(o), "");  // cell_m 0 lies outside (0, inf) but is the declared "automatic"
  o.cell_m = 0.5;
  EXPECT_EQ(RangeError(o), "");
}

TEST(OptionRange, AValueOutsideItsRangeIsNamedByItsDottedPath) {
  OuterOptions o;
  o.cell_m = -1;
  EXPECT_NE(RangeError(o).find("cell_m"), std::string::npos);
  EXPECT_NE(RangeError(o).find("> 0, or 0 (automatic)"), std::string::npos) << RangeError(o);
  o = {};
  o.inner.weight = 1.5;
  EXPECT_NE(RangeError(o, "section").find("section.inner.weight"), std::string::npos) << RangeError(o, "section");
  o = {};
  o.inner.window = 4;  // even
  EXPECT_NE(RangeError(o).find("inner.window"), std::string::npos);
  o = {};
  o.colour.z() = 2;
  EXPECT_NE(RangeError(o).find("colour[2]"), std::string::npos) << RangeError(o);
}

TEST(OptionRange, NonFiniteValuesFailARange) {
  OuterOptions o;
  o.inner.weight = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(RangeError(o).find("inner.weight"), std::string::npos);
  o = {};
  o.cell_m = std::numeric_limits<double>::infinity();
  EXPECT_NE(RangeError(o).find("cell_m"), std::string::npos);
  o = {};
  o.unranged = std::numeric_limits<double>::infinity();  // no declared range: anything goes
  EXPECT_EQ(RangeError(o), "");
}

TEST(OptionRange, TextSaysTheRangeAsTheMessagesDo) {
  EXPECT_EQ(range::AtLeast(1).Text(), ">= 1");
  EXPECT_EQ(range::AboveUpTo(0, 1).Text(), "in (0, 1]");
  EXPECT_EQ(range::OneOf({8, 16}).Text(), "8 or 16");
  EXPECT_EQ(range::Odd(range::AtLeast(3)).Text(), "odd, >= 3");
  EXPECT_FALSE(OptionRange{}.Declared());
  EXPECT_TRUE(range::FromBelow(0, 1).Contains(0));
  EXPECT_FALSE(range::FromBelow(0, 1).Contains(1));
  EXPECT_FALSE(range::Inside(0, 1).Contains(0));
}

}  // namespace
}  // namespace skyfall
