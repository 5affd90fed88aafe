#!/usr/bin/env bash
# Create .venv (Python 3.11), install the pinned requirements and build the package with colcon.
# requirements.txt includes the documentation's Sphinx + myst-parser (test/lint/test_docs.py builds doc/).
# Idempotent: a second run only rebuilds.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p log
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
if [ ! -x .venv/bin/python ] || [ requirements.txt -nt .venv/.installed ]; then
  echo "== creating .venv and installing requirements (first run: about a minute)"
  "$PY" -m venv .venv
  mkdir -p log
  .venv/bin/python -m pip install -q --upgrade pip >log/pip.log 2>&1 || { cat log/pip.log; exit 1; }
  .venv/bin/python -m pip install -q -r requirements.txt >>log/pip.log 2>&1 \
    || { grep -v 'is ignored' log/pip.log; exit 1; }
  touch .venv/.installed
fi
# tf2_msgs (TF for sim_node) has no wheel: generate and compile it with the rosidl wheels
.venv/bin/python scripts/build_tf2_msgs.py 2>log/tf2_msgs.err || { cat log/tf2_msgs.err; exit 1; }
# shellcheck disable=SC1091
source .venv/bin/activate
export ROS_LOG_DIR=${ROS_LOG_DIR:-$PWD/log/ros}
echo "== colcon build"
colcon build --base-paths . --event-handlers console_cohesion- >/dev/null 2>log/colcon_build.err \
  || { cat log/colcon_build.err; exit 1; }
# compile the kernels into the shared cache (core/_numba_cache.py) now, not on the first run
echo "== precompile (the simulator's and tuning's kernels; first build: 6-15 minutes on 2 cores)"
# shellcheck disable=SC1091
set +u; source install/local_setup.bash; set -u
install/mmg_tuner/lib/mmg_tuner/precompile >log/precompile.log 2>&1 || { cat log/precompile.log; exit 1; }
