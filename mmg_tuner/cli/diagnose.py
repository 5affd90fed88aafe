"""
``diagnose``: what the tuned model gets wrong, its physical cause and the extended model.

``diagnose``: what the tuned model gets wrong, its physical cause, the extended model, and its gain
on held-out trials.

Examples
--------
diagnose trials/ --ship suzaku --out diag          # alternate trials held out
diagnose T1 T2 T3 --test T4 T5 --effects current rudder_offset --out diag
diagnose --resume diag                             # continue an interrupted diagnosis

"""
from __future__ import annotations

import argparse
import logging
import sys
from typing import cast

from mmg_tuner import api
from mmg_tuner._outdir import OutputDir
from mmg_tuner.cli.args import add_reading_options, add_writing_options, bounded, positive_float
from mmg_tuner.cli.common import Parser, run_command, SEED, UsageError
from mmg_tuner.cli.tune import (DT, load_tune_and_test, parse_or_resume, show_log,
                                sigterm_as_interrupt, store_args)
from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.diagnosis.settings import BUDGETS  # noqa: F401  (re-exported for scripts)
from mmg_tuner.diagnosis.settings import RESTART_FROUDE, restart_period
from mmg_tuner.tuning.report import fmt_gain, fmt_J

CHECKPOINT = 'checkpoint.json'   # the effect search's; the base tuning's beside it


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='diagnose', description=__doc__.strip().split('\n')[0])
    ap.add_argument('trials', nargs='*', help='trials: bags, .mcap, .csv, .dat, or folders')
    ap.add_argument('--test', nargs='*', default=[],
                    help='held-out trials, at least two (default: every second trial is held '
                    'out)')
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay as the pre-determined values')
    ap.add_argument('--out', help='output directory (new or empty)')
    ap.add_argument('--resume', metavar='DIR', help='continue the interrupted diagnosis in DIR')
    ap.add_argument('--effects', nargs='+', default=list(EFFECTS), choices=list(EFFECTS))
    ap.add_argument('--targets', nargs='+', help="base parameters to tune (default: ship's)")
    ap.add_argument('--ar', type=positive_float, help='relative box half-width a_r')
    ap.add_argument('--budget', choices=list(api.BUDGETS), default='standard')
    ap.add_argument('--max-effects', type=bounded(int, 1, len(EFFECTS), 'number of effects'),
                    default=3)
    add_reading_options(ap, DT, 'resampling step [s]', dt_default=1.0)
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='rk4')
    ap.add_argument('--seed', type=SEED, default=0)
    ap.add_argument('--verdict', choices=('rules', 'evidence'), default='evidence',
                    help='how causes are named after the search: evidence (default; each '
                    'effect by its own held-out contribution and consistency over the trials, '
                    'the error apportioned) or rules (a structural verdict withdraws the '
                    'fitted causes); see doc/guides/diagnosis.md')
    ap.add_argument('--restart-every', type=float, metavar='S', dest='restart_every_s',
                    help='restart every simulation of the diagnosis from the recorded state '
                    'every S seconds (0: one free run per trial). Default: '
                    f'{RESTART_FROUDE:g} sqrt(L_pp/g) (SUZAKU {restart_period(83.0):.0f} s) '
                    'with --verdict evidence, a free run with rules')
    # a flag, not '--residual MODE': an optional value would swallow the first trial path
    ap.add_argument('--residual', action='store_const', const='on', default='auto',
                    help='after the search, always train a residual network on the final model '
                    'and report how much of the remaining held-out error is learnable '
                    'structure and where it lives (needs jax, equinox, optax; tens of '
                    'seconds). Default (auto): only when what remains is above what sensor '
                    'noise alone reaches and JAX is importable')
    ap.add_argument('--no-residual', dest='residual', action='store_const', const='off',
                    help='never train the residual network')
    ap.add_argument('--measured', metavar='FILE.yaml',
                    help='coefficients measured outside the trials (resistance test, wake '
                    'fraction, rudder-angle feedback), each with its standard error: '
                    "'measured: {R_0: {value: V, se: S}}'; priors of every tuning, not fixed "
                    'values. An effect whose parameters are all measured (rudder_lag_tau from '
                    'the rudder-angle feedback) is held at its value and named as measured '
                    'when the trials do not contradict it')
    ap.add_argument('--setting', metavar='VENUE[,POSITION]',
                    help='where the trials were recorded: sea, pond, basin or tank, optionally '
                    'with antenna or reference (positions at a GNSS antenna or of the reference '
                    'point), e.g. tank,reference; effects impossible there are fitted but never '
                    "named (default: the ship YAML's setting:, else what the trial files say)")
    ap.add_argument('--retune', choices=('lsq', 'cmaes'), default='lsq',
                    help="the candidates' warm-started re-tunes: local least squares or CMA-ES")
    add_writing_options(ap, 'no progress messages')
    return ap


# --residual's values as DiagnoseConfig.residual (True / False: a run stored before 'auto')
_RESIDUAL: dict[str | bool, str | bool] = {'auto': 'auto', 'on': True, 'off': False,
                                           True: True, False: False}


def diagnose_config(args: argparse.Namespace) -> api.DiagnoseConfig:
    return api.DiagnoseConfig(effects=tuple(args.effects), targets=args.targets, a_r=args.ar,
                              budget=args.budget, max_effects=args.max_effects,
                              integrator=args.integrator, seed=args.seed,
                              setting=getattr(args, 'setting', None),   # (older resumed runs
                              retune=getattr(args, 'retune', 'lsq'),     # stored neither)
                              residual=_RESIDUAL[getattr(args, 'residual', False)],
                              measured=getattr(args, 'measured', None),
                              verdict=getattr(args, 'verdict', 'rules'),
                              restart_every_s=getattr(args, 'restart_every_s', None))


def verdict_lines(dx: api.DiagnosisResult) -> list[str]:
    """
    Return the lines the command prints about the causes, in order.

    CAUSE with its share of the held-out error (or why none), UNDECIDED (one of a set) with
    the trial that would tell them apart, NOT A CAUSE (fits, but its evidence is against it),
    SUSPECTED (not named) with what would settle it, IMPOSSIBLE HERE, the learnable structure
    and REMAINS (what the causes leave: noise, structural or unexplained); ``dx``: a
    :class:`mmg_tuner.api.DiagnosisResult`.
    """
    out: list[str] = []
    for c in dx.causes:
        # (a share cast to float where it is checked not None)
        out.append(f'CAUSE: {c.summary}'
                   + (f' (measured: {c.measured}, not fitted)' if c.measured else '')
                   + (f' -- {100 * cast(float, c.share):.0f} % of the held-out error '
                      f'(held-out gain {100 * c.heldout_gain:.1f} %)'
                      if getattr(c, 'share', None) is not None
                      else f' -- held-out gain {100 * c.heldout_gain:.1f} %'))
    if not dx.causes:
        by_evidence = bool(getattr(dx, 'decision', None))   # verdict='evidence'
        out.append('CAUSE: none named alone -- see UNDECIDED' if dx.undecided
                   else 'CAUSE: none named -- what the fitted effects explain is not one '
                   'value over the trials, or a hull change explains it better (see NOT A '
                   'CAUSE)' if dx.mimicking and by_evidence
                   else 'CAUSE: none named -- the model structure is the likely cause (see '
                   'REMAINS)' if dx.mimicking
                   else 'CAUSE: none found -- no effect in the library explains the errors '
                   'significantly')
    pairs = {a['about']: a for a in dx.advice if a.get('kind') == 'indistinguishable'}
    for c in dx.undecided:
        sep = [pairs[k] for k in (f'{c.effect} vs {r}' for r in c.indistinguishable_from)
               if k in pairs]
        best = max(sep, key=lambda a: (a['settles'], a['separation']), default=None)
        out.append(f'UNDECIDED: one of {c.summary} or '
                   + ', '.join(r.replace('_', ' ') for r in c.indistinguishable_from)
                   + f' -- held-out gain {100 * c.heldout_gain:.1f} %, these trials cannot tell '
                   'them apart'
                   + ('' if best is None else f"; to tell them apart: {best['instruction']}"
                      if best['settles'] else '; no trial of the repertoire tells them apart'))
    why = {e['effect']: e['why'] for e in getattr(dx, 'decision', None) or []}
    for c in dx.mimicking:
        out.append(f'NOT A CAUSE: {c.summary} fits (held-out gain {100 * c.heldout_gain:.1f} %), '
                   f"but {why.get(c.effect, 'it only mimics the structural gap (REMAINS)')}")
    settle = {a['about']: a for a in dx.advice if a.get('kind') == 'suspected'}
    for x in dx.suspected:   # hinted at by the trials, not named: what would settle it
        a = settle.get(x['effect'])
        out.append(f"SUSPECTED (not named): {x['summary']} -- held-out gain "
                   f"{100 * x['gain']:.1f} ± {100 * x['gain_se']:.1f} %, the held-out trials "
                   'disagree'
                   + (f"; to settle it: {a.get('measure') or a['instruction']}" if a else ''))
    for x in dx.impossible_fits:
        out.append(f"IMPOSSIBLE HERE: {x['effect']} would fit (held-out gain "
                   f"{100 * x['gain']:.1f} %), but {x['reason']}: a structural gap of the model")
    st = dx.structure or {}
    if (st.get('learnable') or {}).get('line'):
        out.append(st['learnable']['line'])
    if st.get('verdict') in ('structure', 'unexplained'):
        out.append(f"REMAINS: {st['summary']}")
    elif dx.causes and st.get('summary'):
        out.append(f"REMAINS: {st['summary']}")
    return out


def command(argv: list[str] | None = None) -> int:
    args, notes, resume = parse_or_resume(build_parser(), argv, 'diagnose', 'trials')
    config = diagnose_config(args)        # every option checked before any work
    log = logging.getLogger(__name__)
    with show_log(args.quiet), OutputDir.open(args.out, resume=resume) as out:
        for n in notes:
            log.warning('resume: %s', n)
        ship = api.load_ship(args.ship, args.params)
        trials, test = load_tune_and_test(args, ship)
        if not args.test:
            if len(trials) < 4:
                raise UsageError(
                    f'{len(trials)} trial(s) and no --test: holding out every second trial '
                    'needs at least four (with one held-out trial no cause can ever be named: '
                    "the gain's uncertainty is infinite); give more trials or --test with two "
                    'or more')
            trials, test = api.split_alternate(trials)
            print(f"held out (every second trial): {', '.join(t.name for t in test)}")
        elif len(test) < 2:
            raise UsageError(
                f'--test gives {len(test)} trial(s): at least two are needed (with one the '
                "held-out gain's uncertainty is infinite and no cause can ever be named)")
        if not resume:
            store_args(out, 'diagnose', args)
        try:
            with sigterm_as_interrupt():
                dx = api.diagnose(ship, trials, test, config,
                                  checkpoint=out.path / CHECKPOINT, resume=resume)
        except KeyboardInterrupt:
            print(f'interrupted: every completed tuning is kept in {out.path / CHECKPOINT}; '
                  f'continue with: diagnose --resume {out.path}', file=sys.stderr)
            return 130
        dx.write(out, plots=not args.no_plots,
                 write_unphysical=getattr(args, 'write_unphysical', False))
    print()
    for line in verdict_lines(dx):
        print(line)
    b, f = dx.baseline.J_test, dx.final.J_test
    print(f'held-out J: tuned base model {fmt_J(b)} -> final model {fmt_J(f)} '
          f'({fmt_gain(b, f)} lower); {dx.wall_s:.0f} s ('
          + ', '.join(f'{k} {v:.0f} s' for k, v in dx.timings_s.items()) + ')')
    print(f'wrote {out.path}/params.yaml, diagnosis.md, diagnosis.json'
          + ('' if args.no_plots else ', residuals_*.png, overlay_*.png'))
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
