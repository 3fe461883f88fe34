# The scenario catalogue of scripts/benchmark.sh and scripts/ablation.sh (sourced, not run).
#
# A scenario is one of the simulator's five occlusion profiles (static stlo mtlo ltlo carried:
# `simulate --scenario NAME`, SECONDS_PER_SEQUENCE long) or a named harder world below (issue 32):
# its simulate options, with --seconds when it is not SECONDS_PER_SEQUENCE long. Sequences are
# <scenario>_s<seed>. Add a harder world as one line: name, then its options.
# walkers, door and three_movers stand on the static profile, so every mover in them is the one
# under test (walkers drop the boxes they overlap and three_movers drops all of them anyway).
# plain_* panels are as large as the boxes they replace (only the texture differs from ltlo/mtlo);
# plain_tall_* panels are up to twice that and hide the whole view for seconds (stop 44's plain movers).
# blind_start: no image (black, no depth) for the first 3 s, the robot still for 2 of them: no map can
# start, the IMU carries the pose (Tracking.PreMapImuPose). blind_ltlo: the same start on ltlo, whose
# first box arrives soon after the map starts (the IMU initialised from the rest before the map,
# ImuInit.FromPreMapRest, carries the pose behind it).
HARDER_WORLDS='
long_mtlo           --scenario mtlo --seconds 300
standstill          --scenario ltlo --still 20,10 --occlusion-at 21 --occlusion-at 27.1
still_start         --scenario ltlo --still 0,3
still_start_static  --scenario static --still 0,3 --occlusion-at 0.5
walkers             --scenario static --walkers 4
door                --scenario static --door
three_movers        --scenario static --three-movers
plain_ltlo          --scenario ltlo --plain-movers
plain_mtlo          --scenario mtlo --plain-movers
plain_tall_ltlo     --scenario ltlo --plain-movers --tall-panels
plain_tall_mtlo     --scenario mtlo --plain-movers --tall-panels
blind_start         --scenario static --still 0,2 --black 0,3
blind_ltlo          --scenario ltlo --still 0,2 --black 0,3
'
PROFILES="static stlo mtlo ltlo carried"

# simulate_options SCENARIO SECONDS: the options of `simulate` (without --seed and --out) for one
# scenario; SECONDS applies unless the catalogue line has --seconds. Exit 2 for an unknown name.
simulate_options() {
  local name=$1 seconds=$2 line
  case " $PROFILES " in *" $name "*) echo "--scenario $name --seconds $seconds"; return 0 ;; esac
  line=$(printf '%s\n' "$HARDER_WORLDS" | awk -v n="$name" '$1 == n { $1 = ""; print; exit }')
  if [ -z "$line" ]; then
    echo "unknown scenario $name (profiles: $PROFILES; harder worlds:$(printf '%s\n' "$HARDER_WORLDS" | awk 'NF { printf " %s", $1 }'))" >&2
    return 2
  fi
  case " $line " in *" --seconds "*) echo "$line" ;; *) echo "$line --seconds $seconds" ;; esac
}

# sequence_scenario NAME: "<scenario> <seed>" of a sequence name <scenario>_s<seed> (nothing when
# the name has no such form).
sequence_scenario() {
  local name=$1
  [[ $name =~ ^(.+)_s([0-9]+)$ ]] && echo "${BASH_REMATCH[1]} ${BASH_REMATCH[2]}"
}
