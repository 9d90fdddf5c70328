// The process-wide cancellation request (walkgraph/cancel.h).
#include "walkgraph/cancel.h"

#include <atomic>

namespace walkgraph {

namespace {

static_assert(std::atomic<int>::is_always_lock_free, "signal handlers need lock-free atomics");
static_assert(std::atomic<bool>::is_always_lock_free, "signal handlers need lock-free atomics");

std::atomic<int> g_cancel_signal{0};
std::atomic<bool> g_cancel{false};

}  // namespace

void RequestCancel(int signal_number) noexcept {
  g_cancel_signal.store(signal_number);
  g_cancel.store(true);
}
bool CancelRequested() noexcept { return g_cancel.load(); }
int CancelSignal() noexcept { return g_cancel_signal.load(); }
void ClearCancelRequest() noexcept {
  g_cancel.store(false);
  g_cancel_signal.store(0);
}

}  // namespace walkgraph
