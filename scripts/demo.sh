#!/usr/bin/env bash
# The main job on the built-in default: a generated long-term large-occlusion (ltlo) sequence.
#   scripts/demo.sh [OUT_DIR]          (default out/demo; SEED, DEMO_SECONDS, SCENARIO override)
# Steps (growing with every capability; see README "What the demo does today"):
#   1. install dependencies and build (as scripts/test.sh, without running the tests)
#   2. simulate: RGB-D + 200 Hz IMU + ground truth + masks of an ltlo sequence
#   3. imu_odometry: IMU-only dead-reckoning baseline from the ground-truth initial state
#   4. evaluate: ATE / RPE of the baseline against ground truth -> metrics.json
#   5. sim_preview: RGB | depth | mask snapshots of occluded and free frames
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/demo}
SEED=${SEED:-1}
SECONDS_TO_SIMULATE=${DEMO_SECONDS:-30}
SCENARIO=${SCENARIO:-ltlo}

scripts/setup.sh
scripts/build.sh
mkdir -p "$OUT"
BIN=build/bin

echo "== simulate: $SCENARIO, seed $SEED, $SECONDS_TO_SIMULATE s -> $OUT/sequence"
rm -rf "$OUT/sequence"
$BIN/simulate --scenario "$SCENARIO" --seed "$SEED" --seconds "$SECONDS_TO_SIMULATE" \
  --out "$OUT/sequence" --progress-every 150

echo "== imu_odometry (IMU-only baseline, zero bias) -> $OUT/imu_only_trajectory.txt"
$BIN/imu_odometry --sequence "$OUT/sequence" --out "$OUT/imu_only_trajectory.txt"

echo "== evaluate -> $OUT/metrics.json"
$BIN/evaluate --gt "$OUT/sequence/groundtruth.txt" --est "$OUT/imu_only_trajectory.txt" \
  --json "$OUT/metrics.json" | tee "$OUT/metrics.txt"

frames=$(grep -vc '^#' "$OUT/sequence/associations.txt")
$BIN/sim_preview --sequence "$OUT/sequence" --out "$OUT/preview.png" \
  --frames 0 $((frames / 3)) $((2 * frames / 3)) $((frames - 1)) --scale 0.5

echo
echo "== outputs in $OUT"
echo "  sequence/              generated input (DATA_FORMAT.md), stats in sequence/stats.txt"
echo "  imu_only_trajectory.txt IMU-only baseline trajectory (TUM, T_w_c)"
echo "  metrics.txt/.json      ATE / RPE of the baseline against ground truth"
echo "  preview.png            RGB | depth | mask of four frames"
echo "  (SLAM, static map and surfel reconstruction join this demo as issues 6+ land)"
