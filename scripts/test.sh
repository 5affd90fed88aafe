#!/usr/bin/env bash
# The whole test suite through colcon test; exits non-zero when any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p log
bash scripts/install.sh
source scripts/env.sh
colcon test --base-paths . --return-code-on-test-failure --event-handlers console_direct+ \
  --pytest-args -q -p no:cacheprovider --durations=25
colcon test-result --verbose
