#!/usr/bin/env bash
# Runs every estimator benchmark in its own process (so peak memory is per benchmark) and writes
# OUT/bench.json and OUT/bench.md. Usage: tools/run_benchmarks.sh [BUILD_DIR] [OUT_DIR] [FILTER]
#   FILTER: a regex over "<estimator>/<walk>/" (default: everything except the 10 h walks).
set -euo pipefail
build=${1:-build}
out=${2:-out/bench}
filter=${3:-'^[^/]+/((hip|foot)-(1|10|16|60)min|plaza1)/'}
bench="$build/tools/bench_estimators"
[ -x "$bench" ] || { echo "run_benchmarks: $bench not built" >&2; exit 1; }
mkdir -p "$out"
# The per-benchmark JSON files go to a folder of our own (OUT may hold the user's files: only
# bench.json and bench.md are written there, at the end).
raw=$(mktemp -d "${TMPDIR:-/tmp}/walkgraph-bench.XXXXXX")
trap 'rm -rf "$raw"' EXIT
mapfile -t names < <("$bench" --benchmark_list_tests=true --benchmark_filter="$filter")
i=0
for name in "${names[@]}"; do
  i=$((i + 1))
  echo "[$i/${#names[@]}] $name" >&2
  "$bench" --benchmark_filter="^${name}\$" --benchmark_out="$raw/$(printf %04d $i).json" \
    --benchmark_out_format=json > /dev/null
done
"$bench" --wg_summarize "$raw"
mv "$raw/bench.json" "$out/bench.json.tmp" && mv "$out/bench.json.tmp" "$out/bench.json"
mv "$raw/bench.md" "$out/bench.md.tmp" && mv "$out/bench.md.tmp" "$out/bench.md"
