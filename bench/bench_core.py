"""
Speed of the MMG core, printed as figures (not a test).

  python -m bench run bench_core [--shipmmg]

1. Right-hand-side evaluations per second, single trajectory: KVLCC2 35 deg turn, standard
   MMG method, classic RK4 with a fixed 0.05 s step over 300 s (model scale), 4 RHS per step.
2. Batched candidate-steps per second: SUZAKU, 128 parameter candidates x 4 trials x 800 Euler
   steps of 1 s (the paper's tuning problem size), one call over both cores.
3. With --shipmmg: the same KVLCC2 turn and step in the public `shipmmg` package (installed
   in bench/.venv-shipmmg, never in the project's environment), and the ratio.
"""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import subprocess
import sys
import time

from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate, simulate_batch
import numpy as np

HERE = Path(__file__).resolve().parent


def best_of(fn, repeats=5):
    fn()  # compile / warm up
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def rhs_rate(dt=0.05, duration=300.0):
    ship = load_ship('kvlcc2')
    n = int(round(duration / dt)) + 1
    ctrl = np.tile([711.0, math.radians(35.0)], (n, 1))
    x0 = np.array([0, 0, 0, 1.179, 0, 0])
    wall = best_of(lambda: simulate(ship, x0, ctrl, dt, 'rk4'))
    return 4 * (n - 1) / wall


def batch_rate(N=128, M=4, T=800):
    ship = load_ship('suzaku')
    rng = np.random.default_rng(0)
    params = np.tile(ship.params, (N, 1))
    for name in ship.tuning_targets:
        params[:, PARAM_INDEX[name]] *= rng.uniform(0.6, 1.4, N)
    ctrls = np.stack([np.column_stack([np.full(T, 106.0), np.full(T, math.radians(a))])
                      for a in (10, -20, 35, -40)[:M]])
    x0s = np.tile([0, 0, 0, 3.086, 0, 0], (M, 1))
    wall = best_of(lambda: simulate_batch(ship.kind, params, x0s, ctrls, 1.0))
    return N * M * (T - 1) / wall


def shipmmg_rate(dt=0.05, duration=300.0):
    venv = HERE / '.venv-shipmmg'
    py = venv / 'bin' / 'python'
    if not py.exists():
        subprocess.run([sys.executable, '-m', 'venv', str(venv)], check=True)
        subprocess.run([str(py), '-m', 'pip', 'install', '-q', 'shipmmg==0.0.11'], check=True,
                       stderr=subprocess.DEVNULL)
    res = subprocess.run([str(py), str(HERE / '_shipmmg_rhs.py'), str(dt), str(duration)],
                         check=True, capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])['rhs_per_s']


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run bench_core`` (quick already: --quick does nothing)."""
    return main(argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--shipmmg', action='store_true', help='also measure shipmmg')
    args = ap.parse_args(argv)
    figures = {}
    print(f'machine: {os.cpu_count()} cores, numba threads: '
          f'{__import__("numba").get_num_threads()}')
    r = rhs_rate()
    print(f'single trajectory: {r:,.0f} RHS evaluations/s ({1e9 / r:.0f} ns each; KVLCC2 35 deg '
          'turn, RK4, dt 0.05 s)')
    b = batch_rate()
    print(f'batched: {b:,.0f} candidate-steps/s ({1e9 / b:.0f} ns per step over all cores; '
          'SUZAKU 128 candidates x 4 trials x 800 Euler steps)')
    figures.update(rhs_per_s=r, ns_per_rhs=1e9 / r, batched_candidate_steps_per_s=b,
                   ns_per_candidate_step=1e9 / b)
    if args.shipmmg:
        s = shipmmg_rate()
        print(f'shipmmg 0.0.11: {s:,.0f} RHS evaluations/s on the same turn and step '
              f'-> mmg_tuner is {r / s:,.0f}x faster per RHS evaluation')
        figures.update(shipmmg_rhs_per_s=s, ratio_per_rhs=r / s)
    return figures


if __name__ == '__main__':
    main()
