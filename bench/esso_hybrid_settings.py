r"""
Choose the Esso Osaka hybrid's training settings on the validation split, then score them.

    python -m bench run esso_hybrid_settings [--quick] [--criterion window|index]
                                             [--only SETTING ...] [--seeds 0 1 2] [--report]

--quick is --report: train nothing, print the table from the results file.

bench/esso_hybrid.py trains the residual with choices (how the windows weigh, which epoch is
kept, the L2 weight, the window length, a scaling at inference). They used to be chosen by
comparing settings on the held-out runs. This script chooses them on the validation split only,
the last quarter of each training run, which ``train_residual`` already uses for early
stopping. The held-out runs are scored and printed for each setting but choose nothing.

Two validation criteria, each fixed before any run of it. Both: the setting chosen is the one
with the lowest score among those run for all the seeds asked; lower is better.

``--criterion window`` (the default; fixed before the first sweep, six settings 1-6 below):

* per seed, for each kind k of run (turning, zigzag, random, berthing), the ratio
  r_k = hybrid validation loss / physics-only validation loss
  (``fit.val_by_group``: the simulation-based loss on the 10 s validation windows of that
  kind, weighted as the setting's training weighs them);
* score of a setting = mean over seeds 0, 1, 2 of the mean over the 4 kinds of r_k. A seed
  whose residual was dropped (no epoch kept, or not significant) has every r_k = 1;
* secondary column, printed only: worst kind = the largest over the kinds of r_k averaged
  over the seeds.

``--criterion index`` (pre-registered 2026-11-23 01:36 UTC, before any run of it:
bench/esso_hybrid_preregistration.md, committed before the first run; all nine settings):

* validation quarter of a training run R: the trial ``train_residual`` holds out of R,
  ``split_validation([R], 0.25, window)[1][0]`` (the last 25 % plus the window's 4 samples of
  history);
  each of the 21 training runs once (not repeated as berthing is in training);
* the paper's index (eq. 26, 100 s restarts) through :func:`esso_hybrid.held_out_scores`, the
  function the held-out scoring uses (``mt.evaluate``, RK4, sigma pooled over the 21
  quarters), for the tuned physics alone and for the hybrid;
* per seed and kind: r_k = mean hybrid index over the kind's quarters / mean physics index
  over them (a dropped residual gives 1; a failed simulation gives infinity);
* score = mean over seeds 0, 1, 2 of the mean over the 4 kinds of r_k; an exact tie goes to
  the setting listed first. Worst kind, the window criterion and the held-out columns are
  printed and choose nothing; ``--report`` also prints the Spearman rank correlation over the
  settings between each criterion and the held-out analogue (mean over seeds and kinds of
  hybrid / tuned held-out index per kind) and the held-out overall index.

The settings (``dur4``: windows weighed by duration, the 3 berthing training runs repeated 4x,
``balance='window'``; ``group``: each kind weighs the same; ``mean``: the epoch with the
lowest mean validation loss; ``every``: the epoch whose worst kind gains most over the physics
alone, ``select='every_group'``; then the L2 weight; all else bench/esso_hybrid.py's defaults:
window 5, 32x32, RK4, 0.5 s grid):

1. ``dur4_mean_l2_0.01``, 2. ``dur4_every_l2_0.01``, 3. ``group_mean_l2_0.01``,
4. ``group_every_l2_0.01``, 5. ``group_every_l2_0.05``, 6. ``group_every_l2_0.2``: 10 s
   windows, already scored on the held-out runs before the index criterion was written;
7. ``dur4_mean_l2_0.01_h20``: as 1 with 20 s training and validation windows;
8. ``dur4_mean_l2_0.01_x0.5``: 1's trained residuals scaled by 0.5 at inference;
9. ``dur4_mean_l2_0.01_h20_x0.5``: 7's scaled by 0.5 the same way.

Weights: new trainings are saved under ``weights/`` beside ``--out``. For a record of an
earlier sweep (which saved none), bench/out/esso_hybrid/'s file of that setting and seed is
used when its training config matches and its held-out indices reproduce the record's to 1e-9
relative; otherwise the pair is retrained (deterministic per seed) and checked the same way.

Results go to ``--out`` (default bench/out/esso_hybrid_settings/results.json), written
atomically after each (setting, seed); a rerun skips what is there, so an interrupted sweep
loses nothing. A results file made with another tuned params file or other options is
refused. Each (setting, seed) trains in 40-120 s, so run it under the CPU lock one pair at a
time, e.g.::

    for s in dur4_mean_l2_0.01 dur4_every_l2_0.01 group_mean_l2_0.01 group_every_l2_0.01 \
             group_every_l2_0.05 group_every_l2_0.2 dur4_mean_l2_0.01_h20 \
             dur4_mean_l2_0.01_x0.5 dur4_mean_l2_0.01_h20_x0.5; do
        for seed in 0 1 2; do
            flock /tmp/cpu.lock python -m bench run esso_hybrid_settings --only $s --seeds $seed
        done
    done
    python -m bench run esso_hybrid_settings --report --criterion index
"""
from __future__ import annotations

import argparse
import contextlib
from dataclasses import dataclass
import hashlib
import io
import json
import math
from pathlib import Path

from bench.esso_hybrid import (
    bench_runs, held_out_scores, OUT as HYBRID_OUT, parser, shrunk, train_network, training_set)
from bench.esso_osaka import fail, PARAMS_OUT
from mmg_tuner._atomic import write_atomic
from mmg_tuner.data.esso import RUN_KINDS as KINDS
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import ResidualNet
from mmg_tuner.learn.train import split_validation
import numpy as np

OUT = Path(__file__).resolve().parent / 'out' / 'esso_hybrid_settings' / 'results.json'
VALIDATION_FRACTION = 0.25   # ResidualConfig's default: what train_residual holds out


@dataclass(frozen=True)
class Setting:
    """
    One candidate: training options, window length [s] and scaling at inference.

    weights_of: for a scaled setting, the setting whose trained residuals are scaled by
    ``shrink`` (no training of its own).
    """

    balance: str
    select: str
    l2: float
    horizon_s: float = 10.0
    shrink: float = 1.0
    weights_of: str | None = None


SETTINGS = {
    'dur4_mean_l2_0.01': Setting('window', 'mean', 0.01),
    'dur4_every_l2_0.01': Setting('window', 'every_group', 0.01),
    'group_mean_l2_0.01': Setting('group', 'mean', 0.01),
    'group_every_l2_0.01': Setting('group', 'every_group', 0.01),
    'group_every_l2_0.05': Setting('group', 'every_group', 0.05),
    'group_every_l2_0.2': Setting('group', 'every_group', 0.2),
    'dur4_mean_l2_0.01_h20': Setting('window', 'mean', 0.01, 20.0),
    'dur4_mean_l2_0.01_x0.5': Setting('window', 'mean', 0.01, 10.0, 0.5, 'dur4_mean_l2_0.01'),
    'dur4_mean_l2_0.01_h20_x0.5': Setting('window', 'mean', 0.01, 20.0, 0.5,
                                          'dur4_mean_l2_0.01_h20'),
}
WINDOW_SETTINGS = list(SETTINGS)[:6]   # the window criterion's pre-registered candidates
# bench/esso_hybrid.py's options that every setting shares (the results must match them)
SHARED = ('dt', 'epochs', 'window', 'hidden', 'max_seconds', 'integrator', 'berthing_weight',
          'hybrid_base')


def ratios(val_by_group: dict) -> dict:
    """Return hybrid / physics-only validation loss per kind (1 where the physics is 0)."""
    return {k: (v['hybrid'] / v['physics'] if v['physics'] > 0 else 1.0)
            for k, v in val_by_group.items()}


def validation_quarters(trials: list, window: int) -> list:
    """
    Return the validation quarter of each distinct run: what ``train_residual`` holds out.

    The same call ``train_residual`` makes (``_split``), so the slices are identical; a run
    repeated in ``trials`` (berthing with balance window) is returned once.
    """
    distinct = list({t.name: t for t in trials}.values())
    return split_validation(distinct, VALIDATION_FRACTION, window)[1]


def index_ratios(physics: dict, hybrid: dict, kind_of: dict) -> dict:
    """
    Return per kind the mean hybrid index over its runs / the mean physics index over them.

    physics, hybrid: run name -> eq. 26 index (None: the simulation failed, ratio infinity);
    runs absent from ``physics`` are ignored.
    """
    out = {}
    for k in KINDS:
        names = [n for n in physics if n != 'all' and kind_of.get(n) == k]
        hyb = [hybrid.get(n) for n in names]
        if any(h is None or not math.isfinite(h) for h in hyb):
            out[k] = math.inf
            continue
        den = float(np.mean([physics[n] for n in names]))
        out[k] = float(np.mean(hyb)) / den if den > 0 else 1.0
    return out


def score(runs: list[dict], key: str) -> tuple[float, float]:
    """
    Return (score, worst kind) of a setting from its seeds' records under criterion ``key``.

    key 'val_ratio' (window) or 'index_ratio' (index). score: mean over the seeds of the mean
    over the kinds of the ratio; worst kind: the largest over the kinds of the ratio averaged
    over the seeds (see the module docstring).
    """
    per_seed = np.array([[r[key][k] for k in KINDS] for r in runs], dtype=float)
    return float(np.mean(np.mean(per_seed, axis=1))), float(np.max(np.mean(per_seed, axis=0)))


def kind_means(runs: list[dict], kind_of: dict) -> dict:
    """Return the held-out index per kind: mean over its runs of the mean over the seeds."""
    out = {}
    for k in KINDS:
        names = [n for n, kk in kind_of.items() if kk == k and n in runs[0]['held_out']]
        out[k] = float(np.mean([np.mean([r['held_out'][n] for r in runs]) for n in names]))
    return out


def held_out_ratio(runs: list[dict], tuned: dict, kind_of: dict) -> float:
    """Return the held-out analogue of the criteria: mean over seeds and kinds of hybrid/tuned."""
    held = [k for k in tuned if k != 'all']
    t = {n: tuned[n] for n in held}
    return float(np.mean([np.mean(list(index_ratios(t, r['held_out'], kind_of).values()))
                          for r in runs]))


def spearman(a: list[float], b: list[float]) -> float:
    """Return Spearman's rank correlation of a and b (average ranks for ties)."""
    def ranks(x):
        x = np.asarray(x, float)
        order = np.argsort(x, kind='stable')
        r = np.empty(len(x))
        r[order] = np.arange(len(x), dtype=float)
        for v in np.unique(x):   # ties share their mean rank
            r[x == v] = r[x == v].mean()
        return r
    ra, rb = ranks(a), ranks(b)
    return float(np.corrcoef(ra, rb)[0, 1])


def load(path: Path, header: dict) -> dict:
    """Return the results so far, refusing a file made with other inputs or options."""
    if not path.exists():
        return {**header, 'runs': {}}
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        fail(f'{path}: cannot read the results so far ({exc}); give another --out')
    for key, value in header.items():
        have = doc.get(key)
        if key == 'options' and isinstance(have, dict):   # later options may be per setting
            have = {k: have.get(k) for k in value}
        if have != value:
            fail(f'{path} was made with {key} = {have!r}, this run has {value!r}; '
                 'give another --out (or delete that file to start again)')
    return doc


class Sweep:
    """The runs, the options and the results file: trains, recovers and scores residuals."""

    def __init__(self, args, base, tuned, train_g, test_g, kind_of, doc):
        self.args, self.base, self.tuned = args, base, tuned
        self.train_g, self.test_g, self.kind_of, self.doc = train_g, test_g, kind_of, doc
        self.weights = args.out.parent / 'weights'

    def save(self) -> None:
        """Write the results so far (atomically)."""
        write_atomic(self.args.out, json.dumps(self.doc, indent=1))

    def opts(self, s: Setting) -> argparse.Namespace:
        """Return esso_hybrid.py's options for setting s."""
        return argparse.Namespace(**{**vars(self.base), 'balance': s.balance,
                                     'select': s.select, 'l2': s.l2, 'horizon': s.horizon_s})

    def quarters(self) -> dict:
        """Return the tuned physics' index on each validation quarter (computed once)."""
        if 'val_quarters' not in self.doc:
            q = validation_quarters(self.train_g, self.base.window)
            self.doc['val_quarters'] = {
                'runs': {t.name: [float(t.t[0]), float(t.t[-1])] for t in q},
                'physics': {k: v[0] for k, v in held_out_scores([self.tuned], q).items()}}
            self.save()
        return self.doc['val_quarters']

    def index_of(self, net: ResidualNet) -> dict:
        """Return the hybrid's index on each validation quarter and 'all'."""
        q = validation_quarters(self.train_g, self.base.window)
        hybrid = Model(self.tuned, net)
        return {k: v[0] for k, v in held_out_scores([hybrid], q).items()}

    def held_out(self, net: ResidualNet) -> dict:
        """Return the hybrid's eq. 26 index on each held-out run and 'all'."""
        hybrid = Model(self.tuned, net)
        return {k: v[0] for k, v in held_out_scores([hybrid], self.test_g).items()}

    def train(self, name: str, seed: int) -> tuple[dict, ResidualNet]:
        """Train setting ``name`` (not a scaled one) for ``seed``; return record and net."""
        s = SETTINGS[name]
        fit = train_network(self.tuned, self.train_g, self.kind_of, self.opts(s), True, seed)
        self.weights.mkdir(parents=True, exist_ok=True)
        fit.net.save(self.weights / f'{name}_seed{seed}.npz')
        rec = {'setting': name, 'seed': seed, 'balance': s.balance, 'select': s.select,
               'l2': s.l2, 'horizon_s': s.horizon_s, 'val_by_group': fit.val_by_group,
               'val_ratio': ratios(fit.val_by_group), 'val_gain': fit.val_gain,
               'best_epoch': fit.best_epoch, 'epochs': fit.epochs,
               'dropped': fit.best_epoch == 0, 'share': fit.share, 'seconds': fit.seconds,
               'notes': fit.notes, 'held_out': self.held_out(fit.net)}
        print(f'{name}/seed{seed}: {fit.seconds:.0f} s, best epoch {fit.best_epoch} of '
              f'{fit.epochs}, window criterion by kind ' + ', '.join(
                  f'{k} {v:.4f}' for k, v in rec['val_ratio'].items()))
        return rec, fit.net

    def recorded_net(self, name: str, seed: int, rec: dict) -> ResidualNet:
        """
        Return the residual of a recorded training (not a scaled setting).

        Its saved weights; else bench/out/esso_hybrid/'s file of that setting and seed when its
        config matches and it reproduces the record's held-out indices; else a retraining,
        checked the same way (see the module docstring).
        """
        own = self.weights / f'{name}_seed{seed}.npz'
        if own.is_file():
            return ResidualNet.load(own)
        s = SETTINGS[name]
        bw = self.base.berthing_weight if s.balance == 'window' else 1
        cand = HYBRID_OUT / f'hybrid_tuned_bw{bw}_{s.balance}_{s.select}_seed{seed}.npz'
        if cand.is_file():
            net = ResidualNet.load(cand)
            cfg = net.meta.get('config', {})
            trials = [t.name for t in training_set(self.train_g, self.kind_of, s.balance,
                                                   self.base.berthing_weight)]
            same = (cfg.get('balance'), cfg.get('select'), cfg.get('l2'), cfg.get('horizon_s'),
                    cfg.get('seed'), net.meta.get('trials')) == (
                s.balance, s.select, s.l2, s.horizon_s, seed, trials)
            if same and _reproduces(self.held_out(net), rec['held_out']):
                self.weights.mkdir(parents=True, exist_ok=True)
                write_atomic(own, cand.read_bytes())
                rec.setdefault('notes', []).append(f'weights: {cand.name} of bench/out/'
                                                   'esso_hybrid (held-out reproduced)')
                print(f'{name}/seed{seed}: weights recovered from {cand} (held-out reproduced)')
                return net
        new, net = self.train(name, seed)
        ok = _reproduces(new['held_out'], rec['held_out'])
        print(f'{name}/seed{seed}: retrained; held-out '
              + ('reproduced' if ok else 'NOT reproduced: the new training replaces the record'))
        if not ok:
            rec.clear()
            rec.update(new)
        rec.setdefault('notes', []).append('weights: retrained, held-out '
                                           + ('reproduced' if ok else 'differed'))
        return net

    def run(self, name: str, seed: int) -> None:
        """Make sure (name, seed) has a record with held-out and validation-quarter indices."""
        key = f'{name}/seed{seed}'
        runs = self.doc['runs']
        s = SETTINGS[name]
        if key in runs and 'index_ratio' in runs[key]:
            print(f'{key}: done before, skipped')
            return
        if s.weights_of is not None:
            self.run(s.weights_of, seed)
            src = runs[f'{s.weights_of}/seed{seed}']
            net = shrunk(self.recorded_net(s.weights_of, seed, src), s.shrink)
            rec = {'setting': name, 'seed': seed, 'shrink': s.shrink,
                   'weights_of': s.weights_of, 'horizon_s': s.horizon_s,
                   'best_epoch': src['best_epoch'], 'dropped': src['dropped'],
                   'held_out': self.held_out(net)}
        elif key in runs:
            rec = runs[key]
            net = self.recorded_net(name, seed, rec)
        else:
            rec, net = self.train(name, seed)
        phys = self.quarters()['physics']
        rec['val_index'] = self.index_of(net)
        rec['index_ratio'] = index_ratios(phys, rec['val_index'], self.kind_of)
        runs[key] = rec
        self.save()
        print(f'{key}: index criterion by kind ' + ', '.join(
            f'{k} {v:.4f}' for k, v in rec['index_ratio'].items()) + f'; written to '
            f'{self.args.out}')


def _reproduces(new: dict, old: dict, rtol: float = 1e-9) -> bool:
    return set(new) == set(old) and all(
        a is not None and b is not None and abs(a - b) <= rtol * max(abs(a), abs(b), 1e-300)
        for a, b in ((new[k], old[k]) for k in new))


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_hybrid_settings`` (``--quick``: --report)."""
    return main((['--report'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--only', nargs='+', choices=list(SETTINGS), default=list(SETTINGS),
                    help='run these settings (default: all)')
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    ap.add_argument('--criterion', choices=('window', 'index'), default='window',
                    help='which pre-registered validation criterion chooses (module docstring)')
    ap.add_argument('--report', action='store_true', help='train nothing; print the table')
    ap.add_argument('--tuned', type=Path, default=PARAMS_OUT,
                    help='the tuned params.yaml (written by bench/esso_osaka.py)')
    ap.add_argument('--out', type=Path, default=OUT)
    args = ap.parse_args(argv)
    base = parser().parse_args(['--tuned', str(args.tuned)])   # esso_hybrid.py's defaults
    ship, tuned, train_g, test_g, kind_of = bench_runs(base.dt, args.tuned)
    header = {'tuned_sha256': hashlib.sha256(args.tuned.read_bytes()).hexdigest(),
              'options': {k: getattr(base, k) for k in SHARED},
              'held_out_runs': [t.name for t in test_g], 'kind_of': kind_of}
    doc = load(args.out, header)
    sweep = Sweep(args, base, tuned, train_g, test_g, kind_of, doc)
    if 'tuned' not in doc:
        doc['tuned'] = {k: v[0] for k, v in held_out_scores([tuned], test_g).items()}
        sweep.save()
    for name in ([] if args.report else args.only):
        for seed in args.seeds:
            sweep.run(name, seed)
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        report(doc, args.seeds, kind_of, args.criterion)
    print(text.getvalue(), end='')
    return {'criterion': args.criterion, 'seeds': args.seeds,
            'trained': [] if args.report else args.only, 'report': text.getvalue()}


def report(doc: dict, seeds: list[int], kind_of: dict, criterion: str) -> None:
    """Print the table: both validation scores beside the held-out means; the choice."""
    tuned = doc['tuned']
    t_kind = {k: float(np.mean([tuned[n] for n, kk in kind_of.items()
                                if kk == k and n in tuned])) for k in KINDS}
    print(f'\nseeds {seeds}; index: hybrid / physics eq. 26 index (100 s restarts) on the '
          'validation quarters; window: hybrid / physics loss on the validation windows '
          '(both: mean over kinds, then seeds; worst kind); held-out: eq. 26 index, mean per '
          'kind over its runs and the seeds, overall mean ± std over the seeds; '
          f'choosing: {criterion}')
    print('| setting | index score | index worst kind | window score | window worst kind | '
          'dropped | turning | zigzag | random | berthing | all |')
    print('|---|---|---|---|---|---|---|---|---|---|---|')
    print('| tuned physics alone | 1 | 1 | 1 | 1 | | '
          + ' | '.join(f'{t_kind[k]:.3f}' for k in KINDS) + f' | {tuned["all"]:.3f} |')
    crit = {'index': {}, 'window': {}}
    held, held_all = {}, {}
    for name in SETTINGS:
        runs = [doc['runs'].get(f'{name}/seed{s}') for s in seeds]
        if any(r is None for r in runs):
            done = [s for s, r in zip(seeds, runs) if r is not None]
            print(f'| {name} | (seeds done: {done}) | | | | | | | | | |')
            continue
        cells = []
        for c, key in (('index', 'index_ratio'), ('window', 'val_ratio')):
            if all(key in r for r in runs):
                sc, worst = score(runs, key)
                crit[c][name] = sc
                cells += [f'{sc:.4f}', f'{worst:.4f}']
            else:
                cells += ['-', '-']
        km = kind_means(runs, kind_of)
        overall = [r['held_out']['all'] for r in runs]
        held[name] = held_out_ratio(runs, tuned, kind_of)
        held_all[name] = float(np.mean(overall))
        print(f'| {name} | ' + ' | '.join(cells)
              + f' | {sum(bool(r["dropped"]) for r in runs)}/{len(runs)} | '
              + ' | '.join(f'{km[k]:.3f}' for k in KINDS)
              + f' | {np.mean(overall):.3f} ± {np.std(overall):.3f} |')
    for c, scores in crit.items():
        for which, among in (('all', list(SETTINGS)), ('the first six', WINDOW_SETTINGS)):
            names = [n for n in among if n in scores and n in held]
            if len(names) < 3:
                continue
            print(f'Spearman rank correlation over {len(names)} settings ({which} with it), '
                  f'{c} criterion vs held-out hybrid/tuned per kind: '
                  f'{spearman([scores[n] for n in names], [held[n] for n in names]):+.2f}; '
                  'vs held-out overall index: '
                  f'{spearman([scores[n] for n in names], [held_all[n] for n in names]):+.2f}')
    candidates = WINDOW_SETTINGS if criterion == 'window' else list(SETTINGS)
    scores = crit[criterion]
    missing = [n for n in candidates if n not in scores]
    if missing:
        print(f'{criterion} criterion: not every candidate has seeds {seeds} ({missing}): '
              'no choice yet')
        return
    chosen = min(candidates, key=lambda n: scores[n])   # a tie: the first listed
    print(f'chosen by the {criterion} criterion: {chosen} (score {scores[chosen]:.4f}; '
          'held-out figures played no part)')


if __name__ == '__main__':
    main()
