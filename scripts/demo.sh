#!/usr/bin/env bash
# The main job on the embedded default ship (SUZAKU).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
OUT=${1:-demo_out}
mkdir -p "$OUT"
echo "== SUZAKU, the paper's verification case: Euler dt = 1 s, 6 kn, 106 rpm, delta = +-35 deg"
simulate --ship suzaku --maneuver turning --rudder-deg 35 --rpm 106 --speed-kn 6 \
  --duration 900 --dt 1.0 --integrator euler --rudder-rate 0 --out "$OUT/turn_stbd35.csv"
simulate --ship suzaku --maneuver turning --rudder-deg -35 --rpm 106 --speed-kn 6 \
  --duration 900 --dt 1.0 --integrator euler --rudder-rate 0 --out "$OUT/turn_port35.csv"
simulate --ship suzaku --maneuver zigzag --rudder-deg 20 --check-deg 20 --rpm 106 --speed-kn 6 \
  --duration 900 --out "$OUT/zigzag20.csv"
echo "== KVLCC2 (standard MMG method) against MARIN's free-running tests"
python bench/verify_kvlcc2.py
