"""``tune``: fine-tune MMG parameters on recorded trials with CMA-ES (Suyama et al. 2023).

Example:
    tune trials/turning_p10 trials/turning_m20 --test trials/turning_m10 --ship suzaku --out tuned
    tune --resume tuned        # continue an interrupted run
"""
from __future__ import annotations

import argparse
import json
import math
import signal
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from mmg_tuner._atomic import write_atomic
from mmg_tuner.cli.common import run_command
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import load_topic_map
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.objective import Objective, TrialBatch, paper_weights
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.report import (markdown_report, plot_trials, write_json,
                                     write_params_yaml)
from mmg_tuner.tuning.tuner import Progress, Tuner


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='tune', description=__doc__.split('\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('trials', nargs='*', help='tuning trials: bags, .mcap, .csv, .dat, folders')
    ap.add_argument('--test', nargs='*', default=[], help='held-out test trials')
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay as the pre-determined values')
    ap.add_argument('--out', help='output directory')
    ap.add_argument('--resume', metavar='DIR', help='continue the interrupted run in DIR')
    ap.add_argument('--targets', nargs='+', help="parameters to tune (default: the ship's)")
    ap.add_argument('--ar', type=float, help='relative box half-width a_r (default: ship, 0.5)')
    ap.add_argument('--bound', action='append', default=[], metavar='NAME=AR|NAME=LO:HI',
                    help='per-parameter a_r or explicit bounds (repeatable)')
    ap.add_argument('--weights', nargs=6, type=float, metavar=('X', 'Y', 'PSI', 'U', 'V', 'R'),
                    help='error weights (default: the paper\'s L_pp, L_pp, pi/4, 0, 0, 0)')
    ap.add_argument('--shoot-every', type=float, default=0.0,
                    help='restart the simulation from the recorded state every H s (0: never)')
    ap.add_argument('--topics', help='topic map YAML for bags')
    ap.add_argument('--dt', type=float, help='resample every trial to this step [s]')
    ap.add_argument('--trial-scale', choices=('ship', 'full'), default='ship',
                    help="'full': trials are full scale, Froude-scale them to the ship config")
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='euler')
    ap.add_argument('--substeps', type=int, default=1)
    ap.add_argument('--popsize', type=int, default=12)
    ap.add_argument('--max-popsize', type=int, default=128)
    ap.add_argument('--max-evals', type=int, default=200_000)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--no-plots', action='store_true')
    ap.add_argument('--quiet', action='store_true', help='no progress bar')
    return ap


def _bounds(items: list[str]) -> dict:
    out: dict = {}
    for item in items:
        name, _, val = item.partition('=')
        try:
            if ':' in val:
                lo, hi = val.split(':')
                out[name] = (float(lo), float(hi))
            else:
                out[name] = float(val)
        except ValueError:
            raise TuningError(f'--bound {item!r}: expected NAME=AR or NAME=LO:HI') from None
    return out


def load_set(paths: list[str], args, ship) -> list:
    tm = load_topic_map(args.topics)
    if args.dt:
        tm = replace(tm, dt=args.dt)
    trials = []
    for p in paths:
        trials.extend(load_trials(p, tm))
    if args.trial_scale == 'full' and ship.scale_ratio != 1.0:
        trials = [t.froude_scaled(ship.scale_ratio) for t in trials]
    if args.dt:
        trials = [t if abs(t.dt - args.dt) < 1e-9 else t.resampled(args.dt) for t in trials]
    return trials


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    resume = False
    if args.resume:
        out = Path(args.resume)
        saved = out / 'args.json'
        if not saved.is_file():
            raise TuningError(f'{out}: nothing to resume (no args.json)')
        args = build_parser().parse_args(json.loads(saved.read_text()))
        resume = True
    else:
        if not args.trials or not args.out:
            raise TuningError('give tuning trials and --out DIR (or --resume DIR)')
        out = Path(args.out)
        write_atomic(out / 'args.json', json.dumps(argv if argv is not None else sys.argv[1:]))
    ship = load_ship(args.ship, args.params)
    tune_trials = load_set(args.trials, args, ship)
    test_trials = load_set(args.test, args, ship) if args.test else []
    space = ParameterSpace.around(ship, args.targets, args.ar, _bounds(args.bound))
    weights = np.array(args.weights) if args.weights else paper_weights(ship.L_pp)
    obj = Objective(ship, TrialBatch.from_trials(tune_trials), weights, args.shoot_every,
                    args.integrator, args.substeps)
    tuner = Tuner(space, obj, popsize=args.popsize, max_popsize=args.max_popsize,
                  max_evaluations=args.max_evals, seed=args.seed,
                  checkpoint=out / 'checkpoint.pkl')
    print(f'tuning {space.dim} parameters of {ship.name} on {len(tune_trials)} trial(s)'
          f'{f", testing on {len(test_trials)}" if test_trials else ""}; box a_r = '
          f'{args.ar or ship.a_r:g}; output {out}', file=sys.stderr)
    bar = None if args.quiet else _progress_bar(args.max_evals)
    old = signal.signal(signal.SIGTERM, _interrupt)
    try:
        result = tuner.run(resume=resume, progress=bar)
    finally:
        signal.signal(signal.SIGTERM, old)
        if bar is not None:
            bar.close()
    tuned = space.full_params(ship.params, result.theta)[0]
    doc = build_report(ship, space, result, obj, tune_trials, test_trials, tuned, args)
    write_params_yaml(out / 'params.yaml', ship, dict(zip(space.names, result.theta)),
                      f'tuned by mmg_tuner on {", ".join(t.name for t in tune_trials)}')
    write_json(out / 'report.json', doc)
    write_atomic(out / 'report.md', markdown_report(doc))
    if not args.no_plots:
        runs = {'pre-determined': ship.params, 'tuned': tuned}
        plot_trials(out, ship, tune_trials + test_trials, runs, 'plot_', args.integrator,
                    args.substeps)
    J = doc['J']
    print(f"J tuning: {J['pre']['tune']:.4g} -> {J['tuned']['tune']:.4g}"
          + (f"; J test: {J['pre']['test']:.4g} -> {J['tuned']['test']:.4g} "
             f"({100 * (1 - J['tuned']['test'] / J['pre']['test']):.1f} % lower)"
             if test_trials else ''))
    if doc['bounds_hit']:
        print(f"on a bound of their box: {', '.join(doc['bounds_hit'])}")
    print(f'{result.evaluations} evaluations in {result.wall_s:.1f} s; wrote {out}/params.yaml, '
          'report.json, report.md' + ('' if args.no_plots else ', plot_*.png'))
    if result.interrupted:
        print(f'interrupted: best so far written; continue with: tune --resume {out}',
              file=sys.stderr)
        return 130
    return 0


def _interrupt(signum, frame) -> None:
    """A kill (SIGTERM) stops like Ctrl-C: best so far written, resumable."""
    raise KeyboardInterrupt


def _progress_bar(total: int):
    from tqdm import tqdm
    bar = tqdm(total=total, unit='eval', file=sys.stderr, dynamic_ncols=True, mininterval=0.5,
               bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}] {postfix}')

    def update(p: Progress) -> None:
        bar.set_postfix_str(f'gen {p.generation} restart {p.restart} pop {p.popsize} '
                            f'best J {p.best_J:.4g}', refresh=False)
        bar.update(min(p.evaluations, total) - bar.n)  # tqdm throttles the redraw

    update.close = bar.close  # type: ignore[attr-defined]
    return update


def build_report(ship, space, result, obj, tune_trials, test_trials, tuned, args) -> dict:
    pre = ship.params
    J_tune_pre, _ = obj.per_trial(pre[None])
    J_tune, _ = obj.per_trial(tuned[None])
    per_trial = {t.name: {'set': 'tune', 'J_pre': float(a), 'J_tuned': float(b)}
                 for t, a, b in zip(tune_trials, J_tune_pre[0], J_tune[0])}
    J_test_pre = J_test = None
    if test_trials:
        tobj = Objective(ship, TrialBatch.from_trials(test_trials), obj.weights,
                         args.shoot_every, args.integrator, args.substeps)
        a, _ = tobj.per_trial(pre[None])
        b, _ = tobj.per_trial(tuned[None])
        J_test_pre, J_test = float(a.sum()), float(b.sum())
        per_trial.update({t.name: {'set': 'test', 'J_pre': float(x), 'J_tuned': float(y)}
                          for t, x, y in zip(test_trials, a[0], b[0])})
    hit = space.on_bound(result.theta)
    return {
        'ship': ship.name,
        'J': {'pre': {'tune': float(J_tune_pre.sum()), 'test': J_test_pre},
              'tuned': {'tune': float(J_tune.sum()), 'test': J_test}},
        'per_trial': per_trial,
        'params': {n: {'pre': float(p), 'tuned': float(v), 'lower': float(lo),
                       'upper': float(hi), 'on_bound': n in hit}
                   for n, p, v, lo, hi in zip(space.names, space.pre, result.theta, space.lower,
                                              space.upper)},
        'bounds_hit': hit, 'evaluations': int(result.evaluations), 'restarts': result.restarts,
        'wall_s': float(result.wall_s), 'interrupted': result.interrupted,
        'settings': {'a_r': args.ar or ship.a_r, 'weights': obj.weights.tolist(),
                     'shoot_every_s': args.shoot_every, 'integrator': args.integrator,
                     'dt': obj.batch.dt, 'seed': args.seed, 'max_evals': args.max_evals,
                     'popsize': [args.popsize, args.max_popsize]},
        'finite': bool(math.isfinite(result.J)),
    }


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
