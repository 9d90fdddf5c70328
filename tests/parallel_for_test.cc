// util/parallel_for.h: the library's one worker pool.
#include "util/parallel_for.h"

#include <signal.h>

#include <atomic>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "walkgraph/cancel.h"

namespace walkgraph::internal {
namespace {

TEST(ParallelFor, RunsEveryIndexOnceOnAnyNumberOfThreads) {
  for (int threads : {0, 1, 3, 16}) {
    std::vector<std::atomic<int>> runs(50);
    const Status s = ParallelFor(0, 50, threads, [&](int i) {
      runs[i].fetch_add(1);
      return Status::Ok();
    });
    ASSERT_TRUE(s.ok()) << s.message();
    for (int i = 0; i < 50; ++i) EXPECT_EQ(runs[i].load(), 1) << "index " << i;
  }
  EXPECT_TRUE(ParallelFor(5, 5, 4, [](int) { return InternalError("never called"); }).ok());
}

TEST(ParallelFor, OneThreadRunsInOrderAndStopsAtTheFirstFailure) {
  std::vector<int> order;
  const Status s = ParallelFor(2, 9, 1, [&](int i) {
    order.push_back(i);
    return i == 5 ? InvalidArgument("five") : Status::Ok();
  });
  EXPECT_EQ(s.message(), "five");
  EXPECT_EQ(order, (std::vector<int>{2, 3, 4, 5}));
}

TEST(ParallelFor, ReturnsTheFailureOfTheSmallestFailedIndex) {
  const Status s = ParallelFor(0, 40, 4, [](int i) {
    return i % 10 == 7 ? InvalidArgument("index " + std::to_string(i)) : Status::Ok();
  });
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "index 7");
}

TEST(ParallelFor, ExceptionsBecomeStatuses) {
  EXPECT_EQ(ParallelFor(0, 3, 2,
                        [](int i) -> Status {
                          if (i == 1) throw std::runtime_error("boom");
                          return Status::Ok();
                        })
                .message(),
            "unexpected exception: boom");
  EXPECT_EQ(ParallelFor(0, 1, 1, [](int) -> Status { throw std::bad_alloc(); }).message(),
            "out of memory");
}

TEST(ParallelFor, ACancelRequestStopsTheLoop) {
  std::atomic<int> ran{0};
  const Status s = ParallelFor(0, 100, 1, [&](int i) {
    ran.fetch_add(1);
    if (i == 3) RequestCancel(SIGINT);
    return Status::Ok();
  });
  ClearCancelRequest();
  EXPECT_EQ(s.code(), StatusCode::kCancelled);
  EXPECT_EQ(s.message(), "interrupted (signal " + std::to_string(SIGINT) + ")");
  EXPECT_EQ(ran.load(), 4);
}

}  // namespace
}  // namespace walkgraph::internal
