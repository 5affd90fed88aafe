"""
Three-fold cross-validation of the Esso Osaka hybrid: the pre-registered verdict.

Registered in bench/esso_hybrid_cv_preregistration.md (written before any run of the two new
folds).

    python -m bench run esso_hybrid_cv    # prints the commands still to run, then the verdict

Each fold f holds out the runs at positions i mod 3 == f of each kind (bench/esso_osaka.py's
rule; fold 1 is the split of every other table). Per fold, two commands produce its results,
with every option at today's defaults:

    python -m bench run esso_osaka --fold f                   # the tuned physics of the fold
    python -m bench run esso_hybrid --fold f --seeds 0 1 2    # networks, hybrid, ensemble, scores

This script only reads their summaries (bench/out/esso_hybrid[/foldF]/summary.yaml), refuses
one written with other options or another split, and prints, per kind k, A_k(M): the mean over
the held-out runs of kind k in folds 0 and 2 of model M's eq. 26 index on the run (networks:
averaged over the seeds), then the two hypotheses: H1 the single hybrid, H2 the 3-seed ensemble
below every rival on every kind. Fold 1 is shown but counts for nothing (its result was known
when the folds were registered).
"""
from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
import sys

from bench.esso_hybrid import out_dir, parser
from bench.esso_osaka import params_path
from bench.esso_osaka import parser as tuning_parser
from mmg_tuner.data.esso import FOLDS, RUN_KINDS as KINDS, runs_by_kind
from mmg_tuner.data.esso import split_runs as split
import numpy as np
import yaml

VERDICT_FOLDS = (0, 2)
SEEDS = [0, 1, 2]
RIVALS = ('published', 'tuned', 'network')
TIE = 1e-6   # relative: a residual dropped by its validation is the physics up to rounding
# options that must be today's defaults in every fold's summary (the registered models)
FIXED = ('dt', 'epochs', 'window', 'hidden', 'horizon', 'network_horizon', 'shrink', 'l2',
         'network_l2', 'max_seconds', 'integrator', 'berthing_weight', 'balance',
         'network_balance', 'select', 'skip', 'hybrid_base')


def held_out_names(fold: int) -> dict[str, str]:
    """Return {held-out run name: kind} of a fold, from the split rule alone (no reading)."""
    return {f.stem: kind for kind, files in runs_by_kind().items()
            for f in split(files, fold)[1]}


def load_fold(fold: int) -> dict | None:
    """
    Return a fold's summary, or None (with the commands to run) when it is missing.

    Exits with a message when the summary was written with options other than the registered
    defaults, other seeds, or another split.
    """
    path = out_dir(fold) / 'summary.yaml'
    if not path.is_file():
        print(f'fold {fold}: {path} missing; run: python -m bench run esso_osaka --fold {fold} && '
              f'python -m bench run esso_hybrid --fold {fold} --seeds 0 1 2')
        return None
    doc = yaml.safe_load(path.read_text())
    defaults = vars(parser().parse_args([]))
    opts = doc.get('options', {})
    bad = [k for k in FIXED if opts.get(k) != defaults[k]]
    if doc.get('seeds') != SEEDS or bad or opts.get('fold', 1) != fold:
        sys.exit(f'ERROR: {path}: not the registered run (seeds {doc.get("seeds")}, options '
                 f'differing from the defaults: {bad}, fold {opts.get("fold", 1)}); rerun: '
                 f'python -m bench run esso_hybrid --fold {fold} --seeds 0 1 2')
    check_tuned(path, doc, fold)
    want = held_out_names(fold)
    got = {n for n in doc['scores']['tuned'] if n != 'all'}
    if got != set(want):
        sys.exit(f'ERROR: {path}: held-out runs {sorted(got)} are not those of fold {fold}: '
                 f'{sorted(want)}')
    doc['kinds'] = want
    return doc


def check_tuned(path: Path, doc: dict, fold: int) -> None:
    """
    Exit unless the summary's physics is the fold's registered tuning, unchanged since.

    Its file must be the fold's default (``params_path``), its bytes those recorded in the
    summary, and its provenance the fold with bench/esso_osaka.py's default options.
    """
    rerun = (f'rerun: python -m bench run esso_osaka --fold {fold} && '
             'python -m bench run esso_hybrid '
             f'--fold {fold} --seeds 0 1 2')
    tuned = params_path(fold)
    if doc['options'].get('tuned') != str(tuned):
        sys.exit(f'ERROR: {path}: its tuned physics is {doc["options"].get("tuned")}, not the '
                 f"fold's {tuned}; {rerun}")
    if 'tuned_sha256' not in doc:
        sys.exit(f'ERROR: {path}: does not record the bytes of its tuned physics (written by '
                 f'an older bench/esso_hybrid.py); {rerun}')
    if not tuned.is_file() or (hashlib.sha256(tuned.read_bytes()).hexdigest()
                               != doc['tuned_sha256']):
        sys.exit(f'ERROR: {path}: {tuned} changed (or vanished) since the summary was written; '
                 f'{rerun}')
    prov = doc.get('tuned_provenance') or {}
    defaults = {k: v for k, v in vars(tuning_parser().parse_args([])).items()
                if k not in ('out', 'fold')}
    opts = prov.get('options', {})
    bad = [k for k, v in defaults.items() if opts.get(k) != v]
    if prov.get('fold', 1) != fold or bad:
        sys.exit(f'ERROR: {tuned}: not tuned as registered (fold {prov.get("fold", 1)}, '
                 f'options differing from the defaults: {bad}); {rerun}')


def run_index(scores: dict, model: str, run: str, seed: int | None = None) -> float:
    """Return a model's index on a run (seed-mean, or one seed's); inf when it failed."""
    v = scores[model][run]
    if seed is not None and len(v) > 1:
        v = [v[seed]]
    if any(a is None for a in v):
        return float('inf')
    return float(np.mean(v))


def by_kind(folds: dict, model: str, seed: int | None = None) -> dict[str, float]:
    """Return A_k(model) over the given folds' held-out runs, per kind."""
    out = {}
    for k in KINDS:
        vals = [run_index(d['scores'], model, r, seed) for d in folds.values()
                for r, kind in d['kinds'].items() if kind == k]
        out[k] = float(np.mean(vals)) if vals else float('nan')
    return out


def verdict(table: dict, model: str, rivals: tuple) -> tuple[bool, list[str]]:
    """Return (model below every rival on every kind, the kinds where it is not)."""
    lost = [k for k in KINDS if not all(table[model][k] < table[r][k] for r in rivals)]
    return not lost, lost


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_hybrid_cv`` (quick already: it only reads)."""
    return main(argv)


def main(argv: list[str] | None = None) -> dict:
    argparse.ArgumentParser(description=__doc__.strip().split('\n')[0]).parse_args(argv)
    folds = {f: load_fold(f) for f in FOLDS}
    missing = [f for f, d in folds.items() if d is None]
    for f, d in folds.items():
        if d is not None:
            n = {k: sum(1 for v in d['kinds'].values() if v == k) for k in KINDS}
            print(f'fold {f}: held out ' + ', '.join(f'{v} {k}' for k, v in n.items())
                  + ('  (known before registration: shown, not counted)' if f == 1 else ''))
    if any(f in missing for f in VERDICT_FOLDS):
        sys.exit('verdict folds incomplete: run the commands above first')
    models = ('published', 'tuned', 'network', 'hybrid', 'ensemble')
    counted = {f: folds[f] for f in VERDICT_FOLDS}
    table = {m: by_kind(counted, m) for m in models}
    print('\nA_k: mean eq. 26 index over the held-out runs of folds '
          f'{" and ".join(map(str, VERDICT_FOLDS))} (networks: mean over seeds {SEEDS})')
    print('| kind | runs | ' + ' | '.join(models) + ' |')
    print('|---|---|' + '---|' * len(models))
    rows = []
    for k in KINDS:
        n = sum(1 for d in counted.values() for v in d['kinds'].values() if v == k)
        rows.append({'kind': k, 'runs': n, **{m: table[m][k] for m in models}})
        best = min(models, key=lambda m: table[m][k])
        print(f'| {k} | {n} | ' + ' | '.join(
            f'**{table[m][k]:.4f}**' if m == best else f'{table[m][k]:.4f}' for m in models)
            + ' |')
    h1, lost1 = verdict(table, 'hybrid', RIVALS)
    h2, lost2 = verdict(table, 'ensemble', RIVALS)
    print('\nH1 (primary): the single hybrid below published, tuned and network on every kind: '
          + ('HOLDS' if h1 else f'FAILS (not best on: {", ".join(lost1)})'))
    print('H2 (secondary): the 3-seed ensemble below published, tuned and network on every '
          'kind: ' + ('HOLDS' if h2 else f'FAILS (not best on: {", ".join(lost2)})'))

    print('\nprinted, deciding nothing:')
    for k in KINDS:
        runs = [(d['scores'], r) for d in counted.values() for r, kind in d['kinds'].items()
                if kind == k]
        # a dropped residual (zero network) gives the physics' index up to rounding: a tie
        ratio = [run_index(s, 'hybrid', r) / run_index(s, 'tuned', r) for s, r in runs]
        wins = sum(q < 1 - TIE for q in ratio)
        ties = sum(abs(q - 1) <= TIE for q in ratio)
        per_seed = [by_kind(counted, 'hybrid', s)[k] for s in SEEDS]
        print(f'  {k}: hybrid (seed mean) below tuned on {wins} of {len(runs)} runs, equal on '
              f'{ties} (within {TIE:g} relative); A_k(hybrid) per seed '
              + ', '.join(f'{v:.4f}' for v in per_seed)
              + f' (std {np.std(per_seed):.4f})')
    if not missing:
        every = {m: by_kind(folds, m) for m in models}
        print('  A_k over all three folds: ' + '; '.join(
            f'{k} ' + ', '.join(f'{m} {every[m][k]:.4f}' for m in models) for k in KINDS))
    return {'A_k_folds_0_and_2': rows, 'H1_single_hybrid': 'holds' if h1 else 'fails',
            'H2_ensemble': 'holds' if h2 else 'fails'}


if __name__ == '__main__':
    main()
