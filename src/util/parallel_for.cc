#include "util/parallel_for.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <new>
#include <system_error>
#include <thread>
#include <vector>

#include "walkgraph/cancel.h"
#include "walkgraph/parallel.h"

namespace walkgraph {

StatusOr<int> ResolveThreads(int requested, int work_items) {
  if (requested > kMaxThreads) {
    return InvalidArgument("threads " + std::to_string(requested) + " is above the limit of " +
                           std::to_string(kMaxThreads) + " (0 = one per hardware thread)");
  }
  int threads = requested > 0 ? requested
                              : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min({threads, std::max(1, work_items), kMaxThreads});
  return threads;
}

namespace internal {

namespace {

Status Guarded(const std::function<Status(int)>& body, int i) {
  try {
    return body(i);
  } catch (const std::bad_alloc&) {
    return InternalError("out of memory");
  } catch (const std::exception& e) {
    return InternalError(std::string("unexpected exception: ") + e.what());
  } catch (...) {
    return InternalError("unexpected exception");
  }
}

}  // namespace

Status ParallelFor(int begin, int end, int threads, const std::function<Status(int)>& body) {
  std::atomic<int> next{begin};
  std::atomic<bool> stop{false};
  std::mutex mutex;
  int failed_index = end;
  Status failure;
  auto worker = [&] {
    while (!stop.load()) {
      const int i = next.fetch_add(1);
      if (i >= end) return;
      Status s = CancelRequested()
                     ? Cancelled("interrupted (signal " + std::to_string(CancelSignal()) + ")")
                     : Guarded(body, i);
      if (!s.ok()) {
        std::lock_guard<std::mutex> lock(mutex);
        if (i < failed_index) {
          failed_index = i;
          failure = std::move(s);
        }
        stop.store(true);
      }
    }
  };
  std::vector<std::thread> pool;
  const int wanted = std::min(threads, end - begin);
  for (int t = 1; t < wanted; ++t) {
    try {
      pool.emplace_back(worker);
    } catch (const std::system_error&) {
      break;  // the caller's thread and the workers started so far share the work
    }
  }
  worker();
  for (std::thread& t : pool) t.join();
  return failure;
}

}  // namespace internal

}  // namespace walkgraph
