"""``diagnose``: what the tuned model gets wrong, its physical cause, the extended model, and
its gain on held-out trials.

Example:
    diagnose trials/ --ship suzaku --out diag          # alternate trials held out
    diagnose T1 T2 T3 --test T4 T5 --effects current rudder_offset --out diag
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mmg_tuner._atomic import write_atomic
from mmg_tuner.cli.common import run_command
from mmg_tuner.cli.tune import load_set
from mmg_tuner.core.effects import EFFECTS, describe_values
from mmg_tuner.core.ship import load_ship
from mmg_tuner.diagnosis.report import markdown, plot_residuals, residuals_for, to_dict
from mmg_tuner.diagnosis.select import DiagnosisSettings, diagnose
from mmg_tuner.errors import DiagnosisError
from mmg_tuner.tuning.report import plot_trials, write_json, write_params_yaml

BUDGETS = {  # base tuning, screening per candidate, re-tune per candidate
    'quick': (6_000, 300, 3_000),
    'standard': (20_000, 400, 6_000),
    'full': (60_000, 800, 15_000),
}


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='diagnose', description=__doc__.split('\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('trials', nargs='+', help='trials: bags, .mcap, .csv, .dat, or folders')
    ap.add_argument('--test', nargs='*', default=[],
                    help='held-out trials (default: every second trial is held out)')
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay as the pre-determined values')
    ap.add_argument('--out', required=True)
    ap.add_argument('--effects', nargs='+', default=list(EFFECTS), choices=list(EFFECTS))
    ap.add_argument('--targets', nargs='+', help="base parameters to tune (default: ship's)")
    ap.add_argument('--ar', type=float)
    ap.add_argument('--budget', choices=list(BUDGETS), default='standard')
    ap.add_argument('--max-effects', type=int, default=3)
    ap.add_argument('--topics')
    ap.add_argument('--dt', type=float, default=1.0, help='resampling step [s]')
    ap.add_argument('--trial-scale', choices=('ship', 'full'), default='ship')
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='rk4')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--no-plots', action='store_true')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    ship = load_ship(args.ship, args.params)
    trials = load_set(args.trials, args, ship)
    if args.test:
        tune, test = trials, load_set(args.test, args, ship)
    else:
        if len(trials) < 2:
            raise DiagnosisError('need at least two trials (one to tune, one to hold out)')
        tune, test = trials[::2], trials[1::2]
        print(f"held out (every second trial): {', '.join(t.name for t in test)}")
    out = Path(args.out)
    base_e, screen_e, eff_e = BUDGETS[args.budget]
    settings = DiagnosisSettings(targets=args.targets, a_r=args.ar, effects=args.effects,
                                 integrator=args.integrator, base_evals=base_e,
                                 screen_evals=screen_e, effect_evals=eff_e,
                                 max_effects=args.max_effects, seed=args.seed)
    d = diagnose(ship, tune, test, settings, log=lambda m: print(m, flush=True))
    print('3/3 reporting')
    res_base, sims_base = residuals_for(ship, d.base_params, test, args.integrator)
    res_final, sims_final = residuals_for(ship, d.params, test, args.integrator)
    doc = to_dict(d, res_base, res_final)
    write_json(out / 'diagnosis.json', doc)
    write_atomic(out / 'diagnosis.md', markdown(doc, ship))
    names = ', '.join(c['effect'] for c in d.causes) or 'none'
    write_params_yaml(out / 'params.yaml', ship, d.params,
                      f'tuned and extended by mmg_tuner diagnose (effects: {names})')
    if not args.no_plots:
        plot_residuals(out, test, sims_base, sims_final)
        plot_trials(out, ship, test, {'base tuned': ship.with_params(d.base_params).params,
                                      'with effects': ship.with_params(d.params).params},
                    'overlay_', args.integrator)
    print()
    if d.causes:
        for c in d.causes:
            print(f"CAUSE: {describe_values(EFFECTS[c['effect']], c['parameters'], c['uncertainty'])}"
                  f" -- held-out gain {100 * c['heldout_gain']:.1f} %"
                  + (f" (not distinguishable here from {', '.join(c['indistinguishable_from'])})"
                     if c.get('indistinguishable_from') else ''))
    else:
        print('CAUSE: none found -- no effect in the library explains the errors significantly')
    b, f = d.baseline['J_test'], d.final['J_test']
    print(f'held-out J: tuned base model {b:.4g} -> final model {f:.4g} '
          f'({100 * (1 - f / b):.1f} % lower); {d.wall_s:.0f} s')
    print(f'wrote {out}/diagnosis.json, diagnosis.md, params.yaml'
          + ('' if args.no_plots else ', residuals_*.png, overlay_*.png'))
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
