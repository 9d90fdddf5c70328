// Cancellation: RequestCancel() (async-signal-safe) asks the library to stop. Long loops poll
// CancelRequested() and return kCancelled: the Kalman driver, the graph solves, the fixed-lag
// smoother, ParallelFor and the output writers (walkgraph/output.h, which leave the old output
// untouched). The walkgraph CLI calls RequestCancel from its SIGINT/SIGTERM/SIGHUP handlers, the
// Python module on Ctrl-C.
#ifndef WALKGRAPH_CANCEL_H_
#define WALKGRAPH_CANCEL_H_

namespace walkgraph {

// RequestCancel, CancelRequested and CancelSignal are async-signal-safe.
void RequestCancel(int signal_number) noexcept;
bool CancelRequested() noexcept;
// The signal passed to RequestCancel (0 when none).
int CancelSignal() noexcept;
// Clears a request (tests, or a program that goes on after a cancelled operation).
void ClearCancelRequest() noexcept;

}  // namespace walkgraph

#endif  // WALKGRAPH_CANCEL_H_
