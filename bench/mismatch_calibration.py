"""
How large is a real ship's mismatch? The benchmark's 'realistic' level calibrated on real data.

What a tuned model leaves on held-out trials, as one dimensionless figure (registered in
``bench/mismatch_calibration_preregistration.md`` before it was computed): the relative n-step
prediction error at the horizon over which the ship sails two ship lengths,

    eps = sqrt(eps_psi * eps_p),
    eps_psi = RMSE of the heading predicted H samples ahead / RMS measured heading change in H,
    eps_p = RMSE of the position predicted H samples ahead / RMS measured displacement in H,

H = round(2 L_pp / (U dt)), U the held-out trials' mean speed over ground; every sample starts
a window from the measured state (the package's ``nstep_errors``). Free of scale and speed:
the error as a fraction of how much the ship turns and moves over two ship lengths.

Real data: the final model of the diagnosis (its documented commands' settings) on MARIN's
KVLCC2 free-running tests and on the Esso Osaka pond runs. Benchmark: the clean class of
``bench_diagnosis_mismatch`` at blend factors alpha (development seeds), the diagnosis run as
the benchmark runs it. alpha_cal: where the median benchmark eps reaches the real data's
(geometric mean of the two datasets), by piecewise-linear interpolation.

    python -m bench run mismatch_calibration [--seeds 0 1 2 3] [--alphas 0 0.35 1 2]
        [--skip-real]
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import statistics

from bench import bench_diagnosis_mismatch as bm
import mmg_tuner as mt
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.marin import marin_data_dir, MARIN_FILES
from mmg_tuner.tuning.nstep import nstep_errors
import numpy as np

REPO = Path(__file__).resolve().parent.parent
SHIP_LENGTHS = 2.0   # the horizon: the distance sailed, in ship lengths


def relative_nstep(model, trials, L_pp: float) -> dict:
    """Return eps_psi, eps_p, eps and the horizon H [samples] of a model on held-out trials."""
    dt = trials[0].dt
    ix = [STATE_NAMES.index(s) for s in ('x', 'y', 'psi', 'u', 'v')]
    speed = np.concatenate([np.hypot(t.states[:, ix[3]], t.states[:, ix[4]]) for t in trials])
    U = float(np.nanmean(speed))
    H = max(1, int(round(SHIP_LENGTHS * L_pp / (U * dt))))
    score, _ = nstep_errors(model, trials, [H])
    dpsi, dp = [], []
    for t in trials:
        s = t.states
        if len(s) <= H:
            continue
        d = s[H:, ix[2]] - s[:-H, ix[2]]
        dpsi.append((d + math.pi) % (2 * math.pi) - math.pi)
        dp.append(np.hypot(s[H:, ix[0]] - s[:-H, ix[0]], s[H:, ix[1]] - s[:-H, ix[1]]))
    rms_psi = float(np.sqrt(np.mean(np.concatenate(dpsi) ** 2)))
    rms_p = float(np.sqrt(np.mean(np.concatenate(dp) ** 2)))
    e_psi = score.rmse['psi'][0] / rms_psi
    e_p = math.hypot(score.rmse['x'][0], score.rmse['y'][0]) / rms_p
    return {'eps': math.sqrt(e_psi * e_p), 'eps_psi': e_psi, 'eps_p': e_p, 'H': H,
            'H_s': H * dt, 'U_ms': U, 'windows': score.windows[0], 'failed': score.failed[0]}


def final_model(dx) -> tuple[object, list]:
    """Return the diagnosis's final model and the held-out trials as it sees them."""
    return dx.ship.with_params(dx.params), list(dx.test_final or dx.test)


def marin() -> dict:
    """KVLCC2 on MARIN's tests: bench/diagnose_kvlcc2_marin.py run A's split and settings."""
    ship = load_ship('kvlcc2')
    d = marin_data_dir()
    tune = [d / MARIN_FILES[k] for k in MARIN_FILES if k.startswith('turn') or '10' in k]
    test = [d / MARIN_FILES[k] for k in MARIN_FILES if k.startswith('zigzag') and '20' in k]

    def load(paths):
        return mt.load_trials(paths, ship=ship, dt=0.1, trial_scale='full')

    dx = mt.diagnose(ship, load(tune), load(test), budget='quick', setting='tank,reference')
    model, held = final_model(dx)
    return {'named': [c.effect for c in dx.causes], **relative_nstep(model, held, ship.L_pp)}


def esso() -> dict:
    """Esso Osaka 3 m: the documented ``diagnose data/esso_osaka_frt ... --dt 1``."""
    ship = load_ship('esso_osaka_3m')
    trials = mt.load_trials([REPO / 'data' / 'esso_osaka_frt'], ship=ship, dt=1.0)
    dx = mt.diagnose(ship, trials, budget='quick', max_effects=2)
    model, held = final_model(dx)
    return {'named': [c.effect for c in dx.causes], **relative_nstep(model, held, ship.L_pp)}


def bench_case(alpha: float, seed: int) -> dict:
    """One clean case of bench_diagnosis_mismatch at blend factor alpha."""
    ship = load_ship('suzaku')
    truth, _ = bm.make_case(ship, 'none', 'clean', seed, blend=alpha)
    trials = bm.sail_trials(truth, seed)
    bm.VERDICT[0] = 'rules'
    dx, _ = bm.diagnose(ship, trials[::2], trials[1::2], seed)
    model, held = final_model(dx)
    return {'alpha': alpha, 'seed': seed, 'named': [c.effect for c in dx.causes],
            **relative_nstep(model, held, ship.L_pp)}


def interpolate(alphas: list[float], eps: list[float], target: float) -> tuple[float, str]:
    """Return (alpha where the piecewise-linear eps(alpha) reaches target, a note)."""
    if target <= eps[0]:
        return alphas[0], 'below the smallest alpha'
    for a0, a1, e0, e1 in zip(alphas, alphas[1:], eps, eps[1:]):
        if e0 <= target <= e1 and e1 > e0:
            return a0 + (a1 - a0) * (target - e0) / (e1 - e0), ''
    return alphas[-1], 'at least (above the largest alpha)'


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run mismatch_calibration`` (``--quick``: 2 seeds)."""
    return main((['--seeds', '0', '1'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2, 3])
    ap.add_argument('--alphas', type=float, nargs='+', default=[0.0, 0.35, 1.0, 2.0])
    ap.add_argument('--skip-real', action='store_true',
                    help='the benchmark side only (eps_real is then not computed)')
    args = ap.parse_args(argv)
    out: dict = {'definition': 'eps = sqrt(eps_psi eps_p) at the horizon of '
                 f'{SHIP_LENGTHS:g} ship lengths (module docstring)'}
    if not args.skip_real:
        out['real'] = {'kvlcc2_marin': marin(), 'esso_osaka': esso()}
        for k, v in out['real'].items():
            print(f"{k}: eps {v['eps']:.4f} (psi {v['eps_psi']:.4f}, position "
                  f"{v['eps_p']:.4f}; H {v['H']} samples = {v['H_s']:.1f} s at "
                  f"{v['U_ms']:.2f} m/s; named {v['named']})", flush=True)
        out['eps_real'] = math.sqrt(out['real']['kvlcc2_marin']['eps']
                                    * out['real']['esso_osaka']['eps'])
        print(f"eps_real (geometric mean): {out['eps_real']:.4f}", flush=True)
    cases = []
    for a in sorted(args.alphas):
        for s in args.seeds:
            c = bench_case(a, s)
            cases.append(c)
            print(f"alpha {a:g} seed {s}: eps {c['eps']:.4f} (psi {c['eps_psi']:.4f}, "
                  f"position {c['eps_p']:.4f}; H {c['H']}; named {c['named']})", flush=True)
    alphas = sorted(args.alphas)
    med = [statistics.median(c['eps'] for c in cases if c['alpha'] == a) for a in alphas]
    out['bench'] = {'cases': cases, 'median_eps': dict(zip(map(str, alphas), med))}
    print('median eps by alpha: ' + ', '.join(f'{a:g}: {m:.4f}' for a, m in zip(alphas, med)))
    if 'eps_real' in out:
        a_cal, note = interpolate(alphas, med, out['eps_real'])
        out['alpha_cal'] = round(a_cal, 2)
        out['alpha_cal_note'] = note
        print(f"alpha_cal = {out['alpha_cal']:.2f} {note}")
    return out


if __name__ == '__main__':
    main()
