#!/usr/bin/env bash
# Long-run and fault soak of rgbd_inertial (issue 14); not part of CI (~15-30 min on 2 cores).
#   scripts/soak.sh [OUT_DIR]          default out/soak; env SOAK_SECONDS (180), SEED (1), KEEP=1
# 1. long:    a generated ltlo sequence of SOAK_SECONDS (VGA, 30 Hz): every frame must get a pose,
#             peak memory <= 1.5 GB; resident memory is sampled at every progress line (every 300
#             frames, synchronised on the program's output) and its growth over the second half of
#             the run is reported; no thread of ours may be left running at the end.
# 2. outages: 60 s ltlo with 5 outages (2 black, 2 without depth, an IMU gap of 0.5 s): every frame
#             must get a pose.
# 3. sigint:  Ctrl-C while loading, at frame 30 and at frame 600 of the long sequence: exit 0, and
#             trajectory.txt parses and holds exactly the processed frames.
# Writes OUT_DIR/soak_summary.txt; exits non-zero when a check fails.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/soak}
SOAK_SECONDS=${SOAK_SECONDS:-180}
SEED=${SEED:-1}
BIN=build/bin
SETTINGS=config_yaml/synthetic.yaml
mkdir -p "$OUT"
SUMMARY=$OUT/soak_summary.txt
: > "$SUMMARY"
status=0

scripts/build.sh >/dev/null || { echo "soak: build failed" >&2; exit 1; }

note() { echo "$*" | tee -a "$SUMMARY"; }
fail() { note "FAIL: $*"; status=1; }
value() { grep -m1 "^$2 " "$1" | awk '{ print $2 }'; }  # value FILE KEY of "key value" lines

generate() {  # generate DIR SECONDS [simulate flags]
  local dir=$1 seconds=$2
  shift 2
  [ -f "$dir/DONE" ] && return 0
  rm -rf "$dir"
  "$BIN/simulate" --scenario ltlo --seed "$SEED" --seconds "$seconds" --out "$dir" --progress-every 1000 "$@" \
    >"$dir.simulate.log" 2>&1 || { echo "soak: simulate failed ($dir.simulate.log)" >&2; exit 1; }
  touch "$dir/DONE"
}

# run_sampled NAME SEQ: rgbd_inertial with the resident memory read from /proc at every progress
# line; writes OUT/NAME.{out,log,rss} (rss: "frames rss_mb").
run_sampled() {
  local name=$1 seq=$2
  local fifo=$OUT/$name.fifo
  rm -f "$fifo" && mkfifo "$fifo"
  rm -rf "${OUT:?}/$name"
  "$BIN/rgbd_inertial" --settings "$SETTINGS" --sequence "$seq" --out "$OUT/$name" --progress-every 300 \
    >"$OUT/$name.out" 2>"$fifo" &
  local pid=$!
  : > "$OUT/$name.rss"
  : > "$OUT/$name.log"
  while IFS= read -r line; do
    echo "$line" >> "$OUT/$name.log"
    if [[ "$line" =~ \]\ info\ frames\ ([0-9]+)/ ]]; then
      local rss_kb
      rss_kb=$(awk '/^VmRSS:/ { print $2 }' "/proc/$pid/status" 2>/dev/null)
      [ -n "$rss_kb" ] && echo "${BASH_REMATCH[1]} $((rss_kb / 1024))" >> "$OUT/$name.rss"
    fi
  done < "$fifo"
  wait "$pid"
  local rc=$?
  rm -f "$fifo"
  return $rc
}

check_poses() {  # check_poses NAME: every frame has a pose, trajectory complete
  local name=$1
  local frames with_pose lines
  frames=$(value "$OUT/$name.out" frames)
  with_pose=$(value "$OUT/$name.out" frames_with_pose)
  lines=$(grep -vc '^#' "$OUT/$name/trajectory.txt")
  note "$name: frames $frames frames_with_pose $with_pose trajectory_lines $lines ate_rmse_m $(value "$OUT/$name.out" ate_rmse_m) maps $(value "$OUT/$name.out" maps) maps_created $(value "$OUT/$name.out" maps_created) loops $(value "$OUT/$name.out" loops) merges $(value "$OUT/$name.out" merges) wall_s $(value "$OUT/$name.out" wall_s) fps $(value "$OUT/$name.out" fps)"
  [ -n "$frames" ] && [ "$frames" = "$with_pose" ] && [ "$lines" = "$frames" ] ||
    fail "$name: not every frame has a pose"
  if grep -q "all threads joined" "$OUT/$name.log"; then
    note "$name: threads: all joined at exit"
  else
    fail "$name: $(grep -m1 'still running' "$OUT/$name.log" || echo 'no thread report')"
  fi
}

# ---- 1. long run ----------------------------------------------------------------------------------
LONG=$OUT/ltlo_${SOAK_SECONDS}s_s$SEED
generate "$LONG" "$SOAK_SECONDS"
echo "== long: $SOAK_SECONDS s ltlo"
run_sampled long "$LONG" || fail "long: rgbd_inertial exit $?"
check_poses long
peak=$(value "$OUT/long.out" peak_memory_mb)
note "long: peak_memory_mb $peak (limit 1536)"
awk -v p="$peak" 'BEGIN { exit !(p != "" && p <= 1536) }' || fail "long: peak memory $peak MB > 1.5 GB"
# Growth: least-squares slope of RSS over frames in the second half, per minute of sequence at 30 Hz.
awk -v fps=30 '{ f[NR] = $1; r[NR] = $2 } END {
  if (NR < 4) { print "long: rss samples too few"; exit }
  h = int(NR / 2) + 1; n = 0; sf = sr = sff = sfr = 0
  for (i = h; i <= NR; i++) { n++; sf += f[i]; sr += r[i]; sff += f[i] * f[i]; sfr += f[i] * r[i] }
  slope = (n * sfr - sf * sr) / (n * sff - sf * sf)
  printf "long: rss_mb first %d at frame %d, half %d at frame %d, last %d at frame %d; second-half growth %.1f MB per minute of sequence\n",
         r[1], f[1], r[h], f[h], r[NR], f[NR], slope * fps * 60 }' "$OUT/long.rss" | tee -a "$SUMMARY"

# ---- 2. outages -----------------------------------------------------------------------------------
OUTAGES=$OUT/ltlo_60s_outages_s$SEED
generate "$OUTAGES" 60 --black 8,1 --no-depth 18,1.5 --imu-gap 28,0.5 --black 38,2 --no-depth 48,1
echo "== outages: 60 s ltlo, 5 outages"
run_sampled outages "$OUTAGES" || fail "outages: rgbd_inertial exit $?"
check_poses outages
note "outages: imu gap warnings: $(grep -c 'gap of' "$OUT/outages.log")"

# ---- 3. Ctrl-C at three moments -------------------------------------------------------------------
# sigint NAME PATTERN: SIGINT when a log line matches PATTERN (bash regex), then check the outputs.
sigint() {
  local name=$1 pattern=$2
  local fifo=$OUT/$name.fifo
  rm -f "$fifo" && mkfifo "$fifo"
  rm -rf "${OUT:?}/$name"
  "$BIN/rgbd_inertial" --settings "$SETTINGS" --sequence "$LONG" --out "$OUT/$name" --progress-every 30 \
    >"$OUT/$name.out" 2>"$fifo" &
  local pid=$! sent=0
  : > "$OUT/$name.log"
  while IFS= read -r line; do
    echo "$line" >> "$OUT/$name.log"
    if [ $sent -eq 0 ] && [[ "$line" =~ $pattern ]]; then
      kill -INT "$pid"
      sent=1
    fi
  done < "$fifo"
  wait "$pid"
  local rc=$?
  rm -f "$fifo"
  local frames lines
  frames=$(value "$OUT/$name.out" frames)
  lines=$(grep -vc '^#' "$OUT/$name/trajectory.txt" 2>/dev/null)
  note "$name: SIGINT sent $sent, exit $rc, frames $frames, trajectory_lines $lines"
  [ "$sent" = 1 ] && [ "$rc" = 0 ] && [ -n "$frames" ] && [ "$lines" = "$frames" ] || fail "$name: outputs not consistent"
  [ ! -e "$OUT/$name/trajectory.txt.part" ] || fail "$name: trajectory.txt.part left behind"
  if [ "${frames:-0}" -ge 3 ]; then
    "$BIN/evaluate" --gt "$LONG/groundtruth.txt" --est "$OUT/$name/trajectory.txt" > "$OUT/$name.eval" 2>&1 ||
      fail "$name: evaluate cannot read the trajectory"
  fi
}
echo "== sigint"
sigint sigint_loading "settings: settings = "
sigint sigint_frame30 "info frames 30/"
sigint sigint_frame600 "info frames 600/"

if [ "${KEEP:-0}" != 1 ]; then rm -rf "$LONG" "$OUTAGES"; fi
note "soak: $([ $status -eq 0 ] && echo all checks passed || echo FAILED)"
exit $status
