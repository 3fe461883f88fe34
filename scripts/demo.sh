#!/usr/bin/env bash
# The main job on the built-in default: a generated long-term large-occlusion (ltlo) sequence.
#   scripts/demo.sh [OUT_DIR]          (default out/demo; SEED, DEMO_SECONDS, SCENARIO override)
# Steps (growing with every capability; README.md, "Two commands"):
#   1. install dependencies and build (as scripts/test.sh, without running the tests)
#   2. simulate: RGB-D + 200 Hz IMU + ground truth + masks of an ltlo sequence
#   3. rgbd_inertial: the SLAM system (tracking, local mapping, loop closing) -> run outputs,
#      with the live viewer writing its video (slam/viewer.avi)
#   4. reconstruct: surfels of the static background from the run (its trajectory and
#      segmentation) and headless snapshots of them
#   5. evaluate: ATE / RPE of the SLAM trajectory and static IoU of its masks against ground
#      truth; check_surfels: the reconstruction against the simulator's scene.ply
#   6. imu_odometry + evaluate: the IMU-only dead-reckoning baseline, for comparison
#   7. sim_preview: RGB | depth | mask snapshots of occluded and free frames
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

echo "== rgbd_inertial (SLAM) -> $OUT/slam/"
rm -rf "$OUT/slam"
$BIN/rgbd_inertial --settings config_yaml/synthetic.yaml --sequence "$OUT/sequence" --out "$OUT/slam" \
  --viewer-video "$OUT/slam/viewer.avi" --progress-every 150 | tee "$OUT/slam_summary.txt"

echo "== reconstruct (surfels of the static background, snapshots) -> $OUT/recon/"
rm -rf "$OUT/recon"
$BIN/reconstruct --run "$OUT/slam" --sequence "$OUT/sequence" --out "$OUT/recon" \
  --progress-every 150 | tee "$OUT/recon_summary.txt"

echo "== evaluate SLAM trajectory -> $OUT/metrics.txt / metrics.json"
$BIN/evaluate --gt "$OUT/sequence/groundtruth.txt" --est "$OUT/slam/trajectory.txt" \
  --gt-masks "$OUT/sequence/masks" --est-masks "$OUT/slam/segmentation" \
  --json "$OUT/metrics.json" | tee "$OUT/metrics.txt"

echo "== check_surfels (reconstruction against scene.ply) -> $OUT/recon/check.txt"
$BIN/check_surfels --surfels "$OUT/recon/surfels.ply" --sequence "$OUT/sequence" \
  --trajectory "$OUT/slam/trajectory.txt" --json "$OUT/recon/check.json" | tee "$OUT/recon/check.txt"

echo "== imu_odometry (IMU-only baseline, zero bias) -> $OUT/imu_only_trajectory.txt"
$BIN/imu_odometry --sequence "$OUT/sequence" --out "$OUT/imu_only_trajectory.txt"
$BIN/evaluate --gt "$OUT/sequence/groundtruth.txt" --est "$OUT/imu_only_trajectory.txt" \
  --json "$OUT/imu_only_metrics.json" >"$OUT/imu_only_metrics.txt"

frames=$(grep -vc '^#' "$OUT/sequence/associations.txt")
$BIN/sim_preview --sequence "$OUT/sequence" --out "$OUT/preview.png" \
  --frames 0 $((frames / 3)) $((2 * frames / 3)) $((frames - 1)) --scale 0.5

value() { awk -v k="$1" '$1 == k { print $2 }' "$2"; }
echo
echo "== results ($SCENARIO, $SECONDS_TO_SIMULATE s, seed $SEED)"
echo "  SLAM ATE RMSE          $(value ate_rmse_m "$OUT/metrics.txt") m"
echo "  online ATE RMSE        $(value ate_online_rmse_m "$OUT/slam_summary.txt") m (each frame's pose as tracked, before later corrections)"
echo "  static IoU (all / >40% occluded)  $(value static_iou "$OUT/metrics.txt") / $(value static_iou_occluded "$OUT/metrics.txt")"
echo "  static IoU in hindsight            $(value static_iou_final "$OUT/slam_summary.txt") (segmentation_final/: relabelled against the final map)"
echo "  IMU-only ATE RMSE      $(value ate_rmse_m "$OUT/imu_only_metrics.txt") m (baseline)"
echo "  frames / with pose     $(value frames "$OUT/slam_summary.txt") / $(value frames_with_pose "$OUT/slam_summary.txt")"
echo "  keyframes, maps, loops $(value keyframes "$OUT/slam_summary.txt"), $(value maps "$OUT/slam_summary.txt"), $(value loops "$OUT/slam_summary.txt")"
echo "  wall time, FPS         $(value wall_s "$OUT/slam_summary.txt") s, $(value fps "$OUT/slam_summary.txt")"
echo "  surfels                $(value surfels "$OUT/recon_summary.txt") ($(value frames_fused "$OUT/recon_summary.txt") frames fused, $(value wall_s "$OUT/recon_summary.txt") s, peak $(value peak_memory_mb "$OUT/recon_summary.txt") MB)"
echo "  surfel accuracy        $(value accuracy "$OUT/recon/check.txt") of the area within 3 cm of the static scene"
echo "  on moving boxes        $(value dynamic_area_fraction "$OUT/recon/check.txt") of the area"
echo "  completeness           $(value completeness "$OUT/recon/check.txt") of the static surface seen"
echo
echo "== outputs in $OUT"
echo "  sequence/               generated input (DATA_FORMAT.md), stats in sequence/stats.txt"
echo "  slam/trajectory.txt     SLAM camera trajectory (TUM, T_w_c, every frame with a pose)"
echo "  slam/trajectory_online.txt  each frame's pose as tracking returned it (never corrected afterwards)"
echo "  slam/keyframes.txt      keyframe poses with id, map and static area ratio"
echo "  slam/static_map.ply     static map points (colour, beta); open with any PLY viewer"
echo "  slam/segmentation/      every frame's dynamic mask (255 = dynamic), like sequence/masks/"
echo "  slam/segmentation_final/  the same masks relabelled after the run against the final map (fused by reconstruct)"
echo "  slam/viewer.avi         the live viewer's video (frame | map), Viewer.Fps pictures per second"
echo "  slam/metrics.json       ATE/RPE, static IoU, per-stage timing, peak memory, maps, loops, merges"
echo "  metrics.txt/.json       evaluate's ATE / RPE and static-background IoU of the SLAM run"
echo "  imu_only_*              IMU-only baseline trajectory and its metrics"
echo "  preview.png             RGB | depth | mask of four frames"
echo "  recon/surfels.ply       surfels of the static background (MeshLab, CloudCompare, Open3D)"
echo "  recon/check.txt         its accuracy, moving-box area and completeness (check_surfels)"
echo
echo "== pictures"
grep '^snapshot ' "$OUT/recon_summary.txt" | sed 's/^snapshot /  /'
echo "  $OUT/preview.png"
echo "  $OUT/slam/viewer.avi (the live viewer's video)"
if [ ! -d "$OUT/slam/segmentation" ]; then
  echo "  (the run wrote no segmentation/ yet: every pixel with depth was fused; boxes are removed"
  echo "   only where later views see through them, see Examples/reconstruct/README.md)"
fi
