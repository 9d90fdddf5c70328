// How walkgraph writes what it produces: never over what it did not write, and whole or not
// at all.
//
// Folders (compare, study, simulate/convert walks) carry a marker file, kOutputMarker, naming
// the program and the command that wrote them. An existing target is replaced only when
//   - it is a folder carrying the marker, or an empty folder, or
//   - OutputOptions::force is set (a folder or regular file without the marker),
// and never when it is `/`, the home folder, the current folder or one of its ancestors, an
// input of the run or a folder holding one, or an existing entry inside an input folder (these
// are refused even with force). Symbolic links, FIFOs, sockets and devices are never replaced.
// A trailing slash names the same folder.
//
// Single files (TUM trajectories) are written only to a new path or over a regular file, with
// the same protection of inputs.
//
// Replacement keeps the old output until the new one is complete: the new output is written
// into a hidden sibling ".<name>.walkgraph-tmp-<pid>" and exchanged with the old one in one
// atomic renameat2(RENAME_EXCHANGE) (on file systems without it: old → ".<name>.walkgraph-old-
// <pid>", new → target, old removed; a crash between the two renames is repaired by the next
// write of the target). A crash or a signal at any instant leaves the old output or the new one
// whole. Temporaries of a process that no longer runs are removed by the next write beside them;
// they are never read as output.
//
// Cancellation (walkgraph/cancel.h): RequestCancel() (async-signal-safe) asks the library to stop;
// the writers poll it and, when set before the exchange, remove their temporary and return
// kCancelled with the old output untouched. The walkgraph CLI installs SIGINT/SIGTERM/SIGHUP
// handlers that call RequestCancel and, when no writer holds a temporary (OutputInProgress() is
// false), end the process at once with 128 + signal: nothing of walkgraph's is on disk to clean up
// then.
#ifndef WALKGRAPH_OUTPUT_H_
#define WALKGRAPH_OUTPUT_H_

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "walkgraph/cancel.h"
#include "walkgraph/status.h"

namespace walkgraph {

// The marker file inside every output folder walkgraph writes.
inline constexpr const char kOutputMarker[] = ".walkgraph-output";

struct OutputOptions {
  // Replace an existing folder (or regular file) that does not carry the marker. Protected
  // paths (see the top of this file) are refused even so.
  bool force = false;
  // The run's inputs (walk folders, config files, manifests): never replaced, nor any folder
  // holding one, nor an existing entry inside an input folder.
  std::vector<std::string> inputs;
  // Recorded in the marker file (e.g. the command line).
  std::string command;
};

enum class OutputKind { kFolder, kFile };

// The checks WriteOutputFolder (kFolder) or WriteOutputFile (kFile) make before writing, alone:
// a program calls it before a long computation so that a refused output fails at once.
Status CheckOutputTarget(const std::string& path, OutputKind kind, const OutputOptions& options);

// Writes the folder `out_dir`: `fill` writes the files into a fresh temporary folder, which
// then replaces (or becomes) out_dir as described at the top of this file. On any failure the
// temporary is removed and out_dir is as it was.
Status WriteOutputFolder(const std::string& out_dir, const OutputOptions& options,
                         const std::function<Status(const std::string& tmp_dir)>& fill);

// Writes the file `path` through a temporary sibling renamed over it: `write` fills the stream
// and returns false on failure. Only a new path or an existing regular file is written.
Status WriteOutputFile(const std::string& path, const OutputOptions& options,
                       const std::function<bool(std::ostream&)>& write);

// Writes `path` inside a temporary folder of WriteOutputFolder's `fill` (no protection checks:
// the folder is walkgraph's own). Fails when the stream fails.
Status WriteFileInOutput(const std::string& path, const std::function<bool(std::ostream&)>& write);

// Whether a writer holds a temporary (async-signal-safe). Cancellation itself
// (RequestCancel, CancelRequested, ...) is walkgraph/cancel.h, included here.
bool OutputInProgress() noexcept;

}  // namespace walkgraph

#endif  // WALKGRAPH_OUTPUT_H_
