// util/text_spill.h: text kept in an anonymous temporary file and copied out whole.
#include "util/text_spill.h"

#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

TEST(TextSpill, CopiesOutEverythingAppendedInOrder) {
  TextSpill spill;
  ASSERT_TRUE(spill.status().ok()) << spill.status().message();
  spill.Append("a,b\n");
  spill.Append([](std::ostream& out) { out << 1 << ',' << 2.5 << '\n'; });
  spill.Append("");
  std::ostringstream first;
  ASSERT_TRUE(spill.CopyTo(first).ok());
  EXPECT_EQ(first.str(), "a,b\n1,2.5\n");
  // Appends after a copy go to the end; a second copy holds everything.
  spill.Append(std::string(100000, 'x'));
  std::ostringstream second;
  ASSERT_TRUE(spill.CopyTo(second).ok());
  EXPECT_EQ(second.str(), "a,b\n1,2.5\n" + std::string(100000, 'x'));
}

TEST(TextSpill, EmptySpillCopiesNothing) {
  TextSpill spill;
  std::ostringstream out;
  ASSERT_TRUE(spill.CopyTo(out).ok());
  EXPECT_EQ(out.str(), "");
}

}  // namespace
}  // namespace walkgraph::internal
