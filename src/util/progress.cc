// Progress inside a running estimator (walkgraph/progress.h).
#include "walkgraph/progress.h"

#include <algorithm>
#include <utility>

namespace walkgraph {

namespace {
thread_local ScopedEstimatorProgress* g_estimator_progress = nullptr;
}  // namespace

void ReportEstimatorProgress(double fraction) {
  ScopedEstimatorProgress* p = g_estimator_progress;
  if (p == nullptr || !p->callback_) return;
  if (fraction > p->reached_) p->reached_ = std::min(fraction, 1.0);  // NaN: no step
  p->callback_(p->reached_);
}

ScopedEstimatorProgress::ScopedEstimatorProgress(std::function<void(double)> callback)
    : callback_(std::move(callback)), previous_(g_estimator_progress) {
  g_estimator_progress = this;
}

ScopedEstimatorProgress::~ScopedEstimatorProgress() { g_estimator_progress = previous_; }

}  // namespace walkgraph
