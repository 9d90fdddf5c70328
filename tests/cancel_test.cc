// walkgraph/cancel.h: the process-wide cancellation request.
#include "walkgraph/cancel.h"

#include <signal.h>

#include <gtest/gtest.h>

#include "walkgraph/output.h"  // still declares cancellation for its callers

namespace walkgraph {
namespace {

TEST(Cancel, RequestIsSeenWithItsSignalUntilCleared) {
  ClearCancelRequest();
  EXPECT_FALSE(CancelRequested());
  EXPECT_EQ(CancelSignal(), 0);
  RequestCancel(SIGTERM);
  EXPECT_TRUE(CancelRequested());
  EXPECT_EQ(CancelSignal(), SIGTERM);
  RequestCancel(SIGHUP);  // the latest signal is the one reported
  EXPECT_EQ(CancelSignal(), SIGHUP);
  ClearCancelRequest();
  EXPECT_FALSE(CancelRequested());
  EXPECT_EQ(CancelSignal(), 0);
}

TEST(Cancel, OutputHeaderKeepsDeclaringCancellation) {
  // walkgraph/output.h includes cancel.h: its callers (the CLI, the writers) need nothing else.
  RequestCancel(SIGINT);
  const bool seen = CancelRequested();
  ClearCancelRequest();
  EXPECT_TRUE(seen);
  EXPECT_FALSE(OutputInProgress());
}

}  // namespace
}  // namespace walkgraph
