// util/input_file.h: what the readers open (regular files only) and how lines are read.
#include "util/input_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace walkgraph::internal {
namespace {

namespace fs = std::filesystem;

class InputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("wg_input_file_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(InputFileTest, CheckInputFileNamesWhatIsThereInstead) {
  EXPECT_TRUE(CheckInputFile(Write("a.txt", "x")).ok());
  EXPECT_EQ(CheckInputFile(Path("missing")).code(), StatusCode::kNotFound);
  const Status folder = CheckInputFile(dir_.string());
  EXPECT_EQ(folder.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(folder.message().find("is a folder; expected a regular file"), std::string::npos);
  ASSERT_EQ(::mkfifo(Path("fifo").c_str(), 0600), 0);
  EXPECT_NE(CheckInputFile(Path("fifo")).message().find("is a FIFO"), std::string::npos);
  fs::create_symlink(Path("nowhere"), Path("dangling"));
  EXPECT_NE(CheckInputFile(Path("dangling")).message().find("symbolic link to nothing"),
            std::string::npos);
  fs::create_symlink(Path("loop2"), Path("loop1"));
  fs::create_symlink(Path("loop1"), Path("loop2"));
  EXPECT_NE(CheckInputFile(Path("loop1")).message().find("symbolic link loop"), std::string::npos);
}

TEST_F(InputFileTest, OptionalInputFileIsFalseOnlyWhenNothingIsThere) {
  EXPECT_TRUE(*OptionalInputFile(Write("a.txt", "")));
  EXPECT_FALSE(*OptionalInputFile(Path("missing")));
  EXPECT_FALSE(OptionalInputFile(dir_.string()).ok());
}

TEST_F(InputFileTest, ReadInputFileReadsWholeFilesUpToTheLimit) {
  const std::string text = "a: 1\nb: [2, 3]\n";
  EXPECT_EQ(*ReadInputFile(Write("c.yaml", text), 1 << 20), text);
  const StatusOr<std::string> big =
      ReadInputFile(Write("big.yaml", std::string(3 << 20, 'x')), 2 << 20);
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.status().message().find("larger than 2 MiB"), std::string::npos);
}

TEST_F(InputFileTest, LineReaderDropsLineEndsAndTheByteOrderMark) {
  LineReader r(Write("l.txt",
                     "\xEF\xBB\xBF"
                     "one\r\ntwo\n\nlast"));
  ASSERT_TRUE(r.Open().ok());
  std::string line;
  std::vector<std::string> lines;
  while (*r.Next(&line)) lines.push_back(line);
  EXPECT_EQ(lines, (std::vector<std::string>{"one", "two", "", "last"}));
  EXPECT_EQ(r.line(), 4);
  EXPECT_EQ(r.Where(), r.path() + ":4: ");
}

TEST_F(InputFileTest, LineReaderRefusesALineLongerThanTheCap) {
  LineReader r(Write("long.txt", "ok\n" + std::string(kMaxLineBytes + 1, 'x')));
  ASSERT_TRUE(r.Open().ok());
  std::string line;
  ASSERT_TRUE(*r.Next(&line));
  const StatusOr<bool> s = r.Next(&line);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find(":2: line longer than 1 MiB"), std::string::npos)
      << s.status().message();
}

TEST_F(InputFileTest, LineReaderOpenFailsOnAFolder) {
  LineReader r(dir_.string());
  EXPECT_EQ(r.Open().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace walkgraph::internal
