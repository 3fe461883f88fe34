#!/usr/bin/env bash
# The project's test command (README): installs dependencies, builds Release with assertions into
# build/ with 2 jobs, runs every test with ctest, exits non-zero on any failure.
# Sanitizer builds: BUILD_DIR=build-asan scripts/test.sh -DLTLO_SANITIZE_ADDRESS=ON
#                   BUILD_DIR=build-tsan scripts/test.sh -DLTLO_SANITIZE_THREAD=ON
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh "$@"
BUILD_DIR=${BUILD_DIR:-build}
cd "$BUILD_DIR"
ctest --output-on-failure -j 2 --timeout 900
