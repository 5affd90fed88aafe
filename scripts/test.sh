#!/usr/bin/env bash
# The whole test suite through colcon test; exits non-zero when any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p log
bash scripts/install.sh
source scripts/env.sh
# pytest-xdist: one worker per core (at most 4: each holds numba's and JAX's compiled code);
# --dist loadfile keeps a file's tests in one worker, so a module's cached diagnosis or tune
# runs once. MMG_TEST_WORKERS=0 runs the suite in one process.
WORKERS=${MMG_TEST_WORKERS:-auto}
colcon test --base-paths . --return-code-on-test-failure --event-handlers console_direct+ \
  --pytest-args -q -p no:cacheprovider --durations=25 -n "$WORKERS" --maxprocesses=4 \
  --dist loadfile
colcon test-result --verbose
