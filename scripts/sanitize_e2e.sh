#!/usr/bin/env bash
# ThreadSanitizer and AddressSanitizer+UndefinedBehaviorSanitizer on an end-to-end run: builds
# build-tsan (LTLO_SANITIZE_THREAD=ON) and build-asan (LTLO_SANITIZE_ADDRESS=ON), both
# RelWithDebInfo with 2 jobs, and runs the end-to-end test binary (tests/system/system_test.cc:
# System with its tracking, local-mapping and loop-closing threads on a generated 8 s 320x240
# static sequence, RGB-D-inertial; and a 27 s lap of the room, RGB-D only, with a loop correction
# and the full-BA thread) under each. Exits non-zero when a test fails or a sanitizer reports anything.
#   scripts/sanitize_e2e.sh [tsan|asan ...]     (default: both; FILTER overrides the gtest filter)
set -uo pipefail
cd "$(dirname "$0")/.."
JOBS=${JOBS:-2}
FILTER=${FILTER:-SystemEndToEnd.RgbdInertialThreaded:SystemEndToEnd.RgbdOnlyThreadedClosesTheLoop}
KINDS=("$@")
[ ${#KINDS[@]} -eq 0 ] && KINDS=(tsan asan)
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$(cd .. && pwd)}
export LTLO_SOURCE_DIR=$PWD

status=0
for kind in "${KINDS[@]}"; do
  case "$kind" in
    tsan) option=-DLTLO_SANITIZE_THREAD=ON ;;
    asan) option=-DLTLO_SANITIZE_ADDRESS=ON ;;
    *) echo "sanitize_e2e: unknown sanitizer '$kind' (tsan or asan)" >&2; exit 2 ;;
  esac
  dir=build-$kind
  echo "== $kind: building $dir/tests/system_test"
  if ! cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLTLO_ENABLE_ASSERTS=ON "$option" >/dev/null ||
     ! cmake --build "$dir" -j "$JOBS" --target system_test; then
    echo "sanitize_e2e: $kind build failed" >&2
    status=1
    continue
  fi
  log=$dir/sanitize_e2e.log
  echo "== $kind: running $FILTER (log: $log)"
  # tests/tsan.supp: Mesa (the simulator's renderer) and GDAL are not instrumented (as ctest uses).
  # OMP_NUM_THREADS=1: CHOLMOD's OpenMP threads (libgomp, not instrumented) otherwise show up as
  # races inside cholmod_* whose barriers TSan cannot see; our own threads are what is checked.
  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
  TSAN_OPTIONS="suppressions=$PWD/tests/tsan.supp halt_on_error=0 second_deadlock_stack=1 exitcode=66 ${TSAN_OPTIONS:-}" \
  ASAN_OPTIONS="detect_leaks=1 exitcode=67 ${ASAN_OPTIONS:-}" \
  LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp ${LSAN_OPTIONS:-}" \
  UBSAN_OPTIONS="print_stacktrace=1 halt_on_error=1 ${UBSAN_OPTIONS:-}" \
    "$dir/tests/system_test" --gtest_filter="$FILTER" >"$log" 2>&1
  rc=$?
  reports=$(grep -cE "WARNING: ThreadSanitizer|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error:" "$log")
  grep -E "^\[  (PASSED|FAILED) |e2e .*ATE" "$log" | sed "s/^/  /"
  if [ "$rc" -ne 0 ] || [ "$reports" -ne 0 ]; then
    echo "sanitize_e2e: $kind FAILED (exit $rc, $reports sanitizer report(s)); see $log" >&2
    grep -m 5 -A 12 -E "WARNING: ThreadSanitizer|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error:" "$log" >&2
    status=1
  else
    echo "sanitize_e2e: $kind clean"
  fi
done
exit $status
