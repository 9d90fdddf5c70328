// util/text.h: user data quoted safely in messages, numbers readably, UTF-8 checks.
#include "util/text.h"

#include <string>

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
