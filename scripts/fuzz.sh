#!/usr/bin/env bash
# libFuzzer on the input readers: builds tests/fuzz with clang into build-fuzz (whole tree with
# ASan + UBSan + coverage, only the readers' libraries are compiled), writes a seed corpus from a
# generated sequence, runs each target for SECONDS_EACH seconds and fails on any crash, leak,
# sanitizer report, timeout or out-of-memory. Not part of scripts/test.sh (docs/testing.md).
#   scripts/fuzz.sh [SECONDS_EACH]           default 60 s per target (8 targets)
#   TARGETS="fuzz_ply fuzz_imu" scripts/fuzz.sh 10
# Findings (crashing inputs) land in build-fuzz/findings/<target>/ (once fixed, keep them in
# tests/fuzz/regressions/<target>/: they are replayed on every run); the corpus grows in
# build-fuzz/corpus/<target>/ and is reused by the next run. Summary: build-fuzz/fuzz_summary.txt.
set -uo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
JOBS=${JOBS:-2}
DIR=build-fuzz
TARGETS=${TARGETS:-"fuzz_settings fuzz_image_lists fuzz_imu fuzz_trajectory fuzz_ply fuzz_surfels fuzz_vocabulary fuzz_atlas"}
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}

# ---- Setup: clang and its libFuzzer runtime (Debian: clang-14, libclang-rt-14-dev) -------------
CXX_FUZZ=$(command -v clang++-14 || command -v clang++ || true)
CC_FUZZ=$(command -v clang-14 || command -v clang || true)
fuzzer_lib_present() {
  [ -n "$CXX_FUZZ" ] && echo 'extern "C" int LLVMFuzzerTestOneInput(const char*, unsigned long) { return 0; }' |
    "$CXX_FUZZ" -x c++ -fsanitize=fuzzer,address,undefined -o /dev/null - 2>/dev/null
}
if ! fuzzer_lib_present; then
  echo "fuzz: installing clang-14 libclang-rt-14-dev"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO=sudo
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq && $SUDO apt-get install -y -qq --no-install-recommends clang-14 libclang-rt-14-dev >/dev/null
  CXX_FUZZ=$(command -v clang++-14)
  CC_FUZZ=$(command -v clang-14)
  fuzzer_lib_present || { echo "fuzz: clang++ cannot link -fsanitize=fuzzer" >&2; exit 1; }
fi

# ---- Build the fuzz targets (clang, own build dir) and the programs that make the seeds --------
echo "== building $DIR ($CXX_FUZZ)"
cmake -S . -B "$DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER="$CC_FUZZ" \
  -DCMAKE_CXX_COMPILER="$CXX_FUZZ" -DLTLO_BUILD_FUZZERS=ON -DLTLO_BUILD_TESTS=OFF >/dev/null || exit 1
# shellcheck disable=SC2086
cmake --build "$DIR" -j "$JOBS" --target $TARGETS || exit 1
scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DLTLO_ENABLE_ASSERTS=ON >/dev/null || exit 1
cmake --build build -j "$JOBS" --target simulate train_vocabulary || exit 1

# ---- Seed corpus: small files from a generated sequence and the shipped settings --------------
SEEDS=$DIR/seeds
if [ ! -f "$SEEDS/DONE" ]; then
  echo "== seeds"
  rm -rf "$SEEDS"
  seq_dir=$DIR/seed_sequence
  rm -rf "$seq_dir"
  build/bin/simulate --scenario ltlo --seed 1 --seconds 1 --width 160 --height 120 --out "$seq_dir" \
    >/dev/null 2>&1 || { echo "fuzz: simulate failed" >&2; exit 1; }
  for t in $TARGETS fuzz_settings fuzz_image_lists fuzz_imu fuzz_trajectory fuzz_ply fuzz_surfels fuzz_vocabulary; do
    mkdir -p "$SEEDS/$t"
  done
  cp config_yaml/*.yaml "$seq_dir/calib.yaml" "$SEEDS/fuzz_settings/"
  head -n 12 "$seq_dir/rgb.txt" > "$SEEDS/fuzz_image_lists/rgb.txt"
  head -n 12 "$seq_dir/depth.txt" > "$SEEDS/fuzz_image_lists/depth.txt"
  head -n 12 "$seq_dir/associations.txt" | sed 's/$/\r/' > "$SEEDS/fuzz_image_lists/associations_crlf.txt"
  head -n 40 "$seq_dir/imu.txt" > "$SEEDS/fuzz_imu/imu.txt"
  # EuRoC imu0/data.csv: nanoseconds and commas.
  awk 'NR == 1 { print "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z"; next } NR <= 40 {
         split($1, t, "."); printf "%s%s000,%s,%s,%s,%s,%s,%s\n", t[1], t[2], $2, $3, $4, $5, $6, $7 }' \
    "$seq_dir/imu.txt" > "$SEEDS/fuzz_imu/data.csv"
  head -n 12 "$seq_dir/groundtruth.txt" > "$SEEDS/fuzz_trajectory/groundtruth.txt"
  awk 'NR == 1 { print "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z"; next } NR <= 12 {
         split($1, t, "."); printf "%s%s,%s,%s,%s,%s,%s,%s,%s\n", t[1], t[2], $2, $3, $4, $8, $5, $6, $7 }' \
    "$seq_dir/groundtruth.txt" > "$SEEDS/fuzz_trajectory/groundtruth.csv"
  # static_map.ply as system::writeStaticMapPly writes it: 3 vertices of float x y z, uchar r g b,
  # float beta (little-endian; 1.0f = 00 00 80 3f, 0.5f = 00 00 00 3f, 2.0f = 00 00 00 40).
  {
    printf 'ply\nformat binary_little_endian 1.0\ncomment LTLO-SLAM static map points\nelement vertex 3\n'
    printf 'property float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n'
    printf 'property uchar blue\nproperty float beta\nend_header\n'
    printf '\x00\x00\x80\x3f\x00\x00\x00\x3f\x00\x00\x00\x40\x10\x20\x30\x00\x00\x80\x3f'
    printf '\x00\x00\x00\x40\x00\x00\x80\x3f\x00\x00\x00\x3f\x40\x50\x60\x00\x00\x00\x3f'
    printf '\x00\x00\x00\x3f\x00\x00\x00\x40\x00\x00\x80\x3f\x70\x80\x90\x00\x00\x80\x3f'
  } > "$SEEDS/fuzz_ply/static_map.ply"
  build/bin/train_vocabulary --images "$seq_dir/rgb" --out "$SEEDS/fuzz_vocabulary/k3_L2.bin" --k 3 --levels 2 \
    --crops 2 --max-images 4 --threads 1 >/dev/null 2>&1 || { echo "fuzz: train_vocabulary failed" >&2; exit 1; }
  build/bin/train_vocabulary --images "$seq_dir/rgb" --out "$SEEDS/fuzz_vocabulary/k4_L3.bin" --k 4 --levels 3 \
    --crops 2 --max-images 4 --threads 1 >/dev/null 2>&1 || { echo "fuzz: train_vocabulary failed" >&2; exit 1; }
  rm -rf "$seq_dir"
  touch "$SEEDS/DONE"
fi

# surfels.ply as recon::writeSurfelPly writes it: 2 surfels of float x y z nx ny nz, uchar red
# green blue, float radius confidence (outside the DONE block: seed folders made before it existed).
if [ ! -f "$SEEDS/fuzz_surfels/surfels.ply" ]; then
  mkdir -p "$SEEDS/fuzz_surfels"
  {
    printf 'ply\nformat binary_little_endian 1.0\ncomment LTLO-SLAM surfels\nelement vertex 2\n'
    printf 'property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n'
    printf 'property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n'
    printf 'property float radius\nproperty float confidence\nend_header\n'
    printf '\x00\x00\x80\x3f\x00\x00\x00\x3f\x00\x00\x00\x40\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f'
    printf '\x10\x20\x30\x00\x00\x00\x3f\x00\x00\x00\x40'
    printf '\x00\x00\x00\x40\x00\x00\x80\x3f\x00\x00\x00\x3f\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x00'
    printf '\x40\x50\x60\x00\x00\x00\x3f\x00\x00\x80\x3f'
  } > "$SEEDS/fuzz_surfels/surfels.ply"
fi

# imu.txt as drivers write it (outside the DONE block too): gyroscope-only and accelerometer-only
# rows ("nan nan nan" for the missing sensor, any case), full rows, a repeated and a late stamp;
# and a file of "t x y z" rows that fuzz_imu cuts at its middle line into accel.txt + gyro.txt.
if [ ! -f "$SEEDS/fuzz_imu/imu_split.txt" ]; then
  mkdir -p "$SEEDS/fuzz_imu"
  cat > "$SEEDS/fuzz_imu/imu_split.txt" <<'SEED'
# timestamp gx gy gz ax ay az
1.000000 0.0101 -0.0203 0.0031 0.102 9.797 0.215
1.002512 0.0102 -0.0201 0.0032 nan nan nan
1.003987 nan nan nan 0.104 9.801 0.213
1.004998 0.0104 -0.0199 0.0035 NaN NaN NaN
1.007503 0.0105 -0.0198 0.0036 nan nan nan
1.007503 0.0105 -0.0198 0.0036 nan nan nan
1.008011 NAN NAN NAN 0.107 9.806 0.210
1.010021 0.0107 -0.0196 0.0038 nan nan nan
1.006001 nan nan nan 0.105 9.803 0.212
1.012490 0.0108 -0.0195 0.0039 0.110 9.809 0.208
1.014999 0.0109 -0.0194 0.0041 nan nan nan
1.016012 -nan -nan -nan 0.112 9.812 0.206
1.017497 0.0111 -0.0192 0.0042 nan nan nan
SEED
  cat > "$SEEDS/fuzz_imu/openloris_accel_gyro.txt" <<'SEED'
1.000000 0.102 9.797 0.215
1.004000 0.104 9.801 0.213
1.008000 0.107 9.806 0.210
1.004000 0.104 9.801 0.213
1.012000 0.110 9.809 0.208
1.001000 0.0101 -0.0203 0.0031
1.003500 0.0102 -0.0201 0.0032
1.006000 0.0104 -0.0199 0.0035
1.008500 0.0105 -0.0198 0.0036
1.011000 0.0107 -0.0196 0.0038
SEED
fi

# ---- Run each target ----------------------------------------------------------------------------
SUMMARY=$DIR/fuzz_summary.txt
echo "# target seconds executions exec_per_s corpus_files result" > "$SUMMARY"
status=0
for t in $TARGETS; do
  corpus=$DIR/corpus/$t
  findings=$DIR/findings/$t
  # fuzz_atlas has no generated seeds: its regressions (small atlases, good and bad) seed it.
  mkdir -p "$corpus" "$findings" "$SEEDS/$t"
  log=$DIR/$t.log
  # Inputs that crashed a reader once (tests/fuzz/regressions/<target>/) are replayed first.
  regressions=""
  [ -d "tests/fuzz/regressions/$t" ] && regressions="tests/fuzz/regressions/$t"
  echo "== $t: ${SECONDS_EACH} s (log: $log)"
  # -timeout: an input running longer than 10 s is a hang; -rss_limit_mb/-malloc_limit_mb: a
  # reader that allocates what a corrupt size field announces is a finding (out-of-memory).
  ASAN_OPTIONS="detect_leaks=1 allocator_may_return_null=0 ${ASAN_OPTIONS:-}" \
  UBSAN_OPTIONS="print_stacktrace=1 halt_on_error=1 ${UBSAN_OPTIONS:-}" \
    "$DIR/fuzz/$t" -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
    -print_final_stats=1 -artifact_prefix="$findings/" "$corpus" "$SEEDS/$t" $regressions >"$log" 2>&1
  rc=$?
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  files=$(find "$corpus" -type f | wc -l)
  if [ "$rc" -eq 0 ]; then
    result=ok
  else
    result="CRASH (exit $rc; $(ls "$findings" | head -3 | tr '\n' ' '))"
    grep -m 3 -E "ERROR: |runtime error:|==[0-9]+==|deadly signal|out-of-memory|timeout" "$log" | sed "s/^/    /" >&2
    status=1
  fi
  echo "$t $SECONDS_EACH ${runs:-?} ${rate:-?} $files $result" | tee -a "$SUMMARY"
done
echo "fuzz: summary in $SUMMARY"
exit $status
