// util/text.h: user data quoted safely in messages, numbers readably, UTF-8 checks, and the
// one splitter, trimmer and joiner of fields.
#include "util/text.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

TEST(Quoted, QuotesAndEscapesControlAndInvalidBytes) {
  EXPECT_EQ(Quoted("abc"), "'abc'");
  EXPECT_EQ(Quoted("a\tb\x7F"), "'a\\x09b\\x7F'");
  EXPECT_EQ(Quoted("caf\xC3\xA9"), "'caf\xC3\xA9'");  // valid UTF-8 kept
  EXPECT_EQ(Quoted("x\xFFy"), "'x\\xFFy'");
  EXPECT_EQ(Quoted(std::string("a\0b", 3)), "'a\\x00b'");
}

TEST(Quoted, CutsLongTextAndNamesItsLength) {
  EXPECT_EQ(Quoted(std::string(200, 'x')),
            "'" + std::string(kMaxEchoBytes, 'x') + "'... (200 bytes)");
  EXPECT_EQ(Quoted("abcdef", 3), "'abc'... (6 bytes)");
  EXPECT_EQ(QuotedNumber(std::string(30, '9')), "'" + std::string(24, '9') + "'... (30 bytes)");
}

TEST(Num, SixSignificantDigits) {
  EXPECT_EQ(Num(1.0), "1");
  EXPECT_EQ(Num(0.1234567), "0.123457");
  EXPECT_EQ(Num(1e300), "1e+300");
  EXPECT_EQ(Num(-2.5), "-2.5");
}

TEST(Num, SignificantDigitsOnRequest) {
  EXPECT_EQ(Num(0.1234567, 6), Num(0.1234567));
  EXPECT_EQ(Num(0.12345678901234, 10), "0.123456789");
  EXPECT_EQ(Num(1234567890123.0, 10), "1.23456789e+12");
  EXPECT_EQ(Num(2.0, 10), "2");
}

TEST(Fixed, DecimalsAfterThePoint) {
  EXPECT_EQ(Fixed(0.5, 2), "0.50");
  EXPECT_EQ(Fixed(2.0, 0), "2");
  EXPECT_EQ(Fixed(-1.23456, 3), "-1.235");
  EXPECT_EQ(Fixed(1e6, 1), "1000000.0");
}

TEST(ExactNum, ShortestTextThatReadsBack) {
  EXPECT_EQ(ExactNum(0.1), "0.1");
  EXPECT_EQ(ExactNum(2.0), "2");
  EXPECT_EQ(ExactNum(-1.5), "-1.5");
  EXPECT_EQ(ExactNum(1e-7), "1e-07");
  EXPECT_EQ(ExactNum(0.1 + 0.2), "0.30000000000000004");  // every digit the double needs
  for (const double v : {1.0 / 3.0, 123456.789e10, -2.2250738585072014e-308}) {
    EXPECT_EQ(std::stod(ExactNum(v)), v) << ExactNum(v);
  }
}

TEST(Split, KeepsEveryFieldAsItIs) {
  using V = std::vector<std::string>;
  EXPECT_EQ(Split("a,b,c", ','), (V{"a", "b", "c"}));
  EXPECT_EQ(Split("a,,b", ','), (V{"a", "", "b"}));
  EXPECT_EQ(Split("", ','), (V{""}));
  EXPECT_EQ(Split(",", ','), (V{"", ""}));
  EXPECT_EQ(Split(" a ;b", ';'), (V{" a ", "b"}));  // spaces kept: Trim is separate
  EXPECT_EQ(Split("a b", ','), (V{"a b"}));
}

TEST(Trim, SpacesAndTabsOnly) {
  EXPECT_EQ(Trim("  a b\t"), "a b");
  EXPECT_EQ(Trim(" \t "), "");
  EXPECT_EQ(Trim(""), "");
  EXPECT_EQ(Trim("\ra\n"), "\ra\n");  // other white space is data
}

TEST(Join, SeparatorBetweenEachTwo) {
  EXPECT_EQ(Join({}, ", "), "");
  EXPECT_EQ(Join({"a"}, ", "), "a");
  EXPECT_EQ(Join({"t_s", "x_m", "y_m"}, ","), "t_s,x_m,y_m");
  EXPECT_EQ(Join({"", "b"}, ","), ",b");
}

TEST(Utf8, ValidityAndRepair) {
  EXPECT_TRUE(IsValidUtf8(""));
  EXPECT_TRUE(IsValidUtf8("plain \xC3\xA9 \xE2\x82\xAC \xF0\x9F\x99\x82"));
  EXPECT_FALSE(IsValidUtf8("\xC0\xAF"));          // overlong '/'
  EXPECT_FALSE(IsValidUtf8("\xED\xA0\x80"));      // a surrogate
  EXPECT_FALSE(IsValidUtf8("\xE2\x82"));          // cut short
  EXPECT_FALSE(IsValidUtf8("\xF4\x90\x80\x80"));  // above U+10FFFF
  EXPECT_EQ(ToValidUtf8("a\xFF"
                        "b\xC3\xA9"),
            "a?b\xC3\xA9");
  EXPECT_EQ(ToValidUtf8("\xE2\x82"), "??");
}

}  // namespace
}  // namespace walkgraph::internal
