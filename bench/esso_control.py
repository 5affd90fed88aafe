"""
Which Esso Osaka model to take at which prediction horizon: n-step RMSE on the seven fresh runs.

    python -m bench run esso_control [--quick] [--out DIR]

Registered in bench/esso_control_preregistration.md (committed before any model here was run
on the fresh runs). Issue 24's real-data part: the control-oriented model
(``config/esso_osaka_3m_control.yaml``: M nu_dot + C(nu) nu + D(nu) nu = tau with the
propeller and rudder in tau, ``screw_rudder_tau``) identified by LO and by LO -> GO
(``mt.identify``) on bench/esso_osaka.py's 32 training runs, scored beside the published and
the tuned low-speed MMG and issue 25's network and hybrid (the ensembles bench/esso_fresh.py
trained and saved in bench/out/esso_fresh; its tuned physics bench/out/esso_osaka/
params_all.yaml: not in git, copy them from that run) by the n-step prediction RMSE
(``tuning.nstep.nstep_errors``: restart from the measured state at every sample) of u, v, r,
x, y, psi at 1 ... 200 steps of 0.5 s, on the seven runs of data/esso_osaka_frt_extra.
Prints the table of S(n) (the mean over the six states of RMSE / sigma) with the model to take
at each horizon, the per-state RMSE, the verdicts, and writes OUT/summary.yaml. ``--quick``:
a smoke run (4 training runs, 3 GO iterations, one fresh run), deciding nothing.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import subprocess
import sys
import time

from bench.esso_fresh import fresh_runs
from bench.esso_osaka import params_path
import mmg_tuner as mt
from mmg_tuner._atomic import write_atomic
from mmg_tuner.data.esso import load_split
from mmg_tuner.learn.residual import ResidualNet
from mmg_tuner.tuning.nstep import nstep_errors, NSTEP_STATES
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
OUT = Path(__file__).resolve().parent / 'out' / 'esso_control'
NETS = Path(__file__).resolve().parent / 'out' / 'esso_fresh'
HORIZONS = (1, 5, 10, 20, 50, 100, 200)   # steps of DT
DT = 0.5                                   # s, the networks' grid
PSI_SIGMA = 1.0                            # rad: a turning run's heading wraps (registered)
MAX_FAILED = 0.01                          # a model failing more windows cannot be taken
SHORT, LONG = (1, 5), (50, 100, 200)


def parser() -> argparse.ArgumentParser:
    """Return the command line (``run``'s argv)."""
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--quick', action='store_true', help='smoke run, deciding nothing')
    ap.add_argument('--out', type=Path, default=OUT)
    ap.add_argument('--nets', type=Path, default=NETS,
                    help='folder of network_ensemble.npz and hybrid_ensemble.npz')
    ap.add_argument('--tuned', type=Path, default=params_path(None))
    return ap


def sigmas(trials) -> dict[str, float]:
    """Return the standard deviation of each scored state over all samples (psi: PSI_SIGMA)."""
    st = np.concatenate([t.states for t in trials])
    names = ('x', 'y', 'psi', 'u', 'v', 'r')
    return {s: (PSI_SIGMA if s == 'psi' else float(np.std(st[:, names.index(s)])))
            for s in NSTEP_STATES}


def normalised(score, sig: dict[str, float]) -> list[float]:
    """S(n) per horizon: the mean over the states of RMSE / sigma (inf: none scored)."""
    out = []
    for i in range(len(score.horizons)):
        vals = [score.rmse[s][i] for s in NSTEP_STATES]
        out.append(float('inf') if any(v is None for v in vals)
                   else float(np.mean([v / sig[s] for v, s in zip(vals, NSTEP_STATES)])))
    return out


def takeable(score, i: int) -> bool:
    """At most MAX_FAILED of the windows reaching horizon i failed."""
    n = score.windows[i] + score.failed[i]
    return n > 0 and score.failed[i] <= MAX_FAILED * n


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Identify, load, score as registered; print the tables and verdicts; return the summary."""
    args = parser().parse_args(argv or [])
    quick = quick or args.quick
    t_all = time.perf_counter()
    commit = subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    print(f'commit {commit}{" (quick: deciding nothing)" if quick else ""}')
    control = mt.load_ship('esso_osaka_3m_control')
    train, _, kind_of = load_split(None)
    if quick:
        seen: set = set()
        train = [t for t in train if not (kind_of[t.name] in seen or seen.add(kind_of[t.name]))]
    print(f'training runs: {len(train)} ({sum(t.duration_s for t in train):.0f} s at '
          f'{train[0].dt:.1f} s)')
    ident = {}
    for method in ('lo', 'lo-go'):
        t0 = time.perf_counter()
        ident[method] = mt.identify(control, train, method=method,
                                    **({'max_iter': 3} if quick else {}))
        print(f'control {method}: {time.perf_counter() - t0:.1f} s wall (under load)')
    res = ident['lo-go']
    print(f'  LO: {res.lo.samples} intervals, condition {res.lo.condition:.3g}, equation error '
          'RMS ' + ', '.join(f'{x:.3g}' for x in res.lo.residual_rms) + ' [N, N, N m], '
          f'{res.lo.wall_s:.1f} s; GO: cost {res.go.cost_start:.4g} -> {res.go.cost:.4g}, '
          f'{res.go.evaluations} simulations, {res.go.wall_s:.1f} s ({res.go.message})')
    published = mt.load_ship('esso_osaka_3m')
    # the file bench/esso_fresh.py used, as registered; not through esso_hybrid's
    # provenance check, whose fingerprint covers the package's parameter layout (a new
    # family adds slots) besides the config and the runs
    tuned = mt.load_ship('esso_osaka_3m', args.tuned)
    models = {
        'published': published,
        'tuned': tuned,
        'network': mt.Model(published, ResidualNet.load(args.nets / 'network_ensemble.npz')),
        'hybrid': mt.Model(tuned, ResidualNet.load(args.nets / 'hybrid_ensemble.npz')),
        'control LO': ident['lo'].identified_ship,
        'control LO->GO': res.identified_ship,
    }
    test, test_kind = fresh_runs()
    if quick:
        test = test[:1]
    test_g = [t.resampled(DT) for t in test]
    print(f'test runs: {len(test_g)} ({sum(t.duration_s for t in test_g):.0f} s at {DT} s)')
    sig = sigmas(test_g)
    scores, S, wall = {}, {}, {}
    for name, m in models.items():
        t0 = time.perf_counter()
        scores[name], _ = nstep_errors(m, test_g, HORIZONS, 'rk4')
        wall[name] = time.perf_counter() - t0
        S[name] = normalised(scores[name], sig)
    cols = list(models)
    print(f'\nS(n) = mean over u, v, r, x, y, psi of RMSE / sigma (sigma over the {len(test_g)} '
          'runs: ' + ', '.join(f'{s} {sig[s]:.3g}' for s in NSTEP_STATES) + '); RK4, '
          f'{DT} s steps; * = more than {100 * MAX_FAILED:g} % of the windows failed')
    print('| horizon | ' + ' | '.join(cols) + ' | take |')
    print('|---|' + '---|' * (len(cols) + 1))
    take = {}
    for i, h in enumerate(HORIZONS):
        ok = [c for c in cols if takeable(scores[c], i) and np.isfinite(S[c][i])]
        take[h] = min(ok, key=lambda c: S[c][i]) if ok else None
        print(f'| {h} ({h * DT:g} s) | ' + ' | '.join(
            f'{S[c][i]:.3f}' + ('' if takeable(scores[c], i) else '*') for c in cols)
            + f' | {take[h]} |')
    for s in NSTEP_STATES:
        unit = {'psi': 'deg', 'r': 'deg/s'}.get(s, 'm' if s in ('x', 'y') else 'm/s')
        f = 180.0 / np.pi if s in ('psi', 'r') else 1.0
        print(f'\nRMSE of {s} [{unit}]')
        print('| horizon | ' + ' | '.join(cols) + ' | best |')
        print('|---|' + '---|' * (len(cols) + 1))
        for i, h in enumerate(HORIZONS):
            v = {c: scores[c].rmse[s][i] for c in cols}
            best = min((c for c in cols if v[c] is not None), key=lambda c: v[c], default=None)
            cells = ['failed' if v[c] is None else f'{v[c] * f:.4g}' for c in cols]
            print(f'| {h} | ' + ' | '.join(cells) + f' | {best} |')
    idx = {h: i for i, h in enumerate(HORIZONS)}
    best = {h: min(S[c][idx[h]] for c in cols) for h in HORIZONS}
    lg = 'control LO->GO'
    verdict = {
        'H1': all(S[lg][idx[h]] <= 1.10 * best[h] for h in SHORT),
        'H2': all(take[h] in ('network', 'hybrid') and S[lg][idx[h]] > S['tuned'][idx[h]]
                  for h in LONG),
        'H3': all(S[lg][i] < S['control LO'][i] for i, h in enumerate(HORIZONS) if h >= 5),
        'H4': all(S[c][i] < S['published'][i] for c in ('tuned', 'network', 'hybrid', lg)
                  for i, h in enumerate(HORIZONS) if h >= 10),
        'H5': sum(scores[lg].failed) == 0,
    }
    print('\nverdicts (bench/esso_control_preregistration.md):')
    for h, v in verdict.items():
        print(f'  {h}: {"PASS" if v else "FAIL"}')
    print('scoring wall time per model (s, under load): '
          + ', '.join(f'{c} {wall[c]:.0f}' for c in cols))
    summary = {
        'commit': commit, 'quick': quick, 'horizons': list(HORIZONS), 'dt': DT,
        'sigma': sig, 'S': S, 'take': {int(h): t for h, t in take.items()},
        'nstep': {c: scores[c].to_dict() for c in cols}, 'verdict': verdict,
        'identified': {m: {k: float(v) for k, v in r.params.items()}
                       for m, r in ident.items()},
        'go': {'cost_start': float(res.go.cost_start), 'cost': float(res.go.cost),
               'evaluations': int(res.go.evaluations), 'wall_s': float(res.go.wall_s)},
        'lo_wall_s': float(res.lo.wall_s), 'scoring_wall_s': wall,
        'test_runs': {t.name: test_kind[t.name] for t in test}}
    args.out.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out / 'summary.yaml', yaml.safe_dump(summary, sort_keys=False))
    print(f'wall time: {time.perf_counter() - t_all:.0f} s (under load)')
    return summary


if __name__ == '__main__':
    benchmark(False, sys.argv[1:])
