#!/usr/bin/env bash
# The benchmark table's filter rows (every estimator id not starting with fg-), run N times
# (default 3) with the given bench_estimators, the minimum wall time per row printed (ms).
# Usage: tools/bench_filters.sh BENCH_BINARY OUT.json [N] [WALK_REGEX]
set -euo pipefail
bench=$1
out=$2
n=${3:-3}
walks=${4:-'((hip|foot)-(1|10|16)min|plaza1)'}
"$bench" --benchmark_filter="^[^f][^/]*/${walks}/|^fg-none" --benchmark_repetitions="$n" \
  --benchmark_out="$out" --benchmark_out_format=json > /dev/null 2>&1
python3 - "$out" <<'PY'
import json, sys
rows = {}
for b in json.load(open(sys.argv[1]))["benchmarks"]:
    if b.get("run_type") != "iteration" or b.get("error_occurred"):
        continue
    name = b["run_name"]
    rows[name] = min(rows.get(name, float("inf")), b["real_time"])
for name in sorted(rows):
    print(f"{name}\t{rows[name]:.3f}")
PY
