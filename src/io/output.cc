// The one writer of walkgraph's outputs (see walkgraph/output.h for the rules).
#include "walkgraph/output.h"

#include <fcntl.h>
#include <limits.h>  // NAME_MAX
#include <signal.h>
#include <stdio.h>     // renameat2, RENAME_EXCHANGE (glibc >= 2.28)
#include <sys/file.h>  // flock
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "io/output_internal.h"

#ifndef WALKGRAPH_VERSION
#define WALKGRAPH_VERSION "unknown"
#endif

namespace walkgraph {

namespace fs = std::filesystem;

namespace {

static_assert(std::atomic<int>::is_always_lock_free, "signal handlers need lock-free atomics");

std::atomic<int> g_in_progress{0};
std::function<void(const std::string&)> g_phase_hook;

void Phase(const std::string& name) {
  if (g_phase_hook) g_phase_hook(name);
}

std::string ErrnoText(int e) { return std::error_code(e, std::generic_category()).message(); }

// Counts a writer that holds (or is about to create) a temporary. The increment precedes the
// writer's cancel check and the signal handler's request precedes its read of the count, both
// sequentially consistent: either the handler sees the writer (and leaves it to clean up) or the
// writer sees the request (and creates nothing).
class InProgress {
 public:
  InProgress() { g_in_progress.fetch_add(1); }
  ~InProgress() { g_in_progress.fetch_sub(1); }
  InProgress(const InProgress&) = delete;
  InProgress& operator=(const InProgress&) = delete;
};

struct Target {
  std::string given;  // as the caller wrote it, for messages
  fs::path path;      // absolute, lexically normal, no trailing separator
  fs::path parent;
  std::string name;
  bool exists = false;
  bool trailing_slash = false;
  struct stat st {};  // lstat of path when it exists
};

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISREG(mode)) return "a regular file";
  if (S_ISLNK(mode)) return "a symbolic link";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
  return "a special file";
}

StatusOr<Target> Resolve(const std::string& given) {
  if (given.empty()) return InvalidArgument("the output path is empty");
  Target t;
  t.given = given;
  t.trailing_slash = given.back() == '/';
  std::error_code ec;
  fs::path p = fs::absolute(fs::path(given), ec);
  if (ec) return IoError(given + ": cannot resolve the output path: " + ec.message());
  p = p.lexically_normal();
  while (!p.has_filename() && p != p.root_path()) p = p.parent_path();
  if (p == p.root_path()) return InvalidArgument(given + ": refusing to write over '/'");
  t.path = p;
  t.parent = p.parent_path();
  t.name = p.filename().string();
  if (::lstat(p.c_str(), &t.st) == 0) {
    t.exists = true;
  } else if (errno != ENOENT) {
    return IoError(given + ": " + ErrnoText(errno));
  }
  return t;
}

// True when `a` is `b` or one of its ancestors (both absolute and normal).
bool IsAncestorOrSelf(const fs::path& a, const fs::path& b) {
  auto ia = a.begin(), ib = b.begin();
  for (; ia != a.end(); ++ia, ++ib) {
    if (ia->empty()) continue;  // a trailing separator
    if (ib == b.end() || *ia != *ib) return false;
  }
  return true;
}

fs::path Canonical(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(p, ec);
  if (ec) return p.lexically_normal();
  while (!c.has_filename() && c != c.root_path()) c = c.parent_path();
  return c;
}

Status CheckProtected(const Target& t, const OutputOptions& o) {
  // The entry itself, with the links of the folders above it resolved (not a link at the end).
  const fs::path entry = Canonical(t.parent) / t.name;
  const std::string& out = t.given;
  std::error_code ec;
  const fs::path cwd = fs::current_path(ec);
  if (!ec && IsAncestorOrSelf(entry, cwd)) {
    return InvalidArgument(out +
                           ": is the current folder or one of its ancestors; refusing to "
                           "replace it (choose a new folder for the output)");
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    if (entry == Canonical(home)) {
      return InvalidArgument(out + ": is the home folder; refusing to replace it");
    }
  }
  for (const std::string& input : o.inputs) {
    if (input.empty()) continue;
    const fs::path in = Canonical(fs::absolute(input, ec));
    if (IsAncestorOrSelf(entry, in)) {
      return InvalidArgument(out + (entry == in ? ": is the input " : ": holds the input ") +
                             input + "; refusing to replace it (choose another output path)");
    }
    struct stat st {};
    if (t.exists && ::stat(in.c_str(), &st) == 0 && S_ISDIR(st.st_mode) &&
        IsAncestorOrSelf(in, entry)) {
      return InvalidArgument(out + ": exists inside the input folder " + input +
                             "; refusing to replace it");
    }
  }
  return Status::Ok();
}

bool IsEmptyFolder(const fs::path& p) {
  std::error_code ec;
  return fs::is_empty(p, ec) && !ec;
}

bool HasMarker(const fs::path& dir) {
  struct stat st {};
  return ::lstat((dir / kOutputMarker).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

Status CheckReplaceableFolder(const Target& t, const OutputOptions& o) {
  if (!t.exists) return Status::Ok();
  const mode_t m = t.st.st_mode;
  const std::string& out = t.given;
  if (S_ISDIR(m)) {
    if (HasMarker(t.path) || IsEmptyFolder(t.path) || o.force) return Status::Ok();
    return InvalidArgument(out + ": exists and was not written by walkgraph (it has no " +
                           kOutputMarker +
                           " marker); refusing to replace it. Choose another output folder, "
                           "or pass --force to replace it with its contents");
  }
  if (S_ISREG(m)) {
    if (o.force) return Status::Ok();
    return InvalidArgument(out +
                           ": exists and is a regular file, not an output folder; refusing "
                           "to replace it (pass --force to replace it)");
  }
  return InvalidArgument(out + ": exists and is " + KindOf(m) +
                         "; walkgraph replaces only folders and regular files");
}

Status CheckReplaceableFile(const Target& t) {
  if (t.trailing_slash) {
    return InvalidArgument(t.given + ": names a folder; expected the path of a file");
  }
  if (!t.exists || S_ISREG(t.st.st_mode)) return Status::Ok();
  return InvalidArgument(t.given + ": exists and is " + KindOf(t.st.st_mode) +
                         "; expected a new path or a regular file to replace");
}

// The lock of a target's writer: an flock(2) on the hidden file ".NAME.walkgraph-lock" beside
// it, held for the whole write. flock works across hosts on a shared folder (NFS, Lustre,
// GPFS) and across PID namespaces, where a PID says nothing: a second writer of the same target
// is refused, and a temporary is stale exactly when nobody holds its target's lock. Release
// unlinks the file (only one walkgraph made: ClaimOrRefuse) while still holding the lock; Acquire
// retries when the file it locked was unlinked under it (then another writer has a newer one).
class WriterLock {
 public:
  WriterLock() = default;
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;
  ~WriterLock() { Release(); }

  Status Acquire(const Target& t) {
    path_ = t.parent / ("." + internal::OutputSiblingBase(t.name) + ".walkgraph-lock");
    for (int attempt = 0; attempt < 100; ++attempt) {
      fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0666);
      if (fd_ < 0) {
        return IoError(t.given + ": cannot create the lock file " + path_.string() + ": " +
                       ErrnoText(errno));
      }
      if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
        const int e = errno;
        ::close(fd_);
        fd_ = -1;
        if (e == EWOULDBLOCK) {
          return FailedPrecondition(
              t.given +
              ": another walkgraph process (on this or another host) is writing this output "
              "now (it holds " +
              path_.string() +
              "); refusing to write it at the same time. Wait for that run to finish, or choose "
              "another output path");
        }
        return IoError(t.given + ": cannot lock " + path_.string() + ": " + ErrnoText(e));
      }
      struct stat held {
      }, now{};
      if (::fstat(fd_, &held) == 0 && ::lstat(path_.c_str(), &now) == 0 &&
          held.st_dev == now.st_dev && held.st_ino == now.st_ino) {
        return ClaimOrRefuse(t);
      }
      ::close(fd_);  // unlinked by the writer before us: lock the file that is there now
      fd_ = -1;
    }
    return IoError(t.given + ": cannot lock " + path_.string() + ": it keeps being replaced");
  }
  void Release() {
    if (fd_ < 0) return;
    if (ours_) ::unlink(path_.c_str());
    ::close(fd_);
    fd_ = -1;
    ours_ = false;
  }

 private:
  // The locked file is walkgraph's when it is a regular file that is empty (just created, or
  // left by a writer killed before it wrote the marker) or holds kLockMarker: then it gets the
  // marker and Release may unlink it. Anything else of that name is the user's: refused, and
  // never written to or removed.
  Status ClaimOrRefuse(const Target& t) {
    static constexpr char kLockMarker[] = "walkgraph output lock\n";
    constexpr size_t kLength = sizeof(kLockMarker) - 1;
    struct stat st {};
    char head[sizeof(kLockMarker)] = {};
    const ssize_t got =
        ::fstat(fd_, &st) == 0 && S_ISREG(st.st_mode) && st.st_size <= static_cast<off_t>(kLength)
            ? ::pread(fd_, head, kLength, 0)
            : -1;
    const bool empty = got == 0;
    if (!empty && !(got == static_cast<ssize_t>(kLength) &&
                    std::string(head, kLength) == std::string(kLockMarker))) {
      ::close(fd_);
      fd_ = -1;
      return FailedPrecondition(t.given + ": " + path_.string() +
                                " exists and was not written by walkgraph (its lock file has "
                                "that name); move it away or choose another output path");
    }
    if (empty && ::pwrite(fd_, kLockMarker, kLength, 0) != static_cast<ssize_t>(kLength)) {
      const int e = errno;
      ::close(fd_);
      fd_ = -1;
      return IoError(t.given + ": cannot write the lock file " + path_.string() + ": " +
                     ErrnoText(e));
    }
    ours_ = true;
    return Status::Ok();
  }

  bool ours_ = false;
  fs::path path_;
  int fd_ = -1;
};

// Removes the temporaries of earlier writers of the target (the caller holds the target's
// WriterLock, so no writer of it runs: every temporary of it is stale, whatever host or PID
// namespace made it); a backup whose target is missing (a crash between the two renames of the
// fallback exchange) is put back first.
void CleanStale(const Target& t) {
  std::error_code ec;
  const std::string base = internal::OutputSiblingBase(t.name);
  const std::string tmp_prefix = "." + base + ".walkgraph-tmp-";
  const std::string old_prefix = "." + base + ".walkgraph-old-";
  fs::directory_iterator it(t.parent, ec), end;
  std::vector<std::pair<fs::path, bool>> stale;  // path, is a backup
  for (; !ec && it != end; it.increment(ec)) {
    const std::string n = it->path().filename().string();
    const bool tmp = n.rfind(tmp_prefix, 0) == 0, old = n.rfind(old_prefix, 0) == 0;
    if (!tmp && !old) continue;
    const std::string digits = n.substr((tmp ? tmp_prefix : old_prefix).size());
    if (digits.empty() || digits.size() > 9 ||
        digits.find_first_not_of("0123456789") != std::string::npos) {
      continue;
    }
    stale.emplace_back(it->path(), old);
  }
  struct stat st {};
  for (const auto& [path, old] : stale) {
    if (old && ::lstat(t.path.c_str(), &st) != 0 && errno == ENOENT &&
        ::rename(path.c_str(), t.path.c_str()) == 0) {
      continue;
    }
    fs::remove_all(path, ec);
  }
}

// Creates the missing folders above `dir`, remembering them so that a failure can take them
// away again.
class Parents {
 public:
  Status Create(const fs::path& dir, const std::string& out) {
    std::vector<fs::path> missing;
    struct stat st {};
    for (fs::path p = dir; !p.empty() && ::lstat(p.c_str(), &st) != 0; p = p.parent_path()) {
      if (errno != ENOENT) return IoError(out + ": " + p.string() + ": " + ErrnoText(errno));
      missing.push_back(p);
      if (p == p.root_path()) break;
    }
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (::mkdir(it->c_str(), 0777) != 0) {
        const int e = errno;
        Undo();
        return IoError(out + ": cannot create the folder " + it->string() + ": " + ErrnoText(e));
      }
      created_.push_back(*it);
    }
    return Status::Ok();
  }
  void Undo() {
    for (auto it = created_.rbegin(); it != created_.rend(); ++it) ::rmdir(it->c_str());
    created_.clear();
  }

 private:
  std::vector<fs::path> created_;
};

Status CancelledStatus(const std::string& out) {
  return Cancelled(out + ": interrupted (signal " + std::to_string(CancelSignal()) +
                   "); the output was left as it was");
}

std::string OneLine(std::string s) {
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

// Puts the complete temporary `tmp` in place of the target (see output.h).
Status Install(const fs::path& tmp, const Target& t) {
  Phase("before-exchange");
  std::error_code ec;
  if (CancelRequested()) {
    fs::remove_all(tmp, ec);
    return CancelledStatus(t.given);
  }
  struct stat st {};
  const bool exists = ::lstat(t.path.c_str(), &st) == 0;
  if (!exists) {
    if (::rename(tmp.c_str(), t.path.c_str()) != 0) {
      const int e = errno;
      fs::remove_all(tmp, ec);
      return IoError(t.given + ": cannot move the new output into place: " + ErrnoText(e));
    }
    Phase("exchanged");
    return Status::Ok();
  }
  if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, t.path.c_str(), RENAME_EXCHANGE) == 0) {
    Phase("exchanged");
    fs::remove_all(tmp, ec);  // now the old output
    return Status::Ok();
  }
  if (errno != EINVAL && errno != ENOSYS && errno != EOPNOTSUPP) {
    const int e = errno;
    fs::remove_all(tmp, ec);
    return IoError(t.given + ": cannot exchange the old output with the new: " + ErrnoText(e));
  }
  // File systems without RENAME_EXCHANGE: two renames; CleanStale repairs a crash between them.
  const fs::path old = t.parent / internal::OutputSiblingName(t.name, "old");
  if (::rename(t.path.c_str(), old.c_str()) != 0) {
    const int e = errno;
    fs::remove_all(tmp, ec);
    return IoError(t.given + ": cannot move the old output aside: " + ErrnoText(e));
  }
  Phase("old-moved");
  if (::rename(tmp.c_str(), t.path.c_str()) != 0) {
    const int e = errno;
    ::rename(old.c_str(), t.path.c_str());
    fs::remove_all(tmp, ec);
    return IoError(t.given + ": cannot move the new output into place: " + ErrnoText(e));
  }
  Phase("exchanged");
  fs::remove_all(old, ec);
  return Status::Ok();
}

}  // namespace

namespace internal {

void SetOutputPhaseHookForTesting(std::function<void(const std::string& phase)> hook) {
  g_phase_hook = std::move(hook);
}

std::string OutputSiblingBase(const std::string& name) {
  // Room for "." + ".walkgraph-lock" or ".walkgraph-tmp-<pid>" around the base.
  constexpr size_t kRoom = 32;
  if (name.size() + kRoom <= NAME_MAX) return name;
  std::uint64_t hash = 14695981039346656037ull;  // FNV-1a: the shortened base stays unique
  for (unsigned char c : name) hash = (hash ^ c) * 1099511628211ull;
  size_t keep = NAME_MAX - kRoom - 17;
  while (keep > 0 && (static_cast<unsigned char>(name[keep]) & 0xC0) == 0x80) --keep;  // UTF-8
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(hash));
  return name.substr(0, keep) + "~" + hex;
}

std::string OutputSiblingName(const std::string& name, const char* kind) {
  return "." + OutputSiblingBase(name) + ".walkgraph-" + kind + "-" + std::to_string(::getpid());
}

}  // namespace internal

bool OutputInProgress() noexcept { return g_in_progress.load() > 0; }

Status CheckOutputTarget(const std::string& path, OutputKind kind, const OutputOptions& options) {
  WG_ASSIGN_OR_RETURN(const Target t, Resolve(path));
  WG_RETURN_IF_ERROR(CheckProtected(t, options));
  return kind == OutputKind::kFolder ? CheckReplaceableFolder(t, options) : CheckReplaceableFile(t);
}

Status WriteFileInOutput(const std::string& path, const std::function<bool(std::ostream&)>& write) {
  if (CancelRequested()) return CancelledStatus(path);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return IoError(path + ": cannot create the file: " + ErrnoText(errno));
  errno = 0;
  bool ok = write(out);
  out.flush();
  ok = ok && out.good();
  const int e = errno;
  out.close();
  if (!ok || out.fail()) {
    return IoError(path + ": write failed" + (e != 0 ? ": " + ErrnoText(e) : std::string()));
  }
  return Status::Ok();
}

namespace {

// The one write path of folders and files (see output.h).
Status WriteOutput(const std::string& out, OutputKind kind, const OutputOptions& options,
                   const std::function<Status(const fs::path& tmp)>& fill) {
  WG_ASSIGN_OR_RETURN(Target t, Resolve(out));
  WG_RETURN_IF_ERROR(CheckProtected(t, options));
  // Checked before anything is created beside it (a device's folder gets no lock file); again
  // under the lock, after the clean-up.
  WG_RETURN_IF_ERROR(kind == OutputKind::kFolder ? CheckReplaceableFolder(t, options)
                                                 : CheckReplaceableFile(t));
  InProgress guard;  // from here on a signal leaves the clean-up to this writer
  if (CancelRequested()) return CancelledStatus(out);
  Parents parents;
  WG_RETURN_IF_ERROR(parents.Create(t.parent, out));
  WriterLock lock;
  Status s = lock.Acquire(t);
  if (s.ok()) {
    CleanStale(t);  // first: it may put back an old output that the checks must then see
    StatusOr<Target> again = Resolve(out);
    s = again.status();
    if (s.ok()) t = *again;
  }
  if (s.ok()) {
    s = kind == OutputKind::kFolder ? CheckReplaceableFolder(t, options) : CheckReplaceableFile(t);
  }
  if (!s.ok()) {
    lock.Release();
    parents.Undo();
    return s;
  }
  const fs::path tmp = t.parent / internal::OutputSiblingName(t.name, "tmp");
  std::error_code ec;
  fs::remove_all(tmp, ec);  // only a process with our pid could have left it
  if (kind == OutputKind::kFolder && ::mkdir(tmp.c_str(), 0777) != 0) {
    const int e = errno;
    lock.Release();
    parents.Undo();
    return IoError(out + ": cannot create the temporary folder " + tmp.string() + ": " +
                   ErrnoText(e));
  }
  Phase("tmp-created");
  s = fill(tmp);
  if (s.ok() && CancelRequested()) s = CancelledStatus(out);
  if (s.ok()) Phase("filled");
  if (s.ok()) s = Install(tmp, t);
  if (!s.ok()) {
    fs::remove_all(tmp, ec);
    lock.Release();
    parents.Undo();
    return s;
  }
  lock.Release();
  Phase("done");
  return Status::Ok();
}

}  // namespace

Status WriteOutputFolder(const std::string& out_dir, const OutputOptions& options,
                         const std::function<Status(const std::string& tmp_dir)>& fill) {
  return WriteOutput(out_dir, OutputKind::kFolder, options, [&](const fs::path& tmp) {
    WG_RETURN_IF_ERROR(WriteFileInOutput((tmp / kOutputMarker).string(), [&](std::ostream& o) {
      o << "walkgraph " << WALKGRAPH_VERSION << " wrote this folder; a later walkgraph run may "
        << "replace it whole.\ncommand: " << OneLine(options.command) << "\n";
      return true;
    }));
    return fill(tmp.string());
  });
}

Status WriteOutputFile(const std::string& path, const OutputOptions& options,
                       const std::function<bool(std::ostream&)>& write) {
  return WriteOutput(path, OutputKind::kFile, options,
                     [&](const fs::path& tmp) { return WriteFileInOutput(tmp.string(), write); });
}

}  // namespace walkgraph
