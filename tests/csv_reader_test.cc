// util/csv_reader.h: the walk format's strict numeric CSV reader and its field helpers.
#include "util/csv_reader.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

namespace fs = std::filesystem;

class CsvReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("wg_csv_reader_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& text) {
    const std::string path = (dir_ / "imu.csv").string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  fs::path dir_;
};

TEST(ParseFiniteDouble, AcceptsDecimalNumbers) {
  double v = 0.0;
  for (const auto& [text, value] :
       std::vector<std::pair<std::string, double>>{{"0", 0.0},
                                                   {"-1.5", -1.5},
                                                   {"+2", 2.0},
                                                   {".25", 0.25},
                                                   {"3.", 3.0},
                                                   {"1e3", 1000.0},
                                                   {"-2.5E-2", -0.025},
                                                   {"1e-320", 1e-320}}) {
    EXPECT_TRUE(ParseFiniteDouble(text, &v)) << text;
    EXPECT_EQ(v, value) << text;
  }
}

TEST(ParseFiniteDouble, RefusesWhatIsNotAFiniteDecimalNumber) {
  double v = 7.0;
  for (const char* text : {"", " 1", "1 ", "abc", "1,5", "0x5", "0x1p3", "nan", "NaN", "inf",
                           "-Infinity", "1e", "1e+", ".", "-", "+.e1", "1e400", "1.2.3"}) {
    EXPECT_FALSE(ParseFiniteDouble(text, &v)) << text;
  }
  EXPECT_EQ(v, 7.0);  // untouched on failure
}

TEST(SplitCsvLine, SplitsAtEveryCommaAndTrimsSpaces) {
  EXPECT_EQ(SplitCsvLine("a, b ,\tc"), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(SplitCsvLine(",,"), (std::vector<std::string>{"", "", ""}));
  EXPECT_EQ(SplitCsvLine(""), (std::vector<std::string>{""}));
}

TEST(StripCarriageReturn, RemovesOneTrailingCarriageReturn) {
  std::string line = "1,2\r";
  StripCarriageReturn(&line);
  EXPECT_EQ(line, "1,2");
  StripCarriageReturn(&line);
  EXPECT_EQ(line, "1,2");
}

TEST_F(CsvReaderTest, ReadsRowsOfTheRequiredColumns) {
  CsvReader r(Write("\xEF\xBB\xBFt,x\r\n0,1.5\r\n0.1,-2\n"), {"t", "x"});
  ASSERT_TRUE(r.Open().ok());
  EXPECT_EQ(r.num_columns(), 2u);
  EXPECT_EQ(r.Column("x"), 1);
  EXPECT_EQ(r.Column("y"), -1);
  std::vector<double> f;
  ASSERT_TRUE(*r.Next(&f));
  EXPECT_EQ(f, (std::vector<double>{0.0, 1.5}));
  ASSERT_TRUE(*r.Next(&f));
  EXPECT_EQ(f, (std::vector<double>{0.1, -2.0}));
  EXPECT_FALSE(*r.Next(&f));
}

TEST_F(CsvReaderTest, OptionalColumnsComeAllOrNone) {
  CsvReader with(Write("t,x,y\n1,2,3\n"), {"t"}, {"x", "y"});
  ASSERT_TRUE(with.Open().ok());
  EXPECT_EQ(with.num_columns(), 3u);
  CsvReader part(Write("t,x\n1,2\n"), {"t"}, {"x", "y"});
  const Status s = part.Open();
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find(":1: header is 't,x'; expected 't' or 't,x,y'"), std::string::npos)
      << s.message();
}

TEST_F(CsvReaderTest, AcceptsAnyOneOfSeveralHeaders) {
  CsvReader r(Write("t,b\n1,2\n"), CsvHeaders{{{"t", "a"}, {"t", "b"}}});
  ASSERT_TRUE(r.Open().ok());
  EXPECT_EQ(r.Column("b"), 1);
}

TEST_F(CsvReaderTest, EmptyFileNamesTheExpectedHeader) {
  CsvReader r(Write(""), {"t", "x"});
  const Status s = r.Open();
  EXPECT_NE(s.message().find(":1: empty file; expected the header line 't,x'"), std::string::npos)
      << s.message();
}

TEST_F(CsvReaderTest, BadRowsFailWithTheLineAndColumn) {
  std::vector<double> f;
  CsvReader count(Write("t,x\n1,2\n3\n"), {"t", "x"});
  ASSERT_TRUE(count.Open().ok());
  ASSERT_TRUE(*count.Next(&f));
  StatusOr<bool> s = count.Next(&f);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find(":3: expected 2 comma-separated columns, found 1"),
            std::string::npos)
      << s.status().message();

  CsvReader number(Write("t,x\n1,nan\n"), {"t", "x"});
  ASSERT_TRUE(number.Open().ok());
  s = number.Next(&f);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find(":2: column 'x': expected a finite decimal number, found "
                                      "'nan'"),
            std::string::npos)
      << s.status().message();
}

TEST_F(CsvReaderTest, OneTrailingEmptyLineEndsTheFileButNotOneInside) {
  std::vector<double> f;
  CsvReader end(Write("t\n1\n\n"), {"t"});
  ASSERT_TRUE(end.Open().ok());
  ASSERT_TRUE(*end.Next(&f));
  EXPECT_FALSE(*end.Next(&f));

  CsvReader inside(Write("t\n1\n\n2\n"), {"t"});
  ASSERT_TRUE(inside.Open().ok());
  ASSERT_TRUE(*inside.Next(&f));
  const StatusOr<bool> s = inside.Next(&f);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find(":3: empty line inside the data"), std::string::npos)
      << s.status().message();
}

}  // namespace
}  // namespace walkgraph::internal
