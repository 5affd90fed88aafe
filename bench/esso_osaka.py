"""
Tune the low-speed model on the real Esso Osaka pond data and score it on held-out runs.

  python -m bench run esso_osaka [--max-evals 4000] [--segment 100] [--balance group]
                             [--prior 0.05] [--targets yaml|lowspeed] [--seed 0] [--fold 1]
                             [--out bench/out/esso_osaka/params.yaml]

Data: the 33 FRT-DS-ESSO runs in data/esso_osaka_frt (CC BY-NC-SA 4.0), read whole with
astern propeller and u <= 0 kept (the lowspeed family covers them), measured true wind driving
the model sample by sample.

Cuts (every run starts with a manually steered approach): turning and zigzag runs from 5 s
before the rudder is first put over (``cut_from_event(..., 'rudder_first_over', 5)``); random
and berthing runs are kept whole (their manoeuvre is the whole run; the rudder event is not
defined for them).

Split, a fixed rule chosen before any tuning and not changed since: within each kind the runs
are sorted by file name; the second and then every third (positions 1, 4, 7, ... counting from
0) are held out, the rest tune (held out: 4 turning, 2 zigzag, 3 random, 2 berthing). A
``turn_cut_X`` file is a trimmed copy of ``turn_X``: it is dropped when ``turn_X`` is present
(it would put the same data on both sides of the split). ``--fold 0`` or ``2`` holds out the
positions i with i mod 3 == 0 or 2 instead, for the cross-validation of
bench/esso_hybrid_cv.py (every run held out exactly once over the three folds).

Tuning: CMA-ES from the published values within the YAML's absolute boxes
(config/esso_osaka_3m.yaml ``tuning.bounds``) on the targets: ``lowspeed`` (default) = the
YAML's 12 default targets plus the turning hull terms X_vr, Y_r, N_v, C_rY, C_rN, the astern
thrust C_6, C_7 and the leading wind coefficients XX1, YY1, NN2 (why: the YAML); ``yaml`` =
the 12 alone. The objective matches the yardstick: the training runs cut into 100 s pieces,
each started from the measured state (tuning/segments.py; the index's restarts), squared errors
of x, y, psi, u, v, r each divided by its standard deviation pooled over the training runs;
each kind of run weighs the same (``--balance group``; 'trial': each run, 'sample': each
sample, the old objective), plus a prior pulling each target toward its published value
(``--prior`` W: W x samples x ((theta - published) / box width)^2), at the recorded 10 Hz
(``--dt`` resamples, e.g. 1.0 to subsample to 1 Hz).

Evaluation: ``mmg_tuner.evaluate`` on the held-out runs together (sigma pooled over them),
RK4 at 10 Hz, restart every 100 s, for the published and the tuned parameters.

Output: the tuned parameters, written atomically to ``--out`` (default
bench/out/esso_osaka/params.yaml; bench/esso_hybrid.py reads it), with a ``provenance`` key:
the options and a SHA-256 fingerprint of the inputs (the ship config and every run file), so a
reader can refuse parameters tuned on other data (:func:`check_provenance`).
"""
from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
import sys
import time

import mmg_tuner as mt
from mmg_tuner._atomic import write_atomic
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.data.esso import FOLDS, load_split, runs_by_kind  # noqa: F401 (esso_hybrid_cv)
from mmg_tuner.data.esso import read_run as read, RUN_KINDS as KINDS  # noqa: F401
from mmg_tuner.data.esso import split_runs as split  # noqa: F401
from mmg_tuner.tuning.evaluate import pooled_sigma
from mmg_tuner.tuning.factory import make_objective, ObjectiveSpec
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.report import params_yaml_text
from mmg_tuner.tuning.tuner import Tuner
import numpy as np
import yaml

RESTART_S = 100.0
LOWSPEED_EXTRA = ('X_vr', 'Y_r', 'N_v', 'C_rY', 'C_rN', 'C_6', 'C_7', 'XX1', 'YY1', 'NN2')
PARAMS_OUT = Path(__file__).resolve().parent / 'out' / 'esso_osaka' / 'params.yaml'
PARAMS_COMMAND = 'python -m bench run esso_osaka'
LEGACY_COMMAND = 'python bench/esso_osaka.py'   # params files written before bench/ was a package


def params_path(fold: int | None) -> Path:
    """Return the default params file of a fold (fold 1: PARAMS_OUT; None: params_all)."""
    if fold is None:
        return PARAMS_OUT.with_name('params_all.yaml')
    return PARAMS_OUT if fold == 1 else PARAMS_OUT.with_name(f'params_fold{fold}.yaml')


def fail(message: str) -> None:
    """Print ``ERROR: message`` to stderr and exit 2 (as the CLIs do)."""
    print(f'ERROR: {message}', file=sys.stderr)
    sys.exit(2)


def inputs_fingerprint(ship_source: str | Path) -> str:
    """
    Return the SHA-256 (hex) of the tuning's inputs: the ship config and every run file.

    Names (kind/file) and bytes, in the split's order, so adding, removing, renaming or
    editing a run or the config changes it.
    """
    h = hashlib.sha256()
    h.update(Path(ship_source).read_bytes())
    for kind, files in runs_by_kind().items():
        for f in files:
            h.update(f'{kind}/{f.name}\0'.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def check_provenance(path: Path, ship_source: str | Path, fold: int | None = 1) -> dict:
    """
    Return the ``provenance`` of a params.yaml this script wrote, if its inputs are today's.

    Exits with a message naming the file and the command to rebuild it when the file is
    missing, was not written by this script, or was tuned on other inputs (a changed ship
    config or run file): tuned parameters are never reused silently.
    """
    redo = (f'produce it with: {PARAMS_COMMAND}'
            + (f' --fold {"none" if fold is None else fold}' if fold != 1 else '')
            + f' --out {path}')
    if not path.is_file():
        fail(f'tuned params file {path} does not exist; {redo}')
    doc = yaml.safe_load(path.read_text())
    prov = doc.get('provenance') if isinstance(doc, dict) else None
    if not isinstance(prov, dict) or 'inputs_sha256' not in prov:
        fail(f'{path} has no provenance.inputs_sha256 (not written by '
             f'{PARAMS_COMMAND}); {redo}')
    now = inputs_fingerprint(ship_source)
    if prov['inputs_sha256'] != now:
        fail(f'{path} was tuned on other inputs (provenance.inputs_sha256 '
             f'{prov["inputs_sha256"][:12]}..., the ship config and runs now give '
             f'{now[:12]}...); {redo}')
    return prov


def _fold(text: str) -> int | None:
    """Parse --fold: 0, 1, 2 or none."""
    if text == 'none':
        return None
    if text not in ('0', '1', '2'):
        raise argparse.ArgumentTypeError(f'{text!r}: give 0, 1, 2 or none')
    return int(text)


def parser() -> argparse.ArgumentParser:
    """Return the command line of this bench (its defaults are the registered tuning)."""
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--max-evals', type=int, default=4000,
                    help='CMA-ES budget (0: no CMA-ES, the polish alone from the published '
                    'values)')
    ap.add_argument('--polish', type=int, default=0,
                    help='then a local least-squares polish of at most this many simulations '
                    '(0: none)')
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='rk4')
    ap.add_argument('--dt', type=float, default=None, help='resample the tuning runs [s]')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--segment', type=float, default=RESTART_S,
                    help='tune on pieces of this length [s] (0: whole runs)')
    ap.add_argument('--balance', choices=('sample', 'trial', 'group'), default='group')
    ap.add_argument('--prior', type=float, default=0.05,
                    help='pull toward the published values (0: none)')
    ap.add_argument('--targets', choices=('yaml', 'lowspeed'), default='lowspeed')
    ap.add_argument('--fold', type=_fold, default=1,
                    help='hold out the runs at positions i mod 3 == FOLD of each kind (1: the '
                    'split of every table; 0 and 2: the cross-validation folds; none: hold '
                    'out nothing, tune on all 33: bench/esso_fresh.py)')
    ap.add_argument('--out', type=Path, default=None,
                    help='write the tuned params.yaml here (atomically; a previous output of '
                    'this script is replaced, any other file refused; default '
                    'bench/out/esso_osaka/params.yaml, params_foldF.yaml for fold 0 or 2)')
    return ap


def benchmark(quick: bool, argv: list[str]) -> dict:
    """
    Entry point of ``python -m bench run esso_osaka``.

    ``--quick``: 200 evaluations, written to params_quick.yaml (never over the params file
    that bench/esso_hybrid.py reads).
    """
    quick_args = ['--max-evals', '200', '--out', str(PARAMS_OUT.with_name('params_quick.yaml'))]
    return main((quick_args if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    args = parser().parse_args(argv)
    if args.out is None:
        args.out = params_path(args.fold)
    if args.out.is_dir():
        fail(f'--out {args.out} is a folder; give a file name (e.g. params.yaml)')
    written_here = any(f'command: {c}' in args.out.read_text()
                       for c in (PARAMS_COMMAND, LEGACY_COMMAND)) if args.out.exists() else True
    if not written_here:
        fail(f'--out {args.out} exists and was not written by {PARAMS_COMMAND}: '
             'not overwriting it; give another file')
    t_all = time.perf_counter()
    ship = mt.load_ship('esso_osaka_3m')
    train, test, kind_of = load_split(args.fold)
    print(f'fold {args.fold}: training runs: {len(train)} '
          f'({sum(t.duration_s for t in train):.0f} s), held out: '
          f'{len(test)} ({sum(t.duration_s for t in test):.0f} s)')
    for kind in KINDS:
        print(f'  {kind:9s} held out: '
              + ', '.join(t.name for t in test if kind_of[t.name] == kind))

    tune_runs = train if args.dt is None else [t.resampled(args.dt) for t in train]
    sig = pooled_sigma(train)
    weights = np.array([1.0 / sig[n] ** 2 for n in STATE_NAMES])
    substeps = max(1, int(round(tune_runs[0].dt / 0.1)))
    targets = (ship.tuning_targets + LOWSPEED_EXTRA if args.targets == 'lowspeed'
               else ship.tuning_targets)
    space = ParameterSpace.around(ship, targets)
    spec = ObjectiveSpec(tuple(weights), 0.0 if args.segment else RESTART_S, args.integrator,
                         substeps, args.segment, args.balance, args.prior, kind_of,
                         x0_window_s=0.0)
    obj = make_objective(ship, tune_runs, spec, space)
    batch = obj.batch
    segs = batch.names
    n_samples = int(batch.lengths.sum()) - len(segs)
    t0 = time.perf_counter()
    J0 = float(obj(ship.params[None])[0])
    t_eval = time.perf_counter() - t0
    print(f'objective: {len(tune_runs)} runs in {len(segs)} pieces of {args.segment:g} s, '
          f'{n_samples} samples at dt {batch.dt:g} s ({substeps} {args.integrator} '
          f'substep(s)), balance {args.balance}, prior {args.prior:g}, {space.dim} targets; '
          f'{t_eval * 1e3:.0f} ms per evaluation; training objective per sample, published '
          f'{J0 / n_samples:.4f}')
    t_tune = time.perf_counter()
    theta, evals, restarts = space.pre.copy(), 0, 0
    if args.max_evals > 0:
        res = Tuner(space, obj, popsize=12, max_popsize=48, max_evaluations=args.max_evals,
                    seed=args.seed).run()
        theta, evals, restarts = res.theta, res.evaluations, res.restarts
        print(f'CMA-ES: {evals} evaluations, {restarts} restart(s), '
              f'{time.perf_counter() - t_tune:.0f} s; J per sample {res.J / n_samples:.4f}')
    if args.polish > 0:   # local least squares on the same objective's residual vector
        t_pol = time.perf_counter()
        loc = local_least_squares(space, obj, theta, args.polish, method='lm')
        theta = loc.theta
        evals += loc.simulations
        print(f'least-squares polish: {loc.simulations} simulations, '
              f'{time.perf_counter() - t_pol:.0f} s; J per sample {loc.J / n_samples:.4f}')
    J_end = float(obj(space.full_params(ship.params, theta[None]))[0])
    tune_s = time.perf_counter() - t_tune
    values = dict(zip(space.names, map(float, theta)))
    tuned = ship.with_params(values)
    how = ' + '.join(x for x, on in (('CMA-ES', args.max_evals > 0),
                                     ('least squares', args.polish > 0)) if on)
    text = params_yaml_text(ship, values, f'{PARAMS_COMMAND}: {how}, {evals} evaluations')
    prov = {'command': PARAMS_COMMAND, 'options': {k: (str(v) if isinstance(v, Path) else v)
                                                   for k, v in vars(args).items()},
            'evaluations': int(evals), 'training_runs': [t.name for t in train],
            'held_out_runs': [t.name for t in test], 'fold': args.fold,
            'inputs_sha256': inputs_fingerprint(ship.source)}
    write_atomic(args.out, text + yaml.safe_dump({'provenance': prov}, sort_keys=False))
    # simulations x one simulation's cost is the figure to compare across machines and loads
    per_sim_ms = tune_s / max(evals, 1) * 1e3
    print(f'tuning: {evals} evaluations ({how}), {tune_s:.0f} s wall ({per_sim_ms:.0f} '
          f'ms per simulation; one objective evaluation {t_eval * 1e3:.0f} ms); training '
          f'objective per sample {J0 / n_samples:.4f} -> {J_end / n_samples:.4f}')
    print('| parameter | published | tuned | box |')
    print('|---|---|---|---|')
    for n, v, lo, hi in zip(space.names, theta, space.lower, space.upper):
        flag = ' (on bound)' if n in space.on_bound(theta) else ''
        print(f'| {n} | {ship[n]:.4g} | {v:.4g}{flag} | [{lo:g}, {hi:g}] |')

    if not test:   # --fold none: nothing held out to score
        print(f'tuned parameters: {args.out}')
        print(f'wall time: {time.perf_counter() - t_all:.0f} s')
        return {'fold': args.fold, 'evaluations': int(evals), 'tuning_s': tune_s,
                'on_bound': space.on_bound(theta), 'wall_s': time.perf_counter() - t_all}
    pub = mt.evaluate(ship, test, restart_every_s=RESTART_S, integrator='rk4')
    tun = mt.evaluate(tuned, test, restart_every_s=RESTART_S, integrator='rk4')
    print(f'\nheld-out runs (index: Wakita et al. 2022 eq. 26, sigma pooled over the {len(test)} '
          f'held-out runs, RK4 0.1 s, restart every {RESTART_S:g} s)')
    print('| kind | run | duration [s] | published | tuned | change |')
    print('|---|---|---|---|---|---|')
    better = {k: [] for k in KINDS}
    rows = []
    for tr in test:
        a, b = pub.trials[tr.name].index, tun.trials[tr.name].index
        kind = kind_of[tr.name]
        ch = 'n/a' if a is None or b is None else f'{100 * (b - a) / a:+.0f} %'
        better[kind].append(a is not None and b is not None and b < a)
        fa = 'failed' if a is None else f'{a:.4f}'
        fb = 'failed' if b is None else f'{b:.4f}'
        print(f'| {kind} | {tr.name} | {tr.duration_s:.0f} | {fa} | {fb} | {ch} |')
        rows.append({'kind': kind, 'run': tr.name, 'duration_s': tr.duration_s,
                     'published': a, 'tuned': b, 'change': ch})
    ch = 100 * (tun.index_all - pub.index_all) / pub.index_all
    print(f'| all | together | {sum(t.duration_s for t in test):.0f} | {pub.index_all:.4f} | '
          f'{tun.index_all:.4f} | {ch:+.0f} % |')
    for kind in KINDS:
        print(f'{kind}: tuned better on {sum(better[kind])} of {len(better[kind])} held-out runs')
    print(f'tuned parameters: {args.out}')
    wall = time.perf_counter() - t_all
    print(f'wall time: {wall:.0f} s')
    rows.append({'kind': 'all', 'run': 'together',
                 'duration_s': sum(t.duration_s for t in test), 'published': pub.index_all,
                 'tuned': tun.index_all, 'change': f'{ch:+.0f} %'})
    return {'fold': args.fold, 'evaluations': int(evals), 'tuning_s': tune_s,
            'on_bound': space.on_bound(theta), 'wall_s': wall,
            'held_out_index': rows,
            'tuned_better': {k: f'{sum(v)} of {len(v)}' for k, v in better.items()}}


if __name__ == '__main__':
    main()
