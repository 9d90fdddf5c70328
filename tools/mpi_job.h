// The processes of a walkgraph run (CLI only; the library knows nothing of MPI): one, or the
// ranks of an MPI job when the CLI is built with MPI (CMake find_package(MPI), option
// WALKGRAPH_MPI) and started by an MPI launcher (mpirun, mpiexec, srun). Without a launcher,
// or in a build without MPI, the run is one process of one and every call below is trivial.
#ifndef WALKGRAPH_TOOLS_MPI_JOB_H_
#define WALKGRAPH_TOOLS_MPI_JOB_H_

#include <string>
#include <vector>

#include "walkgraph/status.h"

namespace walkgraph_cli {

class MpiJob {
 public:
  // Joins the MPI job when started by a launcher (MPI_Init_thread, funneled: only the main
  // thread calls MPI); the destructor leaves it (MPI_Finalize).
  MpiJob(int* argc, char*** argv);
  ~MpiJob();
  MpiJob(const MpiJob&) = delete;
  MpiJob& operator=(const MpiJob&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }

  // Collective: true on every rank when `ok` is true on every rank.
  bool AllOk(bool ok) const;
  // Collective: every rank's bytes on rank 0, in rank order (other ranks get nothing);
  // InvalidArgument when they exceed what one MPI message carries (2 GiB).
  walkgraph::StatusOr<std::vector<std::string>> Gather(const std::string& bytes) const;
  // Collective: rank 0's `value` on every rank.
  int Broadcast(int value) const;

  bool joined() const { return joined_; }

 private:
  bool joined_ = false;
  int rank_ = 0, size_ = 1;
};

// A counter shared by the ranks of a job (MPI one-sided: a window on rank 0, incremented with
// MPI_Fetch_and_op under a passive-target lock, so no rank waits for another to serve it — with
// OpenMPI's shared-memory and UCX windows; over plain TCP a claim may wait until rank 0 next
// calls MPI). Construction and destruction are collective; one process: a plain counter.
class SharedCounter {
 public:
  explicit SharedCounter(const MpiJob& job);
  ~SharedCounter();
  SharedCounter(const SharedCounter&) = delete;
  SharedCounter& operator=(const SharedCounter&) = delete;

  // The counter's value before this call adds 1 (0, 1, 2, ... over all ranks together).
  int FetchAdd();

 private:
  int local_ = 0;
  void* window_ = nullptr;  // MPI_Win (MPI builds, joined jobs)
};

}  // namespace walkgraph_cli

#endif  // WALKGRAPH_TOOLS_MPI_JOB_H_
