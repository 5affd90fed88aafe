"""
The paper's a_r experiment on synthetic SUZAKU turning trials at +-10, +-20, +-35, +-40 deg.

Tune on {+10, -20, +35, -40}, test on {-10, +20, -35, +40}, for a_r = 0.2 ... 0.6.

The 'real' ship has its targets moved (up to 0.3 |theta|) and a steering gear lag the model
does not have (rudder_lag_tau), so the tuned model can only bend its coefficients to mimic
it: that is what makes overfitting possible, as with the paper's real ship.
    python bench/ar_sweep.py [--evals N] [--lag S]
"""
from __future__ import annotations

import argparse
import time

from common import moved_truth, PAPER_TEST, PAPER_TUNE, paper_turning_trials
from mmg_tuner.tuning import ParameterSpace, Tuner
from mmg_tuner.tuning.factory import make_objective


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--evals', type=int, default=40_000)
    ap.add_argument('--lag', type=float, default=6.0, help='hidden rudder lag tau [s]')
    ap.add_argument('--seed', type=int, default=5)
    args = ap.parse_args()
    ship, truth, _, _ = moved_truth(args.seed, spread=0.6,
                                    extra={'rudder_lag_tau': args.lag})
    tune = paper_turning_trials(truth, PAPER_TUNE, seed=args.seed)
    test = paper_turning_trials(truth, PAPER_TEST, seed=args.seed + 10)
    obj = make_objective(ship, tune)   # the paper's J: whole trials, its weights, Euler
    obj_test = make_objective(ship, test)
    print(f'pre-determined: J_tune {obj(ship.params[None])[0]:.4g}, '
          f'J_test {obj_test(ship.params[None])[0]:.4g}')
    print('| a_r | J_tune | J_test | on a bound | wall |')
    print('|---|---|---|---|---|')
    for a_r in (0.2, 0.3, 0.4, 0.5, 0.6):
        space = ParameterSpace.around(ship, a_r=a_r)
        t0 = time.perf_counter()
        res = Tuner(space, obj, seed=args.seed, max_evaluations=args.evals).run()
        tuned = space.full_params(ship.params, res.theta)
        print(f'| {a_r} | {res.J:.4g} | {obj_test(tuned)[0]:.4g} | '
              f'{len(space.on_bound(res.theta))} | {time.perf_counter() - t0:.0f} s |')


if __name__ == '__main__':
    main()
