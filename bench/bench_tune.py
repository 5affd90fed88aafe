"""
The paper's full tuning problem.

12 parameters, four 800 s SUZAKU turning trials at dt = 1 s (+10, -20, +35, -40 deg; truth moved
inside the box, sensor noise), CMA-ES with IPOP restarts from population 12 doubling to 128, until
a whole restart lowers the best J by less than 0.1 % (tuning/tuner.py, RESTART_GAIN), the largest
population converges or 200 000 evaluations. Prints wall time, evaluations per second, final J,
test J and peak memory. Target: <= 60 s, < 500 MB.
    python -m bench run bench_tune [--quick] [--seed N] [--max-evals N] [--polish N]

--polish N: after CMA-ES, the least-squares polish of ``tune --polish`` (Levenberg-Marquardt
on the weighted residuals, ``tuning/lsq.py``) with at most N simulations; each stage's
simulations, wall time and J are printed (registered use: bench_tune_polish_preregistration.md).
"""
from __future__ import annotations

import argparse
import resource
import time

import mmg_tuner as mt
from mmg_tuner.data.generate import PAPER_TEST_DEG, PAPER_TUNE_DEG, paper_turning_trials
from mmg_tuner.tuning import Tuner
from mmg_tuner.tuning.factory import make_objective
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.parameters import moved_truth
from mmg_tuner.tuning.tuner import RESTART_GAIN


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run bench_tune`` (``--quick``: 10 000 evaluations)."""
    return main((['--max-evals', '10000'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser()
    ap.add_argument('--seed', type=int, default=5)
    ap.add_argument('--max-evals', type=int, default=200_000)
    ap.add_argument('--polish', type=int, default=0)
    args = ap.parse_args(argv)
    ship = mt.load_ship('suzaku')
    truth, space, theta = moved_truth(ship, args.seed)
    tune = paper_turning_trials(truth, PAPER_TUNE_DEG, seed=args.seed)
    test = paper_turning_trials(truth, PAPER_TEST_DEG, seed=args.seed + 10)
    obj = make_objective(ship, tune)   # the paper's J: whole trials, its weights, Euler
    obj_test = make_objective(ship, test)
    obj(ship.params[None])  # compile outside the timing
    t0 = time.perf_counter()
    res = Tuner(space, obj, seed=args.seed, max_evaluations=args.max_evals).run()
    cma_wall = time.perf_counter() - t0
    best, J, polish_sims = res.theta, res.J, 0
    if args.polish:
        loc = local_least_squares(space, obj, res.theta, args.polish, method='lm')
        best, J, polish_sims = loc.theta, loc.J, loc.simulations
        print(f'CMA-ES: {res.evaluations} evaluations, J {res.J:.4g}, {cma_wall:.1f} s; '
              f'polish: {polish_sims} simulations, J {J:.4g}; '
              f'{res.evaluations + polish_sims} in all')
    wall = time.perf_counter() - t0
    tuned = space.full_params(ship.params, best)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    steps = res.evaluations * sum(obj.batch.lengths - 1)
    print(f'evaluations: {res.evaluations} ({res.restarts} restarts, IPOP from 12 doubling to '
          f'at most 128, stopped once a restart lowers the best J by < {RESTART_GAIN:.1%})')
    print(f'wall: {wall:.1f} s; CMA-ES {res.evaluations / cma_wall:,.0f} evaluations/s '
          f'({steps / cma_wall / 1e6:.1f} M ship-steps/s)')
    print(f'J tuning trials: pre {obj(ship.params[None])[0]:.4g} -> tuned {J:.4g}')
    print(f'J test trials:   pre {obj_test(ship.params[None])[0]:.4g} -> tuned '
          f'{obj_test(tuned)[0]:.4g} '
          f'(truth {obj_test(space.full_params(ship.params, theta))[0]:.4g})')
    print(f'on a bound: {space.on_bound(best)}')
    print(f'peak memory (RSS): {peak_mb:.0f} MB')
    j_test = (obj_test(ship.params[None])[0], obj_test(tuned)[0])
    return {'evaluations': res.evaluations, 'restarts': res.restarts, 'wall_s': wall,
            'evaluations_per_s': res.evaluations / cma_wall,
            'J_tune_pre': obj(ship.params[None])[0], 'J_tune_cmaes': res.J,
            'polish_simulations': polish_sims, 'simulations': res.evaluations + polish_sims,
            'J_tune_tuned': J, 'J_test_pre': j_test[0], 'J_test_tuned': j_test[1],
            'J_test_change_percent': 100 * (j_test[1] - j_test[0]) / j_test[0],
            'on_bound': space.on_bound(best), 'peak_memory_MB': peak_mb}


if __name__ == '__main__':
    main()
