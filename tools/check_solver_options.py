#!/usr/bin/env python3
"""Checks that Ceres' solver options are filled in one place: ToCeres (src/smoothers/graph.cc).

Usage: tools/check_solver_options.py [--root DIR]
Every graph (fg-batch, fg-window, fg-ins-batch, fg-ins-window, Python's FactorGraph) states its
solver settings as walkgraph's SolverOptions (include/walkgraph/graph.h) and reaches Ceres through
ToCeres, directly or by SolveBatch / FixedLagSmoother. This script prints each line of src/,
tools/, python/ and factors/ outside graph.cc that declares a ceres::Solver::Options to fill
(`ceres::Solver::Options name;` or `{...}`) or sets a field only Ceres' options have, and exits
1 if there is any.
"""
import argparse
import os
import re
import sys

ALLOWED = {os.path.join("src", "smoothers", "graph.cc")}
SCANNED = ["src", "tools", "python", "factors"]
# A Ceres options object made to be filled (not one taken from ToCeres or passed by reference).
FILLED = re.compile(r"ceres::Solver::Options\s+\w+\s*(;|\{)")
# Fields of ceres::Solver::Options that walkgraph's SolverOptions names otherwise or not at all.
CERES_ONLY = re.compile(
    r"\.\s*(max_num_iterations|linear_solver_type|sparse_linear_algebra_library_type|"
    r"minimizer_type|trust_region_strategy_type|minimizer_progress_to_stdout|logging_type|"
    r"dense_linear_algebra_library_type|use_nonmonotonic_steps|max_solver_time_in_seconds)\b")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."))
    root = os.path.abspath(ap.parse_args().root)
    problems, scanned = [], 0
    for d in SCANNED:
        for base, _, names in os.walk(os.path.join(root, d)):
            for n in sorted(names):
                if not n.endswith((".h", ".cc", ".cpp")):
                    continue
                rel = os.path.relpath(os.path.join(base, n), root)
                scanned += 1
                if rel in ALLOWED:
                    continue
                with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
                    for i, line in enumerate(f, 1):
                        if FILLED.search(line) or CERES_ONLY.search(line):
                            problems.append(f"{rel}:{i}: {line.strip()}")
    for p in problems:
        print(p)
    print(f"{scanned} files: " + (f"FAIL: {len(problems)} line(s) fill Ceres' solver options "
                                  "outside ToCeres (src/smoothers/graph.cc)" if problems
                                  else "Ceres' solver options are filled only by ToCeres"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
