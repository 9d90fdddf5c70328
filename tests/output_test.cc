// The output writer: marker, refusals, old-or-new at every phase (cancel and kill), stale
// temporaries, single files.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/output_internal.h"
#include "walkgraph/output.h"

namespace walkgraph {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A fresh sandbox, the process's cwd while the test runs (so '.' and its ancestors are in it).
class OutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    old_cwd_ = fs::current_path();
    root_ = fs::temp_directory_path() /
            ("wg_output_test_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "work");
    fs::current_path(root_ / "work");
    ClearCancelRequest();
  }
  void TearDown() override {
    internal::SetOutputPhaseHookForTesting(nullptr);
    ClearCancelRequest();
    fs::current_path(old_cwd_);
    fs::remove_all(root_);
  }

  static void Write(const fs::path& p, const std::string& text) {
    if (p.has_parent_path()) fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
  }
  static std::string Read(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  // Every file under `dir` with its contents.
  static std::map<std::string, std::string> Tree(const fs::path& dir) {
    std::map<std::string, std::string> out;
    if (!fs::exists(dir)) return out;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      if (e.is_regular_file()) out[fs::relative(e.path(), dir).string()] = Read(e.path());
    }
    return out;
  }
  // Names under `dir` that look like a writer's temporary.
  static std::vector<std::string> Leftovers(const fs::path& dir) {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
      const std::string n = e.path().filename().string();
      if (n.find("walkgraph-tmp") != std::string::npos ||
          n.find("walkgraph-old") != std::string::npos) {
        out.push_back(n);
      }
    }
    return out;
  }
  // Writes a folder holding one file `name` with `text`.
  static Status WriteFolder(const std::string& out, const std::string& text,
                            const OutputOptions& options = {}) {
    return WriteOutputFolder(out, options, [&](const std::string& tmp) {
      return WriteFileInOutput(tmp + "/result.txt", [&](std::ostream& o) {
        o << text;
        return true;
      });
    });
  }

  fs::path root_, old_cwd_;
};

TEST_F(OutputTest, NewFolderCarriesTheMarkerAndReplacesOnlyWhatItWrote) {
  OutputOptions o;
  o.command = "walkgraph compare w --out out";
  ASSERT_TRUE(WriteFolder("out", "one", o).ok());
  EXPECT_EQ(Read("out/result.txt"), "one");
  EXPECT_THAT(Read(std::string("out/") + kOutputMarker), HasSubstr("command: " + o.command));
  ASSERT_TRUE(WriteFolder("out/", "two").ok());  // a trailing slash names the same folder
  EXPECT_EQ(Read("out/result.txt"), "two");
  EXPECT_TRUE(Leftovers(root_).empty());
}

TEST_F(OutputTest, RefusesAFolderItDidNotWriteUnlessForced) {
  Write("mine/notes.txt", "precious");
  const Status s = WriteFolder("mine", "x");
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.message(), HasSubstr("--force"));
  EXPECT_EQ(Read("mine/notes.txt"), "precious");
  EXPECT_EQ(CheckOutputTarget("mine", OutputKind::kFolder, {}).code(), s.code());
  OutputOptions force;
  force.force = true;
  ASSERT_TRUE(WriteFolder("mine", "x", force).ok());
  EXPECT_FALSE(fs::exists("mine/notes.txt"));
  // An empty folder holds nothing to lose.
  fs::create_directories("empty");
  EXPECT_TRUE(WriteFolder("empty", "x").ok());
}

TEST_F(OutputTest, NeverReplacesInputsCwdAncestorsHomeOrRoot) {
  Write("walk/walk.yaml", "format_version: 1\n");
  Write("walk/imu.csv", "t_s\n");
  OutputOptions o;
  o.force = true;  // refused even so
  o.inputs = {"walk"};
  fs::create_directories("sub");
  for (const std::string out :
       {"walk", "walk/", ".", "..", "../..", "/", "sub/..", "walk/imu.csv"}) {
    const auto before = Tree(root_);
    EXPECT_FALSE(WriteFolder(out, "x", o).ok()) << out;
    EXPECT_FALSE(CheckOutputTarget(out, OutputKind::kFolder, o).ok()) << out;
    EXPECT_EQ(Tree(root_), before) << out;
  }
  const char* home = std::getenv("HOME");
  const std::string saved = home ? home : "";
  Write("home/.profile", "x");
  ::setenv("HOME", (root_ / "work" / "home").c_str(), 1);
  EXPECT_FALSE(WriteFolder("home", "x", o).ok());
  ::setenv("HOME", saved.c_str(), 1);
  // A new output inside the input folder replaces nothing: allowed.
  EXPECT_TRUE(WriteFolder("walk/report", "x", o).ok());
  EXPECT_TRUE(
      WriteOutputFile("walk/t.tum", o, [](std::ostream& s) { return bool(s << "t"); }).ok());
  EXPECT_FALSE(WriteOutputFile("walk/imu.csv", o, [](std::ostream& s) { return bool(s); }).ok());
  EXPECT_EQ(Read("walk/imu.csv"), "t_s\n");
}

TEST_F(OutputTest, NeverReplacesLinksOrSpecialFiles) {
  fs::create_directories("real");
  fs::create_directory_symlink("real", "link");
  ASSERT_EQ(::mkfifo("fifo", 0600), 0);
  OutputOptions force;
  force.force = true;
  for (const std::string out : {"link", "fifo"}) {
    const Status s = WriteFolder(out, "x", force);
    EXPECT_FALSE(s.ok()) << out;
  }
  EXPECT_TRUE(fs::is_symlink("link"));
  const auto w = [](std::ostream& o) { return bool(o << "x"); };
  EXPECT_THAT(WriteOutputFile("fifo", {}, w).message(), HasSubstr("FIFO"));
  EXPECT_THAT(WriteOutputFile("/dev/null", {}, w).message(), HasSubstr("device"));
  EXPECT_THAT(WriteOutputFile("real", {}, w).message(), HasSubstr("folder"));
  EXPECT_THAT(WriteOutputFile("new.tum/", {}, w).message(), HasSubstr("folder"));
  Write("old.tum", "old");
  ASSERT_TRUE(WriteOutputFile("old.tum", {}, w).ok());  // a regular file is replaced
  EXPECT_EQ(Read("old.tum"), "x");
}

TEST_F(OutputTest, FailedFillLeavesTheOldOutputAndNoTemporary) {
  ASSERT_TRUE(WriteFolder("out", "old").ok());
  const Status s = WriteOutputFolder("out", {}, [](const std::string& tmp) {
    std::ofstream(tmp + "/partial.txt") << "half";
    return IoError("disk full");
  });
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(Read("out/result.txt"), "old");
  EXPECT_FALSE(fs::exists("out/partial.txt"));
  EXPECT_TRUE(Leftovers(root_).empty());
  // Missing parent folders made for a failed write are taken away again.
  EXPECT_FALSE(
      WriteOutputFolder("a/b/c", {}, [](const std::string&) { return IoError("no"); }).ok());
  EXPECT_FALSE(fs::exists("a"));
  EXPECT_FALSE(WriteOutputFile("d/e.tum", {}, [](std::ostream&) { return false; }).ok());
  EXPECT_FALSE(fs::exists("d"));
}

const char* const kPhases[] = {"tmp-created", "filled", "before-exchange", "exchanged", "done"};

// A cancel request (what the CLI's SIGTERM handler makes) at each phase: before the exchange the
// old output stays and the write reports kCancelled; after it the new output is complete.
TEST_F(OutputTest, CancelAtEachPhaseLeavesTheOldOrTheNewOutputWhole) {
  for (const std::string phase : kPhases) {
    fs::remove_all("out");
    ASSERT_TRUE(WriteFolder("out", "old").ok());
    const auto old_tree = Tree("out");
    internal::SetOutputPhaseHookForTesting([&](const std::string& p) {
      if (p == phase) RequestCancel(SIGTERM);
    });
    const Status s = WriteFolder("out", "new");
    internal::SetOutputPhaseHookForTesting(nullptr);
    const bool before_exchange =
        phase == "tmp-created" || phase == "filled" || phase == "before-exchange";
    if (before_exchange) {
      EXPECT_EQ(s.code(), StatusCode::kCancelled) << phase;
      EXPECT_EQ(Tree("out"), old_tree) << phase;
    } else {
      EXPECT_TRUE(s.ok()) << phase;
      EXPECT_EQ(Read("out/result.txt"), "new") << phase;
    }
    EXPECT_TRUE(Leftovers(root_).empty()) << phase;
    EXPECT_TRUE(OutputInProgress() == false);
    ClearCancelRequest();
  }
}

// The process killed at each phase (no clean-up at all): the target holds the old or the new
// output whole, and the next write removes what the dead process left.
TEST_F(OutputTest, KillAtEachPhaseLeavesTheOldOrTheNewOutputWhole) {
  ::testing::FLAGS_gtest_death_test_style = "fast";  // fork here: same sandbox, same state
  for (const std::string phase : kPhases) {
    fs::remove_all("out");
    ASSERT_TRUE(WriteFolder("out", "old").ok());
    const auto old_tree = Tree("out");
    EXPECT_EXIT(
        {
          internal::SetOutputPhaseHookForTesting([&](const std::string& p) {
            if (p == phase) ::_exit(9);
          });
          (void)WriteFolder("out", "new");
          ::_exit(0);
        },
        ::testing::ExitedWithCode(9), "")
        << phase;
    const auto tree = Tree("out");
    const bool is_old = tree == old_tree;
    const bool is_new = tree.size() == old_tree.size() && Read("out/result.txt") == "new";
    EXPECT_TRUE(is_old || is_new) << phase;
    EXPECT_EQ(is_new, phase == "exchanged" || phase == "done") << phase;
    // The dead writer's temporary (if any) goes with the next write beside it.
    ASSERT_TRUE(WriteFolder("out", "next").ok()) << phase;
    EXPECT_TRUE(Leftovers(root_).empty()) << phase;
  }
}

TEST_F(OutputTest, StaleTemporariesOfDeadProcessesAreRemovedAndBackupsRestored) {
  // pid 2^22 + 1 is above Linux's pid_max default: no such process.
  Write(".out.walkgraph-tmp-4194305/result.txt", "half-written");
  ASSERT_TRUE(WriteFolder("out", "new").ok());
  EXPECT_TRUE(Leftovers(root_).empty());
  // A crash between the two renames of the fallback exchange left the old output as a backup
  // and no target: it is put back before anything else.
  fs::remove_all("out");
  Write(".out.walkgraph-old-4194305/result.txt", "old");
  Write(std::string(".out.walkgraph-old-4194305/") + kOutputMarker, "walkgraph");
  EXPECT_TRUE(CheckOutputTarget("out", OutputKind::kFolder, {}).ok());
  const Status s = WriteOutputFolder(
      "out", {}, [](const std::string&) { return IoError("fails before the exchange"); });
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(Read("out/result.txt"), "old");
  EXPECT_TRUE(Leftovers(root_).empty());
}

TEST_F(OutputTest, ASecondWriterOfTheSameTargetIsRefusedAndTheFirstFinishesWhole) {
  Status second = Status::Ok();
  bool tried = false;
  internal::SetOutputPhaseHookForTesting([&](const std::string& p) {
    if (p != "filled" || tried) return;
    tried = true;
    second = WriteFolder("out", "second");  // its own open file description: flock conflicts
  });
  ASSERT_TRUE(WriteFolder("out", "first").ok());
  EXPECT_EQ(second.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(second.message(), HasSubstr("another walkgraph process"));
  EXPECT_THAT(second.message(), HasSubstr(".out.walkgraph-lock"));
  EXPECT_EQ(Read("out/result.txt"), "first");
  EXPECT_TRUE(Leftovers(root_).empty());
  EXPECT_FALSE(fs::exists(".out.walkgraph-lock"));  // released and removed
}

TEST_F(OutputTest, ATemporaryIsStaleOnlyWhenNobodyHoldsItsTargetsLock) {
  // A writer on another host or in another PID namespace: its PID (here one that does not run
  // in ours) says nothing, its lock does.
  Write(".out.walkgraph-tmp-4194305/result.txt", "half-written by a live writer");
  const int fd = ::open(".out.walkgraph-lock", O_RDWR | O_CREAT, 0666);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  const Status refused = WriteFolder("out", "new");
  EXPECT_THAT(refused.message(), HasSubstr("another walkgraph process"));
  EXPECT_EQ(Read(".out.walkgraph-tmp-4194305/result.txt"), "half-written by a live writer");
  EXPECT_FALSE(fs::exists("out"));
  ::close(fd);  // the other writer died: now its temporary is stale
  ASSERT_TRUE(WriteFolder("out", "new").ok());
  EXPECT_EQ(Read("out/result.txt"), "new");
  EXPECT_TRUE(Leftovers(root_).empty());
}

// A user's file that happens to bear the lock file's name is neither written to nor removed:
// the write is refused, naming it, and the file is as it was (an empty one, as a killed writer
// leaves it, is walkgraph's and goes away with the next write).
TEST_F(OutputTest, AUsersFileNamedLikeTheLockIsNeverTouched) {
  Write(".out.walkgraph-lock", "my notes");
  const Status refused = WriteFolder("out", "new");
  EXPECT_EQ(refused.code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(refused.message(), HasSubstr("not written by walkgraph"));
  EXPECT_EQ(Read(".out.walkgraph-lock"), "my notes");
  EXPECT_FALSE(fs::exists("out"));
  fs::remove(".out.walkgraph-lock");
  Write(".out.walkgraph-lock", "");
  ASSERT_TRUE(WriteFolder("out", "new").ok());
  EXPECT_EQ(Read("out/result.txt"), "new");
  EXPECT_FALSE(fs::exists(".out.walkgraph-lock"));
}

TEST_F(OutputTest, ARefusedTargetGetsNoLockFileBesideIt) {
  Write("file.txt", "mine");
  EXPECT_FALSE(WriteFolder("file.txt", "x").ok());  // a regular file: not replaced
  EXPECT_FALSE(fs::exists(".file.txt.walkgraph-lock"));
  EXPECT_EQ(Read("file.txt"), "mine");
  EXPECT_FALSE(WriteOutputFile("missing/t.tum/", {}, [](std::ostream&) { return true; }).ok());
  EXPECT_FALSE(fs::exists("missing"));  // a refused file target: no parent folders made
}

TEST_F(OutputTest, NamesUpToNameMaxWork) {
  std::string utf8;  // 2-byte characters: a shortened sibling must not split one
  while (utf8.size() + 2 <= 255) utf8 += "\xc3\xa9";
  for (const std::string& name : {std::string(255, 'n'), std::string(230, 'm'), utf8}) {
    ASSERT_TRUE(WriteFolder(name, "one").ok()) << name.size();
    ASSERT_TRUE(WriteFolder(name, "two").ok()) << name.size();  // over its own output
    EXPECT_EQ(Read(name + "/result.txt"), "two");
    ASSERT_TRUE(WriteOutputFile(name + "/" + name, {}, [](std::ostream& o) {
                  o << "file";
                  return true;
                }).ok());
    EXPECT_TRUE(Leftovers(root_).empty());
    for (const auto& e : fs::directory_iterator(".")) {
      EXPECT_EQ(e.path().filename().string(), name);  // no lock file or temporary beside it
    }
    fs::remove_all(name);
  }
  const std::string a = internal::OutputSiblingName(std::string(255, 'a'), "tmp");
  const std::string b = internal::OutputSiblingName(std::string(254, 'a') + "b", "tmp");
  EXPECT_LE(a.size(), 255u);
  EXPECT_NE(a, b);  // the hash keeps long names apart
}

TEST_F(OutputTest, ASocketIsNeverReplaced) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", "sock");
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  ::close(fd);
  OutputOptions force;
  force.force = true;
  EXPECT_THAT(WriteFolder("sock", "x", force).message(), HasSubstr("socket"));
  struct stat st {};
  ASSERT_EQ(::lstat("sock", &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
}

}  // namespace
}  // namespace walkgraph
