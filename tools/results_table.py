#!/usr/bin/env python3
"""Prints a markdown table from a `walkgraph compare` results.json (for docs/results.md blocks).

    tools/results_table.py RESULTS_JSON COLUMN...

COLUMN is a metric key of results.json's estimators (rmse_m, p90_m, ipin_score_m,
floor_hit_rate, anees, ...). A Monte Carlo result prints mean ± std over its runs; an estimator
with diverged or failed runs says how many.
"""
import json
import math
import sys


def cell(e, key):
    v = e.get(key)
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    sd = e.get(key + "_std")
    if sd is None or not math.isfinite(sd):
        return "%.3f" % v
    return "%.3f ± %.3f" % (v, sd)


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    with open(argv[1]) as f:
        results = json.load(f)
    cols = argv[2:]
    runs = results.get("runs", 1)
    print("| estimator | " + " | ".join(cols) + " | runs diverged / failed |")
    print("|---" * (len(cols) + 2) + "|")
    for name, e in results["estimators"].items():
        bad = "%d / %d of %d" % (e.get("diverged_runs", 0), e.get("failed_runs", 0), runs)
        print("| `%s` | " % name + " | ".join(cell(e, c) for c in cols) + " | %s |" % bad)
    for key, label in (("pcrb_rmse_m", "PCRB (smoother)"), ("pcrb_filter_rmse_m", "PCRB (filter)")):
        v = results.get(key)
        if isinstance(v, (int, float)) and math.isfinite(v) and "rmse_m" in cols:
            row = ["%.3f" % v if c == "rmse_m" else "" for c in cols]
            print("| %s | " % label + " | ".join(row) + " | |")


if __name__ == "__main__":
    main(sys.argv)
