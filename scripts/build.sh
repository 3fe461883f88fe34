#!/usr/bin/env bash
# Configures and builds LTLO-SLAM into build/ (Release, assertions on, 2 jobs).
# Extra arguments are passed to cmake at configure time, e.g. -DLTLO_BUILD_BENCHMARKS=ON.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-2}
# ccache keys on the command line: with the checkout as base directory, paths become relative, so
# clones and worktrees in other places reuse each other's cache entries.
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$(pwd)}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release -DLTLO_ENABLE_ASSERTS=ON "$@" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS"
