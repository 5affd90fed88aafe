"""The diagnose workflow: options, the search for causes, its result."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
import logging
import math
from pathlib import Path
import time
from typing import Any, cast, Mapping, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner.api._common import _as_list, _check, _check_common, _config, _is_int, _write_all
from mmg_tuner.api.tuning import _check_residual_options
from mmg_tuner.core.correction import feature_names
from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis import measured as _measured
from mmg_tuner.diagnosis import structure as _structure
from mmg_tuner.diagnosis.context import Setting
from mmg_tuner.diagnosis.decide import decide, Z_FOR
from mmg_tuner.diagnosis.report import markdown as _diagnosis_markdown
from mmg_tuner.diagnosis.report import plot_residuals, residuals_for
from mmg_tuner.diagnosis.residuals import simulate_trials
from mmg_tuner.diagnosis.results import Candidate, Cause, split_undecided
from mmg_tuner.diagnosis.select import check_trial_sets
from mmg_tuner.diagnosis.select import diagnose as _diagnose
from mmg_tuner.diagnosis.settings import (BUDGETS, DiagnosisSettings, MapFn, restart_period,
                                          RETUNE_METHODS)
from mmg_tuner.errors import ConfigError, DiagnosisError, MissingDependencyError
from mmg_tuner.learn import require_jax
from mmg_tuner.tuning.gate import check_before_writing, mark_note
from mmg_tuner.tuning.gate import markdown as gate_markdown
from mmg_tuner.tuning.report import json_text, params_yaml_text, plot_trials, unique_names
import numpy as np


logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split


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
    setting: Setting | str | Mapping[str, Any] | None = None
    retune: str = 'lsq'
    measured_signals: bool = True
    residual: bool | str = 'auto'
    residual_options: Mapping[str, object] = field(default_factory=dict)
    measured: Mapping[str, object] | str | Path | None = None
    # how causes are named after the search: 'evidence' (each effect on its own evidence, the
    # error apportioned: diagnosis/decide.py; the default since the registered run of
    # bench/mismatch_calibration_preregistration.md: fewer false causes at a mismatch
    # calibrated on real data) or 'rules' (the structure verdict withdraws every fitted cause
    # when it blames the structure: structure.one_verdict)
    verdict: str = 'evidence'
    # restart the simulation from the recorded state every this many seconds in every tuning
    # and held-out judgement of the diagnosis; None: settings.restart_period(L_pp) with the
    # evidence verdict, a free run (0) with the rules
    restart_every_s: float | None = None

    def __post_init__(self) -> None:
        E = DiagnosisError
        _check('verdict', self.verdict, self.verdict in ('rules', 'evidence'),
               "'rules' or 'evidence'", E)
        r = self.restart_every_s
        seconds = isinstance(r, (int, float)) and not isinstance(r, bool) and 0 <= r < math.inf
        _check('restart_every_s', r, r is None or seconds,
               'None or a number of seconds >= 0 (0: a free run)', E)
        if isinstance(self.measured, (str, Path)):
            object.__setattr__(self, 'measured', _measured.load(self.measured))
        else:
            # (any mapping: check verifies each entry, or raises naming it)
            given = cast('Mapping[str, _measured.Measurement]', self.measured or {})
            object.__setattr__(self, 'measured', _measured.check(given,
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

    def settings(self, L_pp_m: float | None = None) -> DiagnosisSettings:
        """Return the search's settings; ``L_pp_m``, the ship's length, sets the restart period."""
        base_e, screen_e, eff_e = BUDGETS[self.budget]
        restart = self.restart_every_s
        if restart is None:
            restart = (restart_period(L_pp_m) if self.verdict == 'evidence' and L_pp_m
                       else 0.0)
        # (__post_init__ parsed the setting and checked the measurements)
        setting = cast('Setting | None', self.setting)
        measured = cast('Mapping[str, _measured.Measurement]', self.measured)
        # (a bool and a float: mypy would join them to float)
        evidence: dict[str, Any] = ({'held_out_test_only': True, 'min_gain_z': Z_FOR}
                                    if self.verdict == 'evidence' else {})
        return DiagnosisSettings(
            targets=self.targets, a_r=self.a_r, effects=list(self.effects),
            integrator=self.integrator, base_evals=self.base_evals or base_e,
            screen_evals=self.screen_evals or screen_e, effect_evals=self.effect_evals or eff_e,
            max_effects=self.max_effects, seed=self.seed, retune=self.retune,
            setting=setting, measured_signals=self.measured_signals,
            measurements=dict(measured), restart_every_s=float(restart), **evidence)


@dataclass
class ModelFit:
    """One model of a diagnosis: J on the tuning and test trials, its parameters."""

    J_tune: float
    J_test: float
    J_test_per_trial: dict[str, float]
    params: dict[str, float]
    heldout_gain_total: float | None = None   # final model: 1 - J_test / base model's J_test

    def __getitem__(self, key: str) -> Any:  # dict-style reading, as diagnosis.json has it
        return getattr(self, key)


@dataclass
class DiagnosisResult:
    """
    What :func:`diagnose` found.

    The named ``causes``, the tuned base model (``baseline``) and the final model with the causes
    (``final``, its full parameters in ``params``: ``ship.with_params(dx.params)``), every
    candidate tried per round, effects the trials can barely see, and the residuals of both models
    on the test trials. ``undecided``: effects in the final model that these trials cannot tell
    from their rivals (``Cause.indistinguishable_from``): the verdict is "one of them", never
    the first alone (results.split_undecided).
    """

    causes: list[Cause]
    baseline: ModelFit
    final: ModelFit
    params: dict[str, float]
    candidates: list[list[Candidate]]
    barely_identifiable: dict[str, dict[str, Any]]
    residuals: dict[str, dict[str, Any]]
    wall_s: float
    ship: ShipConfig = field(repr=False)
    test: list[Trial] = field(repr=False, default_factory=list)
    config: DiagnoseConfig = field(repr=False, default_factory=DiagnoseConfig)
    setting: Setting = field(default_factory=Setting)
    impossible: dict[str, str] = field(default_factory=dict)
    impossible_fits: list[dict[str, Any]] = field(default_factory=list)
    measured: list[dict[str, Any]] = field(default_factory=list)
    timings_s: dict[str, float] = field(default_factory=dict)
    # the test trials as each model sees them (without / with the measured wind)
    test_base: list[Trial] = field(repr=False, default_factory=list)
    test_final: list[Trial] = field(repr=False, default_factory=list)
    # the trial that would settle each barely identifiable effect / rival pair (advice.py)
    advice: list[dict[str, Any]] = field(default_factory=list)
    # whether the model structure, not the named effects, is the likely cause (structure.py)
    structure: dict[str, Any] = field(default_factory=dict)
    structure_images: dict[str, bytes] = field(repr=False, default_factory=dict)   # {file: PNG}
    # effects the search kept that the verdict does not name (diagnosis/decide.py: their value
    # follows the manoeuvre, or they add nothing beside the others): in the fitted model
    # (params), never named as causes
    mimicking: list[Cause] = field(default_factory=list)
    # the sensor noise and the held-out J it alone leaves (diagnosis/noise.py)
    noise: dict[str, Any] = field(default_factory=dict)
    # effects the trials hint at but cannot name, each with the trial that would settle it in
    # advice (kind 'suspected'): {effect, values, gain, gain_se, round, summary, beside}
    suspected: list[dict[str, Any]] = field(default_factory=list)
    # fitted, in the final model, but as good as a rival: "one of them", not named
    undecided: list[Cause] = field(default_factory=list)
    # the verdict's evidence per fitted effect (diagnosis/decide.py): contribution, share,
    # per-trial estimates, dispersion, verdict and why
    decision: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
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
                'suspected': self.suspected,
                'undecided': [c.to_dict() for c in self.undecided],
                'decision': self.decision,
                'params': self.params, 'wall_s': self.wall_s, 'timings_s': self.timings_s}

    def write(self, out: str | Path | OutputDir, plots: bool = True,
              write_unphysical: bool = False) -> list[Path]:
        """
        Write the result's files into ``out``, the completion marker last.

        params.yaml first, diagnosis.md, plots, and diagnosis.json last (its presence means the set
        is complete). A model that cannot be a ship or diverges on the test trials is refused
        (TuningError) unless ``write_unphysical`` (``tuning/gate.py``; marked in the report).
        """
        marks = check_before_writing(self.ship, self.params, self.test_final or self.test,
                                     'diagnosed parameters', write_unphysical,
                                     self.config.integrator)
        doc = self.to_dict()
        names = ', '.join([c.effect for c in self.causes]
                          + [f'{c.effect} (mimicking a structural gap)'
                             for c in self.mimicking]
                          + [f"{c.effect} (undecided: or {', '.join(c.indistinguishable_from)})"
                             for c in self.undecided]) or 'none'
        docs = [('params.yaml', params_yaml_text(
                    self.ship, self.params,
                    mark_note(f'tuned and extended by mmg_tuner diagnose (effects: {names})',
                              marks))),
                ('diagnosis.md', _diagnosis_markdown(doc, self.ship) + gate_markdown(marks))]
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
             map_fn: MapFn[Any, Any] | None = None, **options: Any) -> DiagnosisResult:
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
    d = _diagnose(ship, trials, test, cfg.settings(ship.L_pp), checkpoint=checkpoint,
                  resume=resume, map_fn=map_fn)
    logger.info('3/3 reporting')
    t_report = time.perf_counter()
    # the base model is tuned without a measured wind when it is a candidate
    # (Trial's __init__ takes wind, a view of its wind channels; mypy checks only the fields)
    no_wind = [replace(t, wind=None)  # type: ignore[call-arg]
               if t.wind is not None else t for t in test]
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
        d.advice, noise=d.noise, suspected=d.suspected)
    dx.structure = _structure_of(dx, trials, d.measured_wind_used or not cfg.measured_signals)
    if cfg.verdict == 'evidence':
        _decide(dx, trials)
    else:
        dx.causes, dx.mimicking = _structure.one_verdict(dx.causes, dx.structure,
                                                         dx.baseline.J_test, dx.noise)
    dx.causes, dx.undecided = split_undecided(dx.causes)
    return dx


def _decide(dx: 'DiagnosisResult', tune_trials: list[Trial]) -> None:
    """
    Name the causes of the final model by their own evidence (diagnosis/decide.py).

    A fitted effect whose value follows the manoeuvre (inconsistent over the trials) or whose
    contribution is within its error of none moves to ``mimicking`` (kept in the fitted model,
    not named); the rest stay causes with their share of the base held-out error. What remains
    is the structure section's (never a veto of a cause).
    """
    if not dx.causes:
        return
    t0 = time.perf_counter()
    J_base = np.array([dx.baseline.J_test_per_trial[n] for n in unique_names(dx.test)])
    wind_used = any(c.effect == 'measured_wind' for c in dx.causes)
    # (Trial's __init__ takes wind, a view of its wind channels; mypy checks only the fields)
    no_wind = [replace(t, wind=None)  # type: ignore[call-arg]
               if t.wind is not None else t for t in dx.test]
    tune_final = tune_trials if wind_used else [
        replace(t, wind=None)  # type: ignore[call-arg]
        if t.wind is not None else t for t in tune_trials]
    evidence = decide(dx.ship, dx.params, [c.effect for c in dx.causes], tune_final,
                      dx.test_final or dx.test, J_base, dx.config.integrator,
                      test_without_wind=no_wind,
                      restart_every_s=dx.config.settings(dx.ship.L_pp).restart_every_s,
                      base_targets=list(dx.config.targets or dx.ship.tuning_targets))
    dx.decision = [e.to_dict() for e in evidence]
    verdict = {e.effect: e for e in evidence}
    kept = []
    for c in dx.causes:
        e = verdict[c.effect]
        c.share = e.share
        if e.verdict == 'cause' or c.measured:
            kept.append(c)
        else:
            dx.mimicking.append(c)
        logger.info('   %s: %s -- %s (contribution %.1f %% +- %.1f, share %.1f %%)', c.effect,
                    e.verdict, e.why, 100 * e.contribution, 100 * e.contribution_se,
                    100 * e.share)
    dx.causes = kept
    remaining = dx.final.J_test / dx.baseline.J_test if dx.baseline.J_test > 0 else None
    dx.structure['remaining_fraction'] = remaining
    dx.timings_s['decide'] = round(time.perf_counter() - t0, 3)


def _structure_of(dx: 'DiagnosisResult', tune_trials: list[Trial], wind_used: bool
                  ) -> dict[str, Any]:
    """Return the structure verdict (diagnosis/structure.py) of a finished diagnosis."""
    t0 = time.perf_counter()
    cfg = dx.config
    # (Trial's __init__ takes wind, a view of its wind channels; mypy checks only the fields)
    tune_final = tune_trials if wind_used else [
        replace(t, wind=None)  # type: ignore[call-arg]
        if t.wind is not None else t for t in tune_trials]
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

    residual='auto' trains it when what remains is not noise, as the report will say it (with
    ``verdict='rules'``: the named causes moved to mimicking when the structure verdict wins,
    :func:`~mmg_tuner.diagnosis.structure.one_verdict`, what remains is then the tuned base
    model's error), judged against what sensor noise alone reaches (diagnosis/noise.py:
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
    if cfg.verdict == 'rules':
        _structure.one_verdict(list(dx.causes), st, dx.baseline.J_test, dx.noise)
    if st.get('remaining_is_noise') is not False:
        return False, ('not trained: ' + (st.get('noise') or 'no noise floor to judge what '
                                          'remains against'))
    try:   # a family whose channels a network cannot read (core/correction.py)
        feature_names(dx.ship.family)
    except ConfigError as exc:
        return False, f"not trained although {st.get('noise')}: {exc}"
    try:
        require_jax()
    except MissingDependencyError as exc:
        return False, f"not trained although {st.get('noise')}: {exc}"
    return True, f"trained: {st.get('noise')}"
