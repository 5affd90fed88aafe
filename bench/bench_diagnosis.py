"""Diagnosis benchmark: many random cases per effect, the confusion matrix, parameter errors and
run time.

Each case: SUZAKU with its 12 tuning targets moved inside the box (up to 0.3 x half-width),
10 trials of 400 s at 1 Hz (turning, zigzag and random manoeuvres with random angles; 5 tune,
5 held out), realistic sensor noise, and one effect hidden at a random realistic magnitude and
direction (or none: the clean control). The diagnosis runs with the command's budget.
A case is correct when exactly the hidden effect is named (nothing, for clean data).

    python bench/bench_diagnosis.py [--cases 5] [--budget standard] [--effects ...]
                                    [--retune lsq|cmaes]

Results are appended per case to bench/out/diagnosis_cases_<retune>.jsonl (an interrupted run
resumes where it stopped; --fresh starts over) and summarised in
bench/out/diagnosis_summary_<retune>.md, with the median wall time per stage (base tune,
screen, re-tunes, backward step, identifiability, report).
Targets: >= 95 % correct names, no false positive on clean data, median <= 30 s per diagnosis
of 10 trials (issue 15).
"""
from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import common  # noqa: F401  (puts the repository on sys.path)

from mmg_tuner.cli.diagnose import BUDGETS
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.generate import SensorNoise, generate_trial
from mmg_tuner.diagnosis import DiagnosisSettings, diagnose
from mmg_tuner.tuning import ParameterSpace

OUT = Path(__file__).resolve().parent / 'out'
CLASSES = ('clean', 'current', 'wind', 'rudder_offset', 'rudder_lag', 'rpm_scale',
           'yaw_moment_bias', 'antenna_offset', 'time_offset', 'prop_side_force')


def _sign(rng) -> float:
    return 1.0 if rng.uniform() < 0.5 else -1.0


def random_effect(name: str, rng: np.random.Generator) -> dict[str, float]:
    """A realistic magnitude and direction for each effect (full-scale SUZAKU, 83 m)."""
    if name == 'clean':
        return {}
    if name == 'current':
        return {'current_speed': rng.uniform(0.15, 0.6),
                'current_dir': rng.uniform(-math.pi, math.pi)}
    if name == 'wind':   # Beaufort 4-6
        return {'wind_speed': rng.uniform(6.0, 13.0), 'wind_dir': rng.uniform(-math.pi, math.pi)}
    if name == 'rudder_offset':
        return {'rudder_offset': _sign(rng) * math.radians(rng.uniform(1.0, 3.0))}
    if name == 'rudder_lag':
        return {'rudder_lag_tau': rng.uniform(3.0, 10.0)}
    if name == 'rpm_scale':
        return {'rpm_scale': 1.0 + _sign(rng) * rng.uniform(0.03, 0.08)}
    if name == 'yaw_moment_bias':
        return {'yaw_moment_bias': _sign(rng) * rng.uniform(0.0005, 0.0015)}
    if name == 'antenna_offset':  # a mast on the bridge aft or on the forecastle
        return {'antenna_x': _sign(rng) * rng.uniform(10.0, 35.0),
                'antenna_y': rng.uniform(-4.0, 4.0)}
    if name == 'time_offset':
        return {'time_offset': _sign(rng) * rng.uniform(1.0, 2.5)}
    if name == 'prop_side_force':  # 2-6 % of the thrust (K_T ~ 0.17)
        return {'prop_side_force': _sign(rng) * rng.uniform(0.004, 0.01)}
    raise ValueError(name)


def random_trials(truth, rng: np.random.Generator, n: int, duration_s: float, seed: int):
    kinds = ['turning', 'zigzag', 'random', 'turning', 'zigzag'] * ((n + 4) // 5)
    out = []
    for i, kind in enumerate(kinds[:n]):
        if kind == 'turning':
            a = _sign(rng) * rng.uniform(15, 35)
        elif kind == 'zigzag':
            a = _sign(rng) * rng.choice([10.0, 20.0])
        else:
            a = rng.uniform(20, 35)
        name = f'{kind}{a:+.0f}_{i}'
        out.append(generate_trial(truth, kind, float(a), None, 106.0, 3.086, duration_s, 1.0,
                                  SensorNoise(), seed * 100 + i, name)[1])
    return out


def _param_error(name: str, truth: dict, est: dict) -> dict[str, float]:
    err = {}
    for p, v in truth.items():
        e = est.get(p, float('nan')) - v
        if p.endswith('_dir'):
            e = (e + math.pi) % (2 * math.pi) - math.pi
            err[p + '_deg'] = abs(math.degrees(e))
        elif p in ('rudder_offset',):
            err[p + '_deg'] = abs(math.degrees(e))
        else:
            err[p] = abs(e)
    return err


def run_case(ship, cls: str, seed: int, budget: str, n_trials: int, duration_s: float,
             retune: str = 'lsq') -> dict:
    rng = np.random.default_rng(10_000 + seed)
    space = ParameterSpace.around(ship)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-0.3, 0.3, space.dim)
    effect = random_effect(cls, rng)
    truth = ship.with_params({**dict(zip(space.names, theta)), **effect})
    trials = random_trials(truth, rng, n_trials, duration_s, seed)
    base_e, screen_e, eff_e = BUDGETS[budget]
    t0 = time.perf_counter()
    d = diagnose(ship, trials[::2], trials[1::2],
                 DiagnosisSettings(base_evals=base_e, screen_evals=screen_e, effect_evals=eff_e,
                                   seed=seed, retune=retune), log=lambda m: None)
    wall = time.perf_counter() - t0
    named = [c['effect'] for c in d.causes]
    est = {p: v for c in d.causes for p, v in c['parameters'].items()}
    return {'class': cls, 'seed': seed, 'truth': effect, 'named': named,
            'correct': named == ([] if cls == 'clean' else [cls]),
            'estimates': est,
            'param_error': _param_error(cls, effect, est) if cls in named else {},
            'rivals': {c['effect']: c.get('indistinguishable_from', []) for c in d.causes},
            'barely_identifiable': sorted(d.aliased),
            'heldout_gain': d.final['heldout_gain_total'], 'wall_s': wall,
            'timings_s': d.timings_s, 'retune': retune}


def summarise(rows: list[dict]) -> str:
    by = defaultdict(list)
    for r in rows:
        by[r['class']].append(r)
    cols = list(CLASSES) + ['other']
    lines = ['Confusion matrix (rows: hidden effect; columns: first effect named; "clean" = '
             'nothing named; a case is correct only when exactly the hidden effect is named)', '',
             '| hidden \\ named | ' + ' | '.join(c.replace('_', ' ') for c in cols)
             + ' | correct | 2nd effect named | flagged barely identifiable |',
             '|' + '---|' * (len(cols) + 4)]
    total = correct = 0
    for cls in CLASSES:
        rs = by.get(cls, [])
        if not rs:
            continue
        cnt = Counter((r['named'][0] if r['named'] else 'clean') for r in rs)
        other = sum(v for k, v in cnt.items() if k not in CLASSES)
        ok = sum(r['correct'] for r in rs)
        second = sum(len(r['named']) > 1 for r in rs)
        flagged = sum(cls in r.get('barely_identifiable', []) for r in rs)
        total += len(rs)
        correct += ok
        lines.append(f'| {cls} | ' + ' | '.join(str(cnt.get(c, '')) if c != 'other'
                                                else str(other or '') for c in cols)
                     + f' | {ok}/{len(rs)} | {second} | '
                     + (f'{flagged}/{len(rs)}' if cls != 'clean' and all(
                         'barely_identifiable' in r for r in rs) else '') + ' |')
    lines += ['', f'Correct: {correct}/{total} = {100 * correct / max(total, 1):.0f} %', '',
              '| hidden effect | parameter | median abs error | max abs error | cases |',
              '|---|---|---|---|---|']
    for cls in CLASSES:
        errs = defaultdict(list)
        for r in by.get(cls, []):
            for k, v in r['param_error'].items():
                errs[k].append(v)
        for k, v in errs.items():
            lines.append(f'| {cls} | {k} | {np.median(v):.3g} | {np.max(v):.3g} | {len(v)} |')
    walls = [r['wall_s'] for r in rows]
    if walls:
        lines += ['', f'Run time per diagnosis: median {np.median(walls):.0f} s, max '
                      f'{np.max(walls):.0f} s over {len(walls)} cases']
        stages = sorted({k for r in rows for k in r.get('timings_s', {})})
        if stages:
            lines.append('Median per stage: ' + ', '.join(
                f"{k} {np.median([r.get('timings_s', {}).get(k, 0.0) for r in rows]):.1f} s"
                for k in stages))
    return '\n'.join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cases', type=int, default=5, help='random cases per class')
    ap.add_argument('--budget', choices=list(BUDGETS), default='standard')
    ap.add_argument('--effects', nargs='+', default=list(CLASSES), choices=CLASSES)
    ap.add_argument('--trials', type=int, default=10)
    ap.add_argument('--duration', type=float, default=400.0, help='trial length [s]')
    ap.add_argument('--fresh', action='store_true')
    ap.add_argument('--retune', choices=('lsq', 'cmaes'), default='lsq',
                    help="the candidates' re-tunes (lsq: local least squares; cmaes: as before)")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f'diagnosis_cases_{args.retune}.jsonl'
    if args.fresh and path.exists():
        path.unlink()
    rows = [json.loads(x) for x in path.read_text().splitlines()] if path.exists() else []
    done = {(r['class'], r['seed']) for r in rows}
    ship = load_ship('suzaku')
    for seed in range(args.cases):
        for cls in args.effects:
            if (cls, seed) in done:
                continue
            r = run_case(ship, cls, seed, args.budget, args.trials, args.duration, args.retune)
            rows.append(r)
            with path.open('a') as f:
                f.write(json.dumps(r) + '\n')
            print(f"{cls:16s} seed {seed}: named {r['named'] or 'nothing'} "
                  f"{'ok' if r['correct'] else 'WRONG'}  {r['wall_s']:.0f} s  "
                  f"truth {r['truth']}  est {r['estimates']}  stages "
                  + ', '.join(f'{k} {v:.1f}' for k, v in r['timings_s'].items()), flush=True)
    text = summarise(rows)
    (OUT / f'diagnosis_summary_{args.retune}.md').write_text(text + '\n')
    print()
    print(text)


if __name__ == '__main__':
    main()
