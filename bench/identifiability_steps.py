"""
Standard errors on the paper's problem: do they depend on the differences' step.

Per seed: the paper's tuning problem as ``bench_tune`` builds it (12 parameters, four 800 s
SUZAKU turns, truth moved inside the box, sensor noise), CMA-ES to convergence, then
``standard_errors`` at the tuned point from central differences of two steps (the
diagnosis' 1e-3 of the box and 1e-5) and the smallest eigenvalue of J'J / s^2 (below about 12,
the box's information, the trials leave that direction undetermined).
    python -m bench run identifiability_steps [--seeds 6 7 8 9 10]

Registered: bench/identifiability_steps_preregistration.md (S1-S3).
"""
from __future__ import annotations

import argparse

import mmg_tuner as mt
from mmg_tuner.data.generate import PAPER_TUNE_DEG, paper_turning_trials
from mmg_tuner.tuning import Tuner
from mmg_tuner.tuning.factory import make_objective
from mmg_tuner.tuning.identifiability import jacobian, standard_errors
from mmg_tuner.tuning.parameters import moved_truth
import numpy as np

STEPS = (1e-3, 1e-5)
"""The differences' steps compared (unit box): the diagnosis' default and a hundred times
smaller (columns agree to about 5e-6 on seed 5)."""


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run identifiability_steps`` (``--quick``: one seed)."""
    return main((['--seeds', '6'] if quick else []) + argv)


def one_seed(seed: int) -> dict:
    """Tune seed ``seed``'s problem; its standard errors (box widths) at both steps."""
    ship = mt.load_ship('suzaku')
    truth, space, _ = moved_truth(ship, seed)
    obj = make_objective(ship, paper_turning_trials(truth, PAPER_TUNE_DEG, seed=seed))
    theta = Tuner(space, obj, seed=seed, max_evaluations=200_000).run().theta
    width = space.upper - space.lower
    se = {h: standard_errors(obj, space, theta, h) / width for h in STEPS}
    Jac, s2 = jacobian(obj, space, theta, STEPS[0])
    lam_min = float(np.linalg.eigvalsh(Jac.T @ Jac)[0] / s2)
    names = list(space.names)
    rel = np.abs(se[STEPS[0]] / se[STEPS[1]] - 1.0)
    out = {'seed': seed, 'names': names, 'lambda_min_over_s2': lam_min,
           'se_box': {f'{h:g}': se[h].tolist() for h in STEPS},
           'max_rel_difference': float(rel.max()),
           'S1': bool(rel.max() <= 0.01), 'S2': bool(lam_min < 1e-3),
           'S3': bool(se[STEPS[0]][names.index('a_H')] > 0.1
                      and se[STEPS[0]][names.index('R_0')] < 0.1)}
    print(f"seed {seed}: smallest eigenvalue of J'J / s^2 {lam_min:.3g}; standard errors "
          f'(box widths, h = {STEPS[0]:g} / {STEPS[1]:g}) ' + ', '.join(
              f'{n} {a:.3g}/{b:.3g}' for n, a, b in zip(names, se[STEPS[0]], se[STEPS[1]])))
    print(f'  largest relative difference {rel.max():.2e}; S1 {out["S1"]}, S2 {out["S2"]}, '
          f'S3 {out["S3"]}')
    return out


def main(argv: list[str] | None = None) -> dict:
    """Run the seeds; print and return each one's figures and the verdicts."""
    ap = argparse.ArgumentParser()
    ap.add_argument('--seeds', type=int, nargs='+', default=[6, 7, 8, 9, 10])
    args = ap.parse_args(argv)
    seeds = [one_seed(s) for s in args.seeds]
    verdict = {k: all(s[k] for s in seeds) for k in ('S1', 'S2')}
    verdict['S3_seeds'] = sum(s['S3'] for s in seeds)
    print(f'S1 (every error within 1 % across steps, every seed): {verdict["S1"]}; '
          f'S2 (an undetermined direction, every seed): {verdict["S2"]}; '
          f'S3 (a_H > 0.1 > R_0, box widths): {verdict["S3_seeds"]} of {len(seeds)} seeds')
    return {'seeds': seeds, **verdict}
