"""
What the pond wind does to the low-speed model on the real Esso Osaka runs.

  python -m bench run esso_wind [--quick] [--budget quick] [--segment 50] [--dt 0.5]
                                [--no-diagnose]

--quick: parts 1 and 2 only (--no-diagnose).

Data: the 32 FRT-DS-ESSO runs of bench/esso_osaka.py (same cuts, same split), 10 Hz, with
their measured true wind. Index: Wakita et al. (2022) eq. 26, sigma pooled over all 32 runs,
RK4, restart from the measured state every 100 s, published (captive-test) parameters.

1. The wind itself, per kind: mean speed, turbulence intensity (std / mean speed), gust factor
   (largest 3 s mean / mean), steadiness |mean vector| / mean speed (1: steady in speed and
   direction) and the direction spread (circular standard deviation).
2. What it does to the model, per kind: the index with the measured wind sample by sample, with
   the wind columns removed (the model keeps the air drag of its own motion), with the run's
   mean measured wind held steady, and with the best steady wind fitted to each run alone
   (speed and direction by a grid and CMA-ES on that run: an in-sample upper bound of what any
   steady-wind effect can explain). "Explains" = the share of the no-wind error removed.
3. The diagnosis (``mmg_tuner.diagnose``, setting pond) on the runs cut into --segment s
   pieces (multiple shooting at the data level, tuning/segments.py) at --dt s, trained on the
   tuning split and scored on the held-out split of bench/esso_osaka.py: (a) with the wind
   columns removed: what it names, and the steady wind it fits if any; (b) with the measured
   wind present: the line on the measured wind (model with and without it).
"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
import time

from bench import esso_osaka as eb
import mmg_tuner as mt
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.data.esso import load_split
from mmg_tuner.tuning.evaluate import evaluate, pooled_sigma
from mmg_tuner.tuning.factory import make_objective, ObjectiveSpec
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.segments import split_trials
from mmg_tuner.tuning.tuner import Tuner
import numpy as np

RESTART_S = 100.0
MAX_STEADY_MS = 4.0   # box of the fitted steady wind [m/s]; gusts in the pond reach ~8 m/s


def wind_stats(tr) -> dict[str, float]:
    """Mean speed, turbulence intensity, gust factor, steadiness and direction spread."""
    w = tr.wind
    speed = np.hypot(w[:, 0], w[:, 1])
    mean = float(speed.mean())
    k = max(1, int(round(3.0 / tr.dt)))
    gust = float(np.convolve(speed, np.ones(k) / k, mode='valid').max())
    unit = w / np.maximum(speed, 1e-9)[:, None]
    R = float(np.hypot(*unit.mean(axis=0)))
    return {'mean': mean, 'ti': float(speed.std()) / mean, 'gust': gust / mean,
            'steady': float(np.hypot(*w.mean(axis=0))) / mean,
            'spread_deg': math.degrees(math.sqrt(-2.0 * math.log(max(R, 1e-12))))}


def steady_mean(tr):
    """Replace the trial's measured wind by the run's mean wind vector (held steady)."""
    return replace(tr, wind=np.tile(tr.wind.mean(axis=0), (len(tr), 1)))


def fit_steady(ship, tr, weights, seed=0):
    """Fit the steady true wind (speed [m/s], from-direction [rad]) to one run alone."""
    obj = make_objective(ship, [tr], ObjectiveSpec(tuple(weights), integrator='rk4',
                                                   segment_s=RESTART_S, x0_window_s=0.0))
    space = ParameterSpace.around(ship, ('wind_speed', 'wind_dir'),
                                  overrides={'wind_speed': (0.0, MAX_STEADY_MS),
                                             'wind_dir': (-math.pi, math.pi)})
    spd, dirs = np.meshgrid(np.linspace(0.25, MAX_STEADY_MS, 8),
                            np.linspace(-math.pi, math.pi, 16, endpoint=False))
    grid = np.column_stack([spd.ravel(), dirs.ravel()])
    J = obj(space.full_params(ship.params, grid))
    x0 = grid[int(np.argmin(J))]
    res = Tuner(space, obj, popsize=8, max_popsize=8, max_evaluations=240, sigma0=0.1,
                seed=seed, x0=x0).run()
    return float(res.theta[0]), float(res.theta[1])


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_wind`` (``--quick``: --no-diagnose)."""
    return main((['--no-diagnose'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--budget', default='quick', choices=('quick', 'standard', 'full'))
    ap.add_argument('--segment', type=float, default=50.0,
                    help='diagnosis: cut runs into pieces of this length [s]')
    ap.add_argument('--dt', type=float, default=0.5, help='diagnosis: resample to this step [s]')
    ap.add_argument('--no-diagnose', action='store_true', help='only parts 1 and 2')
    args = ap.parse_args(argv)
    t_all = time.perf_counter()
    ship = mt.load_ship('esso_osaka_3m')
    train, test, kind_of = load_split()
    figures = {'wind': [], 'index': []}
    runs = train + test
    print(f'{len(runs)} runs ({sum(t.duration_s for t in runs):.0f} s), all with measured '
          'true wind')

    print('\n1. The pond wind (per kind: median over runs)')
    print('| kind | runs | mean speed [m/s] | turbulence std/mean | gust 3 s/mean | '
          '|mean vector|/mean speed | direction spread [deg] |')
    print('|---|---|---|---|---|---|---|')
    stats = {t.name: wind_stats(t) for t in runs}
    for kind in eb.KINDS + ('all',):
        s = [stats[t.name] for t in runs if kind in ('all', kind_of[t.name])]

        def med(k, s=s):
            return float(np.median([x[k] for x in s]))
        print(f"| {kind} | {len(s)} | {med('mean'):.2f} | {med('ti'):.2f} | {med('gust'):.2f} | "
              f"{med('steady'):.2f} | {med('spread_deg'):.0f} |")
        figures['wind'].append({'kind': kind, 'runs': len(s), 'mean_speed_ms': med('mean'),
                                'std_over_mean': med('ti'), 'gust_3s_over_mean': med('gust'),
                                'steadiness': med('steady'),
                                'direction_spread_deg': med('spread_deg')})

    print('\n2. The published model with and without the wind (index, sigma pooled over all '
          f'runs, restart every {RESTART_S:g} s)')
    t0 = time.perf_counter()
    sig = pooled_sigma(runs)
    weights = np.array([1.0 / sig[n] ** 2 for n in STATE_NAMES])
    no_wind = [replace(t, wind=None) for t in runs]
    fitted = [fit_steady(ship, t, weights) for t in no_wind]
    variants = {
        'measured': evaluate(ship, runs, RESTART_S, sigma=sig),
        'none': evaluate(ship, no_wind, RESTART_S, sigma=sig),
        'run mean': evaluate(ship, [steady_mean(t) for t in runs], RESTART_S, sigma=sig),
    }
    fit_scores = {}
    for t, (spd, d) in zip(no_wind, fitted):
        p = ship.with_params({'wind_speed': spd, 'wind_dir': d})
        fit_scores[t.name] = evaluate(p, [t], RESTART_S, sigma=sig).trials[t.name].index

    def idx(v, names):
        if v == 'fitted':
            vals = [fit_scores[n] for n in names]
        else:
            vals = [variants[v].trials[n].index for n in names]
        w = [len(next(t for t in runs if t.name == n)) for n in names]
        return float(np.average(vals, weights=w))
    print('| kind | no wind | measured wind | explains | run-mean wind, steady | explains | '
          'best steady per run (fitted) | explains |')
    print('|---|---|---|---|---|---|---|---|')
    for kind in eb.KINDS + ('all',):
        names = [t.name for t in runs if kind in ('all', kind_of[t.name])]
        i0 = idx('none', names)
        row = [f'{i0:.3f}']
        for v in ('measured', 'run mean', 'fitted'):
            i = idx(v, names)
            row += [f'{i:.3f}', f'{100 * (1 - i / i0):.0f} %']
        print(f'| {kind} | ' + ' | '.join(row) + ' |')
        figures['index'].append(dict(zip(
            ('kind', 'no wind', 'measured wind', 'measured explains', 'run-mean wind, steady',
             'run-mean explains', 'best steady per run (fitted)', 'fitted explains'),
            [kind] + row)))
    rms = {v: {k: np.sqrt(np.mean([variants[v].trials[t.name].rms[k] ** 2 for t in runs]))
               for k in ('u', 'v', 'r', 'psi')} for v in ('none', 'measured')}
    print('RMS error over all runs (no wind -> measured wind): '
          + ', '.join(f'{k} {rms["none"][k]:.3g} -> {rms["measured"][k]:.3g}'
                      for k in ('u', 'v', 'r', 'psi'))
          + ' (m/s, rad/s, rad)')
    agree = []
    for t, (spd, d) in zip(runs, fitted):
        m = t.wind.mean(axis=0)
        m_spd, m_dir = float(np.hypot(*m)), math.atan2(-m[1], -m[0])
        dd = math.degrees((d - m_dir + math.pi) % (2 * math.pi) - math.pi)
        agree.append((spd, m_spd, dd))
    a = np.array(agree)
    print(f'fitted steady wind vs the run-mean measured wind (median over runs): speed '
          f'{np.median(a[:, 0]):.2f} vs {np.median(a[:, 1]):.2f} m/s, direction off by '
          f'{np.median(np.abs(a[:, 2])):.0f} deg (|difference| < 45 deg on '
          f'{int(np.sum(np.abs(a[:, 2]) < 45))} of {len(a)} runs); part 2 took '
          f'{time.perf_counter() - t0:.0f} s')

    if not args.no_diagnose:
        seg_tr = [s.trial.resampled(args.dt) for s in split_trials(train, args.segment)]
        seg_te = [s.trial.resampled(args.dt) for s in split_trials(test, args.segment)]
        print(f'\n3. The diagnosis on {len(seg_tr)} tuning / {len(seg_te)} held-out pieces of '
              f'{args.segment:g} s at dt {args.dt:g} s, budget {args.budget}, setting pond')
        for label, tr_, te_, measured in (
                ('(a) wind columns removed', [replace(t, wind=None) for t in seg_tr],
                 [replace(t, wind=None) for t in seg_te], False),
                ('(b) measured wind present', seg_tr, seg_te, True)):
            t0 = time.perf_counter()
            dx = mt.diagnose(ship, tr_, te_, budget=args.budget, setting='pond,reference',
                             measured_signals=measured)
            print(f'{label}: {time.perf_counter() - t0:.0f} s; base model J_test '
                  f'{dx.baseline.J_test:.4g}, final {dx.final.J_test:.4g}')
            if not dx.causes:
                print('   named: nothing')
            for c in dx.causes:
                print(f'   named: {c.summary}; held-out gain {100 * c.heldout_gain:.0f} % '
                      f'+- {100 * c.heldout_gain_se:.0f} %')
            for m in dx.measured:
                print(f"   measured signal {m['signal']} (round {m['round']}): held-out J "
                      f"without {m['J_test_without']:.4g}, with {m['J_test_with']:.4g}: gain "
                      f"{100 * m['heldout_gain']:.0f} % +- {100 * m['heldout_gain_se']:.0f} %, "
                      f"named {m['named']} {m['note']}")
            for r, cands in enumerate(dx.candidates, 1):
                for c in cands:
                    if c.effect == 'wind':
                        vals = ', '.join(f'{k} {v:.3g}' for k, v in c.values.items())
                        print(f'   steady wind candidate, round {r}: {vals}; held-out gain '
                              f'{100 * c.gain:.0f} % +- {100 * c.gain_se:.0f} %, accepted '
                              f'{c.accepted}'
                              + (f', on bound {c.on_bound}' if c.on_bound else '')
                              + (f', impossible: {c.impossible}' if c.impossible else ''))
    figures['wall_s'] = time.perf_counter() - t_all
    print(f"\nwall time: {figures['wall_s']:.0f} s")
    return figures


if __name__ == '__main__':
    main()
