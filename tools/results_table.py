#!/usr/bin/env python3
"""Prints a markdown table from a `walkgraph compare` results.json (for docs/results.md blocks).

    tools/results_table.py RESULTS_JSON COLUMN...
    tools/results_table.py --pivot COLUMN NAME=RESULTS_JSON...

COLUMN is a metric key of results.json's estimators (rmse_m, p90_m, ipin_score_m,
floor_hit_rate, anees, ...). A Monte Carlo result prints mean ± std over its runs; an estimator
with diverged or failed runs says how many. --pivot prints one COLUMN of several results (one
table column per NAME, e.g. a preset), one row per estimator in the order first seen; "—"
where an estimator was not run on that walk, "diverged" where every run diverged.
"""
import json
import math
import sys


def number(v):
    return "%.3g" % v if abs(v) >= 1000 else "%.3f" % v


def cell(e, key):
    v = e.get(key)
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    sd = e.get(key + "_std")
    if sd is None or not math.isfinite(sd):
        return number(v)
    return number(v) + " ± " + number(sd)


def pivot(col, named):
    tables = []
    for arg in named:
        name, _, path = arg.partition("=")
        if not path:
            sys.exit("--pivot takes NAME=RESULTS_JSON, not " + arg)
        with open(path) as f:
            tables.append((name, json.load(f)))
    ids = []
    for _, r in tables:
        ids += [i for i in r["estimators"] if i not in ids]
    print("| estimator | " + " | ".join("`%s`" % n for n, _ in tables) + " |")
    print("|---" * (len(tables) + 1) + "|")
    for i in ids:
        cells = []
        for _, r in tables:
            e = r["estimators"].get(i)
            if e is None:
                cells.append("—")
            elif e.get("diverged_runs", 0) + e.get("failed_runs", 0) >= r.get("runs", 1):
                cells.append("diverged" if e.get("diverged_runs", 0) else "fails")
            else:
                bad = e.get("diverged_runs", 0)
                cells.append(cell(e, col) + (" (%d diverged)" % bad if bad else ""))
        print("| `%s` | " % i + " | ".join(cells) + " |")


def main(argv):
    if len(argv) >= 4 and argv[1] == "--pivot":
        pivot(argv[2], argv[3:])
        return
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
