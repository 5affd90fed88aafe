"""
``evaluate``: how good is a model on recorded trials (per-state RMS and the eq. 26 index).

Simulates each trial driven by its recorded inputs (and measured wind), restarting from the
measured state every N s, and writes the RMS error of each state and the index of Wakita et al.
(2022, eq. 26) per trial: evaluate.json, evaluate.md and overlay plots.

Examples
--------
evaluate data/esso_osaka_frt/berthing --ship esso_osaka_3m --restart-every 100 --out ev
evaluate trials/ --ship suzaku --params tuned/params.yaml --out ev_tuned
evaluate twin/ --ship qiuxin_tug --params id/params.yaml --horizons 1 5 10 20 30 40 50 --out ev

"""
from __future__ import annotations

import argparse
import sys
from typing import cast, TYPE_CHECKING

from mmg_tuner import api
from mmg_tuner._outdir import OutputDir
from mmg_tuner.cli.args import add_reading_options, bounded, nonneg_float
from mmg_tuner.cli.common import Parser, run_command, UsageError
from mmg_tuner.cli.tune import show_log
from mmg_tuner.tuning.evaluate import UNITS

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.tuning.nstep import NStepScore

DT = bounded(float, 1e-3, 600.0, 'resampling step dt [s]')
SUBSTEPS = bounded(int, 1, 1000, 'number of substeps')


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='evaluate', description=__doc__.strip().split('\n')[0])
    ap.add_argument('trials', nargs='+', help='recorded trials: bags, .mcap, .csv, .dat, folders')
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay (e.g. a tuned one)')
    ap.add_argument('--out', required=True, help='output directory (new or empty)')
    ap.add_argument('--restart-every', type=nonneg_float, default=100.0, metavar='S',
                    help='restart from the measured state every S seconds (0: never)')
    add_reading_options(ap, DT, 'resample every trial to this step [s]')
    ap.add_argument('--horizons', type=bounded(int, 1, 100_000, 'horizon [steps]'), nargs='+',
                    metavar='N', help='also n-step prediction: restart from the measured state '
                    'at every sample, predict N steps; RMSE per horizon and the free-run '
                    'relative errors of u, v, r (e.g. 1 5 10 20 30 40 50)')
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='rk4')
    ap.add_argument('--substeps', type=SUBSTEPS, default=1)
    ap.add_argument('--no-plots', action='store_true')
    ap.add_argument('--quiet', action='store_true', help='no progress messages')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    config = api.EvaluateConfig(args.restart_every, args.integrator, args.substeps,
                                tuple(args.horizons) if args.horizons else None)
    with show_log(args.quiet), OutputDir.open(args.out, resumable=False) as out:
        model = api.load_model(args.ship, args.params)   # with the network the params name
        ship = model.ship
        # astern and u <= 0 kept when the ship's family covers them (load_trials' default)
        trials = api.load_trials(args.trials, ship=ship, dt=args.dt, topics=args.topics,
                                 trial_scale=args.trial_scale,
                                 cut_from_event=args.cut_from_event, strict=args.strict)
        if not trials:
            raise UsageError(f'no usable trial in {" ".join(args.trials)}')
        result = api.evaluate(model, trials, config)
        result.write(out, plots=not args.no_plots)
        width = max(len(n) for n in result.trials)
        for name, s in result.trials.items():
            idx = (f'failed at t = {s.failed_at_s:.1f} s ({s.failure})' if s.index is None
                   else f'{s.index:.4g}')
            print(f'{name:<{width}}  index {idx}')
        if result.index_all is not None:
            print(f'{"all trials":<{width}}  index {result.index_all:.4g}')
        if result.coverage is not None:   # an ensemble with a calibrated interval
            c = result.coverage
            print(f'{100 * c["all"]:.1f} % of the samples inside the nominal '
                  f'{100 * c["level"]:.0f} % prediction interval')
        if result.nstep is not None:
            print(nstep_text(result))
        print(f'wrote {out.path}/evaluate.json, evaluate.md'
              + ('' if args.no_plots else ', evaluate_*.png'))
    return 0


def nstep_text(result: api.EvaluateResult) -> str:
    """Return the n-step RMSE per horizon and the free-run relative errors as lines."""
    sc = cast('NStepScore', result.nstep)   # (called only with n-step scores)
    states = ('u', 'v', 'r', 'x', 'y', 'psi')
    lines = ['n-step RMSE (restart from the measured state at every sample):',
             f'{"n":>5} {"t [s]":>7} ' + ' '.join(f'{s + " [" + UNITS[s] + "]":>11}'
                                                  for s in states)]
    for i, h in enumerate(sc.horizons):
        lines.append(f'{h:>5} {h * sc.dt:>7.3g} ' + ' '.join(
            f'{"-" if sc.rmse[s][i] is None else format(sc.rmse[s][i], ".4g"):>11}'
            for s in states) + (f'  ({sc.failed[i]} windows failed)' if sc.failed[i] else ''))
    rel = result.relative
    if rel is not None:
        lines.append('free-run relative error ||y_model - y|| / ||y|| (pooled): ' + ', '.join(
            # (an error cast to float where it is checked not None)
            f'{s} ' + ('-' if rel.pooled[s] is None
                       else format(100 * cast(float, rel.pooled[s]), '.3g')) + ' %'
            for s in ('u', 'v', 'r')))
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
