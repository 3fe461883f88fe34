#!/usr/bin/env bash
# Issue 6 acceptance runs on generated sequences (not part of CI: ~15-25 min on 2 cores).
#   scripts/acceptance.sh [OUT_DIR] [SEEDS]        default out/acceptance, seeds "1 2 3"
# For every seed: static 45 s RGB-D-inertial and RGB-D only; stlo/mtlo/ltlo 30 s; forced loss by 3 s
# of black frames and by 3 s without depth (static 45 s). One line per run in OUT_DIR/summary.txt:
#   name ate_rmse_m frames frames_with_pose maps_created maps loops merges wall_s tracking_median_ms false_loops
# (false_loops: loops/merges whose keyframes' relative pose disagrees with ground truth, check_loops.py)
# Needs a built tree (scripts/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/acceptance}
SEEDS=${2:-"1 2 3"}
BIN=build/bin
mkdir -p "$OUT/runs"
SUMMARY="$OUT/summary.txt"
echo "# name ate_rmse_m frames frames_with_pose maps_created maps loops merges wall_s tracking_median_ms false_loops" > "$SUMMARY"

json_value() {  # json_value FILE KEY -> the number after "KEY":
  grep -o "\"$2\": *[-0-9.eE+a-z]*" "$1" | head -1 | sed 's/.*: *//'
}

run_case() {  # run_case NAME SEQ_DIR [rgbd_inertial flags...]
  local name=$1 seq=$2
  shift 2
  local out="$OUT/runs/$name"
  rm -rf "$out"
  local start end
  start=$(date +%s.%N)
  if ! $BIN/rgbd_inertial --settings config_yaml/synthetic.yaml --sequence "$seq" --out "$out" \
      --progress-every 300 "$@" > "$out.log" 2>&1; then
    echo "$name FAILED (see $out.log)" | tee -a "$SUMMARY"
    return
  fi
  end=$(date +%s.%N)
  local m="$out/metrics.json"
  local false_loops
  false_loops=$(scripts/check_loops.py "$out" "$seq" "$out.log" | tee "$out.loops" | grep -c '^FALSE' || true)
  printf '%s %s %s %s %s %s %s %s %.1f %s %s\n' "$name" "$(json_value "$m" ate_rmse_m)" \
    "$(json_value "$m" frames)" "$(json_value "$m" frames_with_pose)" "$(json_value "$m" maps_created)" \
    "$(json_value "$m" maps)" "$(json_value "$m" loops)" "$(json_value "$m" merges)" \
    "$(echo "$end - $start" | bc)" "$(json_value "$m" tracking_frame_median_ms)" "$false_loops" | tee -a "$SUMMARY"
}

simulate() {  # simulate DIR SCENARIO SEED SECONDS [extra flags]
  local dir=$1 scenario=$2 seed=$3 seconds=$4
  shift 4
  [ -f "$dir/groundtruth.txt" ] && return
  $BIN/simulate --scenario "$scenario" --seed "$seed" --seconds "$seconds" --out "$dir" "$@" > /dev/null
}

for seed in $SEEDS; do
  S="$OUT/seq"
  simulate "$S/static_$seed" static "$seed" 45
  run_case "static45_vi_seed$seed" "$S/static_$seed"
  run_case "static45_rgbd_seed$seed" "$S/static_$seed" --no-imu
  for scenario in stlo mtlo ltlo; do
    simulate "$S/${scenario}_$seed" "$scenario" "$seed" 30
    run_case "${scenario}30_vi_seed$seed" "$S/${scenario}_$seed"
  done
  simulate "$S/black_$seed" static "$seed" 45 --black 12,3
  run_case "black3s_vi_seed$seed" "$S/black_$seed"
  simulate "$S/nodepth_$seed" static "$seed" 45 --no-depth 12,3
  run_case "nodepth3s_vi_seed$seed" "$S/nodepth_$seed"
done
echo "summary: $SUMMARY"
