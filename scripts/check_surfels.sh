#!/usr/bin/env bash
# Accuracy, moving-box area and completeness of a run's reconstruction against the sequence's
# ground truth (scene.ply, masks/, groundtruth.txt); the ground truth is used only here.
#   scripts/check_surfels.sh RUN SEQ [RECON_DIR]     (RECON_DIR defaults to RUN/recon)
# Prints check_surfels' "name value" lines and writes RECON_DIR/check.json.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 2 ]; then
  echo "usage: scripts/check_surfels.sh RUN SEQ [RECON_DIR]" >&2
  exit 2
fi
RUN=$1
SEQ=$2
RECON=${3:-$RUN/recon}
TRAJECTORY=$(sed -n 's/.*"trajectory": *"\([^"]*\)".*/\1/p' "$RECON/reconstruct.json" 2>/dev/null || true)
build/bin/check_surfels --surfels "$RECON/surfels.ply" --sequence "$SEQ" \
  --trajectory "${TRAJECTORY:-$RUN/trajectory.txt}" --json "$RECON/check.json"
