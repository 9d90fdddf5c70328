#!/usr/bin/env bash
# Issue 8: every applicable estimator on the real recordings, as markdown tables.
#
#   tools/real_data_tables.sh BUILD_DIR SHARED_DATASETS_DIR
#
# Converts into a temporary directory (nothing is written into the project), runs
# `walkgraph compare` and prints the tables on stdout. Needs jq. Walk-specific choices:
#   Plaza1     the bundled datasets/plaza1; errors vs GPS-RTK truth.
#   PyShoe     every VICON trial in pyshoe_vicon/; --align-se2 (no known start: the converter
#              comment, src/convert/pyshoe.cc); library defaults and datasets/configs/pyshoe.yaml.
#   IPIN       TrainingTrial01/05/21, two set-ups; landmark errors (mean, p75); every estimator
#              on its defaults (the PDR front end finds the phone's carriage itself, issue 41) but
#              pdr-only from the known start (datasets/configs/ipin.yaml, known-start walks
#              only). A/eta/sigma of the log-distance path loss always fitted
#              (`walkgraph fit-path-loss`) on a DIFFERENT trial.
#              Known start (the main table): `convert ipin --known-start` (the walk begins at the
#              first POSI landmark, whose position is given, heading unknown, as IPIN's scoring
#              trials provide it); path loss from a trial on the same level: 05 -> 01, 01 -> 05,
#              and 01 -> 21 (21 is the only level -2 trial); pdr-only from the known start.
#              No known start: the recording before the first landmark dropped (trial 01 has
#              61 s of phone handling before it), no initial_pose; 21 -> 01 and 05, 01 -> 21;
#              pdr-only from the first RSS fix.
#              TrainingTrial52 (Level 0 <-> Level -2 by stairs, issue 22): known start, path
#              loss from 01; scored also by IPIN's rule (third quartile of error + 15 m per
#              floor missed) and the floor hit rate (every known-start trial).
#   BLE tracks A/eta/sigma fitted on straight_01, used on the other five tracks.
set -euo pipefail
if [[ $# -ne 2 ]]; then
  echo "usage: $0 BUILD_DIR SHARED_DATASETS_DIR" >&2
  exit 2
fi
BUILD=$(cd "$1" && pwd)
SHARED=$(cd "$2" && pwd)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
W="$BUILD/tools/walkgraph"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

# compare WALK OUT [args...]: quiet run (failures of single estimators are in results.json).
compare() {
  local walk=$1 out=$2
  shift 2
  "$W" compare "$walk" --threads 2 --out "$out" "$@" >/dev/null 2>&1
}

# Keep rows with t >= the first truth time in imu.csv/rss.csv.
trim_to_first_truth() {
  local dir=$1 t0
  t0=$(sed -n 2p "$dir/truth.csv" | cut -d, -f1)
  for f in imu.csv rss.csv; do
    awk -F, -v t0="$t0" 'NR == 1 || $1 + 0 >= t0 + 0' "$dir/$f" >"$dir/$f.tmp"
    mv "$dir/$f.tmp" "$dir/$f"
  done
}

# set_radio DIR FIT_OUTPUT: A_dbm, eta, sigma_db (and floor_loss_db, on walks with floors) of
# walk.yaml's radio block from a fit.
set_radio() {
  local dir=$1 fit=$2 k v
  for k in A_dbm eta sigma_db floor_loss_db; do
    v=$(grep "^$k:" "$fit" | awk '{print $2}')
    sed -i "s/^\(  $k:\) .*/\1 $v/" "$dir/walk.yaml"
  done
  # A fit on another trial of the same site counts as a measured calibration: the estimators
  # hold it (radio.calibrated; without it the factor graphs would estimate A and eta).
  sed -i "s/^  calibrated: .*/  calibrated: true/" "$dir/walk.yaml"
}

fit_line() { # "A -71.0 dBm, eta 1.98, sigma 4.8 dB (n = 80)"
  local fit=$1
  printf 'A %.1f dBm, eta %.2f, sigma %.1f dB (%s readings)' \
    "$(grep '^A_dbm:' "$fit" | awk '{print $2}')" "$(grep '^eta:' "$fit" | awk '{print $2}')" \
    "$(grep '^sigma_db:' "$fit" | awk '{print $2}')" \
    "$(head -1 "$fit" | sed 's/.*: \([0-9]*\) readings.*/\1/')"
}

# cell RESULTS ID FIELD: a number with 3 decimals, "diverged" (flagged by compare: see
# include/walkgraph/divergence.h) or "fail" (could not run); a number followed by "(a/b)"
# when the estimate does not span the walk: scored on a of the b truth points the others are
# scored on (results.json scored_on_every_point; docs/outputs.md).
cell() {
  jq -r --arg id "$2" --arg f "$3" \
    '[.estimators[] | .n_points? // 0] as $n | ($n | max) as $most |
     .estimators[$id] as $e | if $e == null then "n/a" elif $e.diverged != null then "diverged"
     elif ($e[$f] | type) == "number" then ($e[$f] * 1000 | round / 1000 | tostring) +
       (if $e.scored_on_every_point == false then " (\($e.n_points)/\($most))" else "" end)
     else "fail" end' "$1"
}
ids() { jq -r '.estimators | keys_unsorted[]' "$1"; }

echo "# Real-data tables (tools/real_data_tables.sh $1 $2)"
echo

# ---------------------------------------------------------------- Plaza1
compare "$ROOT/datasets/plaza1" "$TMP/r_plaza"
echo "## Plaza1 (bundled datasets/plaza1; error vs GPS-RTK, m)"
echo
echo "(a/b) = scored on a of the b truth samples the others are scored on: the estimate does not"
echo "span the walk (the radio filters start at their first fix)."
echo
echo "| estimator | RMSE | mean | p90 |"
echo "|---|---|---|---|"
for id in $(ids "$TMP/r_plaza/results.json"); do
  r="$TMP/r_plaza/results.json"
  echo "| $id | $(cell "$r" "$id" rmse_m) | $(cell "$r" "$id" mean_m) | $(cell "$r" "$id" p90_m) |"
done
echo

# ---------------------------------------------------------------- PyShoe
trials=()
for csv in "$SHARED"/pyshoe_vicon/*.csv; do
  t=$(basename "$csv" .csv)
  trials+=("$t")
  "$W" convert pyshoe "$csv" --out "$TMP/ps_$t" >/dev/null
  compare "$TMP/ps_$t" "$TMP/rp_$t" --align-se2 --estimators zupt-ins,jimenez-iez,jimenez-iez-rts,fg-ins-batch
  compare "$TMP/ps_$t" "$TMP/rpc_$t" --align-se2 --estimators zupt-ins,jimenez-iez,jimenez-iez-rts,fg-ins-batch \
    --config "$ROOT/datasets/configs/pyshoe.yaml"
done
echo "## PyShoe VICON (every trial; position RMSE vs Vicon after --align-se2, m)"
echo
echo "config: library defaults / datasets/configs/pyshoe.yaml (fg-ins-batch and zupt-ins front end only)"
echo
hdr="| estimator | config |"
sep="|---|---|"
for t in "${trials[@]}"; do
  hdr+=" $t |"
  sep+="---|"
done
echo "$hdr mean |"
echo "$sep---|"
for id in zupt-ins jimenez-iez jimenez-iez-rts fg-ins-batch; do
  for c in default pyshoe.yaml; do
    row="| $id | $c |"
    vals=()
    for t in "${trials[@]}"; do
      d="$TMP/rp_$t"
      [[ $c == default ]] || d="$TMP/rpc_$t"
      v=$(cell "$d/results.json" "$id" rmse_m)
      vals+=("$v")
      row+=" $v |"
    done
    mean=$(printf '%s\n' "${vals[@]}" | awk '{s += $1; n++} END {printf "%.3f", s / n}')
    echo "$row $mean |"
  done
done
echo

# ---------------------------------------------------------------- IPIN 2023 Track 3
ip() { echo "$SHARED/ipin2023_t3/IPIN2023_T3_TrainingTrial$1_repetition01.txt"; }
ble="$SHARED/ipin2023_t3/BLE_Locations.csv"
"$W" convert ipin "$(ip 52)" "$ble" --known-start --out "$TMP/ks52" >/dev/null
for n in 01 05 21; do
  "$W" convert ipin "$(ip "$n")" "$ble" --known-start --out "$TMP/ks$n" >/dev/null
  "$W" convert ipin "$(ip "$n")" "$ble" --out "$TMP/ip$n" >/dev/null
  trim_to_first_truth "$TMP/ip$n"
done
for n in 01 05 21; do # the fits' sources, before any radio edit
  "$W" fit-path-loss "$TMP/ip$n" >"$TMP/fit$n.txt"
done
set_radio "$TMP/ks01" "$TMP/fit05.txt"
set_radio "$TMP/ks05" "$TMP/fit01.txt"
set_radio "$TMP/ks21" "$TMP/fit01.txt"
set_radio "$TMP/ks52" "$TMP/fit01.txt"
set_radio "$TMP/ip01" "$TMP/fit21.txt"
set_radio "$TMP/ip05" "$TMP/fit21.txt"
set_radio "$TMP/ip21" "$TMP/fit01.txt"
# Without a known start pdr-only cannot start from it (its first RSS fix instead): no config.
for n in 01 05 21; do
  compare "$TMP/ks$n" "$TMP/rk$n" --config "$ROOT/datasets/configs/ipin.yaml"
  compare "$TMP/ip$n" "$TMP/ri$n"
done
compare "$TMP/ks52" "$TMP/rk52" --config "$ROOT/datasets/configs/ipin.yaml"
ipin_table() { # PREFIX: results in $TMP/PREFIX{01,05,21}
  echo "| estimator | 01 mean | 01 p75 | 05 mean | 05 p75 | 21 mean | 21 p75 |"
  echo "|---|---|---|---|---|---|---|"
  for id in $(ids "$TMP/${1}01/results.json"); do
    row="| $id |"
    for n in 01 05 21; do
      r="$TMP/$1$n/results.json"
      row+=" $(cell "$r" "$id" mean_m) | $(cell "$r" "$id" p75_m) |"
    done
    echo "$row"
  done
}
echo "## IPIN 2023 Track 3 (landmark errors, m: mean / p75; defaults, pdr-only from the known start)"
echo
echo "path loss fitted on trial 01: $(fit_line "$TMP/fit01.txt");"
echo "on trial 05: $(fit_line "$TMP/fit05.txt");"
echo "on trial 21: $(fit_line "$TMP/fit21.txt")."
echo "fail = the estimator could not run (e.g. no radio epoch gave a position fix: 05 and 21 hear"
echo "too few beacons at once for a trilateration fix). (a/b) = scored on a of the b landmarks the"
echo "others are scored on: the estimate does not span the walk (it starts at its first fix)."
echo
echo "### Known start (convert --known-start; path loss 05 -> 01, 01 -> 05, 01 -> 21)"
echo
ipin_table rk
echo
echo "### IPIN score and floors, known start (trial 52: Level 0 <-> -2 by stairs, path loss 01 -> 52)"
echo
echo "IPIN score: third quartile of horizontal error + 15 m per floor missed; an estimator without"
echo "a floor estimate is scored on the start floor. 01/05/21 are single-floor."
echo
echo "| estimator | 01 IPIN | 05 IPIN | 21 IPIN | 52 mean | 52 p75 | 52 IPIN | 52 floor hit |"
echo "|---|---|---|---|---|---|---|---|"
for id in $(ids "$TMP/rk01/results.json"); do
  row="| $id |"
  for n in 01 05 21; do row+=" $(cell "$TMP/rk$n/results.json" "$id" ipin_score_m) |"; done
  r="$TMP/rk52/results.json"
  row+=" $(cell "$r" "$id" mean_m) | $(cell "$r" "$id" p75_m) | $(cell "$r" "$id" ipin_score_m) |"
  row+=" $(cell "$r" "$id" floor_hit_rate) |"
  echo "$row"
done
echo
echo "### No known start (path loss 21 -> 01, 21 -> 05, 01 -> 21; pdr-only from the first fix)"
echo
ipin_table ri
echo

# ---------------------------------------------------------------- BLE RSS tracks
tracks=(straight_01 straight_02 straight_03 straight_04 rectangular_without_rotation
  zigzagging_without_rotation)
for t in "${tracks[@]}"; do
  "$W" convert bletracks "$SHARED/ble_tracks/trk/${t}_all_sensors.mbd" \
    "$SHARED/ble_tracks/cnf/tetam.dev" --out "$TMP/bt_$t" >/dev/null
done
"$W" fit-path-loss "$TMP/bt_straight_01" >"$TMP/fitbt.txt"
for t in "${tracks[@]:1}"; do
  set_radio "$TMP/bt_$t" "$TMP/fitbt.txt"
  compare "$TMP/bt_$t" "$TMP/rb_$t"
done
echo "## BLE RSS tracks (radio only, 12 receivers; RMSE / mean vs camera truth, m)"
echo
echo "path loss fitted on straight_01 (used on the other tracks): $(fit_line "$TMP/fitbt.txt")."
echo
hdr="| estimator |"
sep="|---|"
for t in "${tracks[@]:1}"; do
  hdr+=" $t RMSE | mean |"
  sep+="---|---|"
done
echo "$hdr"
echo "$sep"
for id in $(ids "$TMP/rb_straight_02/results.json"); do
  row="| $id |"
  for t in "${tracks[@]:1}"; do
    r="$TMP/rb_$t/results.json"
    row+=" $(cell "$r" "$id" rmse_m) | $(cell "$r" "$id" mean_m) |"
  done
  echo "$row"
done
