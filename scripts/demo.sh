#!/usr/bin/env bash
# The main job on the embedded default ship (SUZAKU): generate trials with a hidden effect,
# tune, diagnose, report. A few minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
OUT=${1:-demo_out}
# Start afresh, but delete only a folder an earlier demo made (it carries our marker file).
if [ -e "$OUT" ]; then
  if [ -f "$OUT/.mmg_tuner_demo" ]; then
    rm -rf "$OUT"
  else
    echo "ERROR: $OUT exists and was not made by this demo; give another folder: $0 DIR" >&2
    exit 2
  fi
fi
mkdir -p "$OUT"
touch "$OUT/.mmg_tuner_demo"
echo "== 1/4 generate: SUZAKU sea trials (turns, zigzags, random manoeuvres) with sensor noise;"
echo "       the 'real' ship differs from the pre-determined model and a current is hidden"
generate --ship suzaku --params config/demo_truth.yaml --out "$OUT/trials" --duration 300 \
  --rate-hz 2 --seed 7 --maneuvers turning:35 zigzag:20 random:30 zigzag:-15 turning:-30 \
  zigzag:10 turning:-20 random:25
echo
echo "== 2/4 inspect the recordings (rosbag2, MCAP storage)"
inspect "$OUT/trials" | grep -E "trial |usable"
echo
echo "== 3/4 tune the paper's 12 parameters with CMA-ES (every second trial held out)"
tune "$OUT"/trials/{turning_p35,random_p30,turning_m30,turning_m20} \
  --test "$OUT"/trials/{zigzag_p20,zigzag_m15,zigzag_p10,random_p25} \
  --ship suzaku --out "$OUT/tuned" --integrator rk4 --max-evals 20000
echo
echo "== 4/4 diagnose: what does the tuned model still get wrong, and why?"
diagnose "$OUT/trials" --ship suzaku --out "$OUT/diagnosis" --budget quick --max-effects 2
echo
echo "Reports: $OUT/tuned/report.md, $OUT/diagnosis/diagnosis.md (plots beside them)."
echo "The extended model: simulate --params $OUT/diagnosis/params.yaml ... or"
echo "  ros2 run mmg_tuner sim_node --ros-args -p params_file:=$OUT/diagnosis/params.yaml"
