"""Tuning the low-speed model on the real Esso Osaka pond data, scored on held-out runs.

  python bench/esso_osaka.py [--max-evals 4000] [--integrator rk4] [--dt 0.1] [--seed 0]

Data: the 33 FRT-DS-ESSO runs in data/esso_osaka_frt (CC BY-NC-SA 4.0), read whole with
astern propeller and u <= 0 kept (the lowspeed family covers them), measured true wind driving
the model sample by sample.

Cuts (every run starts with a manually steered approach): turning and zigzag runs from 5 s
before the rudder is first put over (``cut_from_event(..., 'rudder_first_over', 5)``); random
and berthing runs are kept whole (their manoeuvre is the whole run; the rudder event is not
defined for them).

Split, a fixed rule: within each kind the runs are sorted by file name; the second and then
every third (positions 1, 4, 7, ... counting from 0) are held out, the rest tune. A
``turn_cut_X`` file is a trimmed copy of ``turn_X``: it is dropped when ``turn_X`` is present
(it would put the same data on both sides of the split).

Tuning: the ship's 12 targets and absolute boxes (config/esso_osaka_3m.yaml ``tuning:``),
CMA-ES from the published values; the objective is the evaluation index itself on the training
runs: squared errors of x, y, psi, u, v, r each divided by its standard deviation pooled over
the training runs, restarting from the measured state every 100 s (Wakita et al. 2022's
protocol), at the recorded 10 Hz (``--dt`` resamples, e.g. 1.0 to subsample to 1 Hz).

Evaluation: ``mmg_tuner.evaluate`` on the held-out runs together (sigma pooled over them),
RK4 at 10 Hz, restart every 100 s, for the published and the tuned parameters.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import mmg_tuner as mt  # noqa: E402
from mmg_tuner.core.layout import STATE_NAMES  # noqa: E402
from mmg_tuner.data.esso import cut_from_event, esso_data_dir, read_esso_csv  # noqa: E402
from mmg_tuner.tuning.evaluate import pooled_sigma  # noqa: E402
from mmg_tuner.tuning.objective import Objective, TrialBatch  # noqa: E402
from mmg_tuner.tuning.parameters import ParameterSpace  # noqa: E402
from mmg_tuner.tuning.tuner import Tuner  # noqa: E402

KINDS = ('turning', 'zigzag', 'random', 'berthing')
RESTART_S = 100.0


def runs_by_kind() -> dict[str, list[Path]]:
    out = {}
    for kind in KINDS:
        files = sorted((esso_data_dir() / kind).glob('*.csv'))
        names = {f.name for f in files}
        out[kind] = [f for f in files
                     if not (f.name.startswith('turn_cut_')
                             and f.name.replace('turn_cut_', 'turn_') in names)]
    return out


def split(files: list[Path]) -> tuple[list[Path], list[Path]]:
    held = [f for i, f in enumerate(files) if i % 3 == 1]
    return [f for f in files if f not in held], held


def read(path: Path, kind: str):
    tr = read_esso_csv(path, keep_astern=True)[0]
    if kind in ('turning', 'zigzag'):
        tr = cut_from_event(tr, 'rudder_first_over', before_s=5.0)
    return tr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--max-evals', type=int, default=4000)
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='rk4')
    ap.add_argument('--dt', type=float, default=None, help='resample the tuning runs [s]')
    ap.add_argument('--seed', type=int, default=0)
    args = ap.parse_args()
    t_all = time.perf_counter()
    ship = mt.load_ship('esso_osaka_3m')
    train, test, kind_of = [], [], {}
    for kind, files in runs_by_kind().items():
        a, b = split(files)
        for f in a + b:
            tr = read(f, kind)
            kind_of[tr.name] = kind
            (train if f in a else test).append(tr)
    print(f'training runs: {len(train)} ({sum(t.duration_s for t in train):.0f} s), held out: '
          f'{len(test)} ({sum(t.duration_s for t in test):.0f} s)')
    for kind in KINDS:
        print(f'  {kind:9s} held out: '
              + ', '.join(t.name for t in test if kind_of[t.name] == kind))

    tune_runs = train if args.dt is None else [t.resampled(args.dt) for t in train]
    sig = pooled_sigma(train)
    weights = np.array([1.0 / sig[n] ** 2 for n in STATE_NAMES])
    batch = TrialBatch.from_trials(tune_runs, x0_window_s=0.0)
    substeps = max(1, int(round(batch.dt / 0.1)))
    obj = Objective(ship, batch, weights, RESTART_S, args.integrator, substeps)
    space = ParameterSpace.around(ship)
    n_samples = int(batch.lengths.sum()) - len(tune_runs)
    t0 = time.perf_counter()
    J0 = obj.evaluate(ship.params).total
    t_eval = time.perf_counter() - t0
    print(f'objective: {len(tune_runs)} runs, {n_samples} samples at dt {batch.dt:g} s '
          f'({substeps} {args.integrator} substep(s)), {t_eval * 1e3:.0f} ms per evaluation; '
          f'training index published {J0 / n_samples:.4f}')
    tuner = Tuner(space, obj, popsize=12, max_popsize=48, max_evaluations=args.max_evals,
                  seed=args.seed)
    res = tuner.run()
    tuned = ship.with_params(dict(zip(space.names, map(float, res.theta))))
    print(f'CMA-ES: {res.evaluations} evaluations, {res.restarts} restart(s), '
          f'{res.wall_s:.0f} s; training index {J0 / n_samples:.4f} -> '
          f'{res.J / n_samples:.4f}')
    print('| parameter | published | tuned | box |')
    print('|---|---|---|---|')
    for n, v, lo, hi in zip(space.names, res.theta, space.lower, space.upper):
        flag = ' (on bound)' if n in space.on_bound(res.theta) else ''
        print(f'| {n} | {ship[n]:.4g} | {v:.4g}{flag} | [{lo:g}, {hi:g}] |')

    pub = mt.evaluate(ship, test, restart_every_s=RESTART_S, integrator='rk4')
    tun = mt.evaluate(tuned, test, restart_every_s=RESTART_S, integrator='rk4')
    print(f'\nheld-out runs (index: Wakita et al. 2022 eq. 26, sigma pooled over the {len(test)} '
          f'held-out runs, RK4 0.1 s, restart every {RESTART_S:g} s)')
    print('| kind | run | duration [s] | published | tuned | change |')
    print('|---|---|---|---|---|---|')
    better = {k: [] for k in KINDS}
    for tr in test:
        a, b = pub.trials[tr.name].index, tun.trials[tr.name].index
        kind = kind_of[tr.name]
        ch = 'n/a' if a is None or b is None else f'{100 * (b - a) / a:+.0f} %'
        better[kind].append(a is not None and b is not None and b < a)
        fa = 'failed' if a is None else f'{a:.4f}'
        fb = 'failed' if b is None else f'{b:.4f}'
        print(f'| {kind} | {tr.name} | {tr.duration_s:.0f} | {fa} | {fb} | {ch} |')
    print(f'| all | together | {sum(t.duration_s for t in test):.0f} | {pub.index_all:.4f} | '
          f'{tun.index_all:.4f} | {100 * (tun.index_all - pub.index_all) / pub.index_all:+.0f} % |')
    for kind in KINDS:
        print(f'{kind}: tuned better on {sum(better[kind])} of {len(better[kind])} held-out runs')
    print(f'wall time: {time.perf_counter() - t_all:.0f} s')


if __name__ == '__main__':
    main()
