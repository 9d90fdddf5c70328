#!/usr/bin/env bash
# A scenario's Monte Carlo runs shared among MPI ranks (issue 23): `mpirun -np N walkgraph
# compare --scenario ... --runs R` must write the bytes of the one-process run for N = 1, 2, 3:
# every file but timing.json (run times) and report.html's runtime column. A run that fails on a
# rank must fail the whole command once, naming the run, with no output folder.
# Usage: compare_mpi_test.sh CLI MPIEXEC
set -euo pipefail
cli=$1
mpiexec=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

fail() {
  echo "FAIL: $*" >&2
  exit 1
}
# report.html without the runtime cells (the cell before the n_points one).
report() {
  sed -E 's#<td data-v="[^"]*"( class="best" title="best in column")?>[0-9.]+</td>(<td data-v="[0-9]+\.000">)#<td>runtime</td>\2#g' "$1"
}
same() {  # same DIR_A DIR_B
  [ -f "$2/.walkgraph-output" ] || fail "$2 has no output marker"
  local files
  files=$(cd "$1" && find . -type f ! -name timing.json ! -name report.html ! -name .walkgraph-output | sort)
  [ "$files" = "$(cd "$2" && find . -type f ! -name timing.json ! -name report.html ! -name .walkgraph-output | sort)" ] ||
    fail "$2 holds other files than $1"
  for f in $files; do
    cmp "$1/$f" "$2/$f" || fail "$2/$f differs from $1/$f"
  done
  cmp <(report "$1/report.html") <(report "$2/report.html") ||
    fail "$2/report.html differs from $1/report.html (runtime aside)"
}
run_mpi() {  # run_mpi NP ARGS...
  local np=$1
  shift
  "$mpiexec" --oversubscribe -np "$np" "$cli" "$@"
}

echo "{duration_s: 60}" > ok.yaml
echo "{duration_s: 0.5}" > bad.yaml  # refused by the simulator, on every run
args=(compare --scenario linear-gaussian --runs 5 --seed 7 --threads 1)

"$cli" "${args[@]}" --scenario-config ok.yaml --out plain > /dev/null
[ "$(grep -c ',4$' plain/errors.csv)" -gt 0 ] || fail "plain/errors.csv: no rows of run 4"
grep -q '"pcrb_rmse_m": [0-9]' plain/results.json || fail "plain/results.json: no PCRB"
for np in 1 2 3; do
  run_mpi "$np" "${args[@]}" --scenario-config ok.yaml --out "mpi$np" > "out$np.txt"
  same plain "mpi$np"
  [ "$(grep -c '^wrote mpi' "out$np.txt")" -eq 1 ] || fail "-np $np: rank 0 alone must write"
done

# Every run fails: rank 0 reports its first run's failure, once.
for np in 2 3; do
  if run_mpi "$np" "${args[@]}" --scenario-config bad.yaml --out "bad$np" > /dev/null 2> err.txt; then
    fail "-np $np: failing runs passed"
  fi
  [ "$(grep -c '^walkgraph: run 0 (seed [0-9]*): bad.yaml: ' err.txt)" -eq 1 ] ||
    fail "-np $np message: $(cat err.txt)"
  [ ! -e "bad$np" ] || fail "-np $np: a failed compare wrote bad$np/"
done
# A run that fails on rank 1 alone (its runs given the bad overrides) fails the command: rank 0
# names rank 1's run and writes nothing.
if "$mpiexec" --oversubscribe -np 1 "$cli" "${args[@]}" --scenario-config ok.yaml --out bad1 : \
  -np 1 "$cli" "${args[@]}" --scenario-config bad.yaml --out bad1 > /dev/null 2> err.txt; then
  fail "a run failing on rank 1 passed"
fi
[ "$(grep -c '^walkgraph: run 1 (seed [0-9]*): bad.yaml: ' err.txt)" -eq 1 ] ||
  fail "rank 1 message: $(cat err.txt)"
[ ! -e bad1 ] || fail "a run failing on rank 1 wrote bad1/"
echo "compare under MPI: -np 1, 2, 3 == one process; a failing run fails the command"
