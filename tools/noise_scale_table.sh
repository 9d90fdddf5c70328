#!/usr/bin/env bash
# fg-batch's noise scales (StepGraphOptions::noise_scale_rounds) on the simulated step presets:
# RMSE and ANEES with the σ as given, with the default (σ only raised), and with
# noise_scale_lower: true. 10 runs from seed 1 each; prints a markdown table.
#
#   tools/noise_scale_table.sh BUILD_DIR
set -euo pipefail
if [[ $# -ne 1 ]]; then
  echo "usage: $0 BUILD_DIR" >&2
  exit 2
fi
W="$(cd "$1" && pwd)/tools/walkgraph"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
echo "fg-batch: {noise_scale_rounds: 0}" >"$TMP/given.yaml"
echo "fg-batch: {}" >"$TMP/default.yaml"
echo "fg-batch: {noise_scale_lower: true}" >"$TMP/lower.yaml"
fig() { jq -r --arg f "$2" '.estimators["fg-batch"][$f] * 1000 | round / 1000' "$1"; }
echo "| preset | RMSE, σ given | default (raised only) | noise_scale_lower | ANEES given / default / lower |"
echo "|---|---|---|---|---|"
for p in tarrio-circle correa-corridor correa-classroom gadeke-outage two-floor-building handheld-phone; do
  for c in given default lower; do
    "$W" compare --scenario "$p" --runs 10 --seed 1 --threads 2 --estimators fg-batch \
      --config "$TMP/$c.yaml" --out "$TMP/$p-$c" >/dev/null
  done
  r="$TMP/$p"
  echo "| \`$p\` | $(fig "$r-given/results.json" rmse_m) | $(fig "$r-default/results.json" rmse_m) |" \
    "$(fig "$r-lower/results.json" rmse_m) | $(fig "$r-given/results.json" anees) /" \
    "$(fig "$r-default/results.json" anees) / $(fig "$r-lower/results.json" anees) |"
done
