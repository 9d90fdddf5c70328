#!/usr/bin/env bash
# Peak memory of the CLI where it must not grow (issue 16): Monte Carlo runs, and a long walk.
# Usage: tools/bench_memory.sh [BUILD_DIR] [OUT_DIR] [RUNS...]
#   RUNS: Monte Carlo run counts (default: 100 1000 10000; 10000 runs take ~6 min).
# Writes OUT_DIR/memory.md: the peak resident set size (the kernel's ru_maxrss) of
#   walkgraph compare --scenario tarrio-circle --runs N --estimators rss-only,tarrio-kf
# for each N, and of `walkgraph compare` (every applicable estimator) on a 10-h tarrio-circle
# walk simulated with seed 1. Set WALKGRAPH_BENCH_LONG=0 to leave the long walk out (~4 min).
# WALKGRAPH_BENCH_MPI=1 adds, for each N, `mpirun -np 2 walkgraph study` of a study of two cells
# (the same scenario and estimators, eta 2.5 and 3.0; one cell per rank) of N runs each, --threads
# 1: the peak RSS of its largest process (a rank), i.e. memory per rank against N.
set -euo pipefail
build=${1:-build}
out=${2:-out/bench-memory}
shift $(( $# > 2 ? 2 : $# )) || true
runs=("$@")
[ ${#runs[@]} -gt 0 ] || runs=(100 1000 10000)
cli="$build/tools/walkgraph"
[ -x "$cli" ] || { echo "bench_memory: $cli not built" >&2; exit 1; }
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Runs a command, prints "<peak RSS MB> <wall s>".
peak() {
  python3 - "$@" <<'PY'
import resource, subprocess, sys, time
t0 = time.time()
r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
if r.returncode != 0:
    sys.stderr.write(r.stderr.decode(errors="replace"))
    sys.exit(r.returncode)
print("%.1f %.1f" % (resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0,
                     time.time() - t0))
PY
}

{
  echo "| command | peak RSS [MB] | wall [s] |"
  echo "|---|---:|---:|"
  for n in "${runs[@]}"; do
    read -r mb s < <(peak "$cli" compare --scenario tarrio-circle --runs "$n" \
      --estimators rss-only,tarrio-kf --out "$work/mc")
    echo "| compare --scenario tarrio-circle --runs $n --estimators rss-only,tarrio-kf | $mb | $s |"
  done
  if [ "${WALKGRAPH_BENCH_MPI:-0}" != 0 ]; then
    [ "$(id -u)" != 0 ] || export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    for n in "${runs[@]}"; do
      printf 'name: memory\nestimators: [rss-only, tarrio-kf]\nruns: %d\nsweeps:\n  - name: eta\n    scenario: tarrio-circle\n    scenario_override: eta\n    values: [2.5, 3.0]\n' \
        "$n" > "$work/study.yaml"
      read -r mb s < <(peak mpirun --oversubscribe --bind-to none -np 2 "$cli" study \
        "$work/study.yaml" --threads 1 --out "$work/study")
      echo "| mpirun -np 2 study, 2 cells (one per rank) of $n runs, rss-only,tarrio-kf | $mb | $s |"
    done
  fi
  if [ "${WALKGRAPH_BENCH_LONG:-1}" != 0 ]; then
    echo "duration_s: 36000" > "$work/long.yaml"
    "$cli" simulate --scenario tarrio-circle --seed 1 --config "$work/long.yaml" \
      --out "$work/long10h" > /dev/null
    read -r mb s < <(peak "$cli" compare "$work/long10h" --out "$work/long")
    echo "| compare on a 10-h tarrio-circle walk (seed 1), every applicable estimator | $mb | $s |"
  fi
} | tee "$out/memory.md"
