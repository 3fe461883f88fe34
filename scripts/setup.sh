#!/usr/bin/env bash
# Installs every system dependency of LTLO-SLAM from Debian's packages (idempotent; quiet when all
# are present). See README.md ("Dependencies") for why each one is here.
set -euo pipefail

packages=(
  g++ cmake ninja-build ccache pkg-config
  libeigen3-dev          # linear algebra, fixed-size types
  libopencv-dev          # images, FAST/pyramids, FileStorage YAML settings
  libsuitesparse-dev     # CHOLMOD sparse Cholesky for Thirdparty/sparse_opt
  libdeflate-dev         # fast inflate of the sequences' PNG images (src/io/png_decode.h)
  libosmesa6-dev         # headless OpenGL: simulator renderer and reconstruction snapshots
  libgtest-dev libgmock-dev  # unit and end-to-end tests
  libbenchmark-dev       # kernel and solver benchmarks
  libceres-dev           # benchmark reference for sparse_opt only (never linked into the library)
  libcli11-dev           # command-line parsing of the Examples
  libcpp-httplib-dev     # the live viewer's HTTP server: MJPEG stream, pose events (src/http)
  librosbag-storage-dev libsensor-msgs-dev
                         # reading ROS 1 bags directly (src/io/bag_reader.cc): users' recordings
                         # (TUM RGB-D, OpenLORIS, RealSense) are bags; Debian ships the bag storage
                         # library and the message headers, no ROS installation needed
  python3                # evaluation scripts (scripts/check_loops.py, ...) and the documentation check
  gnome-backgrounds mate-backgrounds lomiri-wallpapers sway-backgrounds
                         # real photographs: simulator textures, vocabulary training and tests
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
