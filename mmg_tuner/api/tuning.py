"""The tune workflow: options, the fit, its results and the optional residual network."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
import logging
import math
from pathlib import Path
import time
from typing import Any, Callable, cast, Mapping, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner.api._common import (_as_list, _check, _check_common, _config, _finite, _is_int,
                                   _write_all, config_fields)
from mmg_tuner.core.correction import FEATURE_PARAMS
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import MissingDependencyError, MmgTunerError, TuningError
from mmg_tuner.learn import ensemble, require_jax, ResidualConfig, ResidualNet, train_residual
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.train import members, n_members, split_validation
from mmg_tuner.tuning.choice import Choice, choose_model
from mmg_tuner.tuning.evaluate import compare_index, evaluate, pooled_sigma
from mmg_tuner.tuning.factory import make_objective, ObjectiveSpec
from mmg_tuner.tuning.gate import check_before_writing, mark_note
from mmg_tuner.tuning.gate import markdown as gate_markdown
from mmg_tuner.tuning.interval import calibrate_interval, with_interval
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.objective import Objective, paper_weights
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.prior_cv import (
    choose_prior, folds, label, PriorChoice, PUBLISHED, sessions, TIE)
from mmg_tuner.tuning.report import (json_text, markdown_report, params_yaml_text, plot_trials,
                                     unique_names)
from mmg_tuner.tuning.tuner import Progress, Tuner, TuningResult
import numpy as np


INDEX_WEIGHTS = 'index'
"""TuneConfig.weights: 1 / sigma^2 of each state pooled over the trials fitted."""
logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split


@dataclass(frozen=True)
class TuneConfig:
    """
    Options of :func:`tune` (the ``tune`` command's flags), validated on creation.

    targets: parameter names to tune (default: the ship's); a_r: relative box half-width
    (default: the ship's, 0.5); bounds: per-parameter a_r or (lower, upper); weights: six
    non-negative error weights on x, y, psi, u, v, r (default: the paper's L, L, pi/4, 0, 0, 0;
    'index': 1 / sigma^2 of each state pooled over the trials fitted, the standardisation of
    the index ``evaluate`` scores with);
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
    the hybrid when JAX is installed and the trials allow it, and their blend (the two
    ensembles averaged, ``learn.ensemble``), compare the candidates on the
    last quarter of each tuning trial per kind of run (``tuning/choice.py``) and keep the
    recommended one; with residual_seeds >= 2 the chosen network's ensemble carries a
    prediction interval calibrated there, ``tuning/interval.py``). polish: after CMA-ES, a
    local least-squares polish of at most this many simulations on the same objective's
    residuals (``tuning/lsq.py``; 0: none). prior_choices: prior weights to choose from by
    cross-validation over sessions (days) of the tuning trials, the published values always
    a candidate (``tuning/prior_cv.py``; the choice and its table are in the result's
    ``prior_choice``); empty: use ``prior``. joint: with model 'auto', a fifth candidate, the
    trained hybrid trained on together with the tuned coefficients (``learn.JointCoefficients``;
    not in the default: registered, it gained nothing over the hybrid).
    """

    targets: tuple[str, ...] | None = None
    a_r: float | None = None
    bounds: Mapping[str, float | tuple[float, float]] = field(default_factory=dict)
    weights: tuple[float, ...] | str | None = None
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
    prior_choices: tuple[float, ...] = ()
    joint: bool = False

    def __post_init__(self) -> None:
        E = TuningError
        _check_common(self, E)
        _check_residual(self, E)
        _check('model', self.model, self.model in MODEL_CHOICES, f'one of {list(MODEL_CHOICES)}',
               E)
        _check('model', self.model, self.model == 'physics' or self.residual is None,
               "'physics' with residual set (model 'auto' trains the networks itself)", E)
        _check('joint', self.joint, isinstance(self.joint, bool) and
               (not self.joint or self.model == 'auto'),
               "True or False; True only with model 'auto' (the joint is one of its "
               'candidates)', E)
        _check('polish', self.polish, _is_int(self.polish) and self.polish >= 0,
               'a whole number >= 0 (0: no least-squares polish)', E)
        _check('segment_s', self.segment_s, _finite(self.segment_s) and self.segment_s >= 0,
               'a finite number >= 0 [s] (0: whole trials)', E)
        _check('balance', self.balance, self.balance in ('sample', 'trial', 'group'),
               "'sample', 'trial' or 'group' (each kind of run the same weight: tune's "
               'groups)', E)
        _check('prior', self.prior, _finite(self.prior) and self.prior >= 0,
               'a finite number >= 0 (0: no prior)', E)
        object.__setattr__(self, 'prior_choices', tuple(self.prior_choices))
        _check('prior_choices', self.prior_choices,
               all(_finite(w) and float(w) >= 0 for w in self.prior_choices),
               'finite numbers >= 0 (the prior weights to choose from by leaving days out; '
               'empty: use prior)', E)
        _check('prior_choices', self.prior_choices, not self.prior_choices or not self.prior,
               f'empty with prior = {self.prior:g} (give one weight or the choices)', E)
        if self.targets is not None:
            object.__setattr__(self, 'targets', tuple(self.targets))
        for name, b in dict(self.bounds).items():
            ok = (_finite(b) and float(b) > 0) if not isinstance(b, tuple) else (
                len(b) == 2 and all(_finite(x) for x in b) and float(b[0]) < float(b[1]))
            _check(f'bounds[{name!r}]', b, ok, 'a finite a_r > 0 or (lower, upper) with '
                   'lower < upper', E)
        if self.weights is not None and not isinstance(self.weights, str):
            w = tuple(float(x) if _finite(x) else math.nan for x in self.weights)
            _check('weights', self.weights, len(w) == 6 and all(x >= 0 for x in w),
                   'six finite numbers >= 0 (x, y, psi, u, v, r)', E)
            _check('weights', self.weights, any(x > 0 for x in w),
                   'not all zero (J would be 0 for every candidate)', E)
            object.__setattr__(self, 'weights', w)
        _check('weights', self.weights, not isinstance(self.weights, str)
               or self.weights == INDEX_WEIGHTS,
               f'six numbers >= 0 or {INDEX_WEIGHTS!r} (1 / sigma^2 of each state)', E)
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
        _check('max_evals', self.max_evals, self.max_evals >= 1 or not self.shoot_every_s,
               f'>= 1 with shoot_every_s = {self.shoot_every_s:g} (the polish alone does not '
               'model its restarts: max_evals=0 and shoot_every_s cancel each other, nothing '
               'would tune)', E)

    def check_polish(self, dim: int) -> None:
        """Refuse a polish budget below one Jacobian of ``dim`` targets and a step."""
        if self.polish and self.polish < dim + 2 and self.residual != 'network':
            raise TuningError(f'polish = {self.polish}: fewer simulations than one finite-'
                              f'difference Jacobian of the {dim} targets and a step; give at '
                              f'least {dim + 2}, or 0 for none')

    def objective_spec(self, trials: Sequence[Trial] = ()) -> ObjectiveSpec:
        """
        Return what CMA-ES minimises, for the one objective factory (tuning/factory.py).

        ``trials``: those fitted, for weights 'index' (1 / sigma^2 pooled over them).
        """
        weights = self.weights
        if weights == INDEX_WEIGHTS:
            if not trials:
                raise TuningError("weights 'index' needs the trials to pool sigma over")
            sig = pooled_sigma(trials)
            weights = tuple(1.0 / sig[n] ** 2 for n in STATE_NAMES)   # (sig > 0: checked)
        return ObjectiveSpec(cast('tuple[float, ...] | None', weights), self.shoot_every_s,
                             self.integrator, self.substeps, self.segment_s, self.balance,
                             self.prior)


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
        return cast(float, self._sum('tune'))   # (a fit always has tuning trials)

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
    prior_choice: PriorChoice | None = None  # prior_choices: the days-out cross-validation
    # tune --model auto: every candidate compared, by name (the recommended: tuned_model)
    candidates: dict[str, ShipConfig | Model] = field(repr=False, default_factory=dict)

    @property
    def tuned_ship(self) -> ShipConfig:
        """Return the tuned ship (the physics; the residual network: :attr:`tuned_model`)."""
        return self.ship.with_params(self.params)

    @property
    def tuned_model(self) -> Model:
        """Return the tuned model: the tuned ship and the trained residual network, if any."""
        return Model(self.tuned_ship, None if self.residual is None else self.residual.net)

    def report(self) -> dict[str, Any]:
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
                         'weights': list(c.objective_spec(self.trials).weights
                                         or paper_weights(self.ship.L_pp)),
                         'weights_rule': (c.weights if isinstance(c.weights, str) else
                                          'given' if c.weights else 'paper'),
                         'shoot_every_s': c.shoot_every_s, 'integrator': c.integrator,
                         'dt': self.dt, 'seed': c.seed, 'max_evals': c.max_evals,
                         'popsize': [c.popsize, c.max_popsize]},
            'finite': bool(math.isfinite(self.J.tune)),
            'residual': None if self.residual is None else self.residual.report(),
            'model_choice': None if self.choice is None else {
                **self.choice.to_dict(), 'notes': list(self.choice_notes)},
            'prior_choice': None if self.prior_choice is None else self.prior_choice.to_dict(),
        }

    def write(self, out: str | Path | OutputDir, plots: bool = True,
              write_unphysical: bool = False) -> list[Path]:
        """
        Write the result's files into ``out``, the completion marker last.

        params.yaml, report.md, plot_<trial>.png, and report.json last (its presence means the set
        is complete). ``out``: a new or empty folder, or an open :class:`OutputDir`. With a trained
        residual, its weights (params.residual.npz) come first and params.yaml names them.
        A model that cannot be a ship or diverges on its trials is refused (TuningError) unless
        ``write_unphysical`` (``tuning/gate.py``; marked in the report).
        """
        names = ', '.join(unique_names(self.trials)) or 'the tuning trials'
        marks = check_before_writing(self.ship, self.params, self.trials + self.test,
                                     'tuned parameters', write_unphysical,
                                     self.config.integrator, self.config.substeps)
        rep = self.report()
        params_text = params_yaml_text(self.ship, self.params,
                                       mark_note(f'tuned by mmg_tuner on {names}', marks))
        md = markdown_report(rep) + gate_markdown(marks)
        if self.prior_choice is not None:
            md += prior_markdown(self.prior_choice)
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


def _write_with_residual(res: TuneResult, out: str | Path | OutputDir, params_text: str,
                         md: str, plots: bool) -> list[Path]:
    """TuneResult.write with a residual: the weights first, then params.yaml naming them."""
    r = cast(ResidualResult, res.residual)   # (called only with a residual)
    own = not isinstance(out, OutputDir)
    # (own: out is a path, else the open OutputDir; mypy does not narrow through own)
    od = OutputDir.open(cast('str | Path', out)) if own else cast(OutputDir, out)
    try:
        paths = [od.write_bytes(RESIDUAL_FILE, r.npz_bytes())]
        text = params_text + (f'# the {r.kind} network beside this file (mmg_tuner tune '
                              f'--residual)\nresidual: {RESIDUAL_FILE}\n')
        images = {}
        if plots and r.kind in ('hybrid', 'joint'):   # the physics curves (the hybrid's: evaluate)
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


def tune(ship: ShipConfig, trials: Trial | Sequence[Trial],
         test: Trial | Sequence[Trial] | None = None, config: TuneConfig | None = None, *,
         checkpoint: str | Path | None = None, resume: bool = False,
         progress: Callable[[Progress], None] | None = None,
         groups: Mapping[str, str] | None = None, **options: Any) -> TuneResult:
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
    cfg.check_polish(space.dim)
    sets = _report_sets(ship, trials, test, cfg)
    obj = sets['tune'][0]
    logger.info('tuning %d parameters of %s on %d trial(s)%s; box a_r = %g', space.dim,
                ship.name, len(trials), f', testing on {len(test)}' if test else '',
                cfg.a_r or ship.a_r)
    if cfg.residual is not None:
        require_jax()   # before any work: says how to install it
    prior_choice = None
    if cfg.prior_choices and cfg.residual != 'network':
        prior_choice = choose_prior_by_days(ship, trials, cfg, groups)
        cfg = replace(cfg, prior=prior_choice.prior or 0.0, prior_choices=())
    if cfg.residual == 'network' or (prior_choice is not None and prior_choice.prior is None):
        # the pure network, or the published values chosen: no physics to tune
        pre = _fit(sets, ship.params)
        result = TuneResult({n: float(ship[n]) for n in space.names}, pre, pre, [], [], 0, 0,
                            0.0, False, ship, space, cfg, trials, test, obj.batch.dt)
    else:
        theta, res, evaluations, wall_s = _fit_physics(
            ship, trials, cfg, space, groups, checkpoint, resume, progress)
        tuned = space.full_params(ship.params, theta)[0]
        result = TuneResult(dict(zip(space.names, map(float, theta))), _fit(sets, tuned),
                            _fit(sets, ship.params), space.on_bound(theta),
                            list(res.history), evaluations, res.restarts, wall_s,
                            res.interrupted, ship, space, cfg, trials, test, obj.batch.dt)
    if prior_choice is not None:   # the choice's fits count as the tuning's work
        result.prior_choice = prior_choice
        result.evaluations += prior_choice.simulations
        result.wall_s += prior_choice.wall_s
    if cfg.residual is not None and not result.interrupted:
        result.residual = _train_residual(result, groups)
    if cfg.model == 'auto' and not result.interrupted:
        _choose(result, groups)
    return result


def _report_sets(ship: ShipConfig, trials: list[Trial], test: list[Trial], cfg: TuneConfig
                 ) -> dict[str, tuple[Objective, list[str]]]:
    """Return the objectives J is reported by (whole trials), per set, with trial names."""
    spec = cfg.objective_spec(trials)
    names = unique_names(trials + test)
    sets = {'tune': (make_objective(ship, trials, spec.plain), names[:len(trials)])}
    if test:
        sets['test'] = (make_objective(ship, test, spec.plain), names[len(trials):])
    return sets


def _fitting_objective(ship: ShipConfig, trials: list[Trial], cfg: TuneConfig,
                       space: ParameterSpace, groups: Mapping[str, str] | None) -> Objective:
    """Return the objective the physics is fitted by (the recipe's segments, prior, ...)."""
    spec = cfg.objective_spec(trials)
    if cfg.balance == 'group':   # without kinds each trial is its own: balance 'trial'
        spec = replace(spec, group_of=dict(groups) if groups else
                       {n: n for n in unique_names(trials)})
    return make_objective(ship, trials, spec, space)


def _fit_physics(ship: ShipConfig, trials: list[Trial], cfg: TuneConfig, space: ParameterSpace,
                 groups: Mapping[str, str] | None, checkpoint: str | Path | None = None,
                 resume: bool = False, progress: Callable[[Progress], None] | None = None
                 ) -> tuple[np.ndarray, TuningResult, int, float]:
    """
    Tune the physics' targets: CMA-ES and/or the least-squares polish (the one fit of ``tune``).

    Returns the tuned targets, CMA-ES's result, the simulations run and the wall time [s].
    """
    spec = cfg.objective_spec(trials)
    minimised = _fitting_objective(ship, trials, cfg, space, groups)
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
            loc = local_least_squares(space, minimised, theta, cfg.polish, method='lm')
            theta, evaluations = loc.theta, evaluations + loc.simulations
            logger.info('least-squares polish: %d simulations, J %.6g -> %.6g',
                        loc.simulations, res.J, loc.J)
    wall_s = res.wall_s + (time.perf_counter() - t0 - res.wall_s if cfg.polish else 0.0)
    return theta, res, evaluations, wall_s


def choose_prior_by_days(ship: ShipConfig, trials: Sequence[Trial], cfg: TuneConfig,
                         groups: Mapping[str, str] | None = None) -> PriorChoice:
    """
    Choose ``cfg.prior_choices``' weight by leaving sessions (days) out (``tuning/prior_cv.py``).

    Each fold of whole sessions is held out once; the physics is tuned on the rest with each
    weight as :func:`tune` tunes it, and scored on the fold by the index (restarts every 100 s,
    sigma pooled over the fold). ``groups``: trial name -> kind of run (the table's columns,
    and the balance of the fits); default each trial its own kind. One trial: nothing to hold
    out, the largest weight is returned unvalidated (``PriorChoice.note`` says so). Ctrl-C
    during a fit stops the choice (KeyboardInterrupt): nothing half-fitted is scored.
    """
    trials = list(trials)
    names = unique_names(trials)
    by_name = dict(zip(names, trials))
    kind_of = {n: (groups or {}).get(t.name, n) for n, t in zip(names, trials)}
    session_of = sessions(names)
    fold_names = folds(session_of)
    priors = sorted({float(w) for w in cfg.prior_choices})
    if len({label(w) for w in priors}) < len(priors):
        raise TuningError(f'prior_choices {priors}: weights closer than 12 significant digits')
    if len(fold_names) < 2:
        choice = PriorChoice.unvalidated(priors, fold_names)
        logger.warning('prior choices: %s; %s', choice.note, choice.chosen)
        return choice
    if all(s == n for n, s in session_of.items()):
        logger.info('prior choices: no date common to the trial names; each trial is its own '
                    'session (runs of one day on both sides of a split look better than a new '
                    'day will)')
    if cfg.max_evals:
        logger.warning('prior choices: %d CMA-ES runs of up to %d evaluations each before the '
                       'tuning itself (max_evals=0 with a polish is the quick way)',
                       len(fold_names) * len(priors), cfg.max_evals)
    space = ParameterSpace.around(ship, cfg.targets, cfg.a_r, dict(cfg.bounds))
    fit_cfg = replace(cfg, prior_choices=(), residual=None, model='physics',
                      joint=False)
    held: dict[str, dict[str, float | None]] = {PUBLISHED: {}, **{label(w): {} for w in priors}}
    sims, t0 = 0, time.perf_counter()
    for i, out in enumerate(fold_names, 1):
        held_out = [by_name[n] for n in out]
        rest = [by_name[n] for n in names if n not in out]
        sig = pooled_sigma(held_out)
        scored = {PUBLISHED: ship}
        for w in priors:
            theta, res, evaluations, _ = _fit_physics(ship, rest, replace(fit_cfg, prior=w),
                                                      space, groups)
            if res.interrupted:   # CMA-ES caught Ctrl-C: do not score half a fit
                raise KeyboardInterrupt
            sims += evaluations
            scored[label(w)] = ship.with_params(dict(zip(space.names, map(float, theta))))
        for c, model in scored.items():
            ev = evaluate(model, held_out, 100.0, cfg.integrator, cfg.substeps, sigma=sig)
            # (evaluate names its scores uniquely, in the trials' order)
            held[c].update(zip(out, (s.index for s in ev.trials.values())))
        logger.info('prior choices: fold %d of %d held out (%s): %s', i, len(fold_names),
                    ', '.join(out), ', '.join(
                        f'{c} {_mean_index([held[c][n] for n in out])}' for c in held))
    choice = choose_prior(priors, held, kind_of, fold_names)
    choice.simulations, choice.wall_s = sims, time.perf_counter() - t0
    logger.info('prior choices: %s chosen (worst ratio to published over the kinds %.3f); %d '
                'simulations in %.0f s', choice.chosen, choice.score[choice.chosen], sims,
                choice.wall_s)
    return choice


def _mean_index(values: list[float | None]) -> str:
    return ('failed' if any(v is None for v in values)
            else f'{np.mean([float(v) for v in values if v is not None]):.3g}')


def prior_markdown(choice: PriorChoice) -> str:
    """Return the report's section on the prior chosen by leaving days out."""
    return ('\n## Prior chosen by leaving days out (prior choices)\n\nEach fold of whole '
            'sessions (the date in the trial names) held out once; the physics tuned on the '
            'rest with each prior weight, scored on the fold (index, Wakita et al. 2022 eq. '
            '26, restarts every 100 s, sigma pooled over the fold); mean per kind, ratio to '
            'the published values in brackets; the lowest worst ratio wins, ties within '
            f'{TIE:g} go to the more cautious (`tuning/prior_cv.py`).\n\n'
            + choice.markdown() + f'\nChosen: **{choice.chosen}**'
            + (' (nothing tuned: no weight beat the published values on every kind of '
               'held-out run)' if choice.prior is None else '')
            + '.\nFolds: ' + '; '.join(', '.join(f) for f in choice.folds) + '\n')


def _choose(result: TuneResult, groups: Mapping[str, str] | None) -> None:
    """
    ``model='auto'``: train the networks the data allow, compare, keep the recommended one.

    Candidates: the tuned physics; the hybrid and the pure network (each ``residual_seeds``
    seeds, one exact ensemble) when JAX is installed and their training succeeds; their blend
    (every member of both averaged: half the physics plus the mean output, no further
    training), which keeps the physics where the network strays and the network where the
    physics' structure is wrong. Compared on
    the last quarter of each tuning trial (``learn.train.split_validation``: the part the
    networks only chose their epoch on) by ``tuning.choice.choose_model``, per kind of run
    (``groups``). The chosen network, an ensemble of >= 2, carries its calibrated interval.
    """
    cfg = result.config
    physics = result.tuned_ship
    cands: dict[str, ShipConfig | Model] = {'physics': physics}
    trained, notes = {}, []
    joint_params: dict[str, float] = {}
    try:
        require_jax()
    except MissingDependencyError as exc:
        notes.append(f'networks not trained: {exc}')
    else:
        for kind in ('hybrid', 'network'):
            sub = replace(result, config=replace(cfg, residual=kind, model='physics', joint=False),
                          residual=None)
            try:
                r = _train_residual(sub, groups)
            except MmgTunerError as exc:   # e.g. trials too short for its windows
                notes.append(f'{kind}: not trained ({exc})')
                logger.warning('--model auto: the %s network was not trained: %s', kind, exc)
                continue
            trained[kind] = r
            cands[kind] = Model(physics, r.net)
        if 'hybrid' in trained and 'network' in trained:
            trained['blend'] = _blend(result, trained['hybrid'], trained['network'])
            cands['blend'] = Model(physics, trained['blend'].net)
        published = result.prior_choice is not None and result.prior_choice.prior is None
        if cfg.joint and published:
            notes.append('joint: not trained (the prior choice kept the published values: '
                         'nothing tuned to train on)')
        elif cfg.joint and 'hybrid' in trained and result.space.dim:
            try:
                joint, joint_params = _train_joint(result, groups, trained['hybrid'])
            except MmgTunerError as exc:
                notes.append(f'joint: not trained ({exc})')
                logger.warning('--model auto: the joint model was not trained: %s', exc)
            else:
                trained['joint'] = joint
                cands['joint'] = Model(result.ship.with_params(
                    {**result.params, **joint_params}), joint.net)
    rc = _residual_config(cfg)
    val = split_validation(result.trials, rc.validation_fraction, rc.window)[1]
    choice = choose_model(cands, val, groups, integrator=rc.integrator)
    logger.info('--model auto: candidates on the validation part of the tuning trials:\n%s'
                'recommended: %s', choice.markdown(), choice.chosen)
    if choice.chosen == 'joint':   # its physics is written: J reported for it
        result.params = {**result.params, **joint_params}
        result.J = _fit(_report_sets(result.ship, result.trials, result.test, cfg),
                        result.tuned_ship.params)
        result.bounds_hit = result.space.on_bound(
            np.array([result.params[n] for n in result.space.names]))
        notes.append("the physics written is the joint training's (its coefficients moved "
                     'from the tuned values with the network); J above is of those')
    if choice.chosen != 'physics':
        r = trained[choice.chosen]
        if r.seeds < 2:
            notes.append(f'no prediction interval: the {choice.chosen} is one network (an '
                         'interval needs an ensemble of >= 2)')
        else:
            try:
                # (the chosen is not the physics: a Model with its network)
                # members that differ in physics as well as weights (the tuned physics and
                # the one the tuning started from, alone) and the recorded start's error:
                # the registered rule of bench/interval_members_preregistration.md (N3)
                iv = calibrate_interval(cast(Model, cands[choice.chosen]), val, 0.9,
                                        integrator=rc.integrator, start_error=True,
                                        physics=(physics, result.ship))
            except TuningError as exc:   # e.g. a member diverges where their mean does not
                notes.append(f'no prediction interval: {exc}')
                logger.warning('--model auto: the recommended %s is written without a '
                               'prediction interval: %s', choice.chosen, exc)
            else:
                # (the interval's model is the chosen network's, which it keeps)
                r.net = cast(ResidualNet, with_interval(iv).residual)
                # the model written (the joint's physics is its own)
                cands[choice.chosen] = Model(cast(Model, cands[choice.chosen]).ship, r.net)
                notes.append('prediction interval: nominal 90 %, factors '
                             f'{iv.to_dict()["scale"]} (calibrated on the validation part; '
                             f'members: the {len(iv.members) - 2} networks, the tuned and the '
                             "starting physics alone; with the recorded start's error)")
        result.residual = r
    result.choice, result.choice_notes, result.candidates = choice, notes, cands


def _train_joint(result: TuneResult, groups: Mapping[str, str] | None,
                 hybrid: ResidualResult) -> tuple[ResidualResult, dict[str, float]]:
    """
    Train the hybrid on together with the tuned coefficients (``--model auto``'s joint).

    Training goes on from the trained hybrid (its ensemble: each member keeps its own block,
    one set of coefficients under them all), so the joint starts where the hybrid is and keeps
    an epoch only if it beats it on the validation windows. The coefficients start from the
    tuned values, stay in the tuning's boxes and are pulled toward the values the tuning
    started from with the tuning's prior weight, carried into the training loss's units (its
    ratio to the fitting objective's data part at the tuned values: the same balance of data
    and prior). Returns the result (scored against the tuned physics) and the coefficients.
    """
    from mmg_tuner.learn import JointCoefficients
    cfg = result.config
    rc = _residual_config(replace(cfg, residual='hybrid', model='physics', joint=False))
    physics = result.tuned_ship
    space = result.space
    free = [i for i, n in enumerate(space.names) if n not in FEATURE_PARAMS]
    names = tuple(space.names[i] for i in free)
    if not names:
        raise TuningError('no tuned coefficient can be trained with the network (only '
                          f'{", ".join(space.names)})')
    weight = 0.0
    if cfg.prior:
        obj = _fitting_objective(result.ship, result.trials, cfg, space, groups)
        p = physics.params[None]
        J, _ = obj.per_trial(p)   # inf where a run failed (the call's total is a ranking)
        total, pull = float(obj(p)[0]), float(obj.prior(p)[0]) if obj.prior else 0.0
        if obj.prior is not None and np.all(np.isfinite(J)) and total - pull > 0:
            weight = obj.prior.weight / (total - pull)
    coeffs = JointCoefficients(names, tuple(float(physics[n]) for n in names),
                               tuple(float(space.lower[i]) for i in free),
                               tuple(float(space.upper[i]) for i in free),
                               tuple(float(space.pre[i]) for i in free), weight)
    logger.info('training the joint model: the hybrid trained on with %d coefficients (prior '
                "weight %.3g per unit of the physics' loss)", len(names), weight)
    fit = train_residual(physics, result.trials, config=rc, coefficients=coeffs,
                         start=hybrid.net)
    # the physics written if it is chosen: it must run alone as any tuned physics (raises)
    check_before_writing(result.ship, {**result.params, **fit.coefficients},
                         result.trials + result.test, 'joint coefficients',
                         integrator=cfg.integrator, substeps=cfg.substeps)
    joint = result.ship.with_params({**result.params, **fit.coefficients})
    model = Model(joint, fit.net)
    index, held = _scored(physics, model, result, rc)
    logger.info('   joint: %.1f s, %d epochs; share %.1f %%', fit.seconds, fit.epochs,
                100 * fit.share)
    return (ResidualResult(fit.net, 'joint', fit.share, fit.val_gain, index, held,
                           fit.seconds, fit.epochs, fit.seed,
                           {**asdict(rc), 'coefficients': fit.coefficients,
                            'start': 'the hybrid'}, n_members(fit.net)),
            fit.coefficients)


def _scored(physics: ShipConfig, model: Model, result: TuneResult, rc: ResidualConfig
            ) -> tuple[dict[str, dict[str, Any]], float | None]:
    """Return the index of physics and model on the tuning and test trials, and the gain."""
    index = {which: compare_index(physics, model, trials, integrator=rc.integrator)
             for which, trials in (('tune', result.trials), ('test', result.test)) if trials}
    return index, index.get('test', {}).get('gain')


def _blend(result: TuneResult, hybrid: ResidualResult, network: ResidualResult
           ) -> ResidualResult:
    """Return the ensemble of every member of the hybrid and the pure network, scored."""
    physics = result.tuned_ship
    nets = members(hybrid.net) + members(network.net)
    net = ensemble(nets)
    model = Model(physics, net)
    index, held = _scored(physics, model, result, _residual_config(result.config))
    k = len(nets)
    share = (hybrid.share * hybrid.seeds + network.seeds) / k   # a pure net's share is 1
    return ResidualResult(net, 'blend', float(share), None, index, held,
                          hybrid.seconds + network.seconds,
                          max(hybrid.epochs, network.epochs), hybrid.seed,
                          {'blend_of': {'hybrid': hybrid.config, 'network': network.config}},
                          k)


# ---------------------------------------------------------------------------------- residual
RESIDUAL_FILE = 'params.residual.npz'
RESIDUAL_KINDS = ('hybrid', 'network')
MODEL_CHOICES = ('physics', 'auto')


def _check_residual(cfg: TuneConfig, error: type[Exception]) -> None:
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


def _check_residual_options(options: Mapping[str, Any], error: type[Exception]) -> None:
    opts = dict(options)
    unknown = sorted(set(opts) - set(config_fields(ResidualConfig)))
    _check('residual_options', opts, not unknown and 'physics' not in opts,
           f'fields of ResidualConfig (unknown: {unknown}; physics follows the mode)', error)
    ResidualConfig(**opts)   # validates the values (ConfigError naming them)


def _residual_config(cfg: TuneConfig) -> ResidualConfig:
    # RK4, as evaluate and mt.simulate run the hybrid by default (Euler: residual_options)
    options: dict[str, Any] = {'seed': cfg.seed, 'integrator': 'rk4',
                               **dict(cfg.residual_options),
                               'physics': cfg.residual != 'network'}
    return ResidualConfig(**options)


@dataclass
class ResidualResult:
    """
    The neural residual trained after the physics (``tune --residual``).

    The network, its share of the total acceleration, its gain on its validation windows, and the
    paper's index (Wakita et al. 2022 eq. 26, restarts every 100 s) of the tuned physics and of the
    model with the network on the tuning and test trials (``heldout_gain``: 1 - index ratio on the
    test trials, None without any).
    """

    net: ResidualNet = field(repr=False)
    kind: str
    share: float
    val_gain: float | None
    index: dict[str, dict[str, Any]]
    heldout_gain: float | None
    seconds: float
    epochs: int
    seed: int
    config: dict[str, Any]
    seeds: int = 1   # residuals averaged (seeds seed .. seed + seeds - 1; 1: one network)

    def npz_bytes(self) -> bytes:
        """Return the network as the portable .npz ResidualNet.save writes."""
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / RESIDUAL_FILE
            self.net.save(path)
            return path.read_bytes()

    def report(self) -> dict[str, Any]:
        d = asdict(self)
        d.pop('net')
        d['file'] = RESIDUAL_FILE
        return d

    def markdown(self) -> str:
        # (a joint's figures are its ensemble's own: its members trained together)
        mean = '' if self.seeds == 1 or self.kind == 'joint' else \
            f' (mean over the {self.seeds} networks)'
        lines = ['', f'## Neural residual ({self.kind})', '',
                 f'Trained in {self.seconds:.1f} s ({self.epochs} epochs, '
                 + (f'seed {self.seed}' if self.seeds == 1 else
                    f'the mean of {self.seeds} networks, seeds {self.seed} to '
                    f'{self.seed + self.seeds // (2 if self.kind == "blend" else 1) - 1}'
                    + (' of each kind' if self.kind == 'blend' else '')) + '); '
                 f'weights in `{RESIDUAL_FILE}`, named by params.yaml. '
                 + (f'Share of the total acceleration{mean}: {100 * self.share:.1f} %. '
                    if self.kind in ('hybrid', 'joint') else 'The network alone gives the '
                    'accelerations (no physics). ' if self.kind == 'pure network' else
                    f'A blend: the mean of {self.seeds} hybrid and pure networks, '
                    f'{100 * self.net.physics:.0f} % of the physics plus their mean output. ')
                 + ('' if self.val_gain is None else
                    f'Gain on its validation windows{mean}: {100 * self.val_gain:.1f} %.')
                 + ('' if self.kind != 'joint' else ' Its physics coefficients were trained '
                    'with it (the physics written): ' + ', '.join(
                        f'{n} {v:.6g}' for n, v in self.config['coefficients'].items()) + '.'),
                 '',
                 '| trials | index, tuned physics | index, with the network | gain |',
                 '|---|---|---|---|']
        for which, v in self.index.items():
            lines.append(f"| {which} | {_fmt_idx(v['physics'])} | {_fmt_idx(v['model'])} | "
                         f"{_fmt_gain_frac(v['gain'])} |")
        return '\n'.join(lines) + '\n'


def _fmt_idx(x: float | None) -> str:
    return 'failed' if x is None else f'{x:.4g}'


def _fmt_gain_frac(g: float | None) -> str:
    return '—' if g is None else f'{100 * g:+.1f} %'


def _train_residual(result: TuneResult, groups: Mapping[str, str] | None = None
                    ) -> ResidualResult:
    """
    Train the residual on the tuning trials with the tuned physics and score both.

    Its validation: the last part of each tuning trial; scored on the tuning and test trials.
    groups: trial name -> kind (a trial not named is its own group), for the options that
    balance or select by group.
    """
    cfg = result.config
    rc = _residual_config(cfg)
    physics = result.tuned_ship
    logger.info('training the %s network on %d trial(s) (seed %d, up to %d epochs)',
                'residual' if rc.physics else 'pure', len(result.trials), rc.seed, rc.epochs)
    full = None if groups is None else {t.name: groups.get(t.name, t.name) for t in result.trials}
    fits = []
    for k in range(cfg.residual_seeds):
        if k:
            logger.info('   seed %d (%d of %d)', rc.seed + k, k + 1, cfg.residual_seeds)
        fits.append(train_residual(physics, result.trials, groups=full,
                                   config=replace(rc, seed=rc.seed + k)))
    fit = fits[0]
    net = fit.net if len(fits) == 1 else ensemble([f.net for f in fits])
    index, held = _scored(physics, Model(physics, net), result, rc)
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
