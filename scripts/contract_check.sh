#!/usr/bin/env bash
# Throws malformed and odd-but-valid inputs at every program in build/bin and prints a table
#   program | input | exit (expected) | first line of the message
# Fails when a program exits by a signal or with a code >= 128, when an exit code differs from
# the contract (0 done, 2 bad input, 1 other error; rgbd_inertial/rgbd: 3 evaluation failed, i.e. a
# malformed groundtruth.txt or masks/ after a complete run) or when a bad-input message does not name the
# file/key it should. Needs a built tree (scripts/build.sh); generates a 1 s VGA sequence.
#   scripts/contract_check.sh [OUT_DIR]       default out/contract
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BIN=${BIN:-$ROOT/build/bin}
OUT=${1:-out/contract}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
SETTINGS=$ROOT/config_yaml/synthetic.yaml
VOC=$ROOT/Vocabulary/ltlo_orb_k10_L5.bin
export LTLO_SOURCE_DIR=$ROOT

for p in simulate evaluate rgbd_inertial rgbd imu_odometry sim_preview train_vocabulary reconstruct check_surfels \
  check_map report; do
  [ -x "$BIN/$p" ] || { echo "contract_check: $BIN/$p missing (run scripts/build.sh)" >&2; exit 1; }
done

SEQ=$OUT/seq
if [ ! -f "$SEQ/DONE" ]; then
  rm -rf "$SEQ"
  "$BIN/simulate" --scenario static --seed 2 --seconds 1 --out "$SEQ" >/dev/null 2>&1 || {
    echo "contract_check: simulate failed" >&2
    exit 1
  }
  touch "$SEQ/DONE"
fi
# grey_png.py DIR [WIDTH HEIGHT]: rewrites every PNG of DIR as 8-bit grey (of its own size, or the
# size given), in pure Python so that no image tool is needed.
cat > "$OUT/grey_png.py" <<'EOF'
import sys, glob, zlib, struct
for path in glob.glob(sys.argv[1] + "/*.png"):
    data = open(path, "rb").read()
    w, h = struct.unpack(">II", data[16:24])
    if len(sys.argv) > 3:
        w, h = int(sys.argv[2]), int(sys.argv[3])
    raw = b"".join(b"\x00" + bytes((x * 7 + y * 3) % 256 for x in range(w)) for y in range(h))
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xffffffff)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 1)) + chunk(b"IEND", b"")
    open(path, "wb").write(png)
EOF
CASES=$OUT/cases
rm -rf "$CASES" "$OUT/runs"
mkdir -p "$CASES" "$OUT/runs"
TABLE=$OUT/table.txt
: > "$TABLE"
failures=0
total=0

# variant NAME [omit...]: a copy of the sequence's text files (image folders linked) in CASES/NAME
# (of VARIANT_OF instead of SEQ when set).
variant() {
  local dir=$CASES/$1
  shift
  mkdir -p "$dir"
  local f
  for f in "${VARIANT_OF:-$SEQ}"/*; do
    local name
    name=$(basename "$f")
    [ "$name" = DONE ] && continue
    local skip=0 o
    for o in "$@"; do [ "$name" = "$o" ] && skip=1; done
    [ $skip -eq 1 ] && continue
    if [ -d "$f" ]; then ln -s "$f" "$dir/$name"; else cp "$f" "$dir/$name"; fi
  done
  echo "$dir"
}

# own_images DIR SUB: DIR/SUB becomes a real copy (to damage images without touching SEQ).
own_images() {
  rm "$1/$2"
  cp -r "$SEQ/$2" "$1/$2"
}

# check PROGRAM "INPUT DESCRIPTION" EXPECTED_EXIT "TEXT THE MESSAGE MUST CONTAIN" ARGS...
check() {
  local program=$1 input=$2 expected=$3 must=$4
  shift 4
  total=$((total + 1))
  local log=$OUT/runs/$total.log
  "$BIN/$program" "$@" >"$log.out" 2>"$log" </dev/null
  local rc=$?
  local message
  if [ "$rc" -ne 0 ]; then  # the error: the last line that is not an info/debug log line
    message=$(grep -v -E '^\[[a-z._]+\] (info|debug|trace) ' "$log" | grep -v '^$' | tail -1 | cut -c1-160)
  else  # the first warning, else the first result line
    message=$(grep -E '^\[[a-z._]+\] (warn|error) ' "$log" | head -1 | cut -c1-160)
    [ -z "$message" ] && message=$(head -1 "$log.out" | cut -c1-160)
  fi
  local verdict=ok
  if [ "$rc" -ge 128 ]; then
    verdict="SIGNAL/>=128"
  elif [ "$rc" -ne "$expected" ]; then
    verdict="EXPECTED $expected"
  elif [ -n "$must" ] && ! grep -qF -- "$must" "$log" "$log.out"; then
    verdict="MESSAGE LACKS '$must'"
  fi
  [ "$verdict" != ok ] && failures=$((failures + 1))
  printf '%-16s | %-52s | %3d %-4s | %s\n' "$program" "$input" "$rc" "$([ "$verdict" = ok ] && echo ok || echo "$verdict")" \
    "$message" | tee -a "$TABLE"
}

evaluation_only() {  # evaluation_only RUN: a malformed evaluation input left the run's outputs whole
  local run=$1
  if [ ! -s "$run/trajectory.txt" ] || ! grep -q '"evaluation_error"' "$run/metrics.json" 2>/dev/null; then
    echo "contract_check: $run: no trajectory.txt or no evaluation_error in metrics.json" | tee -a "$TABLE"
    failures=$((failures + 1))
  fi
}

slam() {  # slam PROGRAM "INPUT" EXPECTED MUST SEQUENCE [extra args]; SLAM_SETTINGS overrides
  local program=$1 input=$2 expected=$3 must=$4 sequence=$5
  shift 5
  check "$program" "$input" "$expected" "$must" --settings "${SLAM_SETTINGS:-$SETTINGS}" --sequence "$sequence" \
    --out "$OUT/runs/slam_$total" --max-frames 3 --vocabulary "$VOC" "$@"
}

printf '%-16s | %-52s | %-8s | %s\n' program input "exit" "first message line" | tee -a "$TABLE"

# ---- simulate ----------------------------------------------------------------------------------
check simulate "no arguments" 2 ""
check simulate "--help" 0 "" --help
check simulate "unknown flag" 2 "" --bogus
check simulate "--scenario bogus" 2 "bogus" --scenario bogus --seed 1 --seconds 1 --out "$OUT/runs/s1"
check simulate "--seconds -1" 2 "" --scenario static --seed 1 --seconds -1 --out "$OUT/runs/s2"
check simulate "--seconds nan" 2 "" --scenario static --seed 1 --seconds nan --out "$OUT/runs/s3"
check simulate "--width 5" 2 "" --scenario static --seed 1 --seconds 1 --width 5 --out "$OUT/runs/s4"
check simulate "--black 1 (no duration)" 2 "--black 1" --scenario static --seed 1 --seconds 1 --black 1 --out "$OUT/runs/s5"
check simulate "--imu-gap a,b" 2 "--imu-gap a,b" --scenario static --seed 1 --seconds 1 --imu-gap a,b --out "$OUT/runs/s6"
check simulate "--config missing" 2 "/nonexistent.yaml" --scenario static --seed 1 --seconds 1 --config /nonexistent.yaml --out "$OUT/runs/s7"
printf '%%YAML:1.0\n---\nSim.PngCompression: 42\n' > "$CASES/sim_bad.yaml"
check simulate "--config key out of range" 2 "Sim.PngCompression" --scenario static --seed 1 --seconds 1 --config "$CASES/sim_bad.yaml" --out "$OUT/runs/s8"
head -c 300 "$VOC" > "$CASES/binary.yaml"
check simulate "--config binary garbage" 2 "binary.yaml" --scenario static --seed 1 --seconds 1 --config "$CASES/binary.yaml" --out "$OUT/runs/s9"
check simulate "--out under a file" 2 "" --scenario static --seed 1 --seconds 0.1 --width 64 --height 48 --out "$CASES/binary.yaml/x"
check simulate "2 outages of each kind, 64x48" 0 "" --scenario static --seed 1 --seconds 0.5 --width 64 --height 48 \
  --black 0.1,0.05 --black 0.3,0.05 --no-depth 0.2,0.05 --no-depth 0.4,0.05 --imu-gap 0.1,0.1 --imu-gap 0.3,0.1 --out "$OUT/runs/s10"

# ---- evaluate -----------------------------------------------------------------------------------
GT=$SEQ/groundtruth.txt
check evaluate "no arguments" 2 ""
check evaluate "--gt missing" 2 "/nonexistent.txt" --gt /nonexistent.txt --est "$GT"
: > "$CASES/empty.txt"
check evaluate "--gt empty file" 2 "empty.txt" --gt "$CASES/empty.txt" --est "$GT"
check evaluate "--gt a directory" 2 "$CASES" --gt "$CASES" --est "$GT"
check evaluate "--est binary garbage" 2 "binary.yaml" --gt "$GT" --est "$CASES/binary.yaml"
sed '3s/ [^ ]* / nan /' "$GT" > "$CASES/nan.txt"
check evaluate "--est with nan on line 3" 2 "nan.txt:3" --gt "$GT" --est "$CASES/nan.txt"
awk 'NR == 4 { print prev } { print; prev = $0 }' "$GT" > "$CASES/repeat.txt"
check evaluate "--est with a repeated timestamp" 2 "repeat.txt:4" --gt "$GT" --est "$CASES/repeat.txt"
awk '/^#/ { print; next } { printf "%s %s %s %s %.9f %.9f %.9f %.9f\n", $1, $2, $3, $4, 2*$5, 2*$6, 2*$7, 2*$8 }' "$GT" > "$CASES/scaled_q.txt"
check evaluate "--est quaternions scaled by 2 (benign)" 0 "normalised" --gt "$GT" --est "$CASES/scaled_q.txt"
sed 's/$/\r/' "$GT" | awk 'NR == 2 { print "# a comment"; print "" } { print }' > "$CASES/crlf.txt"
check evaluate "--est CRLF, comment and blank lines (benign)" 0 "" --gt "$GT" --est "$CASES/crlf.txt"
head -n 3 "$GT" > "$CASES/two_poses.txt"
check evaluate "--est with 2 poses" 2 "two_poses.txt" --gt "$GT" --est "$CASES/two_poses.txt"
awk '/^#/ { print; next } { printf "%s 0 0 0 0 0 0 0\n", $1 }' "$GT" > "$CASES/zero_q.txt"
check evaluate "--est zero quaternion" 2 "zero_q.txt:2" --gt "$GT" --est "$CASES/zero_q.txt"
check evaluate "--gt-masks without --est-masks" 2 "" --gt "$GT" --est "$GT" --gt-masks "$SEQ/masks"
check evaluate "--est-masks missing folder" 2 "/nonexistent" --gt "$GT" --est "$GT" --gt-masks "$SEQ/masks" --est-masks /nonexistent
check evaluate "--json in a missing folder" 2 "/nonexistent/m.json" --gt "$GT" --est "$GT" --json /nonexistent/m.json
check evaluate "--max-dt -1" 2 "" --gt "$GT" --est "$GT" --max-dt -1
check evaluate "--sim3 on itself" 0 "" --gt "$GT" --est "$GT" --sim3

# ---- rgbd_inertial / rgbd -------------------------------------------------------------------------
for program in rgbd_inertial rgbd; do
  check $program "no arguments" 2 ""
  check $program "--max-frames abc" 2 "" --settings "$SETTINGS" --sequence "$SEQ" --out "$OUT/runs/x" --max-frames abc
  slam $program "plain sequence, 3 frames" 0 "" "$SEQ"
  check $program "--settings missing" 2 "/nonexistent.yaml" --settings /nonexistent.yaml --sequence "$SEQ" --out "$OUT/runs/x"
  check $program "--settings empty" 2 "empty.txt" --settings "$CASES/empty.txt" --sequence "$SEQ" --out "$OUT/runs/x"
  check $program "--settings binary garbage" 2 "binary.yaml" --settings "$CASES/binary.yaml" --sequence "$SEQ" --out "$OUT/runs/x"
  sed 's/^ORBextractor.nFeatures: .*/ORBextractor.nFeatures: 7/' "$SETTINGS" > "$CASES/bad_key.yaml"
  check $program "--settings key out of range" 2 "ORBextractor.nFeatures = 7" --settings "$CASES/bad_key.yaml" --sequence "$SEQ" --out "$OUT/runs/x"
  sed 's/^ORBextractor.nFeatures: .*/ORBextractor.nFeatures: many/' "$SETTINGS" > "$CASES/bad_type.yaml"
  check $program "--settings key of the wrong type" 2 "ORBextractor.nFeatures = \"many\"" --settings "$CASES/bad_type.yaml" --sequence "$SEQ" --out "$OUT/runs/x"
  grep -v '^Seg.Clusters' "$SETTINGS" > "$CASES/missing_key.yaml"
  check $program "--settings key missing" 2 "missing key Seg.Clusters" --settings "$CASES/missing_key.yaml" --sequence "$SEQ" --out "$OUT/runs/x"
  sed 's/$/\r/' "$SETTINGS" > "$CASES/settings_crlf.yaml"
  SLAM_SETTINGS="$CASES/settings_crlf.yaml" slam $program "--settings with CRLF line ends (benign)" 0 "" "$SEQ"
  check $program "--sequence missing" 2 "/nonexistent" --settings "$SETTINGS" --sequence /nonexistent --out "$OUT/runs/x"
  mkdir -p "$CASES/empty_dir"
  check $program "--sequence an empty folder" 2 "unknown sequence layout" --settings "$SETTINGS" --sequence "$CASES/empty_dir" --out "$OUT/runs/x"
  check $program "--vocabulary missing" 2 "/nonexistent.bin: vocabulary file does not exist" --settings "$SETTINGS" --sequence "$SEQ" --out "$OUT/runs/x" --vocabulary /nonexistent.bin
  check $program "--vocabulary garbage" 2 "binary.yaml: byte" --settings "$SETTINGS" --sequence "$SEQ" --out "$OUT/runs/x" --vocabulary "$CASES/binary.yaml"
  head -c 100000 "$VOC" > "$CASES/truncated.bin"
  check $program "--vocabulary truncated" 2 "truncated.bin: byte 16" --settings "$SETTINGS" --sequence "$SEQ" --out "$OUT/runs/x" --vocabulary "$CASES/truncated.bin"
done

d=$(variant assoc_empty associations.txt)
printf '# no frames\n\n' > "$d/associations.txt"
slam rgbd_inertial "associations.txt with comments only" 2 "$d/associations.txt: lists no RGB-D frames" "$d"
d=$(variant lists_empty associations.txt)
printf '# colour\n' > "$d/rgb.txt"
slam rgbd_inertial "rgb.txt empty (no associations.txt)" 2 "$d/rgb.txt: lists no images" "$d"
d=$(variant lists_only associations.txt)
slam rgbd_inertial "rgb.txt + depth.txt only (benign)" 0 "" "$d"
d=$(variant assoc_bad associations.txt)
sed '3s/^[^ ]*/12x/' "$SEQ/associations.txt" > "$d/associations.txt"
slam rgbd_inertial "associations.txt bad timestamp on line 3" 2 "$d/associations.txt:3: colour timestamp is not a number: '12x'" "$d"
d=$(variant assoc_extra associations.txt)
sed '3s/$/ extra/' "$SEQ/associations.txt" > "$d/associations.txt"
slam rgbd_inertial "associations.txt 5 columns on line 3" 2 "$d/associations.txt:3: expected" "$d"
d=$(variant crlf)
for f in associations.txt rgb.txt depth.txt imu.txt groundtruth.txt calib.yaml; do sed -i 's/$/\r/' "$d/$f"; done
slam rgbd_inertial "every text file CRLF (benign)" 0 "" "$d"
d=$(variant missing_rgb)
own_images "$d" rgb
rm "$d/rgb/$(ls "$d/rgb" | sed -n 2p)"
slam rgbd_inertial "a colour image missing" 2 "image file does not exist" "$d"
d=$(variant broken_png)
own_images "$d" rgb
img=$(ls "$d/rgb" | sed -n 2p)
head -c 200 "$SEQ/rgb/$img" > "$d/rgb/$img"
slam rgbd_inertial "frame 1's colour PNG truncated (outputs kept)" 2 "$img" "$d"
d=$(variant garbage_png)
own_images "$d" rgb
printf 'not a png' > "$d/rgb/$img"
slam rgbd_inertial "frame 1's colour PNG is text" 2 "$img: cannot read image" "$d"
d=$(variant grey)
own_images "$d" rgb
python3 "$OUT/grey_png.py" "$d/rgb"
slam rgbd_inertial "8-bit grey colour images (benign, warned once)" 0 "grey colour image converted" "$d"
d=$(variant depth8)
own_images "$d" depth
cp "$d/../grey/rgb/$img" "$d/depth/$(ls "$d/depth" | sed -n 2p)"
slam rgbd_inertial "frame 1's depth is 8-bit" 2 "expected 16-bit 1-channel depth" "$d"
d=$(variant no_imu imu.txt)
slam rgbd_inertial "imu.txt missing" 2 "$d/imu.txt: missing (no IMU data in the sequence); run rgbd or pass --no-imu" "$d"
slam rgbd "imu.txt missing (rgbd)" 0 "" "$d"
slam rgbd_inertial "imu.txt missing, --no-imu" 0 "" "$d" --no-imu
d=$(variant imu_empty imu.txt)
printf '# timestamp gx gy gz ax ay az\n' > "$d/imu.txt"
slam rgbd_inertial "imu.txt with comments only" 2 "$d/imu.txt: has no IMU samples" "$d"
d=$(variant imu_nan imu.txt)
sed '5s/ [^ ]*$/ nan/' "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt nan on line 5" 2 "$d/imu.txt:5: value 7 is not finite: 'nan'" "$d"
d=$(variant imu_back imu.txt)
awk 'NR == 6 { keep = $0; next } NR == 7 { print; print keep; next } { print }' "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt lines 6 and 7 swapped (sorted, warned)" 0 "$d/imu.txt: 0 duplicated stamps dropped, 1 samples out of order sorted (first at line 7)" "$d"
d=$(variant imu_repeat imu.txt)
awk 'NR == 6 { print } { print }' "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt line 6 twice (dropped, warned)" 0 "$d/imu.txt: 1 duplicated stamps dropped (first at line 7)" "$d"
d=$(variant imu_joined imu.txt)
cat "$SEQ/imu.txt" "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt twice in one file (stamps jump back)" 2 "more than Sequence.MaxImuReorder = 0.1 s" "$d"
d=$(variant imu_split imu.txt)
awk '/^#/ { print; next } { print $1, $2, $3, $4, "nan nan nan"; printf "%.6f nan nan nan %s %s %s\n", $1 + 0.0005, $5, $6, $7 }' \
  "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt as gyro-only and accel-only rows (benign)" 0 "$d/imu.txt: split stream" "$d"
d=$(variant imu_half_nan imu.txt)
sed '5s/^\([^ ]*\) [^ ]* [^ ]*/\1 nan nan/' "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt line 5 gyro triple partly nan" 2 "$d/imu.txt:5: value 2 is not finite: 'nan' (the gyroscope triple" "$d"
d=$(variant imu_gap imu.txt)
awk 'NR < 40 || NR > 100 { print }' "$SEQ/imu.txt" > "$d/imu.txt"
slam rgbd_inertial "imu.txt with a 0.3 s gap (warned, benign)" 0 "gap of" "$d"
d=$(variant calib_garbage calib.yaml)
head -c 200 "$VOC" > "$d/calib.yaml"
slam rgbd_inertial "calib.yaml binary garbage" 2 "$d/calib.yaml" "$d"
d=$(variant calib_bad calib.yaml)
sed 's/^Camera.fx: .*/Camera.fx: -3/' "$SEQ/calib.yaml" > "$d/calib.yaml"
slam rgbd_inertial "calib.yaml Camera.fx = -3" 2 "$d/calib.yaml: Camera.fx = -3" "$d"
d=$(variant calib_rot calib.yaml)
sed 's/data: \[ [-0-9.e]*/data: [ 2/' "$SEQ/calib.yaml" > "$d/calib.yaml"
slam rgbd_inertial "calib.yaml IMU.T_b_c1 not a rotation" 2 "IMU.T_b_c1" "$d"
d=$(variant no_calib calib.yaml)
slam rgbd_inertial "calib.yaml missing (settings calibration, logged)" 0 "calibration (Camera.*, DepthMapFactor, IMU.*) from the settings file" "$d"
d=$(variant gt_bad groundtruth.txt)
sed '4s/ [^ ]*$/ x/' "$SEQ/groundtruth.txt" > "$d/groundtruth.txt"
slam rgbd_inertial "groundtruth.txt bad value on line 4 (after the run)" 3 "$d/groundtruth.txt:4" "$d"
evaluation_only "$OUT/runs/slam_$((total - 1))"
d=$(variant masks_odd)
own_images "$d" masks
printf 'x' > "$d/masks/not_a_time.png"
slam rgbd_inertial "masks/ with a non-timestamp file name (after the run)" 3 "not_a_time.png" "$d"
evaluation_only "$OUT/runs/slam_$((total - 1))"
check rgbd_inertial "--out under a file" 2 "binary.yaml/x" --settings "$SETTINGS" --sequence "$SEQ" --out "$CASES/binary.yaml/x" --max-frames 2 --vocabulary "$VOC"

# ---- imu_odometry --------------------------------------------------------------------------------
check imu_odometry "no arguments" 2 ""
check imu_odometry "plain sequence" 0 "" --sequence "$SEQ" --out "$OUT/runs/imu.txt"
check imu_odometry "--sequence missing" 2 "/nonexistent" --sequence /nonexistent --out "$OUT/runs/imu.txt"
check imu_odometry "imu.txt missing" 2 "no IMU data" --sequence "$CASES/no_imu" --out "$OUT/runs/imu.txt"
d=$(variant no_gt groundtruth.txt)
check imu_odometry "groundtruth.txt missing" 2 "groundtruth.txt" --sequence "$d" --out "$OUT/runs/imu.txt"
check imu_odometry "--out in a missing folder" 2 "/nonexistent/o.txt" --sequence "$SEQ" --out /nonexistent/o.txt

# ---- sim_preview -------------------------------------------------------------------------------
check sim_preview "no arguments" 2 ""
check sim_preview "plain sequence" 0 "" --sequence "$SEQ" --out "$OUT/runs/p.png" --frames 0,5
check sim_preview "--sequence missing" 2 "/nonexistent/rgb.txt" --sequence /nonexistent --out "$OUT/runs/p.png" --frames 0
check sim_preview "--frames out of range" 2 "no frame 999" --sequence "$SEQ" --out "$OUT/runs/p.png" --frames 999
check sim_preview "--frames -1" 2 "" --sequence "$SEQ" --out "$OUT/runs/p.png" --frames -1
check sim_preview "--out with an unknown extension" 2 "p.xyz" --sequence "$SEQ" --out "$OUT/runs/p.xyz" --frames 0
check sim_preview "a colour PNG that is text" 2 "$img" --sequence "$CASES/garbage_png" --out "$OUT/runs/p.png" --frames 1
check sim_preview "grey colour images (read as colour)" 0 "" --sequence "$CASES/grey" --out "$OUT/runs/p.png" --frames 1
d=$(variant masks_small)
own_images "$d" masks
python3 "$OUT/grey_png.py" "$d/masks" 32 24
check sim_preview "masks of another size" 2 "sizes differ" --sequence "$d" --out "$OUT/runs/p.png" --frames 0
slam rgbd_inertial "masks of another size (after the run)" 3 "differs from 32x24" "$d"
evaluation_only "$OUT/runs/slam_$((total - 1))"

# ---- train_vocabulary --------------------------------------------------------------------------
check train_vocabulary "no arguments" 2 ""
check train_vocabulary "--images missing" 2 "/nonexistent" --images /nonexistent --out "$OUT/runs/v.bin"
check train_vocabulary "--images an empty folder" 2 "no images found" --images "$CASES/empty_dir" --out "$OUT/runs/v.bin"
mkdir -p "$CASES/bad_images"
printf 'text' > "$CASES/bad_images/a.png"
check train_vocabulary "--images only broken PNGs" 2 "bad_images" --images "$CASES/bad_images" --out "$OUT/runs/v.bin"
check train_vocabulary "--k 1" 2 "" --images "$SEQ/rgb" --out "$OUT/runs/v.bin" --k 1
check train_vocabulary "--out in a missing folder" 2 "/nonexistent/v.bin" --images "$SEQ/rgb" --out /nonexistent/v.bin --k 3 --levels 2 --crops 1 --max-images 2
check train_vocabulary "small vocabulary" 0 "" --images "$SEQ/rgb" --out "$OUT/runs/v.bin" --k 3 --levels 2 --crops 1 --max-images 2

# ---- a finished run: the input of reconstruct, check_surfels, check_map and report ----------------
# 3 s at 320x240 (check_map needs 3 keyframes; reconstruct needs 5 fusions of a surface).
RSEQ=$OUT/seq_run
if [ ! -f "$RSEQ/DONE" ]; then
  rm -rf "$RSEQ"
  "$BIN/simulate" --scenario static --seed 2 --seconds 3 --width 320 --height 240 --out "$RSEQ" >/dev/null 2>&1 || {
    echo "contract_check: simulate failed" >&2
    exit 1
  }
  touch "$RSEQ/DONE"
fi
RUN=$OUT/run_3s_320x240
if [ ! -f "$RUN/DONE" ]; then
  rm -rf "$RUN"
  "$BIN/rgbd_inertial" --settings "$SETTINGS" --sequence "$RSEQ" --out "$RUN" --vocabulary "$VOC" \
    >"$OUT/run_ok.out" 2>"$OUT/run_ok.log" || { echo "contract_check: rgbd_inertial on $RSEQ failed" >&2; exit 1; }
  [ -d "$RUN/segmentation" ] && [ -f "$RUN/static_map.ply" ] && [ -f "$RUN/keyframes.txt" ] ||
    { echo "contract_check: $RUN lacks segmentation/, static_map.ply or keyframes.txt" >&2; exit 1; }
  touch "$RUN/DONE"
fi
# run_variant NAME [omit...]: a copy of RUN's files (segmentation/ linked unless omitted) in CASES/NAME.
run_variant() { VARIANT_OF=$RUN variant "$@"; }
# A PLY header announcing more records than the file holds (a reader must not allocate for them).
huge_ply() {  # huge_ply FILE HEADER_PROPERTIES...
  local file=$1
  shift
  { printf 'ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n'
    local p
    for p in "$@"; do printf 'property %s\n' "$p"; done
    printf 'end_header\n0123456789'; } > "$file"
}

# ---- reconstruct ---------------------------------------------------------------------------------
check reconstruct "no arguments" 2 ""
check reconstruct "--help" 0 "" --help
check reconstruct "unknown flag" 2 "" --bogus
# Every option the help names, alone with a path that does not exist.
for option in $("$BIN/reconstruct" --help 2>&1 | grep -o -- '--[a-z][a-z-]*' | sort -u); do
  [ "$option" = --help ] && continue
  check reconstruct "$option /nonexistent (alone)" 2 "" "$option" /nonexistent
done
recon() {  # recon "INPUT" EXPECTED MUST RUN_DIR [extra args]: fusion of every 3rd frame, no pictures
  local input=$1 expected=$2 must=$3 run=$4
  shift 4
  check reconstruct "$input" "$expected" "$must" --run "$run" --sequence "$RSEQ" --out "$OUT/runs/recon_$total" \
    --every 3 --no-snapshots --threads 1 "$@"
}
recon "plain run (every 3rd frame, no snapshots)" 0 "" "$RUN"
check reconstruct "plain run with snapshots 128x96" 0 "" --run "$RUN" --sequence "$RSEQ" --out "$OUT/runs/recon_snap" \
  --size 128x96 --threads 1
check reconstruct "--snapshots-only on that output" 0 "" --run "$RUN" --sequence "$RSEQ" --out "$OUT/runs/recon_snap" \
  --snapshots-only --size 128x96 --threads 1
recon "--run missing" 2 "/nonexistent" /nonexistent
d=$(run_variant recon_no_traj trajectory.txt)
recon "trajectory.txt missing" 2 "$d/trajectory.txt" "$d"
d=$(run_variant recon_traj_empty trajectory.txt)
: > "$d/trajectory.txt"
recon "trajectory.txt empty" 2 "$d/trajectory.txt" "$d"
d=$(run_variant recon_traj_bad trajectory.txt)
sed '3s/ [^ ]* / abc /' "$RUN/trajectory.txt" > "$d/trajectory.txt"
recon "trajectory.txt bad value on line 3" 2 "$d/trajectory.txt:3" "$d"
d=$(run_variant recon_traj_garbage trajectory.txt)
head -c 300 "$VOC" > "$d/trajectory.txt"
recon "trajectory.txt binary garbage" 2 "$d/trajectory.txt" "$d"
d=$(run_variant recon_traj_zero_q trajectory.txt)
awk '/^#/ { print; next } { printf "%s %s %s %s 0 0 0 0\n", $1, $2, $3, $4 }' "$RUN/trajectory.txt" > "$d/trajectory.txt"
recon "trajectory.txt zero quaternions" 2 "$d/trajectory.txt" "$d"
d=$(run_variant recon_traj_crlf trajectory.txt)
sed 's/$/\r/' "$RUN/trajectory.txt" | awk 'NR == 2 { print "# a comment"; print "" } { print }' > "$d/trajectory.txt"
recon "trajectory.txt CRLF, comment, blank line (benign)" 0 "" "$d"
recon "--trajectory missing" 2 "/nonexistent.txt" "$RUN" --trajectory /nonexistent.txt
recon "--trajectory bad value on line 3" 2 "recon_traj_bad/trajectory.txt:3" "$RUN" --trajectory "$CASES/recon_traj_bad/trajectory.txt"
d=$(run_variant recon_no_seg segmentation)
recon "run without segmentation/ (benign, warned)" 0 "no segmentation/" "$d"
d=$(run_variant recon_seg_garbage segmentation)
cp -r "$RUN/segmentation" "$d/segmentation"
seg=$(ls "$d/segmentation" | head -1)
printf 'not a png' > "$d/segmentation/$seg"
recon "segmentation/ mask that is text" 2 "$seg" "$d"
d=$(run_variant recon_seg_name segmentation)
cp -r "$RUN/segmentation" "$d/segmentation"
printf 'x' > "$d/segmentation/not_a_time.png"
recon "segmentation/ with a non-timestamp file name" 2 "not_a_time.png" "$d"
d=$(run_variant recon_seg_small segmentation)
cp -r "$RUN/segmentation" "$d/segmentation"
python3 "$OUT/grey_png.py" "$d/segmentation" 32 24
recon "segmentation/ masks of another size" 2 "$d/segmentation" "$d"
check reconstruct "--sequence missing" 2 "/nonexistent" --run "$RUN" --sequence /nonexistent --out "$OUT/runs/recon_x" --no-snapshots
recon "--settings binary garbage" 2 "binary.yaml" "$RUN" --settings "$CASES/binary.yaml"
sed 's/^Recon.ConfidenceStable: .*/Recon.ConfidenceStable: -1/' "$SETTINGS" > "$CASES/recon_bad_key.yaml"
recon "--settings Recon key out of range" 2 "Recon.ConfidenceStable = -1" "$RUN" --settings "$CASES/recon_bad_key.yaml"
recon "--size 10x10" 2 "--size 10x10" "$RUN" --size 10x10
recon "--view 1,2,3" 2 "--view 1,2,3" "$RUN" --view 1,2,3
check reconstruct "--out under a file" 2 "binary.yaml" --run "$RUN" --sequence "$RSEQ" --out "$CASES/binary.yaml/x" --every 3 --no-snapshots
mkdir -p "$OUT/runs/recon_none"
check reconstruct "--snapshots-only without surfels.ply" 2 "recon_none/surfels.ply" --run "$RUN" --sequence "$RSEQ" \
  --out "$OUT/runs/recon_none" --snapshots-only
mkdir -p "$OUT/runs/recon_trunc"
SURFELS=$OUT/runs/recon_snap/surfels.ply
head -c $(( $(stat -c %s "$SURFELS") - 40 )) "$SURFELS" > "$OUT/runs/recon_trunc/surfels.ply"
check reconstruct "--snapshots-only, surfels.ply truncated" 2 "recon_trunc/surfels.ply: truncated" --run "$RUN" \
  --sequence "$RSEQ" --out "$OUT/runs/recon_trunc" --snapshots-only

# ---- check_surfels -------------------------------------------------------------------------------
check check_surfels "no arguments" 2 ""
check check_surfels "plain (surfels of the run above)" 0 "" --surfels "$SURFELS" --sequence "$RSEQ" --trajectory "$RUN/trajectory.txt" --frame-step 5
check check_surfels "--surfels missing" 2 "/nonexistent.ply" --surfels /nonexistent.ply --sequence "$RSEQ"
check check_surfels "--surfels binary garbage" 2 "binary.yaml" --surfels "$CASES/binary.yaml" --sequence "$RSEQ"
check check_surfels "--surfels truncated" 2 "recon_trunc/surfels.ply: truncated" --surfels "$OUT/runs/recon_trunc/surfels.ply" --sequence "$RSEQ"
huge_ply "$CASES/huge_surfels.ply" "float x" "float y" "float z" "float nx" "float ny" "float nz" "uchar red" "uchar green" \
  "uchar blue" "float radius" "float confidence"
check check_surfels "--surfels announcing 4e12 surfels" 2 "huge_surfels.ply: truncated" --surfels "$CASES/huge_surfels.ply" --sequence "$RSEQ"
check check_surfels "--surfels static_map.ply (other layout)" 2 "static_map.ply" --surfels "$RUN/static_map.ply" --sequence "$RSEQ"
check check_surfels "--sequence missing" 2 "/nonexistent" --surfels "$SURFELS" --sequence /nonexistent
check check_surfels "--scene missing" 2 "/nonexistent.ply" --surfels "$SURFELS" --sequence "$RSEQ" --scene /nonexistent.ply
check check_surfels "--scene binary garbage" 2 "binary.yaml" --surfels "$SURFELS" --sequence "$RSEQ" --scene "$CASES/binary.yaml"
check check_surfels "--trajectory bad value on line 3" 2 "recon_traj_bad/trajectory.txt:3" --surfels "$SURFELS" --sequence "$RSEQ" \
  --trajectory "$CASES/recon_traj_bad/trajectory.txt"
check check_surfels "--json in a missing folder" 2 "/nonexistent/c.json" --surfels "$SURFELS" --sequence "$RSEQ" --frame-step 5 \
  --json /nonexistent/c.json

# ---- check_map -----------------------------------------------------------------------------------
check check_map "no arguments" 2 ""
check check_map "plain run" 0 "" --run "$RUN" --sequence "$RSEQ" --max-share 1
check check_map "--run missing" 2 "/nonexistent" --run /nonexistent --sequence "$RSEQ"
d=$(run_variant map_no_ply static_map.ply)
check check_map "static_map.ply missing" 2 "$d/static_map.ply" --run "$d" --sequence "$RSEQ"
d=$(run_variant map_ply_garbage static_map.ply)
head -c 300 "$VOC" > "$d/static_map.ply"
check check_map "static_map.ply binary garbage" 2 "$d/static_map.ply" --run "$d" --sequence "$RSEQ"
d=$(run_variant map_ply_huge static_map.ply)
huge_ply "$d/static_map.ply" "float x" "float y" "float z" "uchar red" "uchar green" "uchar blue" "float beta"
check check_map "static_map.ply announcing 4e12 points" 2 "$d/static_map.ply" --run "$d" --sequence "$RSEQ"
d=$(run_variant map_kf_bad keyframes.txt)
awk 'NR == 3 { $2 = "x" } { print }' "$RUN/keyframes.txt" > "$d/keyframes.txt"
check check_map "keyframes.txt bad value on line 3" 2 "$d/keyframes.txt:3" --run "$d" --sequence "$RSEQ"
d=$(run_variant map_kf_missing keyframes.txt)
check check_map "keyframes.txt missing" 2 "$d/keyframes.txt" --run "$d" --sequence "$RSEQ"
d=$(VARIANT_OF=$RSEQ variant no_scene scene.ply)
check check_map "--sequence without scene.ply" 2 "$d/scene.ply" --run "$RUN" --sequence "$d"
d=$(VARIANT_OF=$RSEQ variant scene_huge scene.ply)
printf 'ply\nformat ascii 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nend_header\n0 0 0\n' > "$d/scene.ply"
check check_map "scene.ply announcing 2e9 vertices" 2 "$d/scene.ply" --run "$RUN" --sequence "$d"
d=$(VARIANT_OF=$RSEQ variant scene_face scene.ply)
printf 'ply\nformat ascii 1.0\nelement vertex 3\nelement face 1\nend_header\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n' > "$d/scene.ply"
check check_map "scene.ply face of 2e9 vertices" 2 "$d/scene.ply:9" --run "$RUN" --sequence "$d"
check check_map "--list in a missing folder" 2 "/nonexistent/l.txt" --run "$RUN" --sequence "$RSEQ" --max-share 1 --list /nonexistent/l.txt

# ---- report --------------------------------------------------------------------------------------
# bench DIR [omit...]: a scripts/benchmark.sh-like folder DIR/runs/static_s2/core/ holding RUN's files.
bench() {
  local dir=$CASES/$1
  shift
  local run_dir=$dir/runs/static_s2/core
  mkdir -p "$run_dir"
  local f
  for f in trajectory.txt metrics.json; do cp "$RUN/$f" "$run_dir/$f"; done
  ln -s "$RUN/segmentation" "$run_dir/segmentation"
  echo "$RSEQ" > "$run_dir/sequence_path.txt"
  echo "$dir"
}
check report "no arguments" 2 ""
check report "plain benchmark folder, one run" 0 "" --benchmark "$(bench bench_ok)"
check report "--benchmark missing" 2 "/nonexistent" --benchmark /nonexistent
check report "--benchmark without runs/" 2 "$CASES/empty_dir" --benchmark "$CASES/empty_dir"
d=$(bench bench_json)
head -c 300 "$VOC" > "$d/runs/static_s2/core/metrics.json"
check report "metrics.json binary garbage" 2 "$d/runs/static_s2/core/metrics.json" --benchmark "$d"
d=$(bench bench_json_cut)
head -c 40 "$RUN/metrics.json" > "$d/runs/static_s2/core/metrics.json"
check report "metrics.json cut after 40 bytes" 2 "$d/runs/static_s2/core/metrics.json" --benchmark "$d"
d=$(bench bench_traj)
cp "$CASES/recon_traj_bad/trajectory.txt" "$d/runs/static_s2/core/trajectory.txt"
check report "trajectory.txt bad value on line 3" 2 "$d/runs/static_s2/core/trajectory.txt:3" --benchmark "$d"
d=$(bench bench_seq)
echo /nonexistent > "$d/runs/static_s2/core/sequence_path.txt"
check report "sequence_path.txt names a missing sequence" 2 "/nonexistent" --benchmark "$d"
d=$(bench bench_no_seq_path)
rm "$d/runs/static_s2/core/sequence_path.txt"
check report "sequence_path.txt missing" 2 "sequence_path.txt" --benchmark "$d"

echo "contract_check: $total inputs, $failures not as the contract says; table in $TABLE"
[ "$failures" -eq 0 ]
