"""
The public Python API.

Everything ``tune`` and ``diagnose`` do, with typed results, for a notebook or another package. The
commands are thin wrappers: argparse -> a config dataclass -> one call here ->
``result.write(out)``.

Examples
--------
>>> import mmg_tuner as mt
>>> ship = mt.load_ship('suzaku')
>>> trials = mt.load_trials(['trials/'], ship=ship)
>>> fit = mt.tune(ship, trials[:4], test=trials[4:], max_evals=5000)
>>> fit.J.test, fit.bounds_hit
>>> dx = mt.diagnose(ship, trials[:4], test=trials[4:], budget='quick')
>>> [c.summary for c in dx.causes]
>>> run = mt.simulate(ship.with_params(dx.params), trials[5])

Progress and messages go to the ``mmg_tuner`` loggers (silence them with
``logging.getLogger('mmg_tuner').setLevel(logging.WARNING)``). Errors are
:class:`~mmg_tuner.errors.MmgTunerError` subclasses naming the option and value.

"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
import logging
import math
from pathlib import Path
import time
from typing import Callable, Mapping, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.layout import INTEGRATORS
from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data import load as _load
from mmg_tuner.data.consistency import refuse_warnings, WarningLog
from mmg_tuner.data.topics import load_topic_map
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis import measured as _measured
from mmg_tuner.diagnosis import structure as _structure
from mmg_tuner.diagnosis.context import Setting
from mmg_tuner.diagnosis.report import markdown as _diagnosis_markdown
from mmg_tuner.diagnosis.report import plot_residuals, residuals_for
from mmg_tuner.diagnosis.residuals import simulate_trials
from mmg_tuner.diagnosis.results import Candidate, Cause
from mmg_tuner.diagnosis.select import check_trial_sets
from mmg_tuner.diagnosis.select import diagnose as _diagnose
from mmg_tuner.diagnosis.settings import BUDGETS, DiagnosisSettings, MapFn, RETUNE_METHODS
from mmg_tuner.errors import (ConfigError, DiagnosisError, MissingDependencyError, MmgTunerError,
                              TuningError)
from mmg_tuner.learn import ensemble, require_jax, ResidualConfig, train_residual
from mmg_tuner.learn.model import as_model, Model
from mmg_tuner.learn.model import load_model as _load_model
from mmg_tuner.learn.residual import simulate_hybrid as _simulate_hybrid
from mmg_tuner.learn.train import split_validation
from mmg_tuner.tuning.choice import Choice, choose_model
from mmg_tuner.tuning.evaluate import compare_index, EvaluateResult
from mmg_tuner.tuning.evaluate import evaluate as _evaluate
from mmg_tuner.tuning.factory import make_objective, ObjectiveSpec
from mmg_tuner.tuning.interval import (calibrate_interval, coverage, model_interval,
                                       with_interval)
from mmg_tuner.tuning.lo_go import (BollardTable, check_bollard_table, IdentifyResult,
                                    METHODS, read_bollard_table)
from mmg_tuner.tuning.lo_go import identify as _identify
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.nstep import MAX_HORIZON
from mmg_tuner.tuning.objective import Objective, paper_weights
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.report import (json_text, markdown_report, params_yaml_text, plot_trials,
                                     simulate_recorded, unique_names)
from mmg_tuner.tuning.tuner import Progress, Tuner, TuningResult
import numpy as np

__all__ = ['BUDGETS', 'Cause', 'DiagnoseConfig', 'DiagnosisResult', 'Fit', 'ModelFit',
           'Model', 'TuneConfig', 'TuneResult', 'diagnose', 'load_model', 'load_ship',
           'load_trials', 'simulate',
           'tune', 'EvaluateConfig', 'EvaluateResult', 'evaluate', 'IdentifyConfig',
           'IdentifyResult', 'identify']

logger = logging.getLogger(__name__)

MAX_SEED = 2**31 - 1


# ---------------------------------------------------------------------------------- loading
def load_ship(name_or_path: str | Path = 'suzaku', params: str | Path | None = None
              ) -> ShipConfig:
    """
    Return a ship config by name (``'suzaku'``, ``'kvlcc2'``) or YAML path.

    ``params`` overlays a params.yaml (e.g. a tuned one). Tuned values in memory:
    ``ship.with_params(fit.params)``.
    """
    return load_ship_with_params(name_or_path, params)   # refuses another ship's params


def load_model(name_or_path: str | Path = 'suzaku', params: str | Path | None = None) -> Model:
    """
    Return a model: the ship with ``params`` overlaid and the residual network it names.

    A params.yaml written by ``tune --residual`` names a network beside it; the model then
    simulates as the hybrid (or the pure network). Without one it is the physics alone.
    """
    return _load_model(name_or_path, params)


def load_trials(paths: str | Path | Sequence[str | Path], ship: ShipConfig | None = None, *,
                dt: float | None = None, topics: str | Path | None = None,
                trial_scale: str = 'ship', keep_astern: bool | None = None,
                cut_from_event: str | tuple[str, float] | None = None,
                strict: bool = False) -> list[Trial]:
    """
    Read every trial in ``paths`` as the commands read them.

    Every trial in ``paths`` (rosbag2 folders, .mcap, .csv, MARIN .dat, or folders of them,
    searched recursively), as the commands read them: resampled on ``dt`` [s] (default: the topic
    map's, 1 s; MARIN files keep their own rate unless dt is given), and with
    ``trial_scale='full'`` Froude-scaled from full scale to the ship's scale
    (``ship.scale_ratio``).

    keep_astern: keep astern propeller and u <= 0 samples. None (default): what the ship's
    family can simulate (``ship.family.astern_rpm and astern_surge``, e.g. lowspeed); without
    a ship, or for a family that cannot, they are left out with a note. True with a ship whose
    family cannot simulate them is refused.
    cut_from_event: 'EVENT' or 'EVENT:SECONDS' (or a tuple) cuts each trial from SECONDS
    (default 5) before the event, one of ``rudder_first_over`` (real runs start with a
    manually steered approach) or ``propeller_first_astern``; a trial without the event is
    kept whole with a note.
    strict: any ``WARNING:`` line logged while reading (channels that disagree, a column in a
    likely wrong unit, a file skipped) is a TrialDataError instead (``--strict``).
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    fam = ship.family if ship is not None else None
    covers = fam is not None and fam.astern_rpm and fam.astern_surge
    if keep_astern is None:
        keep_astern = covers
    elif keep_astern and fam is not None and not covers:
        raise ConfigError(f'keep_astern=True: the {fam.name} family of {ship.name} cannot '
                          'simulate astern propeller or u <= 0 (they are left out with a note '
                          'by default); use a ship of a family that covers them, e.g. lowspeed')
    cut = None
    if cut_from_event is not None:
        cut = (_load.parse_event_cut(f'{cut_from_event[0]}:{cut_from_event[1]}')
               if isinstance(cut_from_event, tuple) else _load.parse_event_cut(cut_from_event))
    if dt is not None:
        _check('dt', dt, _finite(dt) and 1e-3 <= dt <= 600, 'a step in [0.001, 600] s')
    if trial_scale not in ('ship', 'full'):
        raise ConfigError(f"trial_scale {trial_scale!r}: use 'ship' or 'full'")
    if trial_scale == 'full' and ship is None:
        raise ConfigError("trial_scale='full' needs the ship (its scale_ratio)")
    tm = load_topic_map(topics)
    if dt:
        tm = replace(tm, dt=dt)
    # one call: names unique across all paths; samples the ship cannot show dropped with a note
    limits = input_limits(ship) if ship is not None else None
    with WarningLog() as log:
        trials: list[Trial] = _load.load_many(list(paths), tm, keep_astern=bool(keep_astern),
                                              limits=limits)
    if strict:
        refuse_warnings(log.lines)
    if cut is not None:
        trials = _load.cut_at_event(trials, *cut)
        for t in trials:
            if t.notes and t.notes[-1].startswith('not cut:'):
                logger.warning('%s: %s', t.name, t.notes[-1])
    if trial_scale == 'full' and ship.scale_ratio != 1.0:
        trials = [t.froude_scaled(ship.scale_ratio) for t in trials]
    if dt:
        trials = [t if abs(t.dt - dt) < 1e-9 else t.resampled(dt) for t in trials]
    return trials


# ---------------------------------------------------------------------------------- checks
def _finite(x) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _check(name: str, value, ok: bool, what: str, error=ConfigError) -> None:
    if not ok:
        raise error(f'{name} = {value!r}: must be {what}')


def _check_common(cfg, error) -> None:
    _check('a_r', cfg.a_r, cfg.a_r is None or (_finite(cfg.a_r) and cfg.a_r > 0),
           'a finite number > 0 (relative box half-width)', error)
    _check('integrator', cfg.integrator, cfg.integrator in INTEGRATORS,
           f'one of {sorted(INTEGRATORS)}', error)
    _check('seed', cfg.seed, _is_int(cfg.seed) and 0 <= cfg.seed <= MAX_SEED,
           f'a whole number in [0, {MAX_SEED}]', error)
    if cfg.targets is not None:
        _check('targets', cfg.targets, len(cfg.targets) > 0 and all(
            isinstance(t, str) for t in cfg.targets), 'a non-empty list of parameter names',
            error)


# ---------------------------------------------------------------------------------- tune
@dataclass(frozen=True)
class TuneConfig:
    """
    Options of :func:`tune` (the ``tune`` command's flags), validated on creation.

    targets: parameter names to tune (default: the ship's); a_r: relative box half-width
    (default: the ship's, 0.5); bounds: per-parameter a_r or (lower, upper); weights: six
    non-negative error weights on x, y, psi, u, v, r (default: the paper's L, L, pi/4, 0, 0, 0);
    shoot_every_s: restart from the recorded state every H s (0: never); popsize / max_popsize /
    max_evals: IPOP-CMA-ES budget; seed: a whole number. residual: None, 'hybrid' (after the
    tuning, train a neural residual on the tuning trials: ``tune --residual``) or 'network'
    (the pure network, no physics tuning: ``--residual-only``); residual_options: fields of
    :class:`~mmg_tuner.learn.ResidualConfig` (epochs, window, hidden, ...; the seed
    defaults to this config's, the integrator to 'rk4', as ``evaluate`` runs the hybrid);
    residual_seeds: train that many residuals (seeds seed, seed + 1, ...) and keep their mean,
    one exact ensemble network (``learn.ensemble``): less dependence on one seed's
    initial weights, at that many times the training time. What CMA-ES minimises (the
    reported J keeps shoot_every_s): segment_s: cut the tuning trials into pieces of this
    many s, each started from the measured state (0: whole trials; ``tuning/segments.py``);
    balance: 'sample' (every sample alike) or 'trial' (every trial
    the same total weight); prior: pull toward the pre-determined values, in J per sample per
    squared box width (0: none). model: 'physics' (the tuned physics, and the residual if
    ``residual`` is set) or 'auto' (``tune --model auto``: also train the pure network and
    the hybrid when JAX is installed and the trials allow it, compare the candidates on the
    last quarter of each tuning trial per kind of run (``tuning/choice.py``) and keep the
    recommended one; with residual_seeds >= 2 the chosen network's ensemble carries a
    prediction interval calibrated there, ``tuning/interval.py``). polish: after CMA-ES, a
    local least-squares polish of at most this many simulations on the same objective's
    residuals (``tuning/lsq.py``; 0: none).
    """

    targets: tuple[str, ...] | None = None
    a_r: float | None = None
    bounds: Mapping[str, float | tuple[float, float]] = field(default_factory=dict)
    weights: tuple[float, ...] | None = None
    shoot_every_s: float = 0.0
    integrator: str = 'euler'
    substeps: int = 1
    popsize: int = 12
    max_popsize: int = 128
    max_evals: int = 200_000
    seed: int = 0
    residual: str | None = None
    residual_options: Mapping[str, object] = field(default_factory=dict)
    residual_seeds: int = 1
    segment_s: float = 0.0
    balance: str = 'sample'
    prior: float = 0.0
    model: str = 'physics'
    polish: int = 0

    def __post_init__(self) -> None:
        E = TuningError
        _check_common(self, E)
        _check_residual(self, E)
        _check('model', self.model, self.model in MODEL_CHOICES, f'one of {list(MODEL_CHOICES)}',
               E)
        _check('model', self.model, self.model == 'physics' or self.residual is None,
               "'physics' with residual set (model 'auto' trains the networks itself)", E)
        _check('polish', self.polish, _is_int(self.polish) and self.polish >= 0,
               'a whole number >= 0 (0: no least-squares polish)', E)
        _check('segment_s', self.segment_s, _finite(self.segment_s) and self.segment_s >= 0,
               'a finite number >= 0 [s] (0: whole trials)', E)
        _check('balance', self.balance, self.balance in ('sample', 'trial', 'group'),
               "'sample', 'trial' or 'group' (each kind of run the same weight: tune's "
               'groups)', E)
        _check('prior', self.prior, _finite(self.prior) and self.prior >= 0,
               'a finite number >= 0 (0: no prior)', E)
        if self.targets is not None:
            object.__setattr__(self, 'targets', tuple(self.targets))
        for name, b in dict(self.bounds).items():
            ok = (_finite(b) and float(b) > 0) if not isinstance(b, tuple) else (
                len(b) == 2 and all(_finite(x) for x in b) and float(b[0]) < float(b[1]))
            _check(f'bounds[{name!r}]', b, ok, 'a finite a_r > 0 or (lower, upper) with '
                   'lower < upper', E)
        if self.weights is not None:
            w = tuple(float(x) if _finite(x) else math.nan for x in self.weights)
            _check('weights', self.weights, len(w) == 6 and all(x >= 0 for x in w),
                   'six finite numbers >= 0 (x, y, psi, u, v, r)', E)
            _check('weights', self.weights, any(x > 0 for x in w),
                   'not all zero (J would be 0 for every candidate)', E)
            object.__setattr__(self, 'weights', w)
        _check('shoot_every_s', self.shoot_every_s,
               _finite(self.shoot_every_s) and self.shoot_every_s >= 0,
               'a finite number >= 0 [s] (0: never)', E)
        _check('substeps', self.substeps, _is_int(self.substeps) and 1 <= self.substeps <= 1000,
               'a whole number in [1, 1000]', E)
        _check('popsize', self.popsize, _is_int(self.popsize) and 2 <= self.popsize <= 100_000,
               'a whole number >= 2', E)
        _check('max_popsize', self.max_popsize, _is_int(self.max_popsize)
               and self.popsize <= self.max_popsize <= 100_000,
               f'a whole number >= popsize ({self.popsize})', E)
        _check('max_evals', self.max_evals, _is_int(self.max_evals) and self.max_evals >= 0,
               'a whole number >= 0 (0: no CMA-ES, the least-squares polish alone)', E)
        _check('max_evals', self.max_evals, self.max_evals >= 1 or (
            _is_int(self.polish) and self.polish >= 1), '>= 1 unless polish is set (else '
            'nothing would tune)', E)

    def objective_spec(self) -> ObjectiveSpec:
        """Return what CMA-ES minimises, for the one objective factory (tuning/factory.py)."""
        return ObjectiveSpec(self.weights, self.shoot_every_s, self.integrator, self.substeps,
                             self.segment_s, self.balance, self.prior)


@dataclass
class Fit:
    """
    J (Suyama et al. 2023, eq. 43) of one parameter set.

    Per trial and summed over the tuning and the test set. A run that diverged or left the model's
    range has J = inf and its failure time [s from the trial's start] in ``failed_at_s``.
    """

    per_trial: dict[str, float]
    sets: dict[str, str]                       # trial -> 'tune' | 'test'
    failed_at_s: dict[str, float] = field(default_factory=dict)

    def _sum(self, which: str) -> float | None:
        vals = [j for n, j in self.per_trial.items() if self.sets[n] == which]
        return float(sum(vals)) if vals else None

    @property
    def tune(self) -> float:
        """Return J summed over the tuning trials."""
        return self._sum('tune')

    @property
    def test(self) -> float | None:
        """Return J summed over the test trials (None without any)."""
        return self._sum('test')


def _fit(obj_by_set: dict[str, tuple[Objective, list[str]]], params: np.ndarray) -> Fit:
    per, sets, failed = {}, {}, {}
    for which, (obj, names) in obj_by_set.items():
        J, k_fail = obj.per_trial(params[None])
        for j, name in enumerate(names):
            n = int(obj.batch.lengths[j])
            bad = k_fail[0, j] < n or not math.isfinite(J[0, j])
            per[name] = math.inf if bad else float(J[0, j])
            sets[name] = which
            if bad:
                failed[name] = float(min(k_fail[0, j], n - 1) * obj.batch.dt)
    return Fit(per, sets, failed)


@dataclass
class TuneResult:
    """
    What :func:`tune` found.

    ``params``: tuned values of the targets; ``J`` / ``J_pre``: the tuned / pre-determined model's
    :class:`Fit`; ``bounds_hit``: targets that ended on a bound of their box; ``history``:
    (evaluations, restart, best J) per generation.
    """

    params: dict[str, float]
    J: Fit
    J_pre: Fit
    bounds_hit: list[str]
    history: list[tuple[int, int, float]]
    evaluations: int
    restarts: int
    wall_s: float
    interrupted: bool
    ship: ShipConfig = field(repr=False)
    space: ParameterSpace = field(repr=False)
    config: TuneConfig = field(repr=False)
    trials: list[Trial] = field(repr=False, default_factory=list)
    test: list[Trial] = field(repr=False, default_factory=list)
    dt: float = 0.0
    residual: ResidualResult | None = None   # tune --residual / --residual-only
    choice: Choice | None = None             # tune --model auto: the candidates compared
    choice_notes: list[str] = field(default_factory=list)

    @property
    def tuned_ship(self) -> ShipConfig:
        """Return the tuned ship (the physics; the residual network: :attr:`tuned_model`)."""
        return self.ship.with_params(self.params)

    @property
    def tuned_model(self) -> Model:
        """Return the tuned model: the tuned ship and the trained residual network, if any."""
        return Model(self.tuned_ship, None if self.residual is None else self.residual.net)

    def report(self) -> dict:
        """report.json's content."""
        c = self.config
        per_trial = {n: {'set': self.J.sets[n], 'J_pre': self.J_pre.per_trial[n],
                         'J_tuned': self.J.per_trial[n]} for n in self.J.per_trial}
        for n, t in self.J.failed_at_s.items():
            per_trial[n]['tuned_failed_at_s'] = t
        for n, t in self.J_pre.failed_at_s.items():
            per_trial[n]['pre_failed_at_s'] = t
        sp = self.space
        return {
            'ship': self.ship.name,
            'J': {'pre': {'tune': self.J_pre.tune, 'test': self.J_pre.test},
                  'tuned': {'tune': self.J.tune, 'test': self.J.test}},
            'per_trial': per_trial,
            'params': {n: {'pre': float(p), 'tuned': float(self.params[n]),
                           'lower': float(lo), 'upper': float(hi),
                           'on_bound': n in self.bounds_hit}
                       for n, p, lo, hi in zip(sp.names, sp.pre, sp.lower, sp.upper)},
            'bounds_hit': list(self.bounds_hit), 'evaluations': int(self.evaluations),
            'restarts': self.restarts, 'wall_s': float(self.wall_s),
            'interrupted': self.interrupted,
            'settings': {'a_r': c.a_r or self.ship.a_r,
                         'weights': list(c.weights or paper_weights(self.ship.L_pp)),
                         'shoot_every_s': c.shoot_every_s, 'integrator': c.integrator,
                         'dt': self.dt, 'seed': c.seed, 'max_evals': c.max_evals,
                         'popsize': [c.popsize, c.max_popsize]},
            'finite': bool(math.isfinite(self.J.tune)),
            'residual': None if self.residual is None else self.residual.report(),
            'model_choice': None if self.choice is None else {
                **self.choice.to_dict(), 'notes': list(self.choice_notes)},
        }

    def write(self, out: str | Path | OutputDir, plots: bool = True) -> list[Path]:
        """
        Write the result's files into ``out``, the completion marker last.

        params.yaml, report.md, plot_<trial>.png, and report.json last (its presence means the set
        is complete). ``out``: a new or empty folder, or an open :class:`OutputDir`. With a trained
        residual, its weights (params.residual.npz) come first and params.yaml names them.
        """
        names = ', '.join(unique_names(self.trials)) or 'the tuning trials'
        rep = self.report()
        params_text = params_yaml_text(self.ship, self.params, f'tuned by mmg_tuner on {names}')
        md = markdown_report(rep)
        if self.choice is not None:   # --model auto: what was compared, and why this one
            md += ('\n## Model chosen (--model auto)\n\nIndex (Wakita et al. 2022 eq. 26, '
                   'restarts every 100 s) on the last quarter of each tuning trial, mean per '
                   'kind; score: the worst ratio to the best of the kind.\n\n'
                   + self.choice.markdown() + f'\nRecommended: **{self.choice.chosen}**.\n'
                   + ''.join(f'\n- {n}' for n in self.choice_notes) + '\n')
        if self.residual is not None:
            return _write_with_residual(self, out, params_text, md, plots)
        docs = [('params.yaml', params_text), ('report.md', md)]
        images = {}
        if plots:
            images = plot_trials(self.ship, self.trials + self.test,
                                 {'pre-determined': self.ship.params,
                                  'tuned': self.tuned_ship.params},
                                 'plot_', self.config.integrator, self.config.substeps,
                                 sets=self.J.sets, J={'pre-determined': self.J_pre.per_trial,
                                                      'tuned': self.J.per_trial})
        return _write_all(out, docs, images, ('report.json', json_text(self.report())))


def _write_with_residual(res: TuneResult, out, params_text: str, md: str, plots: bool
                         ) -> list[Path]:
    """TuneResult.write with a residual: the weights first, then params.yaml naming them."""
    r = res.residual
    own = not isinstance(out, OutputDir)
    od = OutputDir.open(out) if own else out
    try:
        paths = [od.write_bytes(RESIDUAL_FILE, r.npz_bytes())]
        text = params_text + (f'# the {r.kind} network beside this file (mmg_tuner tune '
                              f'--residual)\nresidual: {RESIDUAL_FILE}\n')
        images = {}
        if plots and r.kind == 'hybrid':   # the physics curves (the hybrid's: evaluate)
            images = plot_trials(res.ship, res.trials + res.test,
                                 {'pre-determined': res.ship.params,
                                  'tuned physics': res.ship.with_params(res.params).params},
                                 'plot_', res.config.integrator, res.config.substeps,
                                 sets=res.J.sets, J={'pre-determined': res.J_pre.per_trial,
                                                     'tuned physics': res.J.per_trial})
        paths += _write_all(od, [('params.yaml', text), ('report.md', md + r.markdown())],
                            images, ('report.json', json_text(res.report())))
    finally:
        if own:
            od.close()
    return paths


def _write_all(out, docs, images, last) -> list[Path]:
    own = not isinstance(out, OutputDir)
    od = OutputDir.open(out) if own else out
    try:
        paths = [od.write_text(n, t) for n, t in docs]
        paths += [od.write_bytes(n, b) for n, b in images.items()]
        paths.append(od.write_text(*last))
    finally:
        if own:
            od.close()
    return paths


def _as_list(trials) -> list[Trial]:
    if trials is None:
        return []
    if isinstance(trials, Trial):
        return [trials]
    return list(trials)


def _config(cls, config, options: dict):
    if config is None:
        return cls(**options)
    if not isinstance(config, cls):
        raise TypeError(f'config must be a {cls.__name__}, got {type(config).__name__}')
    return replace(config, **options) if options else config


def tune(ship: ShipConfig, trials: Trial | Sequence[Trial],
         test: Trial | Sequence[Trial] | None = None, config: TuneConfig | None = None, *,
         checkpoint: str | Path | None = None, resume: bool = False,
         progress: Callable[[Progress], None] | None = None,
         groups: Mapping[str, str] | None = None, **options) -> TuneResult:
    """
    Tune ``ship``'s targets on ``trials`` with IPOP-CMA-ES (the paper's formulation).

    ``test`` trials are only evaluated. ``options`` are :class:`TuneConfig` fields (e.g.
    ``max_evals=5000, a_r=0.5``). ``checkpoint``: a file written every generation; ``resume=True``
    continues from it. Ctrl-C stops after the current generation and returns the best so far with
    ``interrupted=True``. ``groups``: trial name -> kind of run (turning, zigzag, ...), for
    ``model='auto'``'s comparison per kind (default: each trial its own kind).
    """
    cfg = _config(TuneConfig, config, options)
    trials, test = _as_list(trials), _as_list(test)
    if not trials:
        raise TuningError('no tuning trials given')
    space = ParameterSpace.around(ship, cfg.targets, cfg.a_r, dict(cfg.bounds))
    spec = cfg.objective_spec()
    if cfg.balance == 'group':   # without kinds each trial is its own: balance 'trial'
        spec = replace(spec, group_of=dict(groups) if groups else
                       {n: n for n in unique_names(trials)})
    names = unique_names(trials + test)
    obj = make_objective(ship, trials, spec.plain)   # J as reported: whole trials
    sets = {'tune': (obj, names[:len(trials)])}
    if test:
        sets['test'] = (make_objective(ship, test, spec.plain), names[len(trials):])
    logger.info('tuning %d parameters of %s on %d trial(s)%s; box a_r = %g', space.dim,
                ship.name, len(trials), f', testing on {len(test)}' if test else '',
                cfg.a_r or ship.a_r)
    if cfg.residual is not None:
        require_jax()   # before any work: says how to install it
    if cfg.residual == 'network':   # the pure network: no physics to tune
        pre = _fit(sets, ship.params)
        result = TuneResult({n: float(ship[n]) for n in space.names}, pre, pre, [], [], 0, 0,
                            0.0, False, ship, space, cfg, trials, test, obj.batch.dt)
    else:
        minimised = obj if spec == spec.plain else make_objective(ship, trials, spec, space)
        t0 = time.perf_counter()
        tuner = Tuner(space, minimised,
                      popsize=cfg.popsize, max_popsize=cfg.max_popsize,
                      max_evaluations=cfg.max_evals, seed=cfg.seed, checkpoint=checkpoint)
        if cfg.max_evals:
            res = tuner.run(resume=resume, progress=progress)
        else:   # the polish alone, from the pre-determined values
            J_pre = float(minimised(ship.params[None])[0])
            res = TuningResult(space.pre.copy(), J_pre, 0, 0, 0.0, [], False)
        theta, evaluations = res.theta, res.evaluations
        if cfg.polish and not res.interrupted:
            if spec.shoot_every_s:   # the residual vector has no restarts: not the same J
                logger.warning('polish skipped: it does not model shoot_every_s restarts')
            else:
                loc = local_least_squares(space, minimised, theta, cfg.polish)
                theta, evaluations = loc.theta, evaluations + loc.simulations
                logger.info('least-squares polish: %d simulations, J %.6g -> %.6g',
                            loc.simulations, res.J, loc.J)
        tuned = space.full_params(ship.params, theta)[0]
        result = TuneResult(dict(zip(space.names, map(float, theta))), _fit(sets, tuned),
                            _fit(sets, ship.params), space.on_bound(theta),
                            list(res.history), evaluations, res.restarts,
                            res.wall_s + (time.perf_counter() - t0 - res.wall_s
                                          if cfg.polish else 0.0),
                            res.interrupted, ship, space, cfg, trials, test, obj.batch.dt)
    if cfg.residual is not None and not result.interrupted:
        result.residual = _train_residual(result)
    if cfg.model == 'auto' and not result.interrupted:
        _choose(result, groups)
    return result


def _choose(result: TuneResult, groups: Mapping[str, str] | None) -> None:
    """
    ``model='auto'``: train the networks the data allow, compare, keep the recommended one.

    Candidates: the tuned physics; the hybrid and the pure network (each ``residual_seeds``
    seeds, one exact ensemble) when JAX is installed and their training succeeds. Compared on
    the last quarter of each tuning trial (``learn.train.split_validation``: the part the
    networks only chose their epoch on) by ``tuning.choice.choose_model``, per kind of run
    (``groups``). The chosen network, an ensemble of >= 2, carries its calibrated interval.
    """
    cfg = result.config
    physics = result.tuned_ship
    cands: dict[str, ShipConfig | Model] = {'physics': physics}
    trained, notes = {}, []
    try:
        require_jax()
    except MissingDependencyError as exc:
        notes.append(f'networks not trained: {exc}')
    else:
        for kind in ('hybrid', 'network'):
            sub = replace(result, config=replace(cfg, residual=kind, model='physics'),
                          residual=None)
            try:
                r = _train_residual(sub)
            except MmgTunerError as exc:   # e.g. trials too short for its windows
                notes.append(f'{kind}: not trained ({exc})')
                logger.warning('--model auto: the %s network was not trained: %s', kind, exc)
                continue
            trained[kind] = r
            cands[kind] = Model(physics, r.net)
    rc = _residual_config(cfg)
    val = split_validation(result.trials, rc.validation_fraction, rc.window)[1]
    choice = choose_model(cands, val, groups, integrator=rc.integrator)
    logger.info('--model auto: candidates on the validation part of the tuning trials:\n%s'
                'recommended: %s', choice.markdown(), choice.chosen)
    if choice.chosen != 'physics':
        r = trained[choice.chosen]
        if r.seeds >= 2:
            iv = calibrate_interval(cands[choice.chosen], val, 0.9, integrator=rc.integrator)
            r.net = with_interval(iv).residual
            notes.append(f'prediction interval: nominal 90 %, factors {iv.to_dict()["scale"]}'
                         ' (calibrated on the validation part)')
        result.residual = r
    result.choice, result.choice_notes = choice, notes


# ---------------------------------------------------------------------------------- residual
RESIDUAL_FILE = 'params.residual.npz'
RESIDUAL_KINDS = ('hybrid', 'network')
MODEL_CHOICES = ('physics', 'auto')


def _check_residual(cfg: TuneConfig, error) -> None:
    """TuneConfig.residual and residual_options, checked like the other options."""
    _check('residual', cfg.residual, cfg.residual is None or cfg.residual in RESIDUAL_KINDS,
           f'None or one of {list(RESIDUAL_KINDS)}', error)
    _check_residual_options(cfg.residual_options, error)
    rc = _residual_config(cfg)   # ResidualConfig validates the values (ConfigError naming them)
    n = cfg.residual_seeds
    _check('residual_seeds', n, isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 32,
           'a whole number from 1 to 32', error)
    # checked here, not after the tuning: the last seed must be a seed too
    _check('residual_seeds', n, rc.seed + n - 1 < 2 ** 31,
           f'at most {2 ** 31 - rc.seed} with seed {rc.seed} (seeds seed .. seed + n - 1 must '
           'be < 2**31)', error)


def _check_residual_options(options, error) -> None:
    opts = dict(options)
    unknown = sorted(set(opts) - set(config_fields(ResidualConfig)))
    _check('residual_options', opts, not unknown and 'physics' not in opts,
           f'fields of ResidualConfig (unknown: {unknown}; physics follows the mode)', error)
    ResidualConfig(**opts)   # validates the values (ConfigError naming them)


def _residual_config(cfg: TuneConfig) -> ResidualConfig:
    # RK4, as evaluate and mt.simulate run the hybrid by default (Euler: residual_options)
    return ResidualConfig(**{'seed': cfg.seed, 'integrator': 'rk4',
                             **dict(cfg.residual_options),
                             'physics': cfg.residual != 'network'})


@dataclass
class ResidualResult:
    """
    The neural residual trained after the physics (``tune --residual``).

    The network, its share of the total acceleration, its gain on its validation windows, and the
    paper's index (Wakita et al. 2022 eq. 26, restarts every 100 s) of the tuned physics and of the
    model with the network on the tuning and test trials (``heldout_gain``: 1 - index ratio on the
    test trials, None without any).
    """

    net: object = field(repr=False)
    kind: str
    share: float
    val_gain: float | None
    index: dict
    heldout_gain: float | None
    seconds: float
    epochs: int
    seed: int
    config: dict
    seeds: int = 1   # residuals averaged (seeds seed .. seed + seeds - 1; 1: one network)

    def npz_bytes(self) -> bytes:
        """Return the network as the portable .npz ResidualNet.save writes."""
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / RESIDUAL_FILE
            self.net.save(path)
            return path.read_bytes()

    def report(self) -> dict:
        d = asdict(self)
        d.pop('net')
        d['file'] = RESIDUAL_FILE
        return d

    def markdown(self) -> str:
        mean = '' if self.seeds == 1 else f' (mean over the {self.seeds} networks)'
        lines = ['', f'## Neural residual ({self.kind})', '',
                 f'Trained in {self.seconds:.1f} s ({self.epochs} epochs, '
                 + (f'seed {self.seed}' if self.seeds == 1 else
                    f'the mean of {self.seeds} networks, seeds {self.seed} to '
                    f'{self.seed + self.seeds - 1}') + '); '
                 f'weights in `{RESIDUAL_FILE}`, named by params.yaml. '
                 + (f'Share of the total acceleration{mean}: {100 * self.share:.1f} %. '
                    if self.kind == 'hybrid' else 'The network alone gives the '
                    'accelerations (no physics). ')
                 + ('' if self.val_gain is None else
                    f'Gain on its validation windows{mean}: {100 * self.val_gain:.1f} %.'), '',
                 '| trials | index, tuned physics | index, with the network | gain |',
                 '|---|---|---|---|']
        for which, v in self.index.items():
            lines.append(f"| {which} | {_fmt_idx(v['physics'])} | {_fmt_idx(v['model'])} | "
                         f"{_fmt_gain_frac(v['gain'])} |")
        return '\n'.join(lines) + '\n'


def _fmt_idx(x) -> str:
    return 'failed' if x is None else f'{x:.4g}'


def _fmt_gain_frac(g) -> str:
    return '—' if g is None else f'{100 * g:+.1f} %'


def _train_residual(result: TuneResult) -> ResidualResult:
    """
    Train the residual on the tuning trials with the tuned physics and score both.

    Train the residual on the tuning trials (its validation: the last part of each) with the tuned
    physics, and score both on the tuning and test trials.
    """
    cfg = result.config
    rc = _residual_config(cfg)
    physics = result.ship.with_params(result.params)
    logger.info('training the %s network on %d trial(s) (seed %d, up to %d epochs)',
                'residual' if rc.physics else 'pure', len(result.trials), rc.seed, rc.epochs)
    fits = []
    for k in range(cfg.residual_seeds):
        if k:
            logger.info('   seed %d (%d of %d)', rc.seed + k, k + 1, cfg.residual_seeds)
        fits.append(train_residual(physics, result.trials, config=replace(rc, seed=rc.seed + k)))
    fit = fits[0]
    net = fit.net if len(fits) == 1 else ensemble([f.net for f in fits])
    model = Model(physics, net)
    index = {}
    for which, trials in (('tune', result.trials), ('test', result.test)):
        if trials:
            index[which] = compare_index(physics, model, trials, integrator=rc.integrator)
    held = index.get('test', {}).get('gain')
    # with several seeds: the members' mean share and validation gain (the ensemble's own
    # would need another pass over the trials), their total time, the longest training
    seconds = float(sum(f.seconds for f in fits))
    share = float(np.mean([f.share for f in fits]))
    gains = [f.val_gain for f in fits if f.val_gain is not None]
    val_gain = float(np.mean(gains)) if gains else None
    logger.info('   %s network: %.1f s, %d epochs; share %.1f %%; held-out index gain %s',
                'residual' if rc.physics else 'pure', seconds, max(f.epochs for f in fits),
                100 * share, _fmt_gain_frac(held))
    return ResidualResult(net, 'hybrid' if rc.physics else 'pure network', share, val_gain,
                          index, held, seconds, int(max(f.epochs for f in fits)),
                          int(fit.seed), asdict(rc), len(fits))


# ---------------------------------------------------------------------------------- diagnose
@dataclass(frozen=True)
class DiagnoseConfig:
    """
    Options of :func:`diagnose` (the ``diagnose`` command's flags), validated on creation.

    effects: library entries to search (default: all); targets / a_r: the base model's tuning
    box; budget: 'quick', 'standard' or 'full' (evaluations for the base tuning, the screening
    and each candidate's re-tuning; base_evals / screen_evals / effect_evals override them);
    max_effects: how many causes at most. setting: where the trials were recorded, a
    :class:`~mmg_tuner.diagnosis.context.Setting`, 'tank', 'sea,antenna' or a mapping
    {venue, position} (default: the ship YAML's ``setting:``, else what the trial files say);
    effects impossible there are fitted but never named. residual: after the search, train a
    residual network on the final model and report the share of the remaining held-out error
    it removes and where it lives ("unexplained but learnable structure"; needs JAX;
    residual_options: fields of ResidualConfig): True always, False never, 'auto' (default)
    when what remains is above what sensor noise alone reaches and JAX is
    importable. retune: 'lsq' (local least squares,
    warm-started; default) or 'cmaes' for the candidates' re-tunes. measured_signals: a
    measured wind is a candidate cause (True) or always drives the model (False). measured:
    coefficients measured outside the trials, {name: Measurement(value, se)} or a YAML file
    (diagnosis/measured.py): priors of every tuning with their standard errors, not fixed.
    """

    effects: tuple[str, ...] = tuple(EFFECTS)
    targets: tuple[str, ...] | None = None
    a_r: float | None = None
    budget: str = 'standard'
    max_effects: int = 3
    integrator: str = 'rk4'
    seed: int = 0
    base_evals: int | None = None
    screen_evals: int | None = None
    effect_evals: int | None = None
    setting: Setting | str | Mapping | None = None
    retune: str = 'lsq'
    measured_signals: bool = True
    residual: bool | str = 'auto'
    residual_options: Mapping[str, object] = field(default_factory=dict)
    measured: Mapping[str, object] | str | Path | None = None

    def __post_init__(self) -> None:
        E = DiagnosisError
        if isinstance(self.measured, (str, Path)):
            object.__setattr__(self, 'measured', _measured.load(self.measured))
        else:
            object.__setattr__(self, 'measured', _measured.check(self.measured or {},
                                                                 'DiagnoseConfig.measured'))
        _check('residual', self.residual,
               isinstance(self.residual, bool) or self.residual == 'auto',
               "True, False or 'auto'", E)
        if self.residual is not False:
            _check_residual_options(self.residual_options, E)
        _check_common(self, E)
        object.__setattr__(self, 'effects', tuple(self.effects))
        object.__setattr__(self, 'setting', Setting.parse(self.setting, 'the caller'))
        _check('retune', self.retune, self.retune in RETUNE_METHODS,
               f'one of {list(RETUNE_METHODS)}', E)
        _check('measured_signals', self.measured_signals,
               isinstance(self.measured_signals, bool), 'True or False', E)
        if self.targets is not None:
            object.__setattr__(self, 'targets', tuple(self.targets))
        unknown = [e for e in self.effects if e not in EFFECTS]
        _check('effects', list(self.effects), bool(self.effects) and not unknown,
               f'a non-empty list of {sorted(EFFECTS)}', E)
        _check('budget', self.budget, self.budget in BUDGETS, f'one of {list(BUDGETS)}', E)
        _check('max_effects', self.max_effects,
               _is_int(self.max_effects) and 1 <= self.max_effects <= len(EFFECTS),
               f'a whole number in [1, {len(EFFECTS)}]', E)
        for k in ('base_evals', 'screen_evals', 'effect_evals'):
            v = getattr(self, k)
            _check(k, v, v is None or (_is_int(v) and v >= 1), 'a whole number >= 1', E)

    def settings(self) -> DiagnosisSettings:
        base_e, screen_e, eff_e = BUDGETS[self.budget]
        return DiagnosisSettings(
            targets=self.targets, a_r=self.a_r, effects=list(self.effects),
            integrator=self.integrator, base_evals=self.base_evals or base_e,
            screen_evals=self.screen_evals or screen_e, effect_evals=self.effect_evals or eff_e,
            max_effects=self.max_effects, seed=self.seed, retune=self.retune,
            setting=self.setting, measured_signals=self.measured_signals,
            measurements=dict(self.measured))


@dataclass
class ModelFit:
    """One model of a diagnosis: J on the tuning and test trials, its parameters."""

    J_tune: float
    J_test: float
    J_test_per_trial: dict[str, float]
    params: dict[str, float]
    heldout_gain_total: float | None = None   # final model: 1 - J_test / base model's J_test

    def __getitem__(self, key: str):  # dict-style reading, as diagnosis.json has it
        return getattr(self, key)


@dataclass
class DiagnosisResult:
    """
    What :func:`diagnose` found.

    The named ``causes``, the tuned base model (``baseline``) and the final model with the causes
    (``final``, its full parameters in ``params``: ``ship.with_params(dx.params)``), every
    candidate tried per round, effects the trials can barely see, and the residuals of both models
    on the test trials.
    """

    causes: list[Cause]
    baseline: ModelFit
    final: ModelFit
    params: dict[str, float]
    candidates: list[list[Candidate]]
    barely_identifiable: dict[str, dict]
    residuals: dict[str, dict]
    wall_s: float
    ship: ShipConfig = field(repr=False)
    test: list[Trial] = field(repr=False, default_factory=list)
    config: DiagnoseConfig = field(repr=False, default_factory=DiagnoseConfig)
    setting: Setting = field(default_factory=Setting)
    impossible: dict[str, str] = field(default_factory=dict)
    impossible_fits: list[dict] = field(default_factory=list)
    measured: list[dict] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)
    # the test trials as each model sees them (without / with the measured wind)
    test_base: list[Trial] = field(repr=False, default_factory=list)
    test_final: list[Trial] = field(repr=False, default_factory=list)
    # the trial that would settle each barely identifiable effect / rival pair (advice.py)
    advice: list[dict] = field(default_factory=list)
    # whether the model structure, not the named effects, is the likely cause (structure.py)
    structure: dict = field(default_factory=dict)
    structure_images: dict = field(repr=False, default_factory=dict)   # {file: PNG}
    # effects the search kept that only mimic a structural gap (structure.one_verdict): in the
    # fitted model (params), never named as causes
    mimicking: list[Cause] = field(default_factory=list)
    # the sensor noise and the held-out J it alone leaves (diagnosis/noise.py)
    noise: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """diagnosis.json's content."""
        base = asdict(self.baseline)
        base.pop('heldout_gain_total')
        final = asdict(self.final)
        final.pop('params')
        return {'causes': [c.to_dict() for c in self.causes], 'baseline': base, 'final': final,
                'candidates': [[asdict(c) for c in r] for r in self.candidates],
                'residuals': self.residuals, 'barely_identifiable': self.barely_identifiable,
                'setting': {**asdict(self.setting), 'description': self.setting.describe()},
                'impossible_here': self.impossible,
                'would_fit_but_impossible': self.impossible_fits,
                'measured_signals': self.measured, 'advice': self.advice,
                'structure': self.structure,
                'mimicking': [c.to_dict() for c in self.mimicking], 'noise': self.noise,
                'params': self.params, 'wall_s': self.wall_s, 'timings_s': self.timings_s}

    def write(self, out: str | Path | OutputDir, plots: bool = True) -> list[Path]:
        """
        Write the result's files into ``out``, the completion marker last.

        params.yaml first, diagnosis.md, plots, and diagnosis.json last (its presence means the set
        is complete).
        """
        doc = self.to_dict()
        names = ', '.join([c.effect for c in self.causes]
                          + [f'{c.effect} (mimicking a structural gap)'
                             for c in self.mimicking]) or 'none'
        docs = [('params.yaml', params_yaml_text(
                    self.ship, self.params,
                    f'tuned and extended by mmg_tuner diagnose (effects: {names})')),
                ('diagnosis.md', _diagnosis_markdown(doc, self.ship))]
        images = {}
        if plots:
            integ = self.config.integrator
            base_p = self.ship.with_params(self.baseline.params).params
            final_p = self.ship.with_params(self.params).params
            images = plot_residuals(self.test,
                                    simulate_trials(self.ship, base_p,
                                                    self.test_base or self.test, integ),
                                    simulate_trials(self.ship, final_p,
                                                    self.test_final or self.test, integ))
            images.update(plot_trials(self.ship, self.test, {'base tuned': base_p,
                                                             'with effects': final_p},
                                      'overlay_', integ,
                                      sets={t.name: 'test' for t in self.test},
                                      J={'base tuned': self.baseline.J_test_per_trial,
                                         'with effects': self.final.J_test_per_trial}))
            images.update(self.structure_images)
        return _write_all(out, docs, images, ('diagnosis.json', json_text(doc)))


def split_alternate(trials: Sequence[Trial]) -> tuple[list[Trial], list[Trial]]:
    """Every second trial held out: (tune, test)."""
    return list(trials[::2]), list(trials[1::2])


def diagnose(ship: ShipConfig, trials: Trial | Sequence[Trial],
             test: Trial | Sequence[Trial] | None = None, config: DiagnoseConfig | None = None,
             *, checkpoint: str | Path | None = None, resume: bool = False,
             map_fn: MapFn | None = None, **options) -> DiagnosisResult:
    """
    Tune the base model, search the effects library and name the cause(s).

    Tune the base model on ``trials``, search the effects library, name the cause(s) by their gain
    on the held-out ``test`` trials (default: every second trial of ``trials`` is held out; at
    least two are needed). ``options`` are :class:`DiagnoseConfig` fields (e.g.
    ``budget='quick'``). ``checkpoint``: a file where every completed tuning is stored;
    ``resume=True`` continues from it. Ctrl-C raises KeyboardInterrupt after the last completed
    tuning was stored (never a truncated result). ``map_fn(fn, items) -> list`` runs the
    independent tunings of each step (default: plain map; e.g. a Dask client's map for a fleet),
    results in input order; fn touches neither the checkpoint nor the log.
    """
    cfg = _config(DiagnoseConfig, config, options)
    if cfg.residual is True:
        require_jax()   # before the search: says how to install it
    trials, test = _as_list(trials), _as_list(test)
    if not test:
        if len(trials) < 4:
            raise DiagnosisError(
                f'{len(trials)} trial(s) and no test trials: holding out every second one '
                'needs at least four (two held out, or no cause could ever be named)')
        trials, test = split_alternate(trials)
        logger.info('held out (every second trial): %s', ', '.join(unique_names(test)))
    check_trial_sets(trials, test)
    for t in trials + test:   # before any work: every channel the family needs, all named
        t.input_array(ship.family.channels)
    d = _diagnose(ship, trials, test, cfg.settings(), checkpoint=checkpoint, resume=resume,
                  map_fn=map_fn)
    logger.info('3/3 reporting')
    t_report = time.perf_counter()
    # the base model is tuned without a measured wind when it is a candidate
    no_wind = [replace(t, wind=None) if t.wind is not None else t for t in test]
    test_base = no_wind if cfg.measured_signals else test
    test_final = test if (d.measured_wind_used or not cfg.measured_signals) else no_wind
    res_base, _ = residuals_for(ship, d.base_params, test_base, cfg.integrator)
    res_final, _ = residuals_for(ship, d.params, test_final, cfg.integrator)
    timings = {**d.timings_s, 'report': round(time.perf_counter() - t_report, 3)}
    logger.info('   reporting took %.1f s', timings['report'])
    b, f = d.baseline, d.final
    dx = DiagnosisResult(
        d.causes,
        ModelFit(b['J_tune'], b['J_test'], b['J_test_per_trial'], b['params']),
        ModelFit(f['J_tune'], f['J_test'], f['J_test_per_trial'], dict(d.params),
                 f['heldout_gain_total']),
        dict(d.params), d.rounds, d.aliased,
        {'base_model': res_base, 'final_model': res_final}, d.wall_s, ship, test, cfg,
        d.setting, d.impossible, d.impossible_fits, d.measured, timings, test_base, test_final,
        d.advice, noise=d.noise)
    dx.structure = _structure_of(dx, trials, d.measured_wind_used or not cfg.measured_signals)
    dx.causes, dx.mimicking = _structure.one_verdict(dx.causes, dx.structure,
                                                     dx.baseline.J_test, dx.noise)
    return dx


def _structure_of(dx: 'DiagnosisResult', tune_trials: list[Trial], wind_used: bool) -> dict:
    """Return the structure verdict (diagnosis/structure.py) of a finished diagnosis."""
    t0 = time.perf_counter()
    cfg = dx.config
    tune_final = tune_trials if wind_used else [replace(t, wind=None) if t.wind is not None
                                                else t for t in tune_trials]
    final = dx.ship.with_params(dx.params)
    test_final = list(dx.test_final or dx.test)
    learn = None
    train, why = _residual_wanted(dx, tune_final, test_final)
    if why:
        logger.info('   residual network: %s', why)
    if train:   # what a residual network learns beyond the final model
        learn = _structure.learnable(final, tune_final, test_final, cfg.residual_options,
                                     cfg.integrator)
        dx.structure_images = _structure.plot_learnable(learn)
        learn.pop('_plot')
        logger.info('   %s', learn['line'])
    st = _structure.assess(dx.to_dict(), dx.ship, list(tune_final) + test_final, final.params,
                           cfg.integrator, targets=cfg.targets, a_r=cfg.a_r, learnable=learn)
    st['residual'] = {'mode': cfg.residual, 'trained': bool(train), 'why': why}
    dx.timings_s['structure'] = round(time.perf_counter() - t0, 3)
    logger.info('   structure: %s', st['summary'])
    return st


def _residual_wanted(dx: 'DiagnosisResult', tune_final: list[Trial],
                     test_final: list[Trial]) -> tuple[bool, str]:
    """
    Return whether to train the residual network after the search, and why ('' if asked).

    residual='auto' trains it when what remains is not noise, as the report will say it: the
    structure verdict without the network, with the named causes moved to mimicking when it
    wins (:func:`~mmg_tuner.diagnosis.structure.one_verdict`: what remains is then the tuned
    base model's error), judged against what sensor noise alone reaches (diagnosis/noise.py:
    the floor + 2 standard deviations of its draws, about 2 x the floor; "no sign of a
    structural gap" is said below it), and JAX is importable. On the verdict tests' SUZAKU
    trials: clean 1.0 x the floor and a lag left beside a named current 1.7 x (noise: not
    trained); hull forces x 1.45 (trained).
    """
    mode = dx.config.residual
    if mode != 'auto':
        return bool(mode), ''
    cfg = dx.config
    st = _structure.assess(dx.to_dict(), dx.ship, list(tune_final) + list(test_final),
                           dx.ship.with_params(dx.params).params, cfg.integrator,
                           targets=cfg.targets, a_r=cfg.a_r)
    _structure.one_verdict(list(dx.causes), st, dx.baseline.J_test, dx.noise)
    if st.get('remaining_is_noise') is not False:
        return False, ('not trained: ' + (st.get('noise') or 'no noise floor to judge what '
                                          'remains against'))
    try:
        require_jax()
    except MissingDependencyError as exc:
        return False, f"not trained although {st.get('noise')}: {exc}"
    return True, f"trained: {st.get('noise')}"


# ---------------------------------------------------------------------------------- simulate
def simulate(model: ShipConfig | Model, trial: Trial, *, integrator: str = 'rk4',
             substeps: int = 1) -> Trial:
    """
    Return the model's prediction of a recorded trial (a ship, or a ship and its network).

    As a :class:`Trial` on the same time grid (compare ``run.states`` with ``trial.states`` sample
    by sample). It starts from the state the tuning objective uses (a quadratic fit over the first
    10 s) and is driven by the recorded rpm, rudder, measured wind and thrusters. A run that
    diverges or leaves the model's range has NaN states from then on and a note saying when and
    why.
    """
    _check('integrator', integrator, integrator in INTEGRATORS, f'one of {sorted(INTEGRATORS)}')
    _check('substeps', substeps, _is_int(substeps) and 1 <= substeps <= 1000,
           'a whole number in [1, 1000]')
    ship, net = as_model(model).ship, as_model(model).residual
    if net is not None:  # a hybrid (or pure network) named by the params.yaml
        return _simulate_hybrid(ship, net, trial, integrator=integrator, substeps=substeps)
    traj = simulate_recorded(ship, trial, None, integrator, substeps)
    notes = [f'simulated by mmg_tuner ({ship.name}, {integrator}, {substeps} substep(s)) from '
             'the fitted start state']
    if not traj.ok:
        msg = (f'the simulation stopped at t = {traj.fail_time_s:.2f} s: {traj.status}; '
               'states are NaN from there')
        notes.append(msg)
        logger.warning('%s: %s', trial.name, msg)
    # every input channel by name (a twin-azimuth trial has no rpm/rudder pair)
    return Trial(trial.t.copy(), traj.states, name=trial.name,
                 source=f'simulated: {trial.source or trial.name}', notes=notes,
                 start_s=trial.start_s, inputs={n: v.copy() for n, v in trial.inputs.items()})


def config_fields(cls) -> list[str]:
    """Field names of a config dataclass (for the CLIs)."""
    return [f.name for f in fields(cls)]


# ---------------------------------------------------------------------------------- evaluate
@dataclass(frozen=True)
class EvaluateConfig:
    """
    Options of :func:`evaluate` (the ``evaluate`` command's flags), validated on creation.

    restart_every_s: restart each simulation from the measured state every N s (Wakita et al.
    2022 use 100 s; 0: never); integrator, substeps: as for simulate; horizons: n-step
    prediction horizons [samples] (e.g. (1, 5, 10, 20, 30, 40, 50), the MBPE-LOGO paper's):
    also the n-step RMSE and the free-run relative errors (``tuning/nstep.py``; None: not).
    """

    restart_every_s: float = 100.0
    integrator: str = 'rk4'
    substeps: int = 1
    horizons: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        _check('restart_every_s', self.restart_every_s,
               _finite(self.restart_every_s) and self.restart_every_s >= 0,
               'a finite number >= 0 [s] (0: never)')
        _check('integrator', self.integrator, self.integrator in INTEGRATORS,
               f'one of {sorted(INTEGRATORS)}')
        _check('substeps', self.substeps, _is_int(self.substeps) and 1 <= self.substeps <= 1000,
               'a whole number in [1, 1000]')
        if self.horizons is not None:
            _check('horizons', self.horizons, isinstance(self.horizons, (list, tuple)) and len(
                self.horizons) > 0 and all(_is_int(h) and 1 <= h <= MAX_HORIZON
                                           for h in self.horizons),
                   f'a non-empty list of whole numbers of steps in [1, {MAX_HORIZON}]')
            object.__setattr__(self, 'horizons', tuple(sorted(set(self.horizons))))


def evaluate(ship: ShipConfig | Model, trials: Trial | Sequence[Trial],
             config: EvaluateConfig | None = None, **options) -> 'EvaluateResult':
    """
    How good ``ship``'s model is on recorded ``trials``.

    Each is simulated with its recorded inputs (and measured wind), restarting from the measured
    state every ``restart_every_s`` s, and scored per trial by the RMS error of each state and the
    index of Wakita et al. (2022) eq. 26 (standardised by deviations pooled over all the trials).
    ``options`` are :class:`EvaluateConfig` fields. ``result.write(out)`` writes evaluate.json,
    evaluate.md and the plots. A model whose ensemble network carries a calibrated prediction
    interval (``tune --model auto`` or ``--residual-seeds N``, N >= 2) also gets
    ``result.coverage``: the share of samples inside its interval (``tuning/interval.py``).

    Examples
    --------
    >>> ship = mt.load_ship('esso_osaka_3m')
    >>> trials = mt.load_trials(['data/esso_osaka_frt/berthing'], ship=ship)
    >>> res = mt.evaluate(ship, trials, restart_every_s=100)
    >>> {n: s.index for n, s in res.trials.items()}

    """
    cfg = _config(EvaluateConfig, config, options)
    trials = _as_list(trials)
    res = _evaluate(ship, trials, cfg.restart_every_s, cfg.integrator, cfg.substeps,
                    horizons=cfg.horizons)
    interval = model_interval(as_model(ship))
    if interval is not None:   # an ensemble with a calibrated interval: does it hold here?
        res.coverage = coverage(interval, trials, cfg.restart_every_s, cfg.integrator)
    return res


# ---------------------------------------------------------------------------------- identify
@dataclass(frozen=True)
class IdentifyConfig:
    """
    Options of :func:`identify` (``tune --method``/``--bollard-pull``), validated on creation.

    method: 'lo' (the local step: one linear least-squares problem), 'go' (the global step from
    the ship's values) or 'lo-go' (GO from LO, pulled toward it; MBPE-LOGO); bollard_pull: a
    bollard-pull table (CSV path with columns n,thrust [rev/s, N per thruster], or a
    ``BollardTable``; None: keep the ship's thrust curve); thrust_degree: the polynomial's
    degree (None: by leave-one-out error, <= 5); targets: the hull coefficients (None: the
    family's); smooth_s: Savitzky-Golay window on the velocities before LO [s] (0: none);
    ridge: GO's pull toward LO per squared relative change; segment_s: GO simulates pieces of
    this length from the measured state (0: whole trials, single shooting); integrator,
    substeps: GO's simulation; max_iter: GO's Levenberg-Marquardt iterations; grow: add the
    trials one by one (the paper's Algorithm 1).
    """

    method: str = 'lo-go'
    bollard_pull: str | Path | BollardTable | None = None
    thrust_degree: int | None = None
    targets: tuple[str, ...] | None = None
    smooth_s: float = 2.0
    ridge: float = 1e-6
    segment_s: float = 20.0
    integrator: str = 'rk4'
    substeps: int = 1
    max_iter: int = 40
    grow: bool = False

    def __post_init__(self) -> None:
        E = TuningError
        _check('method', self.method, self.method in METHODS, f'one of {list(METHODS)}', E)
        _check('thrust_degree', self.thrust_degree, self.thrust_degree is None or (
            _is_int(self.thrust_degree) and 1 <= self.thrust_degree <= 5),
            'a whole number in [1, 5] (or None: chosen by leave-one-out error)', E)
        for name in ('smooth_s', 'ridge', 'segment_s'):
            v = getattr(self, name)
            _check(name, v, _finite(v) and v >= 0, 'a finite number >= 0', E)
        _check('integrator', self.integrator, self.integrator in INTEGRATORS,
               f'one of {sorted(INTEGRATORS)}', E)
        _check('substeps', self.substeps, _is_int(self.substeps) and 1 <= self.substeps <= 1000,
               'a whole number in [1, 1000]', E)
        _check('max_iter', self.max_iter, _is_int(self.max_iter) and self.max_iter >= 1,
               'a whole number >= 1', E)
        if self.targets is not None:
            _check('targets', self.targets, len(self.targets) > 0 and all(
                isinstance(t, str) for t in self.targets), 'a non-empty list of names', E)
            object.__setattr__(self, 'targets', tuple(self.targets))


def identify(ship: ShipConfig, trials: Trial | Sequence[Trial],
             config: IdentifyConfig | None = None, **options) -> IdentifyResult:
    """
    Identify a control-oriented model local -> global (MBPE-LOGO, ``tuning/lo_go.py``).

    The thrust polynomial from the bollard table, the azimuth dynamics from command and
    feedback (when recorded), then the hull coefficients by LO, GO or LO -> GO. ``options``
    are :class:`IdentifyConfig` fields. ``result.write(out)`` writes params.yaml (loaded by
    ``load_ship(name, 'out/params.yaml')``), identify.md and identify.json.

    Examples
    --------
    >>> ship = mt.load_ship('qiuxin_tug')
    >>> res = mt.identify(ship, trials, bollard_pull='bollard.csv', method='lo-go')
    >>> res.write('identified')

    """
    cfg = _config(IdentifyConfig, config, options)
    trials = _as_list(trials)
    table = cfg.bollard_pull
    if table is not None and not isinstance(table, BollardTable):
        table = read_bollard_table(table)
    elif isinstance(table, BollardTable):
        table = check_bollard_table(table.n, table.thrust, table.source or 'bollard table')
    return _identify(ship, trials, cfg.method, table, cfg.thrust_degree, cfg.targets,
                     cfg.smooth_s, cfg.ridge, cfg.segment_s, cfg.integrator, cfg.substeps,
                     cfg.max_iter, cfg.grow)
