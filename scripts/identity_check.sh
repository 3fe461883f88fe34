#!/usr/bin/env bash
# A refactor's check that behaviour did not change: runs rgbd_inertial single-threaded (deterministic)
# from a reference build and from this checkout's build/ on the same generated sequence and compares
# trajectory.txt, trajectory_online.txt and keyframes.txt byte for byte.
#
#   scripts/identity_check.sh REF_BIN [SEQUENCE]
#     REF_BIN   the reference's build/bin, e.g. of a worktree at the commit before the change:
#               git worktree add /tmp/ref HEAD~1 && (cd /tmp/ref && scripts/build.sh) -> /tmp/ref/build/bin
#     SEQUENCE  default: a 20 s ltlo sequence, seed 1, generated once into out/identity/ltlo_20s
# Prints IDENTICAL (exit 0) or the first differing lines (exit 1); 2 on bad arguments.
set -uo pipefail
cd "$(dirname "$0")/.."
REF_BIN=${1:?usage: scripts/identity_check.sh REF_BIN [SEQUENCE]}
[ -x "$REF_BIN/rgbd_inertial" ] || { echo "identity_check: $REF_BIN/rgbd_inertial: not a program" >&2; exit 2; }
[ -x build/bin/rgbd_inertial ] || { echo "identity_check: build/bin/rgbd_inertial missing (scripts/build.sh)" >&2; exit 2; }
SEQ=${2:-out/identity/ltlo_20s}
if [ -z "${2:-}" ] && [ ! -f "$SEQ/DONE" ]; then
  rm -rf "$SEQ" && mkdir -p "$(dirname "$SEQ")"
  build/bin/simulate --scenario ltlo --seed 1 --seconds 20 --out "$SEQ" >/dev/null 2>&1 && touch "$SEQ/DONE" ||
    { echo "identity_check: simulate failed" >&2; exit 1; }
fi
OUT=out/identity/runs
rm -rf "$OUT" && mkdir -p "$OUT"
for side in reference current; do
  bin=$([ $side = reference ] && echo "$REF_BIN" || echo build/bin)
  "$bin/rgbd_inertial" --settings config_yaml/synthetic.yaml --sequence "$SEQ" --out "$OUT/$side" --single-thread \
    >"$OUT/$side.log" 2>&1 || { echo "identity_check: the $side run failed (see $OUT/$side.log)" >&2; exit 1; }
done
status=0
for f in trajectory.txt trajectory_online.txt keyframes.txt; do
  if cmp -s "$OUT/reference/$f" "$OUT/current/$f"; then
    echo "$f: identical ($(wc -l <"$OUT/current/$f") lines)"
  else
    echo "$f: DIFFERS"; diff "$OUT/reference/$f" "$OUT/current/$f" | head -5; status=1
  fi
done
[ $status = 0 ] && echo IDENTICAL || echo NOT-IDENTICAL
exit $status
