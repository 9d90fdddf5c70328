#!/usr/bin/env bash
# Study throughput across MPI ranks (issue 23). Not a test: figures for docs/studies-on-clusters.md.
# Usage: tools/bench_study_mpi.sh [BUILD_DIR] [OUT_DIR] [RUNS]
# On datasets/studies/jimenez_tables.yaml cut to RUNS runs per cell (default 3: ~2 min on one
# core; 14 cells), one thread per rank (--threads 1), ranks not bound to cores:
#   T1, T2     wall time of `mpirun -np 1|2 walkgraph study CUT --threads 1` (study.csv and
#              study.html of the two are compared byte for byte);
#   speedup    T1 / T2 (target >= 1.8 on 2 free cores);
#   balance    the CPU times of the two --shard parts, run one after the other, summed, over
#              the larger one: the speedup of 2 ranks on 2 free cores without the serial part,
#              measurable on a busy machine too (CPU time hardly depends on the load);
#   ceiling    2 T1 / (wall of two independent one-process studies run at once): what two
#              processes can gain on this machine at all (2.0 on 2 free cores);
#   serial     what does not shrink with ranks: the launch (`mpirun -np 2 walkgraph --version`)
#              plus rank 0's merge and write after the gather, measured as `walkgraph study
#              merge` of the two --shard parts of the same study;
#   s          serial / T1; Amdahl's projected efficiency on P ranks E(P) = 1 / (1 + s (P - 1)),
#              and the bound of the cells: with C cells at most C ranks have work, E <= C / P.
# Writes OUT_DIR/study-mpi.md. Run it on an otherwise idle machine (the load is recorded).
set -euo pipefail
build=${1:-build}
out=${2:-out/bench-study-mpi}
runs=${3:-3}
here=$(cd "$(dirname "$0")/.." && pwd)
cli="$(cd "$build" && pwd)/tools/walkgraph"
[ -x "$cli" ] || { echo "bench_study_mpi: $cli not built" >&2; exit 1; }
command -v mpirun > /dev/null || { echo "bench_study_mpi: mpirun not found" >&2; exit 1; }
if [ "$(id -u)" = 0 ]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
mkdir -p "$out"
out=$(cd "$out" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
sed "s/^runs: .*/runs: $runs/" "$here/datasets/studies/jimenez_tables.yaml" > cut.yaml
cells=$(python3 -c "
import re, sys
t = open('cut.yaml').read()
print(sum(len(v.split(',')) for v in re.findall(r'values: \[([^]]*)\]', t)))")

timed() {  # timed CMD...: "<wall s> <CPU s of CMD and its children>" (its output dropped)
  python3 - "$@" <<'PY'
import resource, subprocess, sys, time
t0 = time.time()
subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, check=True)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print("%.2f %.2f" % (time.time() - t0, r.ru_utime + r.ru_stime))
PY
}
seconds() { timed "$@" | cut -d' ' -f1; }
mpi=(mpirun --oversubscribe --bind-to none -np)

load0=$(cut -d' ' -f1-3 /proc/loadavg)
read -r t1 c1 < <(timed "${mpi[@]}" 1 "$cli" study cut.yaml --threads 1 --out np1)
read -r t2 c2 < <(timed "${mpi[@]}" 2 "$cli" study cut.yaml --threads 1 --out np2)
# The machine's own ceiling: two independent one-process studies at once (no MPI, nothing
# shared). On a VM whose two vCPUs are not two free cores this is well below 2x.
read -r tc _ < <(timed bash -c '"$0" study cut.yaml --threads 1 --out c1 & "$0" study cut.yaml \
  --threads 1 --out c2; wait' "$cli")
load1=$(cut -d' ' -f1-3 /proc/loadavg)
cmp np1/study.csv np2/study.csv && cmp np1/study.html np2/study.html
launch=$(seconds "${mpi[@]}" 2 "$cli" --version 2> /dev/null)
read -r _ p0 < <(timed "$cli" study cut.yaml --threads 1 --shard 0/2 --out p0)
read -r _ p1 < <(timed "$cli" study cut.yaml --threads 1 --shard 1/2 --out p1)
cmp np1/study.csv <("$cli" study merge p0 p1 --out merged > /dev/null && cat merged/study.csv)
merge=$(seconds "$cli" study merge p0 p1 --out merged)
python3 - "$t1" "$t2" "$launch" "$merge" "$cells" "$runs" "$load0" "$load1" "$c1" "$c2" "$p0" \
  "$p1" "$tc" <<'PY' | tee "$out/study-mpi.md"
import sys
t1, t2, launch, merge = map(float, sys.argv[1:5])
cells, runs = int(sys.argv[5]), int(sys.argv[6])
c1, c2, p0, p1, tc = map(float, sys.argv[9:14])
serial = launch + merge
s = serial / t1
print("jimenez_tables.yaml cut to %d runs per cell (%d cells), --threads 1 per rank" % (runs, cells))
print("load average before / after: %s / %s" % (sys.argv[7], sys.argv[8]))
print()
print("| ranks | wall [s] | CPU [s] | speedup |")
print("|---:|---:|---:|---:|")
print("| 1 | %.1f | %.1f | 1.00 |" % (t1, c1))
print("| 2 | %.1f | %.1f | %.2f |" % (t2, c2, t1 / t2))
print()
ceiling = 2.0 * t1 / tc
print("machine ceiling: two one-process studies at once %.1f s (one alone %.1f s): at most "
      "%.2fx from 2 processes here; 2 ranks reached %.0f %% of it" %
      (tc, t1, ceiling, 100.0 * (t1 / t2) / ceiling))
print("parts 0/2 and 1/2 alone: CPU %.1f s and %.1f s; balance (sum / larger) %.2f" %
      (p0, p1, (p0 + p1) / max(p0, p1)))
print("serial part: launch %.2f s + merge and write %.2f s = %.2f s; s = %.4f of T1" %
      (launch, merge, serial, s))
for p in (2, 8, 64):
    e = 1.0 / (1.0 + s * (p - 1))
    print("P = %2d: Amdahl efficiency %.3f; cell bound min(1, %d/%d) = %.3f" %
          (p, e, cells, p, min(1.0, cells / p)))
PY
