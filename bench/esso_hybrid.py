"""
The hybrid model on the real Esso Osaka pond data: Wakita et al. (2022) Table 9, reproduced.

    python -m bench run esso_hybrid [--quick] [--dt 0.5] [--seeds 0] [--epochs 200]
                                    [--tuned FILE] [--balance window] [--select mean]
                                    [--l2 0.01] [--horizon 20] [--shrink 1]

Needs the tuned physics of ``python -m bench run esso_osaka`` first. --quick trains 5 epochs
per network (a check that it runs, minutes; its figures mean nothing).

Data, cuts and split: bench/esso_osaka.py's (33 FRT-DS-ESSO runs, CC BY-NC-SA 4.0; per kind,
sorted by file name, positions 1, 4, 7, ... held out). Four models are scored on every
held-out run with the paper's index (eq. 26: squared standardised errors of x, u, y, v, psi,
r summed over the states, averaged over the samples; sigma pooled over the held-out runs;
restart from the measured state every 100 s), through ``mt.evaluate``:

* published: the captive-test low-speed MMG (config/esso_osaka_3m.yaml);
* tuned: the same tuned by bench/esso_osaka.py (22 targets, 100 s pieces, kinds balanced,
  prior), read from the params file it writes (``--tuned``, default
  bench/out/esso_osaka/params.yaml; run ``python -m bench run esso_osaka`` first). The file's
  provenance fingerprint must match today's ship config and run files and its split this
  one: parameters tuned on other inputs are refused, never silently reused;
* network: the pure network (the paper's Type-1: a window of recent states, inputs and
  apparent wind; no physics), trained with the simulation-based loss;
* hybrid: the tuned physics plus a neural residual on the accelerations, same training;
* ensemble (with several ``--seeds``): the tuned physics plus the mean of the seeds' residuals,
  as one network (``learn.ensemble``; no further training, nothing chosen).

The hybrid's residual trains on the training runs weighed by duration, the three short
berthing runs repeated ``--berthing-weight`` times (``--balance window``, as the pure network,
``--network-balance``; ``group``: each kind weighs the same, as the physics tuning), with
early stopping on the last quarter of each training run; the hybrid keeps the epoch with the
lowest mean validation loss (``--select mean``; ``every_group``: the epoch whose worst kind
gains most over the physics alone, so the residual is zero unless it helps every kind), with
``--l2 0.01``, on 20 s training and validation windows (``--horizon``; the pure network keeps
10 s, ``--network-horizon``); ``--shrink`` scales the trained residual at inference. The
held-out runs choose nothing: in a training, the epoch and whether the residual is kept come
from the validation split; the defaults of ``--balance``, ``--select``, ``--l2``,
``--horizon`` and ``--shrink`` were chosen among nine settings on that validation split alone
by bench/esso_hybrid_settings.py's pre-registered index criterion (lowest mean over seeds 0-2
and kinds of the hybrid's eq. 26 index, 100 s restarts, over the physics' alone on the last
quarter of each training run; bench/esso_hybrid_preregistration.md). At
``--dt`` (every model is evaluated on that grid, RK4 one step per sample, so the four columns
compare; bench/esso_osaka.py's table is at the recorded 0.1 s). With several ``--seeds`` the
network columns give mean ± standard deviation, as the paper's table does. Training wall time
is printed per network.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
from pathlib import Path
import time

from bench import plain
from bench.esso_osaka import check_provenance, fail, params_path, RESTART_S
import mmg_tuner as mt
from mmg_tuner._atomic import write_atomic
from mmg_tuner.data.esso import FOLDS, load_split, RUN_KINDS as KINDS
from mmg_tuner.learn import ensemble, ResidualConfig, train_residual
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import ResidualNet
from mmg_tuner.learn.train import BALANCE, SELECT
import numpy as np
import yaml

OUT = Path(__file__).resolve().parent / 'out' / 'esso_hybrid'
# the paper's Table 9 for comparison: MMG (captive tests) and Type-1 (mean, std)
PAPER = {'random': (0.272, 0.236), 'turning': (0.858, 0.713), 'zigzag': (1.015, 0.086),
         'berthing': ('0.036-0.189', '0.052-0.138')}


def tuned_ship(ship, test, path: Path, default: bool, fold: int = 1):
    """
    Load the tuned low-speed MMG bench/esso_osaka.py wrote, refusing stale or foreign files.

    The default file must carry esso_osaka.py's provenance (inputs fingerprint and split); a
    file given with ``--tuned`` is checked when it carries one, else used with a note.
    """
    if default or not path.is_file() or 'provenance:' in path.read_text():
        prov = check_provenance(path, ship.source, fold)
        held = [t.name for t in test]
        if prov.get('held_out_runs') != held:
            fail(f'{path} was tuned with another split (held out: '
                 f'{prov.get("held_out_runs")}; this bench holds out {held}); rebuild it '
                 f'with: python -m bench run esso_osaka --fold {fold} --out {path}')
        print(f'tuned low-speed MMG: {path} ({prov["evaluations"]} evaluations, inputs '
              f'{prov["inputs_sha256"][:12]}... match)')
    else:
        print(f'tuned low-speed MMG: {path} (no provenance: inputs not checked)')
    return mt.load_ship('esso_osaka_3m', path)


def parser() -> argparse.ArgumentParser:
    """Return the command line of this bench (its defaults are the settings of the models)."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--dt', type=float, default=0.5, help='grid of the networks [s]')
    ap.add_argument('--seeds', type=int, nargs='+', default=[0])
    ap.add_argument('--epochs', type=int, default=200)
    ap.add_argument('--window', type=int, default=5)
    ap.add_argument('--hidden', type=int, nargs='+', default=[32, 32])
    ap.add_argument('--horizon', type=float, default=20.0,
                    help="hybrid: the residual's training and validation windows [s] (chosen "
                    'on validation: bench/esso_hybrid_settings.py)')
    ap.add_argument('--network-horizon', type=float, default=10.0,
                    help='pure network: its training and validation windows [s]')
    ap.add_argument('--shrink', type=float, default=1.0,
                    help='hybrid: the trained residual is scaled by this at inference (the '
                    "output layer's weights and biases; 1: as trained)")
    ap.add_argument('--l2', type=float, default=1e-2,
                    help="hybrid: weight of the penalty on the residual's size (chosen on "
                    'validation: bench/esso_hybrid_settings.py)')
    ap.add_argument('--network-l2', type=float, default=1e-2,
                    help='pure network: weight of the penalty on its weights')
    ap.add_argument('--max-seconds', type=float, default=400.0, help='per network')
    ap.add_argument('--integrator', default='rk4', choices=('euler', 'rk4'))
    ap.add_argument('--berthing-weight', type=int, default=4,
                    help='a model trained with balance window sees the berthing training runs '
                    'this many times (3 short runs among 21)')
    ap.add_argument('--balance', choices=BALANCE, default='window',
                    help='hybrid: weight of the training/validation windows (window: by '
                    'duration, with --berthing-weight; group: each kind the same)')
    ap.add_argument('--network-balance', choices=BALANCE, default='window',
                    help='pure network: the same (window, with --berthing-weight: its best '
                    'in earlier runs, 0.322 overall against 0.422 with group)')
    ap.add_argument('--select', choices=SELECT, default='mean',
                    help='the epoch kept: best on the mean validation loss, or on the worst '
                    'kind (every_group)')
    ap.add_argument('--fold', type=int, choices=FOLDS, default=1,
                    help="bench/esso_osaka.py's split with this held-out offset (1: the split "
                    'of every table; 0, 2: cross-validation folds, outputs under '
                    'bench/out/esso_hybrid/foldF)')
    ap.add_argument('--tuned', type=Path, default=None,
                    help='the tuned params.yaml (written by bench/esso_osaka.py; default its '
                    'output for --fold)')
    ap.add_argument('--skip', nargs='*', default=[], choices=('network', 'hybrid'))
    ap.add_argument('--hybrid-base', choices=('tuned', 'published'), default='tuned',
                    help='the physics under the residual')
    return ap


def bench_runs(dt: float, tuned_path: Path, fold: int = 1):
    """
    Return the published ship, the tuned one, the training and held-out runs on ``dt``, kinds.

    The split is bench/esso_osaka.py's (held-out offset ``fold``); the tuned ship is checked by
    :func:`tuned_ship`.
    """
    ship = mt.load_ship('esso_osaka_3m')
    train, test, kind_of = load_split(fold)
    print(f'fold {fold}: training runs: {len(train)} '
          f'({sum(t.duration_s for t in train):.0f} s), held out: '
          f'{len(test)} ({sum(t.duration_s for t in test):.0f} s)')
    tuned = tuned_ship(ship, test, tuned_path, tuned_path == params_path(fold), fold)
    return (ship, tuned, [t.resampled(dt) for t in train], [t.resampled(dt) for t in test],
            kind_of)


def training_set(train_g: list, kind_of: dict, balance: str, berthing_weight: int) -> list:
    """Return the runs a network trains on: with balance window, berthing repeated."""
    if balance != 'window':
        return list(train_g)
    return train_g + [t for t in train_g if kind_of[t.name] == 'berthing'] * (
        berthing_weight - 1)


def shrunk(net: ResidualNet, alpha: float) -> ResidualNet:
    """
    Return ``net`` with its output scaled by ``alpha`` (exactly: the output layer is linear).

    The output layer's weights and biases are multiplied by alpha; alpha 1 returns net.
    """
    if alpha == 1.0:
        return net
    meta = {**net.meta, 'shrink': alpha}
    return dataclasses.replace(net, weights=(*net.weights[:-1], net.weights[-1] * alpha),
                               biases=(*net.biases[:-1], net.biases[-1] * alpha), meta=meta)


def train_network(base, train_g: list, kind_of: dict, args, physics: bool, seed: int):
    """
    Train base's residual (physics True) or the pure network on the training runs.

    The options are the command line's (``args``, see :func:`parser`): with balance
    ``window`` the berthing runs are repeated ``--berthing-weight`` times. Returns the fit.
    """
    balance = args.balance if physics else args.network_balance
    fit_set = training_set(train_g, kind_of, balance, args.berthing_weight)
    cfg = ResidualConfig(window=args.window, hidden=tuple(args.hidden),
                         horizon_s=args.horizon if physics else args.network_horizon,
                         epochs=args.epochs,
                         l2=args.l2 if physics else args.network_l2,
                         seed=seed, physics=physics, integrator=args.integrator,
                         max_seconds=args.max_seconds, balance=balance,
                         select=args.select)
    return train_residual(base, fit_set, groups=kind_of, config=cfg)


def held_out_scores(ships: list, test_g: list) -> dict:
    """
    Return the eq. 26 index of each ship on each held-out run, and 'all': {name: [per ship]}.

    ``mt.evaluate`` at the runs' grid, RK4, restart every RESTART_S, sigma pooled over them.
    """
    runs = [mt.evaluate(s, test_g, restart_every_s=RESTART_S, integrator='rk4')
            for s in ships]
    scores = {tr.name: [r.trials[tr.name].index for r in runs] for tr in test_g}
    scores['all'] = [r.index_all for r in runs]
    return scores


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_hybrid`` (``--quick``: 5 epochs)."""
    return main((['--epochs', '5'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    args = parser().parse_args(argv)
    if args.tuned is None:
        args.tuned = params_path(args.fold)
    out = out_dir(args.fold)
    t_all = time.perf_counter()
    ship, tuned, train_g, test_g, kind_of = bench_runs(args.dt, args.tuned, args.fold)
    models = {'published': [ship], 'tuned': [tuned]}
    seconds, shares = {}, {}
    for name, physics in (('network', False), ('hybrid', True)):
        if name in args.skip:
            continue
        base = (tuned if args.hybrid_base == 'tuned' else ship) if physics else ship
        models[name], seconds[name] = [], []
        balance = args.balance if physics else args.network_balance
        bw = args.berthing_weight if balance == 'window' else 1
        for seed in args.seeds:
            fit = train_network(base, train_g, kind_of, args, physics, seed)
            seconds[name].append(fit.seconds)
            on = f'_{args.hybrid_base}' if physics else ''
            net = shrunk(fit.net, args.shrink) if physics else fit.net
            net_file = (out / f'{name}{on}_bw{bw}_{balance}_'
                        f'{args.select}{_variant(args, physics)}_seed{seed}.npz')
            out.mkdir(parents=True, exist_ok=True)
            net.save(net_file)
            print(f'{name} seed {seed}: {fit.seconds:.0f} s, {fit.epochs} epochs (best '
                  f'{fit.best_epoch}), share {100 * fit.share:.1f} %, validation gain '
                  + ('-' if fit.val_gain is None else f'{100 * fit.val_gain:.1f} %')
                  + f'; notes: {"; ".join(fit.notes)}')
            if physics:
                print('  share by kind (training runs): ' + ', '.join(
                    f'{k} {100 * v:.1f} %' for k, v in fit.share_by_group.items())
                    + '; validation loss physics -> hybrid: ' + ', '.join(
                    f'{k} {v["physics"]:.4f} -> {v["hybrid"]:.4f}'
                    for k, v in fit.val_by_group.items()))
            shares.setdefault(name, []).append(fit.share)
            models[name].append(Model(base, net))
        if physics and len(args.seeds) > 1:   # one network averaging the seeds' residuals
            ens = ensemble([m.residual for m in models[name]])
            ens.save(out / f'hybrid_ensemble_{args.balance}_{args.select}'
                     f'{_variant(args, True)}.npz')
            models['ensemble'] = [Model(base, ens)]
    scores = {}
    for name, ships in models.items():
        scores[name] = held_out_scores(ships, test_g)
    cols = list(models)
    print(f'\nheld-out index (Wakita et al. 2022 eq. 26, sigma pooled over the {len(test_g)} '
          f'held-out runs, RK4 on a {args.dt:g} s grid, restart every {RESTART_S:g} s; '
          f'networks: mean ± std over seeds {args.seeds})')
    print('| kind | run | ' + ' | '.join(cols) + ' | best |')
    print('|---|---|' + '---|' * len(cols) + '---|')
    best_by_kind = {k: [] for k in KINDS}
    rows, kind_rows = [], []
    for tr in test_g:
        vals = {c: scores[c][tr.name] for c in cols}
        best = min(cols, key=lambda c: _mean(vals[c]))
        best_by_kind[kind_of[tr.name]].append(best)
        rows.append({'kind': kind_of[tr.name], 'run': tr.name,
                     **{c: _fmt(vals[c]) for c in cols}, 'best': best})
        print(f'| {kind_of[tr.name]} | {tr.name} | '
              + ' | '.join(_fmt(vals[c]) for c in cols) + f' | {best} |')
    print('| all | together | ' + ' | '.join(_fmt(scores[c]['all']) for c in cols) + ' | '
          + min(cols, key=lambda c: _mean(scores[c]['all'])) + ' |')
    for k in KINDS:
        b = best_by_kind[k]
        runs = [tr.name for tr in test_g if kind_of[tr.name] == k]
        mean = {c: float(np.mean([_mean(scores[c][n]) for n in runs])) for c in cols}
        kind_rows.append({'kind': k, **mean, 'best': min(mean, key=mean.get)})
        print(f'{k}: best model per held-out run: {", ".join(b)}'
              + (' (hybrid best on every run)' if b and all(x == 'hybrid' for x in b)
                 else '') + '; mean index over the kind: '
              + ', '.join(f'{c} {v:.4f}' for c, v in mean.items())
              + f' -> best {min(mean, key=mean.get)}')
    for name, s in seconds.items():
        print(f'training wall time, {name}: ' + ', '.join(f'{x:.0f} s' for x in s)
              + f' (seeds {args.seeds})')
    print("paper's Table 9 (its own test runs): MMG / Type-1 = "
          + '; '.join(f'{k} {a} / {b}' for k, (a, b) in PAPER.items()))
    for name, s in shares.items():
        if name == 'hybrid':
            print('hybrid: share of the residual in the total acceleration (training runs): '
                  + ', '.join(f'{100 * x:.1f} %' for x in s) + f' (seeds {args.seeds})')
    summary = {'dt': args.dt, 'seeds': args.seeds, 'options': {
        k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        'scores': scores, 'seconds': seconds, 'share': shares, 'kind_of': kind_of,
        'held_out_runs': [t.name for t in test_g], 'fold': args.fold,
        # which tuned physics: its bytes and how it was tuned (the cross-validation checks them)
        'tuned_sha256': hashlib.sha256(args.tuned.read_bytes()).hexdigest(),
        'tuned_provenance': (yaml.safe_load(args.tuned.read_text()) or {}).get('provenance')}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / 'summary.yaml', yaml.safe_dump(plain(summary), sort_keys=False))
    print(f'wall time: {time.perf_counter() - t_all:.0f} s')
    rows.append({'kind': 'all', 'run': 'together', **{c: _fmt(scores[c]['all']) for c in cols},
                 'best': min(cols, key=lambda c: _mean(scores[c]['all']))})
    return {'fold': args.fold, 'seeds': args.seeds, 'held_out_index': rows,
            'kind_means': kind_rows, 'training_s': seconds, 'residual_share': shares,
            'wall_s': time.perf_counter() - t_all}


def out_dir(fold: int) -> Path:
    """Return where a fold's networks and summary go (fold 1: OUT itself, as always)."""
    return OUT if fold == 1 else OUT / f'fold{fold}'


def _variant(args, physics: bool) -> str:
    """Return the file-name suffix of a window other than 10 s, or of a shrink ('' if none)."""
    horizon = args.horizon if physics else args.network_horizon
    return ((f'_h{horizon:g}' if horizon != 10.0 else '')
            + (f'_x{args.shrink:g}' if physics and args.shrink != 1.0 else ''))


def _mean(v: list) -> float:
    x = [a for a in v if a is not None]
    return float(np.mean(x)) if len(x) == len(v) and x else float('inf')


def _fmt(v: list) -> str:
    if any(a is None for a in v):
        return 'failed'
    if len(v) == 1:
        return f'{v[0]:.4f}'
    return f'{np.mean(v):.4f} ± {np.std(v):.4f}'


if __name__ == '__main__':
    main()
