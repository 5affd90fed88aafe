"""
Issue 25's registered test: the models trained on the Esso Osaka runs, scored on seven new ones.

    python -m bench run esso_osaka --fold none       # the tuned physics on all runs, first
    python -m bench run esso_fresh --seeds 0 1 2 [bench/esso_hybrid.py's options]

--quick trains 5 epochs per network (a check that it runs; its verdicts mean nothing).

Registered in bench/esso_fresh_preregistration.md (committed before the seven runs were read);
the blend's hypotheses B1-B3 in bench/esso_blend_preregistration.md.
Training: bench/esso_osaka.py's runs, reads and cuts, nothing held out (the 33 files, the
``turn_cut_`` copy of a run that is there whole dropped: 32 runs). Test: the seven runs of
data/esso_osaka_frt_extra (turning 2, zigzag 5; CC BY-NC-SA 4.0), read and cut alike.

Models: published (config/esso_osaka_3m.yaml); tuned (bench/esso_osaka.py --fold none, its
provenance checked); network and hybrid (bench/esso_hybrid.py's training with its defaults,
one per seed); ensemble (the exact mean of the hybrid seeds' residuals); blend (every hybrid
and network seed averaged, bench/esso_blend_preregistration.md); auto (the package's
rule, ``tuning.choice.choose_model``, among the tuned physics, the network ensemble and the
hybrid ensemble and the blend on the validation part of the training runs: the last 25 % of each,
``learn.train.split_validation``). Scoring: the paper's eq. 26 index through ``mt.evaluate``,
RK4 on the 0.5 s grid, restart every 100 s, sigma pooled over the seven runs. Uncertainty:
the hybrid ensemble's interval (``tuning.interval``), calibrated to 90 % on the validation
parts, its coverage on the seven. Prints the per-kind table and each hypothesis' verdict,
writes bench/out/esso_fresh/summary.yaml.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import subprocess
import time

from bench import plain
from bench.esso_hybrid import (
    held_out_scores, parser as hybrid_parser, train_network, tuned_ship)
from bench.esso_osaka import params_path
import mmg_tuner as mt
from mmg_tuner._atomic import write_atomic
from mmg_tuner.data.esso import load_split, read_run as read
from mmg_tuner.errors import MmgTunerError
from mmg_tuner.learn import ensemble
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import ResidualNet
from mmg_tuner.learn.train import split_validation
from mmg_tuner.tuning.choice import choose_model
from mmg_tuner.tuning.interval import calibrate_interval, coverage
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
FRESH = ROOT / 'data' / 'esso_osaka_frt_extra'
FRESH_KINDS = ('turning', 'zigzag')
OUT = Path(__file__).resolve().parent / 'out' / 'esso_fresh'
WITHIN = 1.05   # H1, H1e, H2: within 5 % of the best of network and tuned, per kind
COVERAGE = (0.80, 0.95)   # H4


def fresh_runs(folder: Path = FRESH) -> tuple[list, dict]:
    """Return the seven fresh runs (read and cut as the training runs) and their kinds."""
    runs, kind_of = [], {}
    for kind in FRESH_KINDS:
        for f in sorted((folder / kind).glob('*.csv')):
            tr = read(f, kind)
            runs.append(tr)
            kind_of[tr.name] = kind
    return runs, kind_of


def consistency(tr) -> str:
    """Positions against velocities and heading against yaw rate (rms of the mismatch)."""
    x, y, psi, u, v, r = (tr.states[:, i] for i in range(6))
    dx = np.gradient(x, tr.t) - (u * np.cos(psi) - v * np.sin(psi))
    dy = np.gradient(y, tr.t) - (u * np.sin(psi) + v * np.cos(psi))
    dpsi = np.gradient(np.unwrap(psi), tr.t) - r
    return (f'rms(dx/dt - earth vx) {np.sqrt(np.mean(dx ** 2)):.3f} m/s, rms(dy/dt - earth '
            f'vy) {np.sqrt(np.mean(dy ** 2)):.3f} m/s, rms(dpsi/dt - r) '
            f'{np.sqrt(np.mean(dpsi ** 2)):.4f} rad/s')


def kind_means(scores: dict, runs: list[str]) -> float:
    """Mean over the runs of the (seed-mean) index; inf if any failed."""
    vals = []
    for n in runs:
        v = scores[n]
        if any(a is None for a in v):
            return float('inf')
        vals.append(float(np.mean(v)))
    return float(np.mean(vals))


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_fresh`` (``--quick``: 5 epochs)."""
    return main((['--epochs', '5'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    """Train, choose, calibrate and score as registered; print the table and the verdicts."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--tuned', type=Path, default=params_path(None))
    ap.add_argument('--out', type=Path, default=OUT, help='networks and summary.yaml go here')
    ap.add_argument('--load', action='store_true',
                    help="don't train: load the networks an earlier run saved in --out "
                    '(the same trained models, e.g. after a failure in the scoring)')
    ap.add_argument('--test-dir', type=Path, default=FRESH,
                    help='the test runs (KIND/*.csv; default the seven fresh runs; another '
                    'folder only for a smoke test of this script)')
    args, rest = ap.parse_known_args(argv)
    hargs = hybrid_parser().parse_args(rest)
    t_all = time.perf_counter()
    commit = subprocess.run(['git', 'rev-parse', 'HEAD'], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    print(f'commit {commit}; options: {vars(hargs)}')
    ship = mt.load_ship('esso_osaka_3m')
    train, _, kind_of = load_split(None)
    tuned = tuned_ship(ship, [], args.tuned, args.tuned == params_path(None), None)
    test, test_kind = fresh_runs(args.test_dir)
    print(f'training runs: {len(train)} ({sum(t.duration_s for t in train):.0f} s); test runs: '
          f'{len(test)} ({sum(t.duration_s for t in test):.0f} s)')
    for tr in test:
        print(f'  {test_kind[tr.name]:8s} {tr.name}: {tr.duration_s:.0f} s; {consistency(tr)}')
    dt = hargs.dt
    train_g = [t.resampled(dt) for t in train]
    test_g = [t.resampled(dt) for t in test]
    args.out.mkdir(parents=True, exist_ok=True)
    models = {'published': [ship], 'tuned': [tuned]}
    nets = {}
    for name, physics in (('network', False), ('hybrid', True)):
        base = tuned if physics else ship
        models[name], nets[name] = [], []
        for seed in hargs.seeds:
            path = args.out / f'{name}_seed{seed}.npz'
            if args.load:
                net = ResidualNet.load(path)
                print(f'{name} seed {seed}: loaded {path}')
            else:
                fit = train_network(base, train_g, kind_of, hargs, physics, seed)
                net = fit.net
                net.save(path)
                print(f'{name} seed {seed}: {fit.seconds:.0f} s, {fit.epochs} epochs (best '
                      f'{fit.best_epoch}), share {100 * fit.share:.1f} %; notes: '
                      f'{"; ".join(fit.notes)}', flush=True)
            nets[name].append(net)
            models[name].append(Model(base, net))
    ens = {n: ensemble(v) for n, v in nets.items()}
    for n, net in ens.items():
        net.save(args.out / f'{n}_ensemble.npz')
    models['ensemble'] = [Model(tuned, ens['hybrid'])]
    # the blend (bench/esso_blend_preregistration.md): every hybrid and pure member averaged
    blend = ensemble(nets['hybrid'] + nets['network'])
    blend.save(args.out / 'blend.npz')
    models['blend'] = [Model(tuned, blend)]
    # auto: the package's rule on the validation part of the training runs
    val = split_validation(train_g, 0.25, hargs.window)[1]
    cands = {'physics': tuned, 'hybrid': Model(tuned, ens['hybrid']),
             'network': Model(ship, ens['network']), 'blend': models['blend'][0]}
    choice = choose_model(cands, val, kind_of)
    print('\nauto: candidates on the validation part (last 25 %) of the training runs, mean '
          'index per kind (sigma pooled over them, 100 s restarts):')
    print(choice.markdown())
    print(f'auto recommends: {choice.chosen}')
    models['auto'] = [cands[choice.chosen]]
    scores = {name: held_out_scores(ships, test_g) for name, ships in models.items()}
    # uncertainty: the hybrid ensemble's interval, calibrated on the same validation part
    try:
        interval = calibrate_interval(cands['hybrid'], val, 0.9)
    except MmgTunerError as exc:   # e.g. every seed dropped its residual: no spread at all
        print(f'no interval: {exc}')
        interval, cov = None, {'all': float('nan'), 'states': {}}
    else:
        cov = coverage(interval, test_g)
        print(f'interval factors (calibrated to 90 % on validation): {interval.to_dict()}')
    cols = list(models)
    print(f'\nfresh runs: index (Wakita et al. 2022 eq. 26, sigma pooled over the {len(test_g)} '
          f'runs, RK4 on a {dt:g} s grid, restart every 100 s; network and hybrid: mean over '
          f'seeds {hargs.seeds})')
    print('| kind | run | ' + ' | '.join(cols) + ' |')
    print('|---|---|' + '---|' * len(cols))
    for tr in test_g:
        print(f'| {test_kind[tr.name]} | {tr.name} | ' + ' | '.join(
            'failed' if any(a is None for a in scores[c][tr.name])
            else f'{np.mean(scores[c][tr.name]):.4f}' for c in cols) + ' |')
    A = {k: {c: kind_means(scores[c], [t.name for t in test_g if test_kind[t.name] == k])
             for c in cols} for k in FRESH_KINDS}
    print('\n| kind (runs) | ' + ' | '.join(cols) + ' |')
    print('|---|' + '---|' * len(cols))
    kind_rows = []
    for k in FRESH_KINDS:
        nk = sum(1 for t in test_g if test_kind[t.name] == k)
        kind_rows.append({'kind': k, 'runs': nk, **A[k]})
        print(f'| {k} ({nk}) | ' + ' | '.join(f'{A[k][c]:.3f}' for c in cols) + ' |')
    print('| all | ' + ' | '.join(
        'failed' if any(a is None for a in scores[c]['all'])
        else f'{np.mean(scores[c]["all"]):.3f}' for c in cols) + ' |')
    verdict = {}
    for h, m in (('H1', 'hybrid'), ('H1e', 'ensemble'), ('H2', 'auto')):
        verdict[h] = {k: A[k][m] <= WITHIN * min(A[k]['network'], A[k]['tuned'])
                      for k in FRESH_KINDS}
    verdict['H3'] = {k: all(A[k][m] < A[k]['published'] for m in ('hybrid', 'auto'))
                     for k in FRESH_KINDS}
    verdict['H4'] = COVERAGE[0] <= cov['all'] <= COVERAGE[1]
    # bench/esso_blend_preregistration.md (B2 is H2 with the blend among auto's candidates)
    verdict['B1'] = {k: A[k]['blend'] <= WITHIN * min(A[k]['network'], A[k]['tuned'])
                     for k in FRESH_KINDS}
    verdict['B3'] = {k: A[k]['blend'] < A[k]['published'] for k in FRESH_KINDS}
    better = {k: A[k]['blend'] < min(A[k]['network'], A[k]['tuned']) for k in FRESH_KINDS}
    print('blend better than both the network and the tuned physics: '
          + ', '.join(f'{k} {"yes" if v else "no"}' for k, v in better.items()))
    print('\nverdicts (bench/esso_fresh_preregistration.md):')
    for h, v in verdict.items():
        ok = all(v.values()) if isinstance(v, dict) else v
        print(f'  {h}: {"PASS" if ok else "FAIL"}' + (
            ' (' + ', '.join(f'{k} {"pass" if x else "fail"}' for k, x in v.items()) + ')'
            if isinstance(v, dict) else ''))
    print(f'  H4 coverage of the nominal 90 % interval on the fresh runs: '
          f'{100 * cov["all"]:.1f} % (per state: '
          + ', '.join(f'{n} {100 * x:.0f} %' for n, x in cov['states'].items()) + ')')
    summary = {'commit': commit, 'options': {k: (str(v) if isinstance(v, Path) else v)
                                             for k, v in vars(hargs).items()},
               'scores': scores, 'by_kind': A, 'auto': choice.to_dict(),
               'interval': None if interval is None else interval.to_dict(),
               'coverage': cov, 'verdict': verdict,
               'test_kind': test_kind}
    write_atomic(args.out / 'summary.yaml', yaml.safe_dump(plain(summary), sort_keys=False))
    print(f'wall time: {time.perf_counter() - t_all:.0f} s')
    return {'commit': commit, 'seeds': hargs.seeds, 'index_by_kind': kind_rows,
            'auto_recommends': choice.chosen, 'interval_coverage': cov['all'],
            'verdicts': {h: 'pass' if (all(v.values()) if isinstance(v, dict) else v) else 'fail'
                         for h, v in verdict.items()}}


if __name__ == '__main__':
    main()
