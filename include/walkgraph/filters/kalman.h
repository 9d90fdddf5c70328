// Moved to walkgraph/kalman.h (below filters/, so that ins/ and the smoothers include it without
// pointing up into filters/). This forwarding header remains for the includes outside filters/
// that still name the old path; new code includes walkgraph/kalman.h.
#ifndef WALKGRAPH_FILTERS_KALMAN_H_
#define WALKGRAPH_FILTERS_KALMAN_H_

#include "walkgraph/kalman.h"

#endif  // WALKGRAPH_FILTERS_KALMAN_H_
