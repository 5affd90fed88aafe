r"""
Choose the Esso Osaka hybrid's training settings on the validation split, then score them.

    python bench/esso_hybrid_settings.py [--only SETTING ...] [--seeds 0 1 2] [--report]

bench/esso_hybrid.py trains the residual with three choices (how the windows weigh, which
epoch is kept, the L2 weight). They used to be chosen by comparing settings on the held-out
runs. This script chooses them on the validation split only, the last quarter of each
training run, which ``train_residual`` already uses for early stopping. The held-out runs are
scored and printed for each setting but choose nothing.

Validation criterion, fixed before any run of this script:

* per seed, for each kind k of run (turning, zigzag, random, berthing), the ratio
  r_k = hybrid validation loss / physics-only validation loss
  (``fit.val_by_group``: the simulation-based loss on the 10 s validation windows of that
  kind, weighted as the setting's training weighs them);
* score of a setting = mean over seeds 0, 1, 2 of the mean over the 4 kinds of r_k; lower is
  better. A seed whose residual was dropped (no epoch kept, or not significant) has every
  r_k = 1, so it scores 1.0;
* secondary column, printed only: worst kind = the largest over the kinds of r_k averaged
  over the seeds;
* the setting chosen is the one with the lowest score among the settings run for all the
  seeds asked.

The settings are the six 10 s-window rows of the README's "What was tried" table:
``dur4_*``: windows weighed by duration, the 3 berthing training runs repeated 4x
(``balance='window'``); ``group_*``: each kind weighs the same (``balance='group'``);
``*_mean``: the epoch with the lowest mean validation loss; ``*_every``: the epoch whose worst
kind gains most over the physics alone (``select='every_group'``); then the L2 weight. All
else is bench/esso_hybrid.py's defaults (window 5, 32x32, 10 s windows, RK4, 0.5 s grid).

Results go to ``--out`` (default bench/out/esso_hybrid_settings/results.json), written
atomically after each (setting, seed); a rerun skips the pairs already there, so an
interrupted sweep loses nothing. A results file made with another tuned params file or other
options is refused. Each (setting, seed) trains in 40-70 s, so run it under the CPU lock one
setting at a time, e.g.::

    for s in dur4_mean_l2_0.01 dur4_every_l2_0.01 group_mean_l2_0.01 group_every_l2_0.01 \
             group_every_l2_0.05 group_every_l2_0.2; do
        for seed in 0 1 2; do
            flock /tmp/cpu.lock python bench/esso_hybrid_settings.py --only $s --seeds $seed
        done
    done
    python bench/esso_hybrid_settings.py --report
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from esso_hybrid import bench_runs, held_out_scores, parser, train_network  # noqa: E402, I100
from esso_osaka import fail, KINDS, PARAMS_OUT  # noqa: E402
from mmg_tuner._atomic import write_atomic  # noqa: E402

OUT = Path(__file__).resolve().parent / 'out' / 'esso_hybrid_settings' / 'results.json'
# name -> (balance, select, l2); the README's "What was tried" rows with 10 s windows
SETTINGS = {
    'dur4_mean_l2_0.01': ('window', 'mean', 0.01),
    'dur4_every_l2_0.01': ('window', 'every_group', 0.01),
    'group_mean_l2_0.01': ('group', 'mean', 0.01),
    'group_every_l2_0.01': ('group', 'every_group', 0.01),
    'group_every_l2_0.05': ('group', 'every_group', 0.05),
    'group_every_l2_0.2': ('group', 'every_group', 0.2),
}
# bench/esso_hybrid.py's options that every setting shares (the results must match them)
SHARED = ('dt', 'epochs', 'window', 'hidden', 'horizon', 'max_seconds', 'integrator',
          'berthing_weight', 'hybrid_base')


def ratios(val_by_group: dict) -> dict:
    """Return hybrid / physics-only validation loss per kind (1 where the physics is 0)."""
    return {k: (v['hybrid'] / v['physics'] if v['physics'] > 0 else 1.0)
            for k, v in val_by_group.items()}


def validation_score(runs: list[dict]) -> tuple[float, float]:
    """
    Return (score, worst kind) of a setting from its seeds' records.

    score: mean over the seeds of the mean over the kinds of the ratio; worst kind: the
    largest over the kinds of the ratio averaged over the seeds (see the module docstring).
    """
    per_seed = [[r['val_ratio'][k] for k in KINDS] for r in runs]
    return float(np.mean(np.mean(per_seed, axis=1))), float(np.max(np.mean(per_seed, axis=0)))


def kind_means(runs: list[dict], kind_of: dict) -> dict:
    """Return the held-out index per kind: mean over its runs of the mean over the seeds."""
    out = {}
    for k in KINDS:
        names = [n for n, kk in kind_of.items() if kk == k and n in runs[0]['held_out']]
        out[k] = float(np.mean([np.mean([r['held_out'][n] for r in runs]) for n in names]))
    return out


def load(path: Path, header: dict) -> dict:
    """Return the results so far, refusing a file made with other inputs or options."""
    if not path.exists():
        return {**header, 'runs': {}}
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        fail(f'{path}: cannot read the results so far ({exc}); give another --out')
    for key, value in header.items():
        if key != 'tuned' and doc.get(key) != value:
            fail(f'{path} was made with {key} = {doc.get(key)!r}, this run has {value!r}; '
                 'give another --out (or delete that file to start again)')
    return doc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--only', nargs='+', choices=list(SETTINGS), default=list(SETTINGS),
                    help='train these settings (default: all)')
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    ap.add_argument('--report', action='store_true', help='train nothing; print the table')
    ap.add_argument('--tuned', type=Path, default=PARAMS_OUT,
                    help='the tuned params.yaml (written by bench/esso_osaka.py)')
    ap.add_argument('--out', type=Path, default=OUT)
    args = ap.parse_args()
    base = parser().parse_args(['--tuned', str(args.tuned)])   # esso_hybrid.py's defaults
    ship, tuned, train_g, test_g, kind_of = bench_runs(base.dt, args.tuned)
    header = {'tuned_sha256': hashlib.sha256(args.tuned.read_bytes()).hexdigest(),
              'options': {k: getattr(base, k) for k in SHARED},
              'held_out_runs': [t.name for t in test_g], 'kind_of': kind_of}
    doc = load(args.out, header)
    if 'tuned' not in doc:
        doc['tuned'] = {k: v[0] for k, v in held_out_scores([tuned], test_g).items()}
        write_atomic(args.out, json.dumps(doc, indent=1))
    for name in ([] if args.report else args.only):
        balance, select, l2 = SETTINGS[name]
        for seed in args.seeds:
            key = f'{name}/seed{seed}'
            if key in doc['runs']:
                print(f'{key}: done before, skipped')
                continue
            opts = argparse.Namespace(**{**vars(base), 'balance': balance, 'select': select,
                                         'l2': l2})
            fit = train_network(tuned, train_g, kind_of, opts, True, seed)
            hybrid = dataclasses.replace(tuned, residual=fit.net)
            held = {k: v[0] for k, v in held_out_scores([hybrid], test_g).items()}
            rec = {'setting': name, 'seed': seed, 'balance': balance, 'select': select,
                   'l2': l2, 'val_by_group': fit.val_by_group,
                   'val_ratio': ratios(fit.val_by_group), 'val_gain': fit.val_gain,
                   'best_epoch': fit.best_epoch, 'epochs': fit.epochs,
                   'dropped': fit.best_epoch == 0, 'share': fit.share,
                   'seconds': fit.seconds, 'notes': fit.notes, 'held_out': held}
            doc['runs'][key] = rec
            write_atomic(args.out, json.dumps(doc, indent=1))
            print(f'{key}: {fit.seconds:.0f} s, best epoch {fit.best_epoch} of {fit.epochs}, '
                  'validation ratio by kind ' + ', '.join(
                      f'{k} {v:.4f}' for k, v in rec['val_ratio'].items())
                  + f'; written to {args.out}')
    report(doc, args.seeds, kind_of)


def report(doc: dict, seeds: list[int], kind_of: dict) -> None:
    """Print the table: validation score (the choice) beside the held-out means."""
    tuned = doc['tuned']
    t_kind = {k: float(np.mean([tuned[n] for n, kk in kind_of.items()
                                if kk == k and n in tuned])) for k in KINDS}
    print(f'\nseeds {seeds}; validation: hybrid / physics-only loss on the last quarter of each '
          'training run (mean over kinds, then seeds; worst kind); held-out: eq. 26 index, '
          'mean per kind over its runs and the seeds, overall mean ± std over the seeds')
    print('| setting | validation score | worst kind | dropped | turning | zigzag | random | '
          'berthing | all |')
    print('|---|---|---|---|---|---|---|---|---|')
    print('| tuned physics alone | 1 | 1 | | ' + ' | '.join(f'{t_kind[k]:.3f}' for k in KINDS)
          + f' | {tuned["all"]:.3f} |')
    scores = {}
    for name in SETTINGS:
        runs = [doc['runs'].get(f'{name}/seed{s}') for s in seeds]
        if any(r is None for r in runs):
            done = [s for s, r in zip(seeds, runs) if r is not None]
            print(f'| {name} | (seeds done: {done}) | | | | | | | |')
            continue
        score, worst = validation_score(runs)
        scores[name] = score
        km = kind_means(runs, kind_of)
        overall = [r['held_out']['all'] for r in runs]
        print(f'| {name} | {score:.4f} | {worst:.4f} | {sum(r["dropped"] for r in runs)}/'
              f'{len(runs)} | ' + ' | '.join(f'{km[k]:.3f}' for k in KINDS)
              + f' | {np.mean(overall):.3f} ± {np.std(overall):.3f} |')
    if len(scores) < len(SETTINGS):
        print(f'not every setting has seeds {seeds}: no choice yet')
        return
    chosen = min(scores, key=scores.get)
    print(f'chosen by validation: {chosen} (score {scores[chosen]:.4f}; held-out figures '
          'played no part)')


if __name__ == '__main__':
    main()
