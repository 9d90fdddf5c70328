// MpiJob (mpi_job.h): MPI when built with it (WALKGRAPH_HAVE_MPI), one process otherwise.
#include "mpi_job.h"

#include <climits>
#include <cstdlib>

#ifdef WALKGRAPH_HAVE_MPI
#include <mpi.h>
#endif

namespace walkgraph_cli {

#ifdef WALKGRAPH_HAVE_MPI

namespace {

// Whether an MPI launcher started this process (OpenMPI's mpirun, PMI / PMIx: MPICH, srun).
bool StartedByLauncher() {
  for (const char* var : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "PMI_RANK"}) {
    if (std::getenv(var) != nullptr) return true;
  }
  return false;
}

}  // namespace

MpiJob::MpiJob(int* argc, char*** argv) {
  if (!StartedByLauncher()) return;
  int provided = 0;
  if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) return;
  joined_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiJob::~MpiJob() {
  if (joined_) MPI_Finalize();
}

bool MpiJob::AllOk(bool ok) const {
  if (!joined_) return ok;
  int mine = ok ? 1 : 0, all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return all == 1;
}

walkgraph::StatusOr<std::vector<std::string>> MpiJob::Gather(const std::string& bytes) const {
  if (!joined_) return std::vector<std::string>{bytes};
  long long mine = static_cast<long long>(bytes.size());
  std::vector<long long> sizes(rank_ == 0 ? size_ : 0);
  MPI_Gather(&mine, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, 0, MPI_COMM_WORLD);
  long long total = 0;
  for (long long s : sizes) total += s;
  // Every rank must take part in the Gatherv, or none: rank 0 says which.
  const int fits = Broadcast(total <= INT_MAX ? 1 : 0);
  if (fits == 0) {
    return walkgraph::InvalidArgument("the ranks' results exceed 2 GiB: use --shard and merge");
  }
  std::vector<int> counts(sizes.size()), displs(sizes.size());
  int at = 0;
  for (size_t r = 0; r < sizes.size(); ++r) {
    counts[r] = static_cast<int>(sizes[r]);
    displs[r] = at;
    at += counts[r];
  }
  std::string all(rank_ == 0 ? static_cast<size_t>(total) : 0, '\0');
  MPI_Gatherv(bytes.data(), static_cast<int>(bytes.size()), MPI_CHAR, all.data(), counts.data(),
              displs.data(), MPI_CHAR, 0, MPI_COMM_WORLD);
  std::vector<std::string> out;
  for (size_t r = 0; r < sizes.size(); ++r) out.push_back(all.substr(displs[r], counts[r]));
  return out;
}

int MpiJob::Broadcast(int value) const {
  if (joined_) MPI_Bcast(&value, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return value;
}

SharedCounter::SharedCounter(const MpiJob& job) {
  if (!job.joined()) return;
  int* base = nullptr;
  auto* win = new MPI_Win;
  const MPI_Aint bytes = job.rank() == 0 ? sizeof(int) : 0;
  MPI_Win_allocate(bytes, sizeof(int), MPI_INFO_NULL, MPI_COMM_WORLD, &base, win);
  if (job.rank() == 0) {
    MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, *win);
    *base = 0;
    MPI_Win_unlock(0, *win);
  }
  MPI_Barrier(MPI_COMM_WORLD);  // the counter is 0 before anyone adds to it
  window_ = win;
}

SharedCounter::~SharedCounter() {
  if (window_ == nullptr) return;
  auto* win = static_cast<MPI_Win*>(window_);
  MPI_Win_free(win);
  delete win;
}

int SharedCounter::FetchAdd() {
  if (window_ == nullptr) return local_++;
  MPI_Win win = *static_cast<MPI_Win*>(window_);
  const int one = 1;
  int before = 0;
  MPI_Win_lock(MPI_LOCK_SHARED, 0, 0, win);
  MPI_Fetch_and_op(&one, &before, MPI_INT, 0, 0, MPI_SUM, win);
  MPI_Win_unlock(0, win);
  return before;
}

#else  // one process

MpiJob::MpiJob(int*, char***) {}
MpiJob::~MpiJob() = default;
bool MpiJob::AllOk(bool ok) const { return ok; }
walkgraph::StatusOr<std::vector<std::string>> MpiJob::Gather(const std::string& bytes) const {
  return std::vector<std::string>{bytes};
}
int MpiJob::Broadcast(int value) const { return value; }
SharedCounter::SharedCounter(const MpiJob&) {}
SharedCounter::~SharedCounter() = default;
int SharedCounter::FetchAdd() { return local_++; }

#endif

}  // namespace walkgraph_cli
