#!/usr/bin/env bash
# The scenario suite in one command: SLAM on every sequence and variant, reconstruction of the
# full system's runs, and OUT/report.md with tables and plots (build/bin/report, our own C++).
#
#   scripts/benchmark.sh [OUT]                                   (default out/benchmark)
#
# Environment (defaults in brackets):
#   SCENARIOS ["static stlo mtlo ltlo carried"]   SEEDS ["1 2 3"]   SECONDS_PER_SEQUENCE [45]
#             besides the five profiles, any harder world of scripts/scenarios.sh's catalogue
#             (e.g. SCENARIOS="long_mtlo standstill"); the report gives those a section of their own
#   VARIANTS  ["rgbd_inertial rgbd_only seg_off"]  rgbd_inertial: the full system;
#             rgbd_only: --no-imu; seg_off: Seg.Enable = 0 (every pixel static)
#   SEQ_ROOT  [/work/seqs]  sequences <scenario>_s<seed> that hold a DONE file are used from there;
#             the others are generated into OUT/sequences/ (simulate; 1.1-1.2 GB a 45 s sequence, and
#             simulate exits 2 before the first frame when the file system lacks about 1.5 GB)
#   SETTINGS  [config_yaml/synthetic.yaml]   RECON [1]: reconstruct + check_surfels the
#             rgbd_inertial runs   BUILD [1]: build first (scripts/build.sh)
#   RATE      [0]  --rate of the SLAM runs: 1 plays each sequence at the camera's pace, as a robot
#             runs it (local mapping and loop closing get a robot's time; a 45 s run takes 45 s);
#             0: frames as fast as tracking goes
#   RESULTS_MD [unset]  e.g. docs/results.md: its benchmark block becomes this report's summary
#             (scripts/update_results.sh)
#
# Resumable: a run folder with a DONE file is skipped, so the command can be stopped and started
# again; a failed run is reported and retried on the next start. Progress: one line per run.
# OUT/runs/<sequence>/<variant>/ holds each run's outputs (slam.log, metrics.json, trajectory.txt,
# recon/); OUT/report.md the tables, OUT/plots/ the figures.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/benchmark}
SCENARIOS=${SCENARIOS:-static stlo mtlo ltlo carried}
SEEDS=${SEEDS:-1 2 3}
VARIANTS=${VARIANTS:-rgbd_inertial rgbd_only seg_off}
SEQ_ROOT=${SEQ_ROOT:-/work/seqs}
SECONDS_PER_SEQUENCE=${SECONDS_PER_SEQUENCE:-45}
SETTINGS=${SETTINGS:-config_yaml/synthetic.yaml}
RECON=${RECON:-1}
RATE=${RATE:-0}
BIN=build/bin
# shellcheck source=scripts/scenarios.sh
source scripts/scenarios.sh
read -r -a scenarios <<<"$SCENARIOS"
for scenario in "${scenarios[@]}"; do simulate_options "$scenario" "$SECONDS_PER_SEQUENCE" >/dev/null || exit 2; done

if [ "${BUILD:-1}" = 1 ]; then scripts/build.sh; fi
mkdir -p "$OUT/runs" "$OUT/sequences" "$OUT/settings"

# Seg.Enable = 0: through --set when rgbd_inertial has it, else a copy of the settings file.
if "$BIN/rgbd_inertial" --help 2>/dev/null | grep -qE -- '--set[[:space:]]'; then
  SEG_OFF_ARGS=(--settings "$SETTINGS" --set Seg.Enable=0)
else
  sed 's/^Seg\.Enable:.*/Seg.Enable: 0/' "$SETTINGS" >"$OUT/settings/seg_off.yaml"
  grep -q '^Seg.Enable: 0' "$OUT/settings/seg_off.yaml" || {
    echo "benchmark: $SETTINGS has no Seg.Enable key to switch off" >&2
    exit 2
  }
  SEG_OFF_ARGS=(--settings "$OUT/settings/seg_off.yaml")
fi

variant_args() {
  case "$1" in
    rgbd_inertial) echo "--settings $SETTINGS" ;;
    rgbd_only) echo "--settings $SETTINGS --no-imu" ;;
    seg_off) echo "${SEG_OFF_ARGS[*]}" ;;
    *) echo "benchmark: unknown variant $1" >&2; exit 2 ;;
  esac
}
json_value() { sed -n "s/.*\"$1\": *\([-0-9.eE+]*\).*/\1/p" "$2" | head -1; }

read -r -a seeds <<<"$SEEDS"
read -r -a variants <<<"$VARIANTS"
total=$((${#scenarios[@]} * ${#seeds[@]} * ${#variants[@]}))
k=0
failed=0
suite_start=$(date +%s)
for scenario in "${scenarios[@]}"; do
  for seed in "${seeds[@]}"; do
    name=${scenario}_s${seed}
    seq=$SEQ_ROOT/$name
    if [ ! -f "$seq/DONE" ]; then
      seq=$OUT/sequences/$name
      if [ ! -f "$seq/DONE" ]; then
        read -r -a sim_args <<<"$(simulate_options "$scenario" "$SECONDS_PER_SEQUENCE")"
        echo "== simulate $name (${sim_args[*]}) -> $seq"
        rm -rf "$seq"
        "$BIN/simulate" "${sim_args[@]}" --seed "$seed" --out "$seq" --progress-every 300 \
          >"$OUT/sequences/$name.log" 2>&1
        touch "$seq/DONE"
      fi
    fi
    for variant in "${variants[@]}"; do
      k=$((k + 1))
      run=$OUT/runs/$name/$variant
      if [ -f "$run/DONE" ]; then
        echo "[$k/$total] $name $variant: finished before, skipped"
        continue
      fi
      rm -rf "$run"
      mkdir -p "$run"
      echo "$seq" >"$run/sequence_path.txt"
      run_start=$(date +%s)
      printf '[%d/%d] %s %s: SLAM' "$k" "$total" "$name" "$variant"
      # shellcheck disable=SC2046
      if ! "$BIN/rgbd_inertial" $(variant_args "$variant") --sequence "$seq" --out "$run" \
        --rate "$RATE" --progress-every 300 >"$run/slam.log" 2>&1; then
        echo " FAILED (see $run/slam.log)"
        failed=$((failed + 1))
        continue
      fi
      if [ "$RECON" = 1 ] && [ "$variant" = rgbd_inertial ]; then
        printf ', reconstruct'
        if ! "$BIN/reconstruct" --run "$run" --sequence "$seq" --out "$run/recon" \
          --progress-every 300 >"$run/recon.log" 2>&1 ||
          ! "$BIN/check_surfels" --surfels "$run/recon/surfels.ply" --sequence "$seq" \
            --trajectory "$run/trajectory.txt" --json "$run/recon/check.json" >"$run/check.log" 2>&1; then
          echo " FAILED (see $run/recon.log, $run/check.log)"
          failed=$((failed + 1))
          continue
        fi
      fi
      if [ -f "$seq/groundtruth.txt" ] && ! python3 scripts/check_loops.py "$run" "$seq" "$run/slam.log" \
        >"$run/check_loops.txt" 2>&1; then
        printf ', FALSE loops (see %s)' "$run/check_loops.txt"
      fi
      touch "$run/DONE"
      ate=$(json_value ate_rmse_m "$run/metrics.json")
      fps=$(json_value fps "$run/metrics.json")
      echo ": done in $(($(date +%s) - run_start)) s (ATE ${ate:-n/a} m, ${fps:-n/a} fps)"
    done
  done
done

echo "== report ($(($(date +%s) - suite_start)) s for this invocation, $failed failed)"
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
"$BIN/report" --benchmark "$OUT" \
  --title "$(date -u '+%Y-%m-%d %H:%M UTC'), commit $commit, $(nproc) cores; scenarios: $SCENARIOS; seeds: $SEEDS; variants: $VARIANTS"
echo
sed -n '/^## Summary/,/^## All runs/p' "$OUT/report.md" | sed '$d'
echo "report: $OUT/report.md   plots: $OUT/plots/"
if [ -n "${RESULTS_MD:-}" ]; then scripts/update_results.sh "$OUT/report.md" "$RESULTS_MD"; fi
[ "$failed" = 0 ]
