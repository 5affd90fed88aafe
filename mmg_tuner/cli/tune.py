"""
``tune``: fine-tune MMG parameters on recorded trials with CMA-ES (Suyama et al. 2023).

Examples
--------
tune trials/turning_p10 trials/turning_m20 --test trials/turning_m10 --ship suzaku --out tuned
tune --resume tuned        # continue an interrupted run (from any working directory)
tune twin/*.csv --ship qiuxin_tug --bollard-pull bollard.csv --method lo-go --out id

A control-oriented family (surge_decoupled, simplified6, surge_decoupled_rudder) is identified
local -> global (MBPE-LOGO: thrust polynomial from the bollard pull, azimuth dynamics, LO least
squares, GO simulation fit; ``tuning/lo_go.py``) unless --method cmaes asks for CMA-ES.

"""
from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
from pathlib import Path
import signal
import sys
from types import FrameType
from typing import Any, cast, Iterator, NoReturn, Sequence, TYPE_CHECKING

from mmg_tuner import api
from mmg_tuner._limits import load_json
from mmg_tuner._outdir import OutputDir
from mmg_tuner.cli.args import (add_reading_options, add_writing_options, bounded, nonneg_float,
                                nonneg_int, positive_float, positive_int)
from mmg_tuner.cli.common import Parser, progress_bar, run_command, SEED, UsageError
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, MmgTunerError
from mmg_tuner.tuning.lo_go import GO_RIDGE, METHODS
from mmg_tuner.tuning.report import fmt_gain, fmt_J
from mmg_tuner.tuning.tuner import Progress

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.api.tuning import ResidualResult
    from mmg_tuner.tuning.nstep import RelativeErrors

ARGS_FILE = 'args.json'
CHECKPOINT = 'checkpoint.npz'
# what older versions wrote: pickles, which run code when loaded, so never loaded
LEGACY_CHECKPOINTS = ('checkpoint.pkl', 'checkpoint.pkl.base')
ARGS_VERSION = 2
DT = bounded(float, 1e-3, 600.0, 'resampling step dt [s]')
SUBSTEPS = bounded(int, 1, 1000, 'number of substeps')
POPSIZE = bounded(int, 2, 100_000, 'population size')


def bound_spec(s: str) -> tuple[str, float | tuple[float, float]]:
    """NAME=AR (a finite a_r > 0) or NAME=LO:HI (finite, LO < HI)."""
    name, eq, val = s.partition('=')
    if not eq or not name.strip():
        raise argparse.ArgumentTypeError(f'{s!r}: expected NAME=AR or NAME=LO:HI')
    try:
        if ':' in val:
            lo, hi = (float(x) for x in val.split(':'))
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError
            return name.strip(), (lo, hi)
        ar = float(val)
        if not (math.isfinite(ar) and ar > 0):
            raise ValueError
        return name.strip(), ar
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'{s!r}: expected NAME=AR with a finite AR > 0, or NAME=LO:HI with finite '
            'LO < HI') from None


def weights_option(words: list[float] | str | None) -> tuple[float, ...] | str | None:
    """Return --weights / --index-weights (or a recipe's ``weights``) as TuneConfig takes it."""
    return words if words is None or isinstance(words, str) else tuple(map(float, words))


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='tune', description=__doc__.strip().split('\n')[0])
    ap.add_argument('trials', nargs='*', help='tuning trials: bags, .mcap, .csv, .dat, folders')
    ap.add_argument('--test', nargs='*', default=[], help='held-out test trials')
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay as the pre-determined values')
    ap.add_argument('--out', help='output directory (new or empty)')
    ap.add_argument('--resume', metavar='DIR', help='continue the interrupted run in DIR')
    ap.add_argument('--targets', nargs='+', help="parameters to tune (default: the ship's)")
    ap.add_argument('--ar', type=positive_float,
                    help='relative box half-width a_r (default: ship, 0.5)')
    ap.add_argument('--bound', action='append', default=[], type=bound_spec,
                    metavar='NAME=AR|NAME=LO:HI',
                    help='per-parameter a_r or explicit bounds (repeatable)')
    ap.add_argument('--weights', nargs=6, type=nonneg_float,
                    metavar=('X', 'Y', 'PSI', 'U', 'V', 'R'),
                    help="error weights, >= 0, not all 0 (default: the paper's L_pp, L_pp, "
                    'pi/4, 0, 0, 0)')
    ap.add_argument('--index-weights', dest='weights', action='store_const',
                    const=api.INDEX_WEIGHTS,
                    help='weigh each state by 1 / sigma^2 pooled over the tuning trials (the '
                    "index's standardisation) instead of --weights (a recipe: weights: index)")
    ap.add_argument('--shoot-every', type=nonneg_float, default=0.0,
                    help='restart the simulation from the recorded state every H s (0: never)')
    ap.add_argument('--segment', type=nonneg_float, default=0.0, metavar='S',
                    help='tune on pieces of S s, each started from the recorded state '
                    '(multiple shooting at the data level; 0: whole trials)')
    ap.add_argument('--balance', choices=('sample', 'trial', 'group'), default='sample',
                    help="'trial': every tuning trial weighs the same, whatever its length; "
                    "'group': every kind of run (the trials' folders) weighs the same")
    ap.add_argument('--prior', type=nonneg_float, default=0.0, metavar='W',
                    help='pull toward the pre-determined values: W x J per sample per squared '
                    'box width (0: none)')
    ap.add_argument('--prior-choices', type=nonneg_float, nargs='+', default=None, metavar='W',
                    help='choose the --prior from these weights by leaving days out: each '
                    'session (the date in the trial names) held out once, the published values '
                    "always a candidate; the report shows the table (a ship's tuning.recipe may "
                    'set it; --prior given wins)')
    add_reading_options(ap, DT, 'resample every trial to this step [s]')
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='euler')
    ap.add_argument('--substeps', type=SUBSTEPS, default=1)
    ap.add_argument('--popsize', type=POPSIZE, default=12)
    ap.add_argument('--max-popsize', type=POPSIZE, default=128)
    ap.add_argument('--max-evals', type=nonneg_int, default=200_000,
                    help='CMA-ES budget (0: none, the --polish alone from the pre-determined '
                    'values)')
    ap.add_argument('--seed', type=SEED, default=0)
    res = ap.add_mutually_exclusive_group()
    res.add_argument('--residual', action='store_true',
                     help='after tuning, train a neural residual on the accelerations (the '
                     'hybrid model; needs jax, equinox, optax); params.yaml names its weights')
    res.add_argument('--residual-only', action='store_true',
                     help='no physics tuning: train the pure network (Wakita et al. 2022 '
                     'Type-1), for comparison')
    ap.add_argument('--residual-epochs', type=positive_int, metavar='N',
                    help='residual: most epochs (default 200; early stopping decides)')
    ap.add_argument('--residual-window', type=positive_int, metavar='N',
                    help='residual: samples of history the network sees (default 5)')
    ap.add_argument('--residual-hidden', type=positive_int, nargs='+', metavar='N',
                    help='residual: hidden layer sizes (default 32 32)')
    ap.add_argument('--residual-horizon', type=positive_float, metavar='S',
                    help='residual: length of each simulated training window [s] (default 10)')
    ap.add_argument('--residual-max-seconds', type=positive_float, metavar='S',
                    help='residual: stop training after this wall time [s]')
    ap.add_argument('--residual-physics-input', action='store_true', default=None,
                    help="residual: the network also reads the physics' accelerations at each "
                    'sample (the prediction it corrects)')
    ap.add_argument('--residual-seeds', type=bounded(int, 1, 32, 'residual seeds'), metavar='N',
                    help='residual: train N networks (seeds --seed, --seed + 1, ...) and keep '
                    'their mean, one exact ensemble (default 1; N times the training time)')
    ap.add_argument('--model', choices=api.MODEL_CHOICES, default='physics',
                    help='auto: also train the pure network and the hybrid (when JAX is '
                    'installed and the trials allow it), compare them with the tuned physics '
                    'on the last quarter of each trial per kind of run (the folder of the trial) '
                    'and write the recommended one (report.md: the table); with '
                    '--residual-seeds N >= 2 it carries a calibrated 90 %% interval')
    ap.add_argument('--joint', action='store_true',
                    help='with --model auto: a fifth candidate, the trained hybrid trained on '
                    'together with the tuned coefficients (kept only if it beats the hybrid)')
    ap.add_argument('--polish', type=nonneg_int, default=0, metavar='N',
                    help='after CMA-ES, a local least-squares polish of at most N simulations '
                    '(0: none)')
    lg = ap.add_argument_group('local -> global identification (control-oriented families)')
    lg.add_argument('--method', choices=('cmaes',) + METHODS,
                    help="'lo': one linear least-squares problem on measured accelerations; "
                    "'go': simulation fit from the ship's values; 'lo-go': GO from LO, pulled "
                    "toward it; 'cmaes': the CMA-ES tuning (default: lo-go for a "
                    'control-oriented family, cmaes otherwise)')
    lg.add_argument('--bollard-pull', metavar='FILE.csv',
                    help='bollard-pull table, columns n,thrust (rev/s, N per thruster): the '
                    'thrust polynomial is fitted to it first')
    lg.add_argument('--thrust-degree', type=bounded(int, 1, 5, 'thrust degree'),
                    help='degree of the thrust polynomial (default: by leave-one-out error)')
    lg.add_argument('--smooth', type=nonneg_float, default=2.0, metavar='S',
                    help='LO: Savitzky-Golay window on the velocities [s] (0: none)')
    lg.add_argument('--ridge', type=nonneg_float, default=GO_RIDGE,
                    help='GO: pull toward its start (LO, the ship) per squared relative change '
                         f'(default {GO_RIDGE:g})')
    lg.add_argument('--go-segment', type=nonneg_float, default=20.0, metavar='S',
                    help='GO: simulate pieces of S s from the measured state (0: whole trials)')
    lg.add_argument('--go-iter', type=positive_int, default=40, metavar='N',
                    help='GO: most Levenberg-Marquardt iterations')
    lg.add_argument('--grow', action='store_true',
                    help="GO: add the trials one by one (the paper's Algorithm 1)")
    add_writing_options(ap, 'no progress bar or progress messages')
    return ap


def trial_kinds(trials: Sequence[Trial]) -> dict[str, str] | None:
    """
    Return trial name -> kind of run: the name of the folder each trial was read from.

    None when the trials come from one folder (each trial is then its own kind).
    """
    kinds = {t.name: Path(str(t.source).split('#')[0]).parent.name for t in trials if t.source}
    return kinds if len(set(kinds.values())) > 1 and len(kinds) == len(trials) else None


# ----------------------------------------------------------------- shared with ``diagnose``
PATH_LISTS = ('trials', 'test')
PATH_OPTS = ('params', 'topics', 'out')


def absolute_paths(opts: dict[str, Any]) -> dict[str, Any]:
    """
    Option values with every path made absolute (a resume may run from another folder).

    --ship stays a name unless it names an existing file.
    """
    o = dict(opts)
    for k in PATH_LISTS:
        if o.get(k):
            o[k] = [str(Path(p).absolute()) for p in o[k]]
    for k in PATH_OPTS:
        if o.get(k):
            o[k] = str(Path(o[k]).absolute())
    ship = o.get('ship')
    if ship and (Path(ship).is_file() or Path(ship).suffix in ('.yaml', '.yml')):
        o['ship'] = str(Path(ship).absolute())
    return o


def explicit_options(parser: argparse.ArgumentParser, argv: list[str] | None) -> dict[str, Any]:
    """Return the options actually given on the command line (not defaults)."""
    quiet = Parser(prog=parser.prog, add_help=False)
    for a in parser._actions:
        if a.dest == 'help':
            continue
        kw: dict[str, Any] = {'dest': a.dest, 'default': argparse.SUPPRESS}
        # (argparse takes type=None, no conversion, which typeshed's add_argument does not)
        conv: Any = a.type
        if isinstance(a, argparse._StoreTrueAction):
            quiet.add_argument(*a.option_strings, action='store_true', **kw)
        elif isinstance(a, argparse._StoreConstAction):   # diagnose --residual/--no-residual
            quiet.add_argument(*a.option_strings, action='store_const', const=a.const, **kw)
        elif isinstance(a, argparse._AppendAction):
            quiet.add_argument(*a.option_strings, action='append', type=conv, **kw)
        elif a.option_strings:
            quiet.add_argument(*a.option_strings, nargs=a.nargs, type=conv,
                               choices=a.choices, **kw)
        else:
            quiet.add_argument(a.dest, nargs=a.nargs, type=conv, default=argparse.SUPPRESS)
    given = vars(quiet.parse_args(argv))
    return {k: v for k, v in given.items() if not (k in PATH_LISTS and v == [])}


def option_name(parser: argparse.ArgumentParser, dest: str) -> str:
    for a in parser._actions:
        if a.dest == dest:
            return a.option_strings[0] if a.option_strings else dest
    return dest


def parse_or_resume(parser: argparse.ArgumentParser, argv: list[str] | None, command: str,
                    what: str) -> tuple[argparse.Namespace, list[str], bool]:
    """
    Parse argv, or with --resume DIR read the stored run's options.

    Parse argv; with --resume DIR the stored run's options (and notes on what was applied or
    refused), else require trials and --out. Returns (args, notes, resume).
    """
    args = parser.parse_args(argv)
    if args.resume:
        args, notes = resumed_args(parser, argv, command, ('quiet', 'no_plots'))
        return args, notes, True
    if not args.trials or not args.out:
        raise UsageError(f'give {what} and --out DIR (or --resume DIR)')
    return args, [], False


def resumed_args(parser: argparse.ArgumentParser, argv: list[str] | None, command: str,
                 applicable: tuple[str, ...]) -> tuple[argparse.Namespace, list[str]]:
    """
    Return the stored options of the run in --resume DIR.

    Options given with --resume must equal the stored ones, except ``applicable`` ones (which
    cannot change the result so far), which are applied. Returns (options, messages about what was
    applied).
    """
    given = explicit_options(parser, argv)
    out = Path(given.pop('resume'))
    saved = out / ARGS_FILE
    if not out.is_dir():
        raise UsageError(f'--resume {out}: no such folder')
    if not saved.is_file():
        raise UsageError(f'--resume {out}: nothing to resume (no {ARGS_FILE}; is it a '
                         f'{command} output folder?)')
    for name in LEGACY_CHECKPOINTS:   # refused before anything is read or run
        if (out / name).exists():
            raise UsageError(f'--resume {out}: {out / name} is a checkpoint in the old pickle '
                             'format; it is never loaded, because unpickling a file runs '
                             'whatever code it holds (and a folder may come from someone '
                             f'else): re-run without --resume, with --out in a new folder')
    try:   # a handed-over folder: size and depth checked before parsing
        doc = load_json(saved, ARGS_FILE, limit=1 << 20)
    except ConfigError as exc:
        raise UsageError(f'--resume {out}: {exc}') from None
    if isinstance(doc, list):  # version 1: the raw argv (paths relative to where it ran)
        stored = vars(parser.parse_args(doc))
    elif isinstance(doc, dict) and doc.get('command') == command and 'options' in doc:
        stored = {**vars(parser.parse_args([])), **doc['options']}
        stored['bound'] = [tuple(b) if isinstance(b, list) else b
                           for b in stored.get('bound', [])]
        stored['bound'] = [(n, tuple(v) if isinstance(v, list) else v)
                           for n, v in stored['bound']]
    else:
        raise UsageError(f'--resume {out}: {saved} is not a {command} run')
    stored['resume'] = str(out)
    stored['out'] = str(out)
    notes = []
    given = absolute_paths(given)
    for k, v in given.items():
        if k == 'out' and Path(v) == out.absolute():
            continue
        cur = stored.get(k)
        if k == 'bound':
            v = [(n, tuple(x) if isinstance(x, list) else x) for n, x in v]
        if k in applicable:
            if v != cur:
                notes.append(f'{option_name(parser, k)} {v} applied (the run had {cur})')
            stored[k] = v
        elif v != cur:
            raise UsageError(
                f'--resume {out}: {option_name(parser, k)} {v} differs from the stored run '
                f'({cur}); a resumed run keeps its options (only '
                f'{", ".join(option_name(parser, a) for a in applicable)} can change): start a '
                'new run with another --out to change it')
    return argparse.Namespace(**stored), notes


def store_args(out: OutputDir, command: str, args: argparse.Namespace) -> None:
    opts = absolute_paths({k: v for k, v in vars(args).items() if k != 'resume'})
    out.write_text(ARGS_FILE, json.dumps({'command': command, 'version': ARGS_VERSION,
                                          'options': opts}, indent=1) + '\n')


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Make a kill (SIGTERM) stop like Ctrl-C: what is done is kept, the run is resumable."""
    def interrupt(signum: int, frame: FrameType | None) -> NoReturn:
        raise KeyboardInterrupt
    try:
        old = signal.signal(signal.SIGTERM, interrupt)
    except ValueError:  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextlib.contextmanager
def show_log(quiet: bool = False) -> Iterator[None]:
    """Print the library's progress messages (the ``mmg_tuner`` loggers) on stderr."""
    root = logging.getLogger('mmg_tuner')
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter('%(message)s'))
    old_level = root.level
    root.addHandler(handler)
    root.setLevel(logging.WARNING if quiet else logging.INFO)
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(old_level)


# ----------------------------------------------------------------------------- the command
RESIDUAL_OPTIONS = {'residual_epochs': 'epochs', 'residual_window': 'window',
                    'residual_hidden': 'hidden', 'residual_horizon': 'horizon_s',
                    'residual_max_seconds': 'max_seconds',
                    'residual_physics_input': 'physics_input'}


def tune_config(args: argparse.Namespace) -> api.TuneConfig:
    # runs stored before the residual options have none of them: getattr
    kind = ('network' if getattr(args, 'residual_only', False) else
            'hybrid' if getattr(args, 'residual', False) else None)
    opts = {field: getattr(args, dest) for dest, field in RESIDUAL_OPTIONS.items()
            if getattr(args, dest, None) is not None}
    seeds = getattr(args, 'residual_seeds', None)
    auto = getattr(args, 'model', 'physics') == 'auto'
    if (opts or seeds is not None) and kind is None and not auto:
        given = [d for d in (*RESIDUAL_OPTIONS, 'residual_seeds')
                 if getattr(args, d, None) is not None]
        raise UsageError(', '.join('--' + d.replace('_', '-') for d in given)
                         + ': only with --residual, --residual-only or --model auto')
    if 'hidden' in opts:
        opts['hidden'] = tuple(opts['hidden'])
    return api.TuneConfig(targets=args.targets, a_r=args.ar, bounds=dict(args.bound),
                          weights=weights_option(args.weights),
                          shoot_every_s=args.shoot_every, integrator=args.integrator,
                          substeps=args.substeps, popsize=args.popsize,
                          max_popsize=args.max_popsize, max_evals=args.max_evals,
                          seed=args.seed, segment_s=getattr(args, 'segment', 0.0),
                          balance=getattr(args, 'balance', 'sample'),
                          prior=getattr(args, 'prior', 0.0),
                          prior_choices=tuple(getattr(args, 'prior_choices', None) or ()),
                          residual=kind, residual_options=opts,
                          residual_seeds=1 if seeds is None else seeds,
                          model=getattr(args, 'model', 'physics'),
                          polish=getattr(args, 'polish', 0),
                          joint=getattr(args, 'joint', False))


RECIPE_KEYS = ('targets', 'weights', 'segment', 'balance', 'prior', 'prior_choices', 'max_evals',
               'polish', 'integrator', 'substeps', 'popsize', 'max_popsize')
"""What a ship config's ``tuning.recipe`` may set (the dests of this command's options)."""


def apply_recipe(args: argparse.Namespace, given: dict[str, Any], ship: ShipConfig) -> list[str]:
    """
    Fill the options not given on the command line from the ship config's ``tuning.recipe``.

    A plain ``tune TRIALS --ship NAME`` then tunes as that ship's config says works on its
    kind of data (config/esso_osaka_3m.yaml: the low-speed recipe of bench/esso_osaka.py);
    an option given on the command line always wins (``--prior`` also over the recipe's
    ``prior_choices`` and ``--prior-choices`` over its ``prior``). Returns what was applied.
    """
    recipe = (ship.extra.get('tuning') or {}).get('recipe') or {}
    if not isinstance(recipe, dict):
        raise UsageError(f'{ship.source}: tuning.recipe must be a mapping of option: value')
    bad = sorted(set(recipe) - set(RECIPE_KEYS))
    if bad:
        raise UsageError(f'{ship.source}: tuning.recipe: unknown option(s) {bad} (known: '
                         f'{list(RECIPE_KEYS)})')
    for k in ('targets', 'prior_choices'):
        if k in recipe and not isinstance(recipe[k], list):
            raise UsageError(f'{ship.source}: tuning.recipe.{k}: a list, not {recipe[k]!r}')
    w = recipe.get('weights')
    if w is not None and w != api.INDEX_WEIGHTS and not (isinstance(w, list) and len(w) == 6):
        raise UsageError(f'{ship.source}: tuning.recipe.weights: six numbers (x, y, psi, u, v, '
                         f'r) or {api.INDEX_WEIGHTS!r}, not {w!r}')
    # a prior given on the command line cancels the recipe's choices, and choices given
    # cancel the recipe's prior
    cancelled = {'prior_choices': 'prior', 'prior': 'prior_choices'}
    applied = []
    for k, v in recipe.items():
        if k not in given and cancelled.get(k) not in given:
            setattr(args, k, list(v) if isinstance(v, list) else v)
            applied.append(f'{k}={v if k != "targets" else len(v)}')
    return applied


def identify_method(args: argparse.Namespace, ship: ShipConfig | None) -> str | None:
    """Return the local -> global method to run (None: the CMA-ES tuning)."""
    method = getattr(args, 'method', None)
    if method == 'cmaes':
        return None
    if method is None and getattr(args, 'bollard_pull', None) is None:
        # (None is passed only with --method or --bollard-pull: the ship is given here)
        return 'lo-go' if cast(ShipConfig, ship).family.motion is not None else None
    return method or 'lo-go'


def load_tune_and_test(args: argparse.Namespace, ship: ShipConfig
                       ) -> tuple[list[Trial], list[Trial]]:
    """
    Read the command's trials and its --test trials (none: []) with its reading options.

    Arguments stored by an older version may lack --cut-from-event and --strict.
    """
    load = {'ship': ship, 'dt': args.dt, 'topics': args.topics,
            'trial_scale': args.trial_scale,
            'cut_from_event': getattr(args, 'cut_from_event', None),
            'strict': getattr(args, 'strict', False)}
    trials = api.load_trials(args.trials, **load)
    return trials, (api.load_trials(args.test, **load) if args.test else [])


def identify_command(args: argparse.Namespace, method: str) -> int:
    """``tune`` for a control-oriented family: identification local -> global."""
    if args.resume:
        raise UsageError('--resume: an identification is not resumable (it takes seconds): '
                         'run it again with a new --out')
    config = api.IdentifyConfig(method=method, bollard_pull=args.bollard_pull,
                                thrust_degree=args.thrust_degree, targets=args.targets,
                                smooth_s=args.smooth, ridge=args.ridge,
                                segment_s=args.go_segment, max_iter=args.go_iter,
                                grow=args.grow)
    with show_log(args.quiet), OutputDir.open(args.out) as out:
        ship = api.load_ship(args.ship, args.params)
        trials, test = load_tune_and_test(args, ship)
        store_args(out, 'tune', args)
        from mmg_tuner.data.consistency import refuse_warnings, WarningLog
        with WarningLog() as log:   # the bollard table's units: errors under --strict
            result = api.identify(ship, trials, config)
        if getattr(args, 'strict', False):
            refuse_warnings([ln for ln in log.lines if 'bollard' in ln])
        result.write(out, getattr(args, 'write_unphysical', False), trials + test)
        rep = result.report()
        if result.thrust is not None:
            t = result.thrust
            print(f'thrust: degree {t.degree} polynomial, RMSE {t.rmse_N:.3g} N over '
                  f'{t.points} bollard points'
                  + (f'; astern {t.astern_ratio:.3g} x ahead from {t.astern_points} astern '
                     'rows' if t.astern_ratio is not None else ''))
        for fit in result.actuators.values():
            print(fit.describe())
        if 'lo' in rep:
            lo = rep['lo']
            print(f"LO: {lo['samples']} "
                  + (f"windows of {lo['window_s']:g} s" if lo['window_s'] > 0 else 'intervals')
                  + ', one least-squares problem'
                  + (f" (constrained: {', '.join(lo['constraints_active'])})"
                     if lo['constraints_active'] else '') + f", {lo['wall_s']:.2f} s")
        if 'go' in rep:
            g = rep['go']
            print(f"GO: cost {g['cost_start']:.4g} -> {g['cost']:.4g} in {g['evaluations']} "
                  f"simulations, {g['wall_s']:.1f} s ({g['message']})"
                  + (f"; start {g['start_line']}" if g.get('start_line') else ''))
        if test:
            ev = api.evaluate(result.identified_ship, test, horizons=(1, 10, 50))
            # (evaluate computes the free-run errors with horizons)
            rel = cast('RelativeErrors', ev.relative).pooled
            print('held-out free-run relative error: ' + ', '.join(
                f'{k} {"-" if v is None else format(100 * v, ".3g")} %' for k, v in rel.items()))
        print(f'identified {len(result.params)} parameters ({method}) in {result.wall_s:.1f} s; '
              f'wrote {out.path}/params.yaml, identify.md, identify.json')
    return 0


def command(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, notes, resume = parse_or_resume(parser, argv, 'tune', 'tuning trials')
    if getattr(args, 'method', None) not in (None, 'cmaes') or getattr(args, 'bollard_pull',
                                                                       None):
        # (with --method or --bollard-pull the method is named: lo, go or lo-go)
        return identify_command(args, cast(str, identify_method(args, None)))
    given = explicit_options(parser, argv)
    recipe = [] if resume else apply_recipe(   # a resumed run keeps its stored options
        args, given, api.load_ship(args.ship, args.params))
    refuse_cancelling(args, given)         # before any work: nothing would run
    config = tune_config(args)             # every option checked before any work
    if not resume:
        try:
            ship = api.load_ship(args.ship, args.params)
        except MmgTunerError:   # reported where the tuning loads it, as before
            ship = None
        method = None if ship is None else identify_method(args, ship)
        if method is not None:
            return identify_command(args, method)
        if ship is not None:   # before the output folder: nothing would tune
            config.check_polish(len(config.targets or ship.tuning_targets))
    with show_log(args.quiet), OutputDir.open(args.out, resume=resume) as out:
        for n in notes:
            logging.getLogger(__name__).warning('resume: %s', n)
        if recipe:
            logging.getLogger(__name__).info(
                "options from the ship config's tuning.recipe: %s (options given on the "
                'command line win)', ', '.join(recipe))
        ship = api.load_ship(args.ship, args.params)
        tune_trials, test_trials = load_tune_and_test(args, ship)
        if not resume:
            store_args(out, 'tune', args)
        bar = None if args.quiet else progress_bar(
            config.max_evals, 'eval', _show_generation, mininterval=0.5,
            bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}] {postfix}')
        try:
            with sigterm_as_interrupt():
                result = api.tune(ship, tune_trials, test_trials, config,
                                  checkpoint=out.path / CHECKPOINT, resume=resume,
                                  progress=bar, groups=trial_kinds(tune_trials))
        finally:
            if bar is not None:
                bar.close()
        result.write(out, plots=not args.no_plots,
                     write_unphysical=getattr(args, 'write_unphysical', False))
        J, J0 = result.J, result.J_pre
        print(f'J tuning: {fmt_J(J0.tune)} -> {fmt_J(J.tune)}'
              + (f'; J test: {fmt_J(J0.test)} -> {fmt_J(J.test)} '
                 f'({fmt_gain(J0.test, J.test)} lower)' if test_trials else ''))
        for n, t in J.failed_at_s.items():
            print(f'the tuned model diverges on {n} at t = {t:.1f} s')
        if result.choice is not None:
            print('--model auto: candidates on the last quarter of each tuning trial (index, '
                  'mean per kind):\n' + result.choice.markdown()
                  + f'recommended: {result.choice.chosen} (written as params.yaml)')
        if result.prior_choice is not None:
            pc = result.prior_choice
            print('--prior-choices: held-out index per kind with each days-out fit (ratio to '
                  'the published values):\n' + pc.markdown() + f'chosen: {pc.chosen}'
                  + (' (no weight beat the published values on every kind of held-out run: '
                     'nothing tuned)' if pc.prior is None else ''))
        if result.residual is not None:
            print(_residual_line(result.residual))
        if result.bounds_hit:
            print(f"on a bound of their box: {', '.join(result.bounds_hit)}")
        print(f'{result.evaluations} evaluations in {result.wall_s:.1f} s; wrote {out.path}/'
              'params.yaml, report.json, report.md' + ('' if args.no_plots else ', plot_*.png'))
        if result.interrupted:
            print(f'interrupted: best so far written; continue with: tune --resume {out.path}',
                  file=sys.stderr)
            return 130
        if result.residual is None and result.choice is None and all(
                float(v) == float(ship[n]) for n, v in result.params.items()):
            print(f'nothing changed: the {len(result.params)} tuned values are the ship '
                  f"config's ({ship.source}) as they were; exit status {NOTHING_CHANGED}")
            return NOTHING_CHANGED
    return 0


NOTHING_CHANGED = 3
"""Exit status of a tune that ran but left every value as it was (doc/reference/commands.md)."""


def refuse_cancelling(args: argparse.Namespace, given: dict[str, Any]) -> None:
    """
    Refuse options that cancel each other, naming both and where each came from.

    ``--max-evals 0`` (no CMA-ES: the ``--polish`` alone, e.g. a ship's ``tuning.recipe``) with
    ``--shoot-every H``: the polish does not model the restarts and is skipped, so nothing
    would be tuned (issue 45: ``0 evaluations`` and the published values, exit 0).
    """
    if not (getattr(args, 'max_evals', 1) == 0 and getattr(args, 'shoot_every', 0)):
        return

    def said(dest: str, option: str) -> str:
        where = '' if dest in given else " (from the ship config's tuning.recipe)"
        return f'{option} {getattr(args, dest):g}{where}'

    raise UsageError(f"{said('shoot_every', '--shoot-every')} and "
                     f"{said('max_evals', '--max-evals')} cancel each other: without CMA-ES "
                     'only the least-squares --polish would run, and it does not model '
                     '--shoot-every restarts, so nothing would be tuned; drop --shoot-every '
                     'or give --max-evals N')


def _residual_line(r: ResidualResult) -> str:
    """One line on the trained network: share, held-out gain, time, seed."""
    held = ('' if r.heldout_gain is None else
            f'; held-out index (eq. 26) {r.index["test"]["physics"]:.4g} -> '
            f'{r.index["test"]["model"]:.4g} ({100 * r.heldout_gain:+.1f} % gain)')
    share = {'hybrid': f'share of the acceleration {100 * r.share:.1f} %',
             'joint': f'share of the acceleration {100 * r.share:.1f} %, its coefficients '
                      'trained with it',
             'blend': f'{100 * r.net.physics:.0f} % of the physics plus the mean output of '
                      'the hybrid and pure networks'}.get(r.kind, 'the network alone')
    seeds = (f'seed {r.seed}' if r.seeds == 1 else
             f'mean of {r.seeds} networks' if r.kind == 'blend' else
             f'mean of {r.seeds} networks, seeds {r.seed}-{r.seed + r.seeds - 1}')
    return (f'{r.kind} network: {share}{held}; trained in {r.seconds:.1f} s ({r.epochs} '
            f'epochs, {seeds}); weights in {api.RESIDUAL_FILE}')


def _show_generation(bar: Any, p: Progress) -> None:   # bar: tqdm's (no annotations)
    bar.set_postfix_str(f'gen {p.generation} restart {p.restart} pop {p.popsize} '
                        f'best J {p.best_J:.4g}', refresh=False)
    bar.update(min(p.evaluations, bar.total) - bar.n)  # tqdm throttles the redraw


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
