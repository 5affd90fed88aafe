"""
The paper's full tuning problem.

12 parameters, four 800 s SUZAKU turning trials at dt = 1 s (+10, -20, +35, -40 deg; truth moved
inside the box, sensor noise), CMA-ES with IPOP restarts from population 12 doubling to 128, until
the restarts converge or 200 000 evaluations. Prints wall time, evaluations per second, final J,
test J and peak memory. Target: <= 60 s, < 500 MB.    python bench/bench_tune.py [--seed N]
"""
from __future__ import annotations

import argparse
import resource
import time

from common import moved_truth, PAPER_TEST, PAPER_TUNE, paper_turning_trials
from mmg_tuner.tuning import Tuner
from mmg_tuner.tuning.factory import make_objective


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--seed', type=int, default=5)
    args = ap.parse_args()
    ship, truth, space, theta = moved_truth(args.seed)
    tune = paper_turning_trials(truth, PAPER_TUNE, seed=args.seed)
    test = paper_turning_trials(truth, PAPER_TEST, seed=args.seed + 10)
    obj = make_objective(ship, tune)   # the paper's J: whole trials, its weights, Euler
    obj_test = make_objective(ship, test)
    obj(ship.params[None])  # compile outside the timing
    t0 = time.perf_counter()
    res = Tuner(space, obj, seed=args.seed, max_evaluations=200_000).run()
    wall = time.perf_counter() - t0
    tuned = space.full_params(ship.params, res.theta)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    steps = res.evaluations * sum(obj.batch.lengths - 1)
    print(f'evaluations: {res.evaluations} ({res.restarts} restarts, IPOP 12 -> 128)')
    print(f'wall: {wall:.1f} s -> {res.evaluations / wall:,.0f} evaluations/s '
          f'({steps / wall / 1e6:.1f} M ship-steps/s)')
    print(f'J tuning trials: pre {obj(ship.params[None])[0]:.4g} -> tuned {res.J:.4g}')
    print(f'J test trials:   pre {obj_test(ship.params[None])[0]:.4g} -> tuned '
          f'{obj_test(tuned)[0]:.4g} '
          f'(truth {obj_test(space.full_params(ship.params, theta))[0]:.4g})')
    print(f'on a bound: {space.on_bound(res.theta)}')
    print(f'peak memory (RSS): {peak_mb:.0f} MB')


if __name__ == '__main__':
    main()
