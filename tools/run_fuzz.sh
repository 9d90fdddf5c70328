#!/usr/bin/env bash
# Runs the libFuzzer target tools/fuzz_readers for a bounded time per reader, seeded from the
# repository's own files; any finding (crash, hang, sanitizer report, leak) fails the run and
# leaves its input in BUILD_DIR/fuzz-findings/.
# Usage: tools/run_fuzz.sh BUILD_DIR [WALK_S CONFIG_S MANIFEST_S]   (default 120 60 60)
#   BUILD_DIR: a clang build with -DWALKGRAPH_FUZZ=ON (see tools/fuzz_readers.cc).
set -euo pipefail
cd "$(dirname "$0")/.."
build=$1
times=("${2:-120}" "${3:-60}" "${4:-60}")
fuzzer="$build/tools/fuzz_readers"
[ -x "$fuzzer" ] || { echo "run_fuzz: $fuzzer not built" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
findings="$build/fuzz-findings"
mkdir -p "$findings" "$work/walk" "$work/config" "$work/manifest"

# walk: one byte naming the file (fuzz_readers.cc's kFiles order), then the file's contents.
files=(walk.yaml anchors.csv imu.csv rss.csv range.csv odometry.csv truth.csv stance_truth.csv)
n=0
for dir in tests/data/walks/* tests/data/accepted/* tests/data/malformed/*; do
  for i in "${!files[@]}"; do
    f="$dir/${files[$i]}"
    [ -f "$f" ] || continue
    n=$((n + 1))
    { printf "\\$(printf %03o "$i")"; head -c 16384 "$f"; } > "$work/walk/$n"
  done
done
for f in datasets/configs/*.yaml; do cp "$f" "$work/config/"; done
printf '{sigma_p_m: 0.5, smooth: true}\n' > "$work/config/a.yaml"
printf 'window: 5\nthreshold: 3e5\ndetector: glrt\n' > "$work/config/b.yaml"
for f in datasets/studies/*.yaml; do cp "$f" "$work/manifest/"; done

status=0
readers=(walk config manifest)
for k in 0 1 2; do
  reader=${readers[$k]}
  echo "run_fuzz: $reader for ${times[$k]} s ($(ls "$work/$reader" | wc -l) seeds)"
  if ! WALKGRAPH_FUZZ_READER=$reader "$fuzzer" "$work/$reader" -max_total_time="${times[$k]}" \
      -timeout=20 -rss_limit_mb=4096 -max_len=65536 -print_final_stats=1 \
      -artifact_prefix="$findings/$reader-" 2>&1 | tail -n 25; then
    echo "run_fuzz: $reader: FINDING (see $findings)" >&2
    status=1
  fi
done
exit $status
