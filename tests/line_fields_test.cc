// convert/line_fields.h: the fields of one line of a converter's source log.
#include "convert/line_fields.h"

#include <string>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

TEST(LineFields, SplitsAtEverySeparatorKeepingEmptyFields) {
  const LineFields f("log.txt", 7, "ACCE;1.5;;x\r", ';');
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f.field(0), "ACCE");
  EXPECT_EQ(f.field(2), "");
  EXPECT_EQ(f.field(3), "x");  // the '\r' of a CRLF line is dropped
  EXPECT_EQ(f.Where(), "log.txt:7: ");
  EXPECT_EQ(LineFields("a", 1, "", ',').size(), 1u);
}

TEST(LineFields, NumbersAndIntegersAllowSurroundingSpaces) {
  const LineFields f("log.txt", 2, " 1.25 ,\t-3 ,4e2", ',');
  EXPECT_EQ(*f.Number(0), 1.25);
  EXPECT_EQ(*f.Integer(1), -3);
  EXPECT_EQ(*f.Integer(2), 400);
}

TEST(LineFields, BadFieldsFailWithLineFieldAndText) {
  const LineFields f("log.txt", 9, "abc,1.5,nan", ',');
  const StatusOr<double> word = f.Number(0);
  ASSERT_FALSE(word.ok());
  EXPECT_EQ(word.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(word.status().message(), "log.txt:9: field 1 'abc' is not a finite decimal number");
  EXPECT_EQ(f.Integer(1).status().message(), "log.txt:9: field 2 '1.5' is not an integer");
  EXPECT_FALSE(f.Number(2).ok());
  EXPECT_EQ(f.Number(3).status().message(), "log.txt:9: field 4 missing");
}

TEST(LineFields, ExpectCountNamesBothAllowedCounts) {
  const LineFields f("log.txt", 3, "a,b,c", ',');
  EXPECT_TRUE(f.ExpectCount(3).ok());
  EXPECT_TRUE(f.ExpectCount(5, 3).ok());
  EXPECT_EQ(f.ExpectCount(4).message(), "log.txt:3: expected 4 fields, found 3");
  EXPECT_EQ(f.ExpectCount(4, 5).message(), "log.txt:3: expected 4 or 5 fields, found 3");
  EXPECT_EQ(f.Error("odd").message(), "log.txt:3: odd");
}

}  // namespace
}  // namespace walkgraph::internal
