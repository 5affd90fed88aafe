"""
MBPE-LOGO on the synthetic Qiuxin No.5 twin: LO, GO, LO -> GO; 22 vs 6 coefficients.

  python -m bench run tug_logo [--quick] [--noise rtk|none] [--seed 0] [--cmaes-evals 3000]
                               [--out DIR] [--starts 20] [--convergence-only]

--quick skips the CMA-ES comparison and the perturbed starts (--cmaes-evals 0 --starts 0).

Truth: ``config/qiuxin_tug.yaml`` (the paper's Table 3 coefficients, Pedersen's Coriolis form)
with its labelled stand-ins (thrust 0.4 n|n| N per thruster, azimuth k1 = 4 1/s^2, k2 = 3.6
1/s, 0.8 rad/s drive limit). The twin is simulated at 0.05 s (RK4, 4 substeps) and recorded at
5 Hz (0.2 s) with the commanded and the measured azimuth angles.

Identification set, the paper's Table 2 (12 manoeuvres, ~4400 samples): straight runs at 3, 5,
7, 10 rev/s; +20/+20 azimuth zigzags at the same speeds (closed on heading); turning with
10, 15, 20, 30 deg of azimuth at 10 rev/s. Held out: mirrored zigzags (-20/-20 at 4 and 8
rev/s), turns at -15 and -25 deg (6 rev/s), two random command sequences (shaft speeds and
angles held 4-8 s) and a differential-thrust run (azimuths 0, 10 vs 4 rev/s).

Noise ``rtk`` (ASSUMPTION, the reference's protocol: RTK 1-2 cm and 0.3 deg on heading; the
velocities as a navigation filter gives them): position 1.5 cm, heading 0.3 deg, u and v
0.01 m/s, r 0.2 deg/s, azimuth feedback 0.2 deg, shaft speed 0.05 rev/s, white.

Compared: LO alone (one least-squares problem), GO alone (from the paper's empirical start:
m11 = 1.05 m, m22 = 1.5 m, m33 = 1.3 m (L/4)^2 and every other coefficient 0, and from the
config's values moved by up to +-20 %), LO -> GO; the 6-coefficient model
(``qiuxin_tug_simplified6``) by LO -> GO on the same data; CMA-ES (the package's tuner, the
same 20 s pieces, a prior toward LO) against the Levenberg-Marquardt GO. Scored on the held-out
runs: free-run relative errors ||y_model - y|| / ||y|| of u, v, r (pooled) beside the paper's
Table 5, n-step RMSE (n = 1 ... 50), coefficient errors, wall time (figures taken on a shared
machine under load: compare them with each other, not with another computer).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import time

import mmg_tuner as mt
from mmg_tuner.core.integrate import actuator_outputs
from mmg_tuner.core.simulate import simulate
from mmg_tuner.core.trial import Trial
from mmg_tuner.tuning import lo_go
from mmg_tuner.tuning.nstep import nstep_figure, PAPER_HORIZONS
from mmg_tuner.tuning.plots import png_bytes
import numpy as np

DT = 0.2
SUB = 4
PAPER_T5 = {22: (2.33, 4.45, 5.85), 6: (215.0, 345.0, 446.0)}
"""MBPE-LOGO Table 5, velocity relative errors [%] of u, v, r."""


def _record(truth, ch, T, name, rng, noise):
    """Simulate the truth at DT / SUB, record at DT with the measured angles and noise."""
    run = simulate(truth, [0, 0, 0, 0.2, 0, 0], ch, DT, 'rk4', SUB)
    if not run.ok:
        raise RuntimeError(f'{name}: {run.status}')
    ctrl = run.input_array(truth.family.channels)
    act = np.zeros((T, len(truth.family.outputs)))
    actuator_outputs(truth.kind, truth.params, ctrl, T, DT, act)
    fb = act[:, 2:4]   # the angle acting over each interval (the repository's convention)
    st = run.states.copy()
    inputs = dict(ch, azimuth_port=fb[:, 0], azimuth_stbd=fb[:, 1])
    if noise:
        st[:, :2] += rng.normal(0, 0.015, (T, 2))
        st[:, 2] += rng.normal(0, math.radians(0.3), T)
        st[:, 3:5] += rng.normal(0, 0.01, (T, 2))
        st[:, 5] += rng.normal(0, math.radians(0.2), T)
        for k in ('azimuth_port', 'azimuth_stbd'):
            inputs[k] = inputs[k] + rng.normal(0, math.radians(0.2), T)
        for k in ('n_port', 'n_stbd'):
            inputs[k] = inputs[k] + rng.normal(0, 0.05, T)
    return Trial(run.t, st, inputs=inputs, name=name)


def _zigzag_commands(truth, n, amp_deg, T):
    """Azimuth zigzag closed on heading: command +amp until psi moved amp, then reverse."""
    a = math.radians(amp_deg)
    cmd = np.zeros(T)
    k0 = 15   # 3 s straight first
    sign = 1.0
    # a positive azimuth turns the tug to port (psi falls): switch when |dpsi| passes amp
    seg = k0
    psi0 = None
    while seg < T:
        cmd[seg:] = sign * a
        ch = _channels(n, n, cmd, cmd)
        run = simulate(truth, [0, 0, 0, 0.2, 0, 0], ch, DT, 'rk4', SUB)
        psi = run.states[:, 2]
        psi0 = psi[k0] if psi0 is None else psi0
        d = (psi - psi0) * -sign   # turning "in the command's direction" makes this grow
        past = np.nonzero(d[seg + 1:] >= a)[0]
        if not len(past):
            break
        seg = seg + 1 + int(past[0])
        sign = -sign
    return cmd


def _channels(n_p, n_s, az_p, az_s):
    T = len(az_p)
    return {'n_port': np.broadcast_to(np.asarray(n_p, float), (T,)).copy(),
            'n_stbd': np.broadcast_to(np.asarray(n_s, float), (T,)).copy(),
            'azimuth_port': np.zeros(T), 'azimuth_stbd': np.zeros(T),
            'azimuth_cmd_port': np.asarray(az_p, float),
            'azimuth_cmd_stbd': np.asarray(az_s, float)}


def twin(truth, seed: int, noise: bool) -> tuple[list[Trial], list[Trial]]:
    """Return (the 12 identification manoeuvres, the held-out ones)."""
    rng = np.random.default_rng(seed)
    train, test = [], []
    T = 365   # 73 s each: 12 x 365 = 4380 samples (the paper: 4390)
    for n in (3, 5, 7, 10):
        train.append(_record(truth, _channels(n, n, np.zeros(T), np.zeros(T)), T,
                             f'straight_{n}', rng, noise))
    for n in (3, 5, 7, 10):
        c = _zigzag_commands(truth, n, 20.0, T)
        train.append(_record(truth, _channels(n, n, c, c), T, f'zigzag20_{n}', rng, noise))
    for a in (10, 15, 20, 30):
        c = np.where(np.arange(T) >= 15, math.radians(a), 0.0)
        train.append(_record(truth, _channels(10, 10, c, c), T, f'turn{a}', rng, noise))
    for n in (4, 8):
        c = _zigzag_commands(truth, n, -20.0, T)
        test.append(_record(truth, _channels(n, n, c, c), T, f'zigzag-20_{n}', rng, noise))
    for a in (-15, -25):
        c = np.where(np.arange(T) >= 15, math.radians(a), 0.0)
        test.append(_record(truth, _channels(6, 6, c, c), T, f'turn{a}', rng, noise))
    for s in (1, 2):
        r2 = np.random.default_rng(100 + s)
        k, nn, az = 0, np.zeros(T), np.zeros(T)
        while k < T:
            d = int(r2.integers(20, 41))
            nn[k:k + d] = r2.uniform(3, 10)
            az[k:k + d] = math.radians(r2.uniform(-30, 30))
            k += d
        test.append(_record(truth, _channels(nn, nn, az, az), T, f'random{s}', rng, noise))
    test.append(_record(truth, _channels(10.0, 4.0, np.zeros(T), np.zeros(T)), T,
                        'differential', rng, noise))
    return train, test


def generated_twin(noise: bool, seed: int, folder: Path) -> tuple[list, list, Path]:
    """Return (identification, validation trials, bollard table) of ``generate``'s twin."""
    import yaml

    from mmg_tuner.cli.generate import command as generate
    out = folder / ('tug' if noise else 'tug_clean')
    if not (out / 'trials.yaml').is_file():
        args = ['--ship', 'qiuxin_tug', '--out', str(out), '--seed', str(seed)]
        if generate(args + ([] if noise else ['--no-noise'])) != 0:
            raise RuntimeError('generate failed')
    doc = yaml.safe_load((out / 'trials.yaml').read_text())
    ship = mt.load_ship('qiuxin_tug')

    def load(names):
        return mt.load_trials([str(out / 'csv' / f'{n}.csv') for n in names], ship=ship)
    return load(doc['identification']), load(doc['validation']), out / doc['bollard_pull']


def score(ship, test) -> dict:
    ev = mt.evaluate(ship, test, restart_every_s=0, horizons=PAPER_HORIZONS)
    return {'rel': ev.relative.pooled, 'nstep': ev.nstep, 'failed': ev.relative.failed}


def pct(rel) -> str:
    return ' / '.join('fail' if rel[k] is None else f'{100 * rel[k]:.3g}' for k in 'uvr')


def perturbed(truth, names, rng, spread: float = 0.5) -> dict[str, float]:
    """
    Return the coefficients, each times a factor log-uniform in [1 - spread, 1 + spread].

    Signs are kept; m23, whose published value (1.1 kg m) is small beside its box, is drawn
    like the rest.
    """
    lo, hi = math.log(1 - spread), math.log(1 + spread)
    return {n: truth[n] * math.exp(rng.uniform(lo, hi)) for n in names}


def convergence(truth, train, test, bollard, starts: int = 20, seed: int = 0) -> dict:
    """
    LO -> GO and GO alone from ``starts`` perturbed starts (seeds fixed): the spread.

    Each start moves every coefficient by a factor log-uniform in [0.5, 1.5]
    (:func:`perturbed`, generator seeded with ``seed + 1000 + k`` for start k). Returns, per
    method, the held-out free-run relative errors of u, v, r [%] and the median and largest
    coefficient error [%] of every start (None where the run failed or its model diverged on
    a held-out run), with their summary (median, min, max over the starts).
    """
    names = lo_go.coefficient_names(truth)
    true = np.array([truth[n] for n in names])
    out: dict = {'starts': starts, 'seed': seed, 'methods': {}}
    for label, cfg in (('LO -> GO', mt.IdentifyConfig(bollard_pull=bollard)),
                       ('GO alone', mt.IdentifyConfig(method='go', bollard_pull=bollard,
                                                      ridge=0.0))):
        runs = []
        for k in range(starts):
            start = truth.with_params(perturbed(truth, names, np.random.default_rng(
                seed + 1000 + k)))
            t = time.perf_counter()
            try:
                res = mt.identify(start, train, config=cfg)
            except mt.errors.MmgTunerError as exc:
                runs.append({'start': k, 'failed': str(exc)})
                continue
            sc = score(res.identified_ship, test, (1,))   # the free runs are what counts
            th = np.array([res.params[n] for n in names])
            err = np.abs(th / true - 1) * 100
            rel = sc['rel']
            runs.append({'start': k, 'wall_s': time.perf_counter() - t,
                         'rel_pct': {q: None if rel[q] is None else 100 * rel[q]
                                     for q in 'uvr'},
                         'coef_median_pct': float(np.median(err)),
                         'coef_max_pct': float(np.max(err))})
            r = runs[-1]
            print(f"  {label} start {k}: u / v / r {pct(sc['rel'])} %, median coef err "
                  f"{r['coef_median_pct']:.3g} %, {r['wall_s']:.1f} s", flush=True)
        summary = {}
        for key in ('u', 'v', 'r', 'coef_median_pct', 'coef_max_pct'):
            vals = [r['rel_pct'][key] if key in 'uvr' else r[key] for r in runs
                    if 'failed' not in r and (key not in 'uvr' or r['rel_pct'][key] is not None)]
            summary[key] = ({'median': float(np.median(vals)), 'min': float(np.min(vals)),
                             'max': float(np.max(vals))} if vals else None)
        summary['failed'] = sum('failed' in r or None in r['rel_pct'].values() for r in runs)
        out['methods'][label] = {'runs': runs, 'summary': summary}
    return out


def print_convergence(conv: dict) -> None:
    """Print :func:`convergence`'s spread: median [min, max] over the starts."""
    print(f"\nconvergence from {conv['starts']} starts, every coefficient x log-uniform "
          f"[0.5, 1.5] (seeds {conv['seed'] + 1000} ...): median [min, max] over the starts")
    print(f'{"method":<12} {"u %":>22} {"v %":>22} {"r %":>22} {"median coef err %":>24} '
          f'{"largest coef err %":>24} {"failed":>6}')

    def cell(s):
        return '-' if s is None else f"{s['median']:.3g} [{s['min']:.3g}, {s['max']:.3g}]"
    for label, m in conv['methods'].items():
        s = m['summary']
        print(f'{label:<12} ' + ' '.join(f'{cell(s[k]):>22}' for k in 'uvr')
              + f' {cell(s["coef_median_pct"]):>24} {cell(s["coef_max_pct"]):>24} '
              f'{s["failed"]:>6}')


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run tug_logo`` (``--quick``: no CMA-ES, no starts)."""
    return main((['--cmaes-evals', '0', '--starts', '0'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--noise', choices=('rtk', 'none'), default='rtk')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--cmaes-evals', type=int, default=3000, help='0: skip CMA-ES')
    ap.add_argument('--out', help='folder for the n-step figure')
    ap.add_argument('--twin', choices=('generate', 'builtin'), default='generate',
                    help="'generate': the repository's twin (generate --ship qiuxin_tug); "
                    "'builtin': this file's smaller catalogue")
    ap.add_argument('--data', default='bench/out/tug_logo', help='where generate writes')
    ap.add_argument('--starts', type=int, default=20,
                    help='convergence: LO -> GO and GO alone from this many perturbed starts '
                    '(0: skip)')
    ap.add_argument('--convergence-only', action='store_true',
                    help='run only the convergence from perturbed starts')
    a = ap.parse_args(argv)
    truth = mt.load_ship('qiuxin_tug')
    names = lo_go.coefficient_names(truth)
    theta_true = np.array([truth[n] for n in names])
    t0 = time.perf_counter()
    if a.twin == 'generate':
        train, test, table = generated_twin(a.noise == 'rtk', a.seed, Path(a.data))
        bollard = lo_go.read_bollard_table(table)
    else:
        train, test = twin(truth, a.seed, a.noise == 'rtk')
        nb = np.arange(0.0, 12.5, 1.0)
        noise_1pc = 1 + 0.01 * np.random.default_rng(a.seed).normal(size=nb.size)
        bollard = lo_go.check_bollard_table(nb, 0.4 * nb * nb * noise_1pc, 'bollard, 1 % noise')
    print(f'twin ({a.twin}): {len(train)} identification manoeuvres ({sum(len(t) for t in train)} '
          f'samples), {len(test)} held out; noise {a.noise}; ready in '
          f'{time.perf_counter() - t0:.1f} s')
    if a.convergence_only:
        mt.identify(truth, train[:1], method='lo-go', max_iter=1)   # compile first
        score(truth, test[:1])
        conv = convergence(truth, train, test, bollard, a.starts, a.seed)
        print_convergence(conv)
        return {'noise': a.noise, 'twin': a.twin, 'convergence': conv}
    rows, scores = [], {}
    s6 = mt.load_ship('qiuxin_tug_simplified6')
    for ship in (truth, s6):   # compile every kernel first: wall times without compilation
        mt.identify(ship, train[:1], method='lo-go', max_iter=1)
        score(ship, test[:1])

    def run(label, ship, cfg):
        t = time.perf_counter()
        res = mt.identify(ship, train, config=cfg)
        wall = time.perf_counter() - t
        sc = score(res.identified_ship, test)
        nm = res.lo.names if res.lo else res.go.names
        th = np.array([res.params[n] for n in nm])
        coef = (np.median(np.abs(th / theta_true - 1)) * 100 if len(nm) == 22 else None)
        rows.append((label, len(nm), wall, pct(sc['rel']), coef, res))
        scores[label] = sc['nstep']
        return res

    base = mt.IdentifyConfig(bollard_pull=bollard)
    run('LO', truth, mt.IdentifyConfig(method='lo', bollard_pull=bollard))
    empirical = {'m11': 1.05 * truth['m'], 'm22': 1.5 * truth['m'],
                 'm33': 1.3 * truth['m'] * (truth['L_pp'] / 4) ** 2,
                 **{n: 0.0 for n in names if not n.startswith('m')}, 'm23': 0.0, 'm32': 0.0}
    run('GO (empirical start)', truth.with_params(empirical),
        mt.IdentifyConfig(method='go', bollard_pull=bollard, ridge=0.0))
    rng = np.random.default_rng(a.seed + 7)
    moved = {n: truth[n] * (1 + rng.uniform(-0.2, 0.2)) for n in names}
    run('GO (+-20 % start)', truth.with_params(moved),
        mt.IdentifyConfig(method='go', bollard_pull=bollard, ridge=0.0))
    logo = run('LO -> GO', truth, base)
    run('LO -> GO, Algorithm 1', truth, mt.IdentifyConfig(bollard_pull=bollard, grow=True))
    run('LO -> GO, single shooting', truth,
        mt.IdentifyConfig(bollard_pull=bollard, segment_s=0.0))
    run('6 coeff., LO -> GO', s6, base)
    sc6 = score(s6, test)
    rows.append(('6 coeff., Table 4 values', 6, 0.0, pct(sc6['rel']), None, None))
    sc_true = score(truth, test)
    rows.append(('truth (Table 3)', 22, 0.0, pct(sc_true['rel']), 0.0, None))
    print('\nheld-out free-run relative error ||y_model - y|| / ||y|| [%] (u / v / r), pooled '
          'over the held-out runs')
    print(f'{"method":<30} {"coef":>4} {"wall s":>7}  {"u / v / r %":<22} '
          f'{"median coef err %":>8}')
    for label, k, wall, rel, coef, _ in rows:
        c = '-' if coef is None else f'{coef:.3g}'
        print(f'{label:<30} {k:>4} {wall:>7.2f}  {rel:<22} {c:>8}')
    for k, v in PAPER_T5.items():
        print(f'{"paper Table 5, " + str(k) + " coeff.":<30} {k:>4} {"":>7}  '
              f'{" / ".join(f"{x:g}" for x in v):<22}')
    print('\nLO -> GO: identification time of the 12 manoeuvres (thrust, azimuth, LO, GO): '
          f'{logo.wall_s:.1f} s (LO {logo.lo.wall_s:.2f} s, GO {logo.go.wall_s:.1f} s, '
          f'{logo.go.evaluations} simulations of all pieces)')
    if logo.azimuth is not None:
        print(f'azimuth: k1 = {logo.azimuth.k1:.4g} (truth 4), k2 = {logo.azimuth.k2:.4g} '
              f'(truth 3.6); thrust degree {logo.thrust.degree}, p2 = '
              f'{logo.thrust.coefficients[2]:.4g} (truth 0.4)')
    print('\nn-step RMSE on the held-out runs (u [m/s], v [m/s], r [deg/s], psi [deg]):')
    print(f'{"method":<30} ' + ' '.join(f'{"n=" + str(h):>22}' for h in (1, 10, 30, 50)))
    for label, sc in list(scores.items()) + [('truth (Table 3)', sc_true['nstep'])]:
        cells = []
        for h in (1, 10, 30, 50):
            i = sc.horizons.index(h)
            v = [sc.rmse[s][i] for s in ('u', 'v', 'r', 'psi')]
            cells.append('fail' if None in v else 'diverges' if not max(v) < 10 else
                         f'{v[0]:.3f} {v[1]:.3f} {math.degrees(v[2]):.2f} '
                         f'{math.degrees(v[3]):.1f}')
        print(f'{label:<30} ' + ' '.join(f'{c:>22}' for c in cells))
    print('\ncoefficient relative errors [%]:')
    print(f'{"":<10}' + ''.join(f'{lab[:12]:>13}' for lab, *_ in rows[:6]))
    for j, n in enumerate(names):
        line = f'{n:<10}'
        for _, k, _, _, _, res in rows[:6]:
            line += f'{100 * (res.params[n] / theta_true[j] - 1):>13.3g}'
        print(line)
    if a.cmaes_evals:
        lo = rows[0][5]
        start = truth.with_params(lo.params)
        sig = lo_go.pooled_velocity_sigma(train)
        t = time.perf_counter()
        fit = mt.tune(start, train, targets=list(names), integrator='rk4',
                      weights=(0, 0, 0, *(1 / sig ** 2)), segment_s=20.0, prior=1e-6,
                      max_evals=a.cmaes_evals, seed=a.seed, a_r=0.5)
        wall = time.perf_counter() - t
        sc = score(fit.tuned_ship, test)
        print(f'\nCMA-ES from LO (same 20 s pieces, prior 1e-6, {fit.evaluations} evaluations):'
              f' held-out u / v / r {pct(sc["rel"])} %, {wall:.1f} s '
              f'(Levenberg-Marquardt GO: {rows[3][3]} %, {rows[3][2]:.1f} s)')
    conv = None
    if a.starts:
        conv = convergence(truth, train, test, bollard, a.starts, a.seed)
        print_convergence(conv)
    if a.out:
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        shown = ('LO', 'GO (+-20 % start)', 'LO -> GO', '6 coeff., LO -> GO')
        keep = {k: v for k, v in scores.items() if k in shown}
        keep['truth (Table 3)'] = sc_true['nstep']
        (out / 'tug_logo_nstep.png').write_bytes(png_bytes(nstep_figure(
            keep, f'Qiuxin twin, held-out runs, noise {a.noise}: n-step RMSE')))
        print(f'wrote {out / "tug_logo_nstep.png"}')
    return {'noise': a.noise, 'twin': a.twin, 'held_out_relative_error': [
        {'method': label, 'coefficients': k, 'wall_s': wall, 'u / v / r %': rel,
         'median coefficient error %': coef} for label, k, wall, rel, coef, _ in rows],
        **({'convergence': conv} if conv else {})}


if __name__ == '__main__':
    main()
