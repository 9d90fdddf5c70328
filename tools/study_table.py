#!/usr/bin/env python3
"""Prints one sweep of a `walkgraph study` study.csv as a markdown table (for docs/results.md).

    tools/study_table.py STUDY_CSV SWEEP METRIC [--column "TITLE=V1 V2 ..."]... [--label TEXT]

One row per swept value (in the file's order), one column per estimator with the metric's
mean ± std over the cell's runs ("failed" where every run failed, "(k diverged)" after a mean
that left k runs out). --column adds a column of given values before the estimators (e.g. a
paper's published figures, one per swept value, in the same order).
"""
import argparse
import csv


def cell(row, metric):
    if not row.get(metric):
        return "failed"
    text = "%.3f" % float(row[metric])
    if row.get(metric + "_std"):
        text += " ± %.3f" % float(row[metric + "_std"])
    diverged = int(row.get("diverged_runs") or 0)
    return text + (" (%d diverged)" % diverged if diverged else "")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("sweep")
    ap.add_argument("metric")
    ap.add_argument("--column", action="append", default=[])
    ap.add_argument("--label")
    a = ap.parse_args()
    with open(a.csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["sweep"] == a.sweep]
    if not rows:
        raise SystemExit("%s: no sweep '%s'" % (a.csv, a.sweep))
    values, estimators, by = [], [], {}
    for r in rows:
        if r["value"] not in values:
            values.append(r["value"])
        if r["estimator"] not in estimators:
            estimators.append(r["estimator"])
        by[(r["value"], r["estimator"])] = r
    extra = []
    for c in a.column:
        title, _, vals = c.partition("=")
        vals = vals.split()
        if len(vals) != len(values):
            raise SystemExit("--column %s: %d values for %d swept values" %
                             (title, len(vals), len(values)))
        extra.append((title, vals))
    head = [a.label or rows[0]["parameter"]] + [t for t, _ in extra] + ["`%s`" % e for e in estimators]
    print("| " + " | ".join(head) + " |")
    print("|---" * len(head) + "|")
    for i, v in enumerate(values):
        cells = [v] + [vals[i] for _, vals in extra]
        cells += [cell(by[(v, e)], a.metric) if (v, e) in by else "—" for e in estimators]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
