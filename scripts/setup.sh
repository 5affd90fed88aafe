#!/usr/bin/env bash
# README command 1: install everything into .venv, build with colcon, run the main job.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install.sh
bash scripts/demo.sh "$@"
