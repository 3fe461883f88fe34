#!/usr/bin/env bash
# The project's test command (README): installs dependencies, builds Release with assertions into
# build/ with 2 jobs, runs every test with ctest, exits non-zero on any failure.
# Sanitizer builds: BUILD_DIR=build-asan scripts/test.sh -DLTLO_SANITIZE_ADDRESS=ON
#                   BUILD_DIR=build-tsan scripts/test.sh -DLTLO_SANITIZE_THREAD=ON
# At the end it lists the skipped tests with their reasons and prints their count
# (scripts/skipped_tests.sh on ctest's JUnit file BUILD_DIR/ctest-results.xml). With CI=true (set
# by .ci/run) a test skipped for a missing vocabulary or missing photographs fails the run too: a
# broken environment must not pass as green.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
scripts/setup.sh
scripts/build.sh "$@"
BUILD_DIR=${BUILD_DIR:-build}
cd "$BUILD_DIR"
junit="$PWD/ctest-results.xml"
rm -f "$junit"
tests_status=0
ctest --output-on-failure -j 2 --timeout 900 --output-junit "$junit" || tests_status=$?
skips_status=0
"$ROOT/scripts/skipped_tests.sh" "$junit" || skips_status=$?
if [ "$tests_status" -ne 0 ]; then exit "$tests_status"; fi
exit "$skips_status"
