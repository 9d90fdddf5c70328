#!/usr/bin/env bash
# One study through every way of running it (issue 23): one process, and either its parts
# (--shard i/n) merged with `study merge`, or (given an MPI launcher) mpirun -np 1, 2 and 3.
# study.csv and study.html must be byte-identical to the one-process run's (timing.csv holds
# run times, which differ). A cell that fails on another part or rank than 0 must fail the whole
# study, naming the cell, with no output folder.
# Usage: study_parts_test.sh CLI [MPIEXEC]
set -euo pipefail
cli=$1
mpiexec=${2:-}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

fail() {
  echo "FAIL: $*" >&2
  exit 1
}
same() {  # same DIR_A DIR_B
  for f in study.csv study.html; do
    cmp "$1/$f" "$2/$f" || fail "$2/$f differs from $1/$f"
  done
  [ -f "$2/.walkgraph-output" ] || fail "$2 has no output marker"
}

# 7 cells of two costs (4 × 3 runs, 3 × 2 runs); the PCRB on (linear-gaussian has it).
manifest() {  # manifest RANGE_VALUES
  cat <<EOF
name: parts
estimators: [odometry-dr]
runs: 3
seed: 11
sweeps:
  - name: step-noise
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    scenario_override: step_sigma_m
    values: [0.02, 0.04, 0.06, 0.1]
  - name: range-noise
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    scenario_override: range_sigma_m
    values: $1
    runs: 2
EOF
}
manifest "[0.1, 0.3, 0.9]" > m.yaml
# Cell 5 (range-noise, -1: refused by the simulator) is part 1 of 2 and part 2 of 3.
manifest "[0.1, -1, 0.9]" > bad.yaml
bad_cell="bad.yaml:15: sweep 'range-noise', value -1"

"$cli" study m.yaml --out plain > /dev/null
[ "$(wc -l < plain/study.csv)" -eq 8 ] || fail "plain/study.csv: expected 7 rows"
grep -q '^range-noise,range_sigma_m,0.9,odometry-dr,2,11,' plain/study.csv ||
  fail "plain/study.csv: no range-noise row"

if [ -z "$mpiexec" ]; then
  for n in 2 3; do
    parts=()
    for ((i = n - 1; i >= 0; i--)); do
      "$cli" study m.yaml --shard "$i/$n" --out "part$i-$n" > /dev/null
      parts+=("part$i-$n")
    done
    "$cli" study merge "${parts[@]}" --out "merged$n" > /dev/null
    same plain "merged$n"
  done
  # An incomplete set of parts is refused, and nothing is written.
  if "$cli" study merge part0-3 part2-3 --out partial 2> err.txt; then fail "merged 2 of 3 parts"; fi
  grep -q "study part 1/3 is missing" err.txt || fail "merge message: $(cat err.txt)"
  [ ! -e partial ] || fail "an incomplete merge wrote partial/"
  # A failing cell in part 1 of 2: that part fails naming it; part 0 runs.
  if "$cli" study bad.yaml --shard 1/2 --out bad1 2> err.txt; then fail "bad part 1/2 passed"; fi
  grep -qF "$bad_cell" err.txt || fail "part message: $(cat err.txt)"
  [ ! -e bad1 ] || fail "a failed part wrote bad1/"
  "$cli" study bad.yaml --shard 0/2 --out bad0 > /dev/null || fail "part 0/2 of bad.yaml failed"
  echo "study parts: plain == merged (2 and 3 parts); incomplete and failing parts refused"
  exit 0
fi

run_mpi() {  # run_mpi NP ARGS...
  local np=$1
  shift
  "$mpiexec" --oversubscribe -np "$np" "$cli" "$@"
}
for np in 1 2 3; do
  run_mpi "$np" study m.yaml --out "mpi$np" > "out$np.txt"
  same plain "mpi$np"
  [ "$(grep -c '^wrote mpi' "out$np.txt")" -eq 1 ] || fail "-np $np: rank 0 alone must write"
done
for np in 2 3; do
  if run_mpi "$np" study bad.yaml --out "bad$np" > /dev/null 2> err.txt; then
    fail "-np $np: a failing cell passed"
  fi
  [ "$(grep -cF "walkgraph: $bad_cell" err.txt)" -eq 1 ] || fail "-np $np message: $(cat err.txt)"
  [ ! -e "bad$np" ] || fail "-np $np: a failed study wrote bad$np/"
done
echo "study under MPI: -np 1, 2, 3 == one process; a failing cell on rank 1 fails the study"
