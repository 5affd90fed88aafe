"""
The paper's a_r experiment on synthetic SUZAKU turning trials at +-10, +-20, +-35, +-40 deg.

Tune on {+10, -20, +35, -40}, test on {-10, +20, -35, +40}, for a_r = 0.2 ... 0.6.

The 'real' ship has its targets moved (up to 0.3 |theta|) and a steering gear lag the model
does not have (rudder_lag_tau), so the tuned model can only bend its coefficients to mimic
it: that is what makes overfitting possible, as with the paper's real ship.
    python -m bench run ar_sweep [--quick] [--evals N] [--lag S]
"""
from __future__ import annotations

import argparse
import time

import mmg_tuner as mt
from mmg_tuner.data.generate import PAPER_TEST_DEG, PAPER_TUNE_DEG, paper_turning_trials
from mmg_tuner.tuning import ParameterSpace, Tuner
from mmg_tuner.tuning.factory import make_objective
from mmg_tuner.tuning.parameters import moved_truth


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run ar_sweep`` (``--quick``: 2000 evaluations each)."""
    return main((['--evals', '2000'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser()
    ap.add_argument('--evals', type=int, default=40_000)
    ap.add_argument('--lag', type=float, default=6.0, help='hidden rudder lag tau [s]')
    ap.add_argument('--seed', type=int, default=5)
    args = ap.parse_args(argv)
    ship = mt.load_ship('suzaku')
    truth, _, _ = moved_truth(ship, args.seed, spread=0.6, extra={'rudder_lag_tau': args.lag})
    tune = paper_turning_trials(truth, PAPER_TUNE_DEG, seed=args.seed)
    test = paper_turning_trials(truth, PAPER_TEST_DEG, seed=args.seed + 10)
    obj = make_objective(ship, tune)   # the paper's J: whole trials, its weights, Euler
    obj_test = make_objective(ship, test)
    print(f'pre-determined: J_tune {obj(ship.params[None])[0]:.4g}, '
          f'J_test {obj_test(ship.params[None])[0]:.4g}')
    print('| a_r | J_tune | J_test | on a bound | wall |')
    print('|---|---|---|---|---|')
    rows = []
    for a_r in (0.2, 0.3, 0.4, 0.5, 0.6):
        space = ParameterSpace.around(ship, a_r=a_r)
        t0 = time.perf_counter()
        res = Tuner(space, obj, seed=args.seed, max_evaluations=args.evals).run()
        tuned = space.full_params(ship.params, res.theta)
        rows.append({'a_r': a_r, 'J_tune': res.J, 'J_test': obj_test(tuned)[0],
                     'on_bound': len(space.on_bound(res.theta)),
                     'wall_s': time.perf_counter() - t0})
        print(f'| {a_r} | {res.J:.4g} | {rows[-1]["J_test"]:.4g} | '
              f'{rows[-1]["on_bound"]} | {rows[-1]["wall_s"]:.0f} s |')
    return {'evaluations_each': args.evals, 'hidden_rudder_lag_s': args.lag,
            'J_tune_pre': obj(ship.params[None])[0], 'J_test_pre': obj_test(ship.params[None])[0],
            'a_r': rows}


if __name__ == '__main__':
    main()
