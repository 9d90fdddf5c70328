// The results table of report.html (internal): one row per ranked estimator, grouped by family,
// the best value of each column marked, diverged and failed estimators in a table of their own.
#ifndef WALKGRAPH_SRC_REPORT_REPORT_TABLE_H_
#define WALKGRAPH_SRC_REPORT_REPORT_TABLE_H_

#include <string>
#include <vector>

#include "report/estimator_style.h"
#include "walkgraph/compare.h"

namespace walkgraph::report {

// `styles[k]` is the style of comparison.outcomes[k].
std::string ResultsTableHtml(const Comparison& comparison, const std::vector<LineStyle>& styles);

}  // namespace walkgraph::report

#endif  // WALKGRAPH_SRC_REPORT_REPORT_TABLE_H_
