"""
The plain ``tune`` on the 33 pond runs: its prior chosen by leaving days out, and checked.

    python -m bench run esso_prior_cv [--quick]

Registered in bench/esso_prior_cv_preregistration.md (with its amendment). Runs the user's
command, ``tune data/esso_osaka_frt --ship esso_osaka_3m`` (the YAML's recipe: 22 targets,
weights 1 / sigma^2, 100 s pieces, kinds balanced, least-squares polish, prior chosen among
``prior_choices`` by ``tuning/prior_cv.py``), prints the days-out table and the choice, then
the registered checks with the chosen weight:

* C1: the three position folds of ``bench/esso_osaka.py`` (``data.esso.split_runs``): the
  command on each fold's training files with ``--prior`` the chosen weight, both models scored
  on the fold's held-out runs; mean index per kind (sigma pooled per fold).
* C2: the seven fresh runs of data/esso_osaka_frt_extra, published and tuned, mean index per
  kind (sigma pooled over the seven).

Runs are read whole, as the command reads them, and scored as the issue scores the withheld
eight: ``mt.evaluate``, RK4 at the recorded 10 Hz, restart every 100 s. ``--quick``: the
days-out table on the zigzag and random runs alone, polish 40 (a check that it runs).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import tempfile
import time

import mmg_tuner as mt
from mmg_tuner.cli.tune import command as tune
from mmg_tuner.data.esso import runs_by_kind, split_runs
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PONDS = ROOT / 'data' / 'esso_osaka_frt'
FRESH = ROOT / 'data' / 'esso_osaka_frt_extra'
SHIP = 'esso_osaka_3m'


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run esso_prior_cv``."""
    return main((['--quick'] if quick else []) + argv)


def _run_tune(paths: list[Path], out: Path, extra: list[str]) -> dict:
    """Run the user's command; return its report.json (exit 3, nothing changed, is a result)."""
    rc = tune([str(p) for p in paths] + ['--ship', SHIP, '--out', str(out), '--no-plots',
                                         '--quiet'] + extra)
    if rc not in (0, 3):
        raise SystemExit(f'tune exited {rc}')
    return json.loads((out / 'report.json').read_text())


def index_by_kind(model: object, runs: list, kind_of: dict[str, str]) -> dict[str, float]:
    """Mean eq. 26 index per kind over ``runs`` (sigma pooled over them; failed: inf)."""
    ev = mt.evaluate(model, runs, restart_every_s=100.0, integrator='rk4')
    out: dict[str, list[float]] = {}
    for t in runs:
        idx = ev.trials[t.name].index
        out.setdefault(kind_of[t.name], []).append(np.inf if idx is None else idx)
    return {k: float(np.mean(v)) for k, v in out.items()}


def _load(files: list[Path], ship: object) -> tuple[list, dict[str, str]]:
    """Read the files; each run's kind is its folder's name."""
    runs, kind_of = [], {}
    for f in files:
        for t in mt.load_trials([str(f)], ship=ship):
            runs.append(t)
            kind_of[t.name] = f.parent.name
    return runs, kind_of


def _cell(x: float | None, r: float | None) -> str:
    return 'failed' if x is None else f'{x:.3f} ({r:.2f})'


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(prog='python -m bench run esso_prior_cv')
    ap.add_argument('--quick', action='store_true')
    args = ap.parse_args(argv)
    ship = mt.load_ship(SHIP)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        if args.quick:
            paths = [PONDS / 'zigzag', PONDS / 'random']
            rep = _run_tune(paths, Path(tmp) / 'all', ['--polish', '40'])
        else:
            rep = _run_tune([PONDS], Path(tmp) / 'all', [])
        tune_s = time.perf_counter() - t0
        pc = rep['prior_choice']
        print(f'tune (the recipe, prior chosen by leaving days out): {tune_s:.0f} s wall; '
              f"chosen: {pc['chosen']}")
        kinds = sorted(next(iter(pc['index_by_kind'].values())))
        print('| candidate | ' + ' | '.join(kinds) + ' | worst ratio |')
        print('|---|' + '---|' * (len(kinds) + 1))
        for c, v in pc['index_by_kind'].items():
            score = pc['score'][c]
            print(f'| {c} | ' + ' | '.join(
                _cell(v[k], pc['ratio_to_published'][c][k]) for k in kinds)
                + f" | {'inf' if score is None else f'{score:.3f}'} |")
        figures: dict = {'tune_wall_s': tune_s, 'prior_choice': pc, 'quick': args.quick}
        if args.quick:
            return figures
        prior = pc['prior']
        tuned = ship.with_params({n: v['tuned'] for n, v in rep['params'].items()})
        # C1: the position folds, the chosen weight given
        files = runs_by_kind(PONDS)
        c1: dict[str, dict[str, list[float]]] = {}
        for fold in (0, 1, 2):
            train, test = [], []
            for fs in files.values():
                a, b = split_runs(fs, fold)
                train += a
                test += b
            runs, kind_of = _load(test, ship)
            model = ship
            if prior is not None:
                r = _run_tune(train, Path(tmp) / f'fold{fold}', ['--prior', f'{prior:g}'])
                model = ship.with_params({n: v['tuned'] for n, v in r['params'].items()})
            for name, m in (('published', ship), ('tuned', model)):
                for k, x in index_by_kind(m, runs, kind_of).items():
                    c1.setdefault(k, {}).setdefault(name, []).append(x)
    c1_mean = {k: {m: float(np.mean(x)) for m, x in v.items()} for k, v in c1.items()}
    fresh_files = sorted(FRESH.glob('*/*.csv'))
    runs, kind_of = _load(fresh_files, ship)
    c2 = {name: index_by_kind(m, runs, kind_of)
          for name, m in (('published', ship), ('tuned', tuned))}
    print('\nC1, three position folds (mean over folds of the mean index per kind), '
          'published -> tuned:')
    for k, v in c1_mean.items():
        print(f"  {k}: {v['published']:.3f} -> {v['tuned']:.3f}")
    print('C2, the seven fresh runs, published -> tuned:')
    for k in c2['published']:
        print(f"  {k}: {c2['published'][k]:.3f} -> {c2['tuned'][k]:.3f}")
    c1_pass = all(v['tuned'] < v['published'] for v in c1_mean.values())
    c2_pass = all(c2['tuned'][k] < c2['published'][k] for k in c2['published'])
    print(f"C1 {'pass' if c1_pass else 'fail'}; C2 {'pass' if c2_pass else 'fail'}")
    print(f'wall time: {time.perf_counter() - t0:.0f} s')
    figures.update({'C1_index_by_kind': c1_mean, 'C2_index_by_kind': c2,
                    'verdicts': {'C1': 'pass' if c1_pass else 'fail',
                                 'C2': 'pass' if c2_pass else 'fail'}})
    return figures


if __name__ == '__main__':
    main()
