#!/usr/bin/env python3
"""Checks that includes run one way: from a folder to itself or to a lower one, never up.

Usage: tools/check_layers.py [--root DIR] [--list]
Reads every #include "..." in src/, include/walkgraph/, factors/, tools/ and python/, resolves it
to a file of the tree and prints each include from a lower layer to a higher one; exits 1 if
there is any, or if a file of those folders has no layer. --list prints the layers and their
files' counts.

LAYERS below is the one place where the order is written down (docs/library.md describes it).
A layer may include itself and any layer above it in the list (lower, more basic). A file
belongs to the layer of the longest entry that is a prefix of its path; public headers are
placed by name next to the folder that implements them.
"""
import argparse
import os
import re
import sys

# Lowest first.
LAYERS = [
    ("core", [  # status, walk and trajectory types, small helpers, cancellation, progress
        "src/util/", "src/log.h", "src/logging.cc", "src/status.cc", "src/walk.cc",
        "include/walkgraph/angle.h", "include/walkgraph/barometric.h",
        "include/walkgraph/cancel.h", "include/walkgraph/enum_names.h",
        "include/walkgraph/estimate_result.h",
        "include/walkgraph/logging.h", "include/walkgraph/measurements.h",
        "include/walkgraph/parallel.h", "include/walkgraph/progress.h",
        "include/walkgraph/sim_truth.h", "include/walkgraph/status.h",
        "include/walkgraph/trajectory.h", "include/walkgraph/walk.h"]),
    ("config", ["src/config/", "include/walkgraph/config.h"]),  # ConfigReader (YAML maps)
    ("io", ["src/io/", "include/walkgraph/io.h", "include/walkgraph/output.h"]),
    ("convert", ["src/convert/", "include/walkgraph/convert.h"]),
    ("kalman", ["src/kalman/", "include/walkgraph/kalman.h", "include/walkgraph/kalman_driver.h"]),
    ("stance", ["src/stance/", "include/walkgraph/stance.h"]),
    ("ins", ["src/ins/", "include/walkgraph/strapdown.h", "include/walkgraph/strides.h"]),
    ("pdr", ["src/pdr/", "include/walkgraph/pdr.h"]),
    ("radio", ["src/radio/", "include/walkgraph/radio.h", "include/walkgraph/path_loss.h"]),
    ("simulate", ["src/simulate/", "include/walkgraph/simulate.h"]),
    ("factors", ["factors/"]),
    # The estimator interface, the paper filters, the graph core and smoothers, the registry
    # and the estimators' option parsers: one layer (the registry's box in ARCHITECTURE.md).
    ("estimators", [
        "src/estimators/", "src/filters/", "src/smoothers/", "src/config/parsers.h",
        "include/walkgraph/estimator.h", "include/walkgraph/dead_reckoning.h",
        "include/walkgraph/zupt_ins.h", "include/walkgraph/graph.h",
        "include/walkgraph/filters/", "include/walkgraph/smoothers/"]),
    ("eval", ["src/eval/", "include/walkgraph/metrics.h", "include/walkgraph/divergence.h",
              "include/walkgraph/compare.h", "include/walkgraph/pcrb.h",
              "include/walkgraph/survey.h"]),
    ("report", ["src/report/"]),
    ("study", ["src/study/", "include/walkgraph/study.h"]),
    ("bindings", ["tools/", "python/"]),
]

SCANNED = ["src", "include/walkgraph", "factors", "tools", "python"]
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def layer_of(path):
    best = None
    for rank, (name, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if path.startswith(p) and (best is None or len(p) > best[2]):
                best = (rank, name, len(p))
    return best


def resolve(root, source, target):
    """The tree path an include names, or None (a system or generated header)."""
    candidates = [os.path.join(os.path.dirname(source), target)]
    if target.startswith("walkgraph/factors/"):
        candidates.append(target[len("walkgraph/"):])
    candidates += [os.path.join("include", target), os.path.join("src", target), target]
    for c in candidates:
        c = os.path.normpath(c)
        if os.path.isfile(os.path.join(root, c)):
            return c
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."))
    ap.add_argument("--list", action="store_true")
    a = ap.parse_args()
    root = os.path.abspath(a.root)
    files = []
    for d in SCANNED:
        for base, _, names in os.walk(os.path.join(root, d)):
            files += [os.path.relpath(os.path.join(base, n), root) for n in names
                      if n.endswith((".h", ".cc", ".cpp"))]
    problems, counts = [], {}
    for f in sorted(files):
        own = layer_of(f)
        if own is None:
            problems.append(f"{f}: in no layer (add it to LAYERS in tools/check_layers.py)")
            continue
        counts[own[1]] = counts.get(own[1], 0) + 1
        text = open(os.path.join(root, f), encoding="utf-8", errors="replace").read()
        for m in INCLUDE.finditer(text):
            target = resolve(root, f, m.group(1))
            if target is None:
                continue
            theirs = layer_of(target)
            if theirs is None:
                problems.append(f"{f}: includes {target}, which is in no layer")
            elif theirs[0] > own[0]:
                line = text.count("\n", 0, m.start()) + 1
                problems.append(f"{f}:{line}: {own[1]} includes {m.group(1)} ({theirs[1]})")
    if a.list:
        for name, _ in LAYERS:
            print(f"{name:12s} {counts.get(name, 0):4d} files")
    for p in problems:
        print(p)
    print(f"{len(files)} files, {len(LAYERS)} layers: " +
          (f"FAIL: {len(problems)} include(s) up or file(s) without a layer" if problems
           else "every include runs down"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
