// convert/text_table.h: whitespace- or comma-separated numeric tables of other people's files.
#include "convert/text_table.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

namespace fs = std::filesystem;

class TextTableTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = (fs::temp_directory_path() /
             ("wg_text_table_test_" + std::to_string(::getpid()) + "_" +
              ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".txt"))
                .string();
  }
  void TearDown() override { fs::remove(path_); }
  const std::string& Write(const std::string& text) {
    std::ofstream(path_, std::ios::binary) << text;
    return path_;
  }
  std::string path_;
};

TEST_F(TextTableTest, ReadsMixedSeparatorsAndSkipsBlankLines) {
  const StatusOr<TextTable> t = ReadTextTable(Write("t x y\n0, 1\t2\n\n0.5 -1 3e1\r\n"), 3, true);
  ASSERT_TRUE(t.ok()) << t.status().message();
  EXPECT_EQ(t->header, (std::vector<std::string>{"t", "x", "y"}));
  ASSERT_EQ(t->rows.size(), 2u);
  EXPECT_EQ(t->rows[0], (std::vector<double>{0.0, 1.0, 2.0}));
  EXPECT_EQ(t->rows[1], (std::vector<double>{0.5, -1.0, 30.0}));
  EXPECT_EQ(t->line_numbers, (std::vector<int>{2, 4}));
}

TEST_F(TextTableTest, WithoutHeaderEveryLineIsData) {
  const StatusOr<TextTable> t = ReadTextTable(Write("1 2\n3 4\n"), 2, false);
  ASSERT_TRUE(t.ok()) << t.status().message();
  EXPECT_TRUE(t->header.empty());
  EXPECT_EQ(t->rows.size(), 2u);
}

TEST_F(TextTableTest, FailsWithTheLineOfTheFirstBadRow) {
  EXPECT_EQ(ReadTextTable(Write("a b\n1 2\n"), 3, true).status().message(),
            path_ + ":1: header has 2 columns; expected 3");
  EXPECT_EQ(ReadTextTable(Write("1 2\n3\n"), 2, false).status().message(),
            path_ + ":2: expected 2 numeric columns, found 1");
  EXPECT_EQ(ReadTextTable(Write("1 2\n3 0x4\n"), 2, false).status().message(),
            path_ + ":2: column 2: expected a finite decimal number, found '0x4'");
  EXPECT_EQ(ReadTextTable(Write("a b\n\n"), 2, true).status().message(), path_ + ": no data rows");
  EXPECT_EQ(ReadTextTable(path_ + ".missing", 2, false).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace walkgraph::internal
