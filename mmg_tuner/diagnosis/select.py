"""
Name the cause.

Extend the model with each candidate effect, re-tune (effect parameters plus the base targets,
warm-started), and keep the effect whose held-out gain is significant.

Selection rule (stepwise, like forward-backward regression):
* held-out gain G = 1 - J_test(extended) / J_test(current model), summed over test trials;
  its uncertainty is the jackknife standard error over test trials;
* an effect is accepted when G > min_gain + param_penalty x (number of its parameters) and
  G > min_gain_z x its standard error, the
  reduction is at least min_abs_gain of the base model's held-out error, and no test trial
  gets worse by more than worse_tol with an increase above worse_abs of the held-out error
  and above that trial's noise floor (what sensor noise alone leaves on it) (an
  effect shows in some trials more than in others, but a wrong one makes some trials worse; a
  trial the model fits almost exactly may get many times worse by a negligible amount). Gains
  are measured against the current model re-tuned
  with the same warm start and budget (a null candidate), so extra tuning is not mistaken for
  an effect. Nothing significant: nothing is named (clean data must name nothing);
* an estimate smaller than the effect's smallest magnitude worth finding (e.g. a 0.02 m/s
  current) is not accepted. With a reduction of the held-out J within the noise floor
  (diagnosis/noise.py: what sensor noise alone leaves) it fits noise; above the floor it is
  no noise-fitting but an effect bending to share an error with another (a 9 m/s wind beside
  a rudder offset came out below 5 m/s and was once called noise-fitting with a 39 % gain on
  a base error 12 x the clean case's): the pairs are then tried jointly. Never named alone: a
  0.04 m/s current fitted a rudder stall outside the library that way;
* the reduction must be min_abs_gain of the base model's held-out error, or above
  noise_margin noise floors: after a large effect is named, a second one explains a small
  share of the base error that is still far above what noise leaves;
* an estimate pinned on its box (a non-periodic parameter within bound_tol of the box width of
  a bound that is not its neutral value) is not accepted: the optimiser is using the effect to
  absorb something else, as the paper's tuned coefficients pinned on their bounds do;
* the best accepted effect joins the model and the search repeats, up to max_effects; another
  significant effect within the combined uncertainty is reported as indistinguishable;
* joint round: after a cause is named, when a candidate competes (significant, not
  acceptable alone), the last named effect is re-fitted jointly with each such candidate from the
  model before it was named (it may have bent to take the other's share) and a pair is
  judged against the current model by the rule of one effect, per member. The candidates so
  paired are the round's competitors, the suspected ones, and those significant beside the
  last named one in the round that named it (the next screen, beside it, ranks by a loss and
  may never re-tune them). When such a joint fit leaves the last named effect below its
  smallest magnitude worth finding beside a rival (as good alone, within the combined
  uncertainty), the rival is named instead and the other listed as indistinguishable (a yaw
  moment bias named as a 6.8 m/s wind: beside the bias the wind fits at 0 m/s). A member that a
  significant pair's tuning fit sizes below its smallest magnitude worth finding is sized on
  every trial, tuning and held-out (the tuning trials may leave its size in a flat valley
  along which the re-tuned coefficients trade with it: a 1.5 deg rudder offset beside a wind
  came out at 0.68 deg on five trials, 1.79 on ten); the causes' values are then the final
  model's fitted on every trial, the held-out J that of the tuning fit;
* suspected, not named: when a round names nothing, a candidate whose held-out gain exceeds
  the least gain and whose reduction counts as evidence, possible, plausible, off its bounds
  and not too small, but which the held-out trials disagree on (one made worse, or the gain
  within its standard error), is reported as suspected (suspected_effects) with the advice
  that would settle it: the trial that separates the model with it from the model without
  it, or, when none does, its measurement (a rudder offset beside a wind bent 17 deg to take
  its share: no manoeuvre separates them, the rudder indicator does);
* measured coefficients (diagnosis/measured.py) are priors of every tuning with their
  standard errors, never fixed values;
* backward step: with two or more named, one whose removal loses no significant gain is
  dropped (a yaw moment bias named first is made redundant by the rudder offset named next);
  "significant" is the same :func:`acceptance` rule as the forward step, with the model
  without the effect as the reference;
* cheap ranking first: each candidate is fitted with the base targets held at their tuned
  values and the named effects free (a few hundred evaluations); only the top `screen`
  candidates are re-tuned fully;
* two starts: the screen also fits each candidate with the base targets held at their
  pre-determined values (where the base tune started; PRE_SCREEN_SHARE of the evaluations),
  and the re-tune starts from whichever start has the lower tuning J; so does the null
  candidate. The base tune bends the coefficients to absorb what the model lacks, and a local
  re-tune stays in that basin (a tug's azimuth offset tied there with a yaw moment bias);
* a named effect's standard error is the larger of Gauss-Newton's and the trial-robust
  (sandwich, one cluster per tuning trial) one: residuals along a trajectory are correlated;
* single-parameter effects whose standard error at the base optimum (base targets free)
  exceeds half the smallest magnitude worth finding are reported as barely identifiable
  from these trials (e.g. rpm_scale against w_P0 and t_P), so that a miss is explained.
* checkpoint: every completed tuning is stored (atomically) under a key of what it was
  given; a resumed search replays the same steps and takes each finished one from the store.
  An interrupted tuning is never used: the interrupt propagates (KeyboardInterrupt).
* a cause must be plausible and consistent (diagnosis/plausible.py): a fit outside the
  effect's plausible range for the ship (config/effect_plausibility.yaml) is "implausible";
  an effect that makes a held-out trial clearly worse (by more than clearly_worse and by more
  than that trial's noise floor) or whose estimates, fitted on each held-out trial alone,
  disagree beyond their errors is "inconsistent": neither is named (a physical effect has one
  value for the whole recording); both are evidence of a structural gap;
* plausibility (diagnosis/context.py): an effect impossible where the trials were recorded
  (wind indoors, current in a tank, an antenna offset when positions are of the reference
  point) is screened and fitted like any other but never named; a significant fit by one is
  reported as "would fit, but impossible here": evidence of a structural gap of the model.
* measured signals: when trials carry a measured wind, "the measured wind is used" is itself
  a candidate (no parameters): the base model is tuned without it, the model with it gets its
  own base tune by the same procedure (equal effort: a re-tune from the windless optimum may
  stay in that optimum's basin), and it must pass the same acceptance rule (the steady-wind
  effect is then not searched: the recording says what the wind was).
* re-tunes start next to an optimum, so they use a local bounded least-squares method
  (scipy.optimize.least_squares, 'trf', in the unit box) on the weighted residuals, with a
  forward-difference Jacobian computed in one batched multi-core simulation call; CMA-ES tunes
  the base model (the paper's method; here stopped on stagnation and polished by the same
  least squares, see DiagnosisSettings.base_*) and screens the effects (directions are
  multimodal).
"""  # noqa: A005
from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
import logging
import math
from pathlib import Path
import time
from typing import Any, Callable, cast, Mapping, NamedTuple, Sequence, TypeVar

from mmg_tuner.core.effects import describe_values, Effect, EFFECTS
from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis import measured as measured_mod
from mmg_tuner.diagnosis.checkpoint import fingerprint, SearchCheckpoint
from mmg_tuner.diagnosis.context import impossible_effects, resolve
from mmg_tuner.diagnosis.noise import describe as noise_describe, noise_floor, sensor_noise
from mmg_tuner.diagnosis.plausible import disagreement, implausible, per_trial
from mmg_tuner.diagnosis.residuals import simulate_trials
from mmg_tuner.diagnosis.results import Candidate, Cause, Diagnosis
from mmg_tuner.diagnosis.settings import DiagnosisSettings, MapFn, MEASURED, RETUNE_METHODS
from mmg_tuner.diagnosis.stats import acceptance, jackknife_se, pinned_on_bound, Verdict
from mmg_tuner.errors import DiagnosisError
from mmg_tuner.tuning.identifiability import aliasing, standard_errors
from mmg_tuner.tuning.identifiability import trial_robust_standard_errors
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.tuner import Tuner
import numpy as np

# The effect fits spend their whole budget (the tuner's early stop after a restart that finds
# nothing better is not used here): the registered benchmark of the diagnosis
# (bench/bench_diagnosis_mismatch_preregistration_600.md) was measured so.
NO_EARLY_STOP = 0.0

logger = logging.getLogger(__name__)
# the screen from the pre-determined base values gets this share of screen_evals: it need only
# show a far better start (a tug azimuth offset: tuning J 24 there, 226 000 from the tuned
# base); the re-tune polishes it. A full second screen cost the tug tests 16 % more simulation
PRE_SCREEN_SHARE = 0.25
# a joint fit leaves an effect "at nothing" when every sized parameter lies within this
# fraction of its smallest magnitude worth finding: the rival that does it may be named in its
# place. Their standard errors do not tell: Gauss-Newton's leave a yaw moment bias of 1.4e-4
# beside a real rudder offset 10 standard errors from none (1.4e-5), the trial-robust ones a
# real offset of -0.68 deg beside a bias within 1.2 of none (0.59 deg)
AT_NOTHING = 0.5
_T = TypeVar('_T')
_R = TypeVar('_R')


class _Model:
    """
    A model structure under test.

    Base targets + effect parameters with their boxes, and whether the measured wind drives it.
    """

    def __init__(self, ship: ShipConfig, base: ParameterSpace, effects: list[Effect],
                 measured_wind: bool = False):
        names = list(base.names)
        lo, hi, pre = list(base.lower), list(base.upper), list(base.pre)
        for e in effects:
            for p, (a, b) in zip(e.params, e.bounds(ship)):
                names.append(p)
                lo.append(a)
                hi.append(b)
                pre.append(min(max(EFFECT_NEUTRAL[p], a), b))
        self.base = base
        self.effects = effects
        self.measured_wind = measured_wind
        self.space = ParameterSpace(tuple(names), np.array(pre), np.array(lo), np.array(hi))


# a candidate as tried: (its Candidate, its model, its optimum, its per-trial held-out J)
_Tried = tuple[Candidate, _Model, np.ndarray, np.ndarray]
# the members of a joint fit: (effect, its fitted values)
_Members = list[tuple[str, dict[str, float]]]
# an accepted joint fit: (Candidate, model, theta, per-trial held-out J, members, the effects
# sized on every trial, the parameters they were sized at)
_Joint = tuple[Candidate, _Model, np.ndarray, np.ndarray, _Members, list[str], np.ndarray]


class _NamedFrom(NamedTuple):
    """The round that named a cause, as a later joint fit starts from it."""

    model: _Model                  # the model before the cause
    theta: np.ndarray              # its optimum
    screened: dict[str, np.ndarray]  # {effect: its screened theta}
    ranking: list[str]             # the screen's order
    significant: list[str]         # effects significant beside the cause, not named
    accepted: dict[str, _Tried]    # {effect: (Candidate, model, theta, J_test)}, as good alone


@dataclass(frozen=True, eq=False)
class _Objectives:
    """
    Tuning and test objectives, without and with the measured wind.

    The tuning and test objectives without and (when trials carry one) with the measured wind
    driving the model.
    """

    plain: tuple[Objective, Objective]
    wind: tuple[Objective, Objective] | None

    def of(self, model: _Model) -> tuple[Objective, Objective]:
        # (a model the measured wind drives exists only when the trials carry one: wind set)
        return cast(tuple[Objective, Objective], self.wind) if model.measured_wind \
            else self.plain


@dataclass(frozen=True, eq=False)
class _Fit:
    """
    One tuning of the search, self-contained so that a ``map_fn`` may run it in another process.

    It touches neither the checkpoint nor the log.
    """

    ship: ShipConfig
    space: ParameterSpace
    n_effect: int            # effect parameters at the end of space (screening moves only them)
    obj: Objective
    x0: np.ndarray
    evals: int
    seed: int
    fixed_base: bool
    method: str              # 'cmaes', 'lsq' or 'cmaes+lsq' (a CMA-ES search, then polished)

    def key(self) -> str:
        parts = [self.space.names, np.asarray(self.x0, float), self.evals, self.seed,
                 self.fixed_base, self.obj.batch.names]
        if self.method != 'cmaes' and not self.fixed_base:
            parts.append(self.method)
        if self.obj.batch.ctrls.shape[2] > 2:
            parts.append('measured wind')
        return SearchCheckpoint.key(*parts)


def _run_fit(f: _Fit) -> np.ndarray:
    """
    Run one tuning.

    An interrupted CMA-ES run raises KeyboardInterrupt (never a truncated result).
    """
    space = f.space
    x0 = np.asarray(f.x0, float)
    if f.fixed_base:  # screening: the base held, the effect parameters (new and named) move
        n_base = len(x0) - f.n_effect
        base_vals = x0[:n_base]
        sub = ParameterSpace(space.names[n_base:], space.pre[n_base:], space.lower[n_base:],
                             space.upper[n_base:])
        shipb = f.ship.with_params(dict(zip(space.names[:n_base], base_vals)))
        o = Objective(shipb, f.obj.batch, f.obj.weights, f.obj.shoot_every_s,
                      {0: 'euler', 1: 'rk4'}[f.obj.method], f.obj.substeps)
        if sub.dim == 0:
            return x0.copy()
        res = Tuner(sub, o, seed=f.seed, max_evaluations=f.evals, max_popsize=24,
                    sigma0=0.3, restart_gain=NO_EARLY_STOP).run()
        if res.interrupted:
            raise KeyboardInterrupt
        return np.concatenate([base_vals, res.theta])
    if f.method == 'lsq':
        return local_least_squares(space, f.obj, x0, f.evals).theta
    res = Tuner(space, f.obj, seed=f.seed, max_evaluations=f.evals, max_popsize=48,
                sigma0=0.3 if f.method == 'cmaes+lsq' else 0.1, x0=x0,
                restart_gain=NO_EARLY_STOP).run()
    if res.interrupted:
        raise KeyboardInterrupt
    if f.method == 'cmaes+lsq':   # a global search, then the local polish the others get
        return local_least_squares(space, f.obj, res.theta, f.evals).theta
    return res.theta


def _plain_map(fn: Callable[[_T], _R], items: Sequence[_T]) -> list[_R]:
    return [fn(x) for x in items]


def _tune_many(fits: Sequence[_Fit], store: SearchCheckpoint | None,
               map_fn: MapFn[_Fit, np.ndarray] | None) -> list[np.ndarray]:
    """
    Every tuning, in input order.

    Finished ones from the checkpoint, the rest through map_fn (plain map by default: each stored
    as soon as it is done). The checkpoint is read before and written after the mapping, here in
    the calling process.
    """
    keys = [f.key() for f in fits]
    out: list[np.ndarray | None] = [store.get(k) if store is not None else None for k in keys]
    todo = [i for i, th in enumerate(out) if th is None]
    # (each return below follows the filling of every entry: no None is left)
    if not todo:
        return cast(list[np.ndarray], out)
    if map_fn is None:
        for i in todo:
            out[i] = _run_fit(fits[i])
            if store is not None:
                store.put(keys[i], cast(np.ndarray, out[i]))
        return cast(list[np.ndarray], out)
    got = list(map_fn(_run_fit, [fits[i] for i in todo]))
    if len(got) != len(todo):
        raise DiagnosisError(f'map_fn returned {len(got)} results for {len(todo)} tasks')
    for i, th in zip(todo, got):
        out[i] = np.asarray(th, float)
        if store is not None:
            store.put(keys[i], cast(np.ndarray, out[i]))
    return cast(list[np.ndarray], out)


def _pct_change(ref: float, new: float) -> str:
    if not (math.isfinite(ref) and math.isfinite(new)) or ref <= 0:
        return 'undefined (a run diverges)'
    return f'{100 * (new / ref - 1):+.1f} %'


def _per_trial_J(obj: Objective, ship: ShipConfig, space: ParameterSpace, theta: np.ndarray
                 ) -> np.ndarray:
    J, _ = obj.per_trial(space.full_params(ship.params, theta))
    first: np.ndarray = J[0]
    return first


def _failure_text(obj: Objective, ship: ShipConfig, space: ParameterSpace, theta: np.ndarray
                  ) -> str:
    """'diverged on trial X at t = ... s' for the first failing trial ('' if none)."""
    ev = obj.evaluate(space.full_params(ship.params, theta)[0])
    return str(ev.failures[0]) if ev.failures else ''


def check_trial_sets(tune_trials: Sequence[Trial], test_trials: Sequence[Trial]) -> None:
    """Refuse, before any work, trial sets on which no cause can ever be named."""
    if not tune_trials or not test_trials:
        raise DiagnosisError('the diagnosis needs tuning trials and held-out test trials')
    if len(test_trials) < 2:
        raise DiagnosisError(
            f"only one held-out trial ({test_trials[0].name}): the held-out gain's jackknife "
            'standard error needs at least two, so no cause could ever be named; give two or '
            'more test trials (or at least four trials without --test)')


def _without_wind(trials: Sequence[Trial]) -> list[Trial]:
    # (Trial's __init__ takes wind, a view of its wind channels; mypy checks only the fields)
    return [replace(t, wind=None) if t.wind is not None else t  # type: ignore[call-arg]
            for t in trials]


class _Clock:
    """Wall time per stage (seconds, summed over visits)."""

    def __init__(self) -> None:
        self.t: dict[str, float] = {}
        self._stage: str | None = None
        self._t0 = 0.0

    def __call__(self, stage: str | None) -> None:
        now = time.perf_counter()
        if self._stage is not None:
            self.t[self._stage] = self.t.get(self._stage, 0.0) + now - self._t0
        self._stage, self._t0 = stage, now


def _base_tune(base: ParameterSpace, obj: Objective, s: DiagnosisSettings,
               store: SearchCheckpoint, what: str, side: Path | None, resume: bool,
               log: Callable[[str], None]) -> np.ndarray:
    """
    Tune the base targets: CMA-ES stopped on stagnation, then a least-squares polish.

    CMA-ES starts from the pre-determined values (see DiagnosisSettings.base_*); a tuning
    already in the checkpoint is taken from there.
    """
    key = SearchCheckpoint.key(what, base.names, base.lower, base.upper, s.base_evals, s.seed,
                               s.base_popsize, s.base_max_popsize, s.base_rtol, s.base_polish)
    theta = store.get(key)
    if theta is not None:
        return theta
    # checkpointed every generation beside the search's checkpoint (side): an interrupted
    # base tuning resumes where it stopped (removed once the result is stored)
    res = Tuner(base, obj, seed=s.seed, max_evaluations=s.base_evals, popsize=s.base_popsize,
                max_popsize=max(s.base_popsize, s.base_max_popsize), rtol=s.base_rtol,
                checkpoint=side).run(resume=bool(side is not None and resume and side.is_file()))
    if res.interrupted:
        raise KeyboardInterrupt
    theta = res.theta
    if s.base_polish > 0:   # CMA-ES stopped on stagnation: a few local steps finish it
        theta = local_least_squares(base, obj, theta, s.base_polish).theta
    log(f'   {what}: {res.evaluations} CMA-ES evaluations, {res.restarts} restart(s)'
        + (', polished by least squares' if s.base_polish > 0 else ''))
    store.put(key, theta)
    if side is not None:
        side.unlink(missing_ok=True)   # ours, written by this diagnosis
    return theta


def diagnose(ship: ShipConfig, tune_trials: list[Trial], test_trials: list[Trial],
             settings: DiagnosisSettings | None = None,
             log: Callable[[str], None] | None = None, *,
             checkpoint: str | Path | None = None, resume: bool = False,
             map_fn: MapFn[Any, Any] | None = None) -> Diagnosis:
    """
    Tune the base model, search the effects library, name the cause(s).

    checkpoint: a file where every completed tuning is stored; with resume=True the search
    continues from it (the result equals an uninterrupted run). Ctrl-C (KeyboardInterrupt)
    propagates after the last completed tuning was stored. Progress goes to ``log`` (default:
    the ``mmg_tuner.diagnosis.select`` logger at INFO). map_fn(fn, items) -> list: how the
    independent tunings of a step (the screening of every candidate; the null re-tune with
    the top candidates' re-tunes; the removals of the backward step) are run, results in input
    order (default: plain map, here). The mapped function touches neither the checkpoint nor
    the log.
    """
    s = settings or DiagnosisSettings()
    log = log or logger.info
    check_trial_sets(tune_trials, test_trials)
    unknown = [e for e in s.effects if e not in EFFECTS]
    if unknown:
        raise DiagnosisError(f'unknown effects {unknown}; known: {sorted(EFFECTS)}')
    if s.retune not in RETUNE_METHODS:
        raise DiagnosisError(f'retune = {s.retune!r}: must be one of {list(RETUNE_METHODS)}')
    clock = _Clock()
    clock('setup')
    # measured coefficients: their values are the pre-determined ones, and every tuning is
    # pulled toward them by their standard errors (diagnosis/measured.py), never fixed
    # (the settings hold Measurements, typed object there; check verifies them)
    meas = measured_mod.check(cast(Mapping[str, measured_mod.Measurement], s.measurements),
                              'the diagnosis settings (measurements)')
    if meas:
        ship = ship.with_params({n: m.value for n, m in meas.items()})
        log('   measured (priors, value +- standard error): ' + ', '.join(
            f'{n} = {m.value:.4g} +- {m.se:.2g}' + (f' ({m.source})' if m.source else '')
            for n, m in meas.items()))
    effects = list(s.effects)
    # an actuator's effects (core/effects.py Effect.actuator) act only where the family has it
    foreign = [e for e in effects if EFFECTS[e].actuator not in ('', *ship.family.actuators)]
    if foreign:
        effects = [e for e in effects if e not in foreign]
        log(f'   left out: {", ".join(foreign)} (effects of actuators {ship.name} has not: '
            f'it has {", ".join(ship.family.actuators)})')
        if not effects:
            raise DiagnosisError(f'none of the effects {list(s.effects)} acts on {ship.name} '
                                 f'(its actuators: {", ".join(ship.family.actuators)})')
    # an effect whose every parameter was measured outside the trials (a steering-gear lag
    # from the rudder-angle feedback) is in every model at its measured value (the ship above
    # carries it): the trials could not size it, which is why it was measured, so it is not
    # searched; after the search it is named as measured when the measurement sets it clearly
    # apart from no effect and the trials do not contradict it (_by_measurement)
    by_measurement = [e for e in effects if all(p in meas for p in EFFECTS[e].params)]
    if by_measurement:
        effects = [e for e in effects if e not in by_measurement]
        log(f"   measured, so held in every model and not searched: {', '.join(by_measurement)}")
    if 'wind' in effects and not ship.has_windage:
        effects.remove('wind')
        log(f'   wind left out: {ship.source or ship.name} has no windage section (A_F, A_L, '
            'L_OA, CD_t, rho_air)')
    setting = resolve(ship, list(tune_trials) + list(test_trials), s.setting)
    impossible = impossible_effects(setting)
    for sig, (eff, _) in MEASURED.items():
        if eff in impossible:
            impossible[sig] = impossible[eff]
    ruled_out = [f'{e} ({why})' for e, why in impossible.items() if e in effects]
    log(f'   setting: {setting.describe()}'
        + ('; impossible here: ' + ', '.join(ruled_out) if ruled_out else ''))
    t_start = time.perf_counter()
    has_wind = any(t.wind is not None for t in list(tune_trials) + list(test_trials))

    def mk(trials: Sequence[Trial]) -> Objective:
        return Objective(ship, TrialBatch.from_trials(trials), shoot_every_s=s.restart_every_s,
                         integrator=s.integrator)

    wind_pair = (mk(tune_trials), mk(test_trials)) if has_wind else None
    if has_wind and s.measured_signals:
        objs = _Objectives((mk(_without_wind(tune_trials)), mk(_without_wind(test_trials))),
                           wind_pair)
        if 'wind' in effects and ship.has_windage:
            effects.remove('wind')
        measured = ['measured_wind'] if ship.has_windage else []
        log('   the trials carry a measured wind: "measured wind used" is a candidate (the '
            'base model is tuned without it; a steady wind is not searched)'
            if measured else '   the trials carry a measured wind, but the ship has no '
            'windage section: it cannot be used')
    else:
        objs = _Objectives(wind_pair or (mk(tune_trials), mk(test_trials)), None)
        measured = []
    base = ParameterSpace.around(ship, s.targets, s.a_r)
    plain_objs = objs
    if meas:   # the base tune's prior weighs with the untuned model's J per residual
        objs = _with_measurements(plain_objs, meas,
                                  measured_mod.s2_of(objs.plain[0], ship, base, base.pre))
    obj, obj_test = objs.plain
    # one objective per held-out trial (per-trial fits of a cause), as each model sees them
    plain_test = _without_wind(test_trials) if objs.wind is not None else list(test_trials)
    singles = {False: [mk([t]) for t in plain_test],
               True: [mk([t]) for t in test_trials] if objs.wind is not None else []}
    # every trial, tuning and held-out: where the held-out rule has found a pair whose member
    # the tuning trials alone size too small, its size is estimated from all the recordings
    # (_joint_objections)
    plain_all = list(_without_wind(tune_trials)) + plain_test \
        if objs.wind is not None else list(tune_trials) + list(test_trials)
    every = _Objectives((mk(plain_all),) * 2, None if objs.wind is None
                        else (mk(list(tune_trials) + list(test_trials)),) * 2)
    sized_on_all: list[str] = []
    all_fit = None     # (model's names, its fit on every trial) of the pair sized there
    fp_obj = objs.wind or objs.plain
    store = SearchCheckpoint(checkpoint, fingerprint(ship, fp_obj[0], fp_obj[1], s), resume)
    if store.done:
        log(f'   resuming: {len(store.done)} completed tuning(s) in {store.path}')

    clock('base_tune')
    log(f'1/3 tuning the base model ({base.dim} parameters) on {len(tune_trials)} trial(s)')
    model = _Model(ship, base, [])
    theta = _base_tune(base, obj, s, store, 'base', store.base_tune_path, resume, log)
    # a measured wind changes the whole balance of forces (at low speed it dominates): the
    # model driven by it gets its own base tune by the same procedure, so that "with" and
    # "without" are compared at equal effort (a re-tune from the windless optimum may stay in
    # that optimum's basin)
    # (a measured signal is a candidate only when the trials carry a wind: objs.wind is set,
    # here and where the search reads it for one)
    wind_theta = _base_tune(base, cast(tuple[Objective, Objective], objs.wind)[0], s, store,
                            'base with the measured wind', None, False, log) \
        if measured else None
    if meas:   # from here on, with the tuned base model's J per residual (its s^2)
        objs = _with_measurements(plain_objs, meas,
                                  measured_mod.s2_of(obj, ship, model.space, theta))
        obj = objs.plain[0]
    J_test = _per_trial_J(obj_test, ship, model.space, theta)
    baseline: dict[str, Any] = {
        'J_tune': float(_per_trial_J(obj, ship, model.space, theta).sum()),
        'J_test': float(J_test.sum()),
        'J_test_per_trial': dict(zip(obj_test.batch.names, J_test.tolist())),
        'params': dict(zip(base.names, theta.tolist()))}
    base_fail = _failure_text(obj_test, ship, model.space, theta) \
        if not np.all(np.isfinite(J_test)) else ''
    if base_fail:
        baseline['diverged'] = base_fail
    base_theta = theta.copy()
    log('   base model: J_test = ' + (f'{J_test.sum():.4g}' if not base_fail else base_fail))
    clock('noise')
    noise = _noise(ship, model.space.full_params(ship.params, theta)[0], plain_test, s,
                   obj_test.weights, log)
    J_floor = noise.get('J')
    clock('identifiability')
    aliased = _aliased_effects(ship, base, theta, obj, effects)
    for name, a in aliased.items():
        log(f"   {name} is barely identifiable here: its standard error {a['se']:.3g} with the "
            f'base targets free is over half the smallest magnitude worth finding '
            f"({a['smallest']:.3g}); {', '.join(a['mimicked_by'])} mimic "
            f"{_pct(a['r2'])} of its signature")

    log('2/3 searching the effects library')
    causes: list[Cause] = []
    rounds: list[list[Candidate]] = []
    impossible_fits: list[dict[str, Any]] = []
    measured_doc: list[dict[str, Any]] = []
    rival_pairs: list[dict[str, Any]] = []
    suspected: list[dict[str, Any]] = []
    first_screen: dict[str, float] = {}
    named_from: _NamedFrom | None = None
    swapped_out: set[str] = set()   # named, then replaced by a rival (never named back)
    remaining = effects + measured
    while remaining and len(causes) < s.max_effects:
        clock('screen')
        cands = []
        o_now, ot_now = objs.of(model)
        J_now = _per_trial_J(o_now, ship, model.space, theta).sum()
        # cheap screen: the effect alone, base held, from two starts: the base at its tuned
        # values and at its pre-determined ones (where the base tune started). The base tune
        # bends the coefficients to absorb what the model lacks, into another basin: a 3 deg
        # azimuth offset on the tug, screened from the bent base, re-tuned to a held-out J 700
        # x the truth's, level with a yaw moment bias (which was named); from the
        # pre-determined coefficients it fits at once. The re-tune starts from the start with
        # the lower tuning J; the null candidate gets the same choice (equal effort)
        fits, order = [], []
        now_pre = np.concatenate([base.pre, theta[base.dim:]])
        pre_evals = max(1, int(s.screen_evals * PRE_SCREEN_SHARE))
        null_pre = _Fit(ship, model.space, model.space.dim - base.dim, o_now, now_pre,
                        pre_evals, s.seed, True, 'cmaes')
        for name in remaining:
            if name in MEASURED:
                continue
            m = _Model(ship, base, model.effects + [EFFECTS[name]], model.measured_wind)
            # (the named effects move too, with CMA-ES's wide first steps, and every later
            # screen ranks by a loss: 'rudder offset screens at 0 %' beside a named wind.
            # Holding them was tried: beside a wind it then ranked a propeller side force
            # first and named it for a rudder offset, a false cause; see doc/guides/diagnosis)
            for start, evals in ((theta, s.screen_evals), (now_pre, pre_evals)):
                fits.append(_Fit(ship, m.space, m.space.dim - base.dim, objs.of(m)[0],
                                 np.concatenate([start, m.space.pre[len(theta):]]),
                                 evals, s.seed, True, 'cmaes'))
            order.append(name)
        *got, null_th = _tune_many(fits + [null_pre], store, map_fn)
        screened, from_pre = [], []
        for k, name in enumerate(order):
            m = _Model(ship, base, model.effects + [EFFECTS[name]], model.measured_wind)
            (J_m, th), (J_p, th_p) = [(_per_trial_J(objs.of(m)[0], ship, m.space, x).sum(), x)
                                      for x in got[2 * k:2 * k + 2]]
            if J_p < J_m or not math.isfinite(J_m):
                (J_m, th), (J_p, th_p) = (J_p, th_p), (J_m, th)
                from_pre.append(name)
            drop = float(1 - J_m / J_now) if math.isfinite(J_m) and J_now > 0 else -math.inf
            screened.append((drop, name, th))
        null_start = theta
        if _per_trial_J(o_now, ship, model.space, null_th).sum() < J_now:
            null_start = null_th
        for name in remaining:   # a measured signal has nothing to fit: its J with the base
            if name in MEASURED:
                J_m = _per_trial_J(cast(tuple[Objective, Objective], objs.wind)[0], ship,
                                   model.space, theta).sum()
                drop = float(1 - J_m / J_now) if math.isfinite(J_m) and J_now > 0 \
                    else -math.inf
                screened.append((drop, name, theta.copy()))
        screened.sort(key=lambda x: -x[0])
        if not rounds:   # what each effect alone explained at first: orders the advice
            first_screen = {n: d for d, n, _ in screened}
        log('   screen (tuning-J drop, effect alone): ' +
            ', '.join((f'{n} {100 * d:.0f}%' if math.isfinite(d) else f'{n} diverges')
                      + ('*' if n in from_pre else '') for d, n, _ in screened)
            + ('  (*: from the pre-determined base values, a lower tuning J than from the '
               'tuned ones)' if from_pre else '')
            + ('; the current model re-tunes from the pre-determined base values'
               if null_start is not theta else ''))
        # the null candidate (the current model re-tuned with the same warm start and budget,
        # so that a gain measures the effect, not the extra tuning) and the top candidates'
        # re-tunes (a measured signal always: it costs no screening), in one mapping
        clock('retune')
        top = screened[:s.screen] + [x for x in screened[s.screen:] if x[1] in MEASURED]
        models = []
        fits = [_Fit(ship, model.space, 0, o_now, null_start, s.effect_evals, s.seed, False,
                     s.retune)]
        for drop, name, th0 in top:
            if name in MEASURED:
                m = _Model(ship, base, model.effects, True)
                # from its own base tune (or the current optimum, whichever fits better)
                own = np.concatenate([wind_theta, theta[base.dim:]])
                J2 = cast(tuple[Objective, Objective], objs.wind)[0](
                    m.space.full_params(ship.params, np.vstack([own, th0])))
                th0 = own if J2[0] <= J2[1] or not np.isfinite(J2[1]) else th0
            else:
                m = _Model(ship, base, model.effects + [EFFECTS[name]], model.measured_wind)
            models.append(m)
            fits.append(_Fit(ship, m.space, 0, objs.of(m)[0], th0, s.effect_evals, s.seed,
                             False, s.retune))
        thetas = _tune_many(fits, store, map_fn)
        theta = thetas[0]
        J_test = _per_trial_J(ot_now, ship, model.space, theta)
        null_fail = _failure_text(ot_now, ship, model.space, theta) \
            if not np.all(np.isfinite(J_test)) else ''
        for (drop, name, _), m, th in zip(top, models, thetas[1:]):
            o_m, ot_m = objs.of(m)
            Jt = _per_trial_J(ot_m, ship, m.space, th)
            params = EFFECTS[name].params if name in EFFECTS else ()
            v = acceptance(J_test, Jt, len(params), baseline['J_test'], s, J_floor,
                           noise.get('per_trial'))
            fail = _failure_text(ot_m, ship, m.space, th) if not np.all(np.isfinite(Jt)) else ''
            vals = {p: float(x) for p, x in zip(m.space.names[base.dim:], th[base.dim:])
                    if p in params}
            pinned = pinned_on_bound(m.space, th, params, s.bound_tol)
            # too small is never named (a 0.04 m/s current once fitted a rudder stall); with a
            # reduction far above the noise floor it is no noise-fitting but an effect sharing
            # an error with another: the pairs are tried
            tiny = EFFECTS[name].too_small(ship, vals) if name in EFFECTS else False
            shares = bool(tiny and J_floor
                          and J_test.sum() - Jt.sum() > s.noise_margin * J_floor)
            why_not = impossible.get(name, '')
            ok = v.significant and not pinned and not tiny and not why_not
            # a barely identifiable estimate is judged with its standard error
            se = ({params[0]: float(aliased[name]['se'])}
                  if name in aliased and len(params) == 1 else {})
            implaus = implausible(ship, name, vals, se) if ok and name in EFFECTS else ''
            incons, est = '', []
            if ok and not implaus and name in EFFECTS:
                incons = _clearly_worse(J_test, Jt, noise, s, ot_m.batch.names)
                if not incons:
                    clock('consistency')
                    est = per_trial(ship, m.space, th, params, singles[m.measured_wind])
                    incons = disagreement(ship, name, est, vals)
                    clock('retune')
            ok = ok and not implaus and not incons
            cand = Candidate(name, float(Jt.sum()), v.per_trial_gain.tolist(), float(v.gain),
                             v.gain_se, ok, vals, float(drop), pinned, float(J_test.sum()),
                             why_not, fail or (('reference ' + null_fail) if null_fail else ''),
                             bool(v.significant), implaus, incons, est)
            cands.append((cand, m, th, Jt))
            verdict = 'significant' if ok else 'not significant'
            if v.significant and why_not:
                verdict = f'would fit, but impossible here: {why_not}'
                if not tiny:
                    impossible_fits.append({'effect': name, 'gain': float(v.gain),
                                            'gain_se': float(v.gain_se), 'reason': why_not,
                                            'values': vals, 'on_bound': pinned,
                                            'round': len(rounds) + 1})
            elif v.significant and pinned:
                verdict = ('significant but rejected: ' + ', '.join(
                    f'{p} = {vals[p]:.4g} on its bound' for p in pinned)
                    + ' (a likely mis-attribution)')
            elif v.significant and implaus:
                verdict = f'significant but implausible: {implaus}'
            elif v.significant and incons:
                verdict = f'significant but inconsistent: {incons}'
            elif v.significant and tiny:
                verdict = ('significant but rejected: smaller than the smallest magnitude worth '
                           'finding' + (' while its reduction is above the noise floor: it '
                                        'shares an error with another effect' if shares
                                        else ' (noise-fitting)'))
            elif not v.significant:
                verdict += f' ({fail or null_fail or v.reason})'
            per = ', '.join(f'{100 * x:+.0f}%' if math.isfinite(x) else 'diverges'
                            for x in v.per_trial_gain)
            log(f'   {name}: held-out gain {_pct(v.gain)} ± {_pct(v.gain_se)} '
                f'({_pct(v.absolute)} of the base error; per trial {per}) {verdict}')
            if name in MEASURED:
                measured_doc.append({
                    'signal': name, 'round': len(rounds) + 1,
                    'J_test_without': float(J_test.sum()), 'J_test_with': float(Jt.sum()),
                    'heldout_gain': float(v.gain), 'heldout_gain_se': float(v.gain_se),
                    'named': ok, 'note': '' if ok else (why_not or fail or v.reason)})
        rounds.append([c[0] for c in cands])
        accepted = [c for c in cands if c[0].accepted]
        # effects that compete or bend (significant, yet none acceptable alone): the plausible
        # pairs of the top of the screen, fitted jointly, by the same held-out rule
        competing = [c[0] for c in cands if c[0].significant and not c[0].accepted
                     and not c[0].impossible]
        if not accepted and competing and s.pairs > 1 and len(causes) + 2 <= s.max_effects:
            clock('pairs')
            pair = _pair_round(ship, base, model, theta, objs, screened, J_test, baseline,
                               s, impossible, noise, singles, store, map_fn, log, every)
            if pair is not None:
                pcand, model, theta, J_test, members, on_all, th_all = pair
                sized_on_all += on_all
                all_fit = (model.space.names, th_all) if on_all else all_fit
                rounds[-1].append(pcand)
                causes += _causes_from_fit(pcand, model, theta, objs, members)
                for e, _ in members:
                    remaining.remove(e)
                log(f"   -> named (jointly): {' + '.join(e for e, _ in members)}")
                continue
        # the last named effect may have bent to take another's share (a wind turned 20 deg
        # toward a rudder offset, which then fits too small to name): when a candidate
        # competes (significant, not acceptable alone), the last named one and each such
        # candidate are fitted jointly from before it was named. (Also trying the top of the
        # screens whenever what remains is above the noise was tried: it can name a
        # propeller side force for a rudder offset beside a wind, a false cause.)
        # what the trials hint at but disagree on (suspected_effects): a member of a pair whose
        # other member bent to take its share makes a held-out trial worse when fitted beside
        # it (a rudder offset beside a current bent 20 deg: one held-out trial 6.6 x worse,
        # the rest 45-96 % better), so it competes too
        hinted = suspected_effects(
            ship, [(c, None if m.measured_wind else m.space.full_params(ship.params, th)[0])
                   for c, m, th, _ in cands], s, baseline['J_test'], J_floor, len(rounds),
            [e.name for e in model.effects] + ['measured_wind'] * model.measured_wind,
            None if model.measured_wind else model.space.full_params(ship.params, theta)[0])
        last = causes[-1].effect if causes else ''
        news = [c.effect for c in competing if c.effect in EFFECTS and c.effect != last]
        news += [x['effect'] for x in hinted if x['effect'] not in news + [last]]
        # and what was significant beside the last named one where it was named: the next
        # screen, beside it, ranks by a loss (a rudder offset at -3486 % beside a wind bent
        # from 7.9 to 10.7 m/s, so never re-tuned), but the joint fit starts from before it
        news += [e for e in (named_from.significant if named_from is not None else [])
                 if e in remaining and e not in news + [last]]
        # and, while what remains is not noise, the barely identifiable effects: the screen
        # holds the base, and the base coefficients mimic such an effect, so it screens at
        # nothing however much it explains with them free (a rudder offset of -1.3 deg beside
        # a 0.33 m/s current screened at -2 %, while current + offset with the base free left
        # a held-out J 0.28 x the current's alone; a wind was named in its place)
        above_noise = noise_describe(float(np.sum(J_test)), noise)[0] is False
        if above_noise:
            news += [e for e in aliased if e in remaining and e not in news + [last]
                     and e not in impossible]
        if not accepted and news and named_from is not None and last in EFFECTS \
                and s.pairs > 1 and len(causes) + 1 <= s.max_effects:
            clock('pairs')
            joint, absorbed = _joint_round(ship, base, named_from, last,
                                           [(last, b) for b in news], objs, J_test,
                                           baseline, s, noise, singles, store, map_fn, log,
                                           every)
            # a rival of the last named one (as good alone, within the combined uncertainty)
            # that, fitted jointly with it from before it was named, leaves it at nothing
            # (_at_nothing; too small alone is no sign: mimics share the error):
            # with both free the trials keep the rival (a yaw moment bias named as a 6.8 m/s
            # wind, the wind fitted at 0 m/s beside the bias). The rival is named instead,
            # the other listed as indistinguishable; never back (swapped_out)
            swap = [b for b in absorbed if joint is None and b not in swapped_out
                    and b in causes[-1].indistinguishable_from and b in named_from.accepted]
            if swap:
                # (bound first: a lambda loses the narrowing of named_from, reassigned below)
                as_good = named_from.accepted
                b = max(swap, key=lambda e: as_good[e][0].gain)
                cb, model, theta, J_test = named_from.accepted[b]
                old = causes.pop()
                causes += _causes_from_fit(
                    cb, model, theta, objs, [(b, cb.values)],
                    [last] + [e for e in old.indistinguishable_from if e != b])
                swapped_out.add(last)
                remaining.remove(b)
                remaining.append(last)
                named_from = named_from._replace(
                    significant=[e for e in named_from.significant if e != b] + [last])
                log(f'   -> named instead of {last}: {b} (fitted jointly from before {last} '
                    f'was named, the trials leave {last} at nothing beside it)')
                continue
            if joint is not None:
                pcand, model, theta, J_test, (_, (e, vals)), on_all, th_all = joint
                sized_on_all += on_all
                all_fit = (model.space.names, th_all) if on_all else all_fit
                rounds[-1].append(pcand)
                causes += _causes_from_fit(pcand, model, theta, objs, [(e, vals)])
                remaining.remove(e)
                log(f'   -> named (jointly with {last}): {e}')
                continue
        # a rival of the last named one (as good alone) may be the half of a pair the last
        # named one only imitates: a current 0.25 m/s + rudder offset 1.5 deg named as an 8 m/s
        # wind (wind alone 78 %, current alone 74 %); beside the wind the offset fits to 0, but
        # current + offset, fitted from before the wind, leaves a held-out J 4.4 x smaller.
        # When what remains is not noise, each rival is fitted with each plausible partner
        # from there, judged as a candidate of the round that named the last one (against the
        # model before it: the wind's lucky fit of one trial is no veto), and named in its
        # place when it explains clearly more: its gain above the last one's by more than the
        # combined uncertainty (the rule that calls rivals "about as well")
        rivals = [r for r in (causes[-1].indistinguishable_from if causes else [])
                  if named_from is not None and r in named_from.accepted and r in remaining
                  and r not in swapped_out]
        if not accepted and rivals and last in EFFECTS and s.pairs > 1 \
                and len(causes) + 1 <= s.max_effects and above_noise:
            clock('pairs')
            named_from = cast(_NamedFrom, named_from)   # set: the rivals come from it
            partners = [e for e in named_from.ranking
                        if e in EFFECTS and e in remaining and e not in impossible]
            model0, theta0 = named_from.model, named_from.theta
            rjoint, _ = _joint_round(ship, base, named_from, last,
                                     [(r, x) for r in rivals for x in partners if x != r],
                                     objs, _per_trial_J(objs.of(model0)[1], ship, model0.space,
                                                        theta0),
                                     baseline, s, noise, singles, store, map_fn, log, every,
                                     before=True)
            old = causes[-1]
            if rjoint is not None and rjoint[0].gain - old.heldout_gain <= np.hypot(
                    rjoint[0].gain_se, old.heldout_gain_se):
                log(f'   {rjoint[0].effect.replace("+", " + ")} is accepted but explains no '
                    f'more than {last} (within the combined uncertainty): {last} stays')
                rjoint = None
            if rjoint is not None:
                pcand, model, theta, J_test, members, on_all, th_all = rjoint
                sized_on_all += on_all
                all_fit = (model.space.names, th_all) if on_all else all_fit
                rounds[-1].append(pcand)
                causes.pop()
                causes += _causes_from_fit(pcand, model, theta, objs, members)
                for e, _ in members:
                    remaining.remove(e)
                swapped_out.add(last)
                remaining.append(last)
                # the trial that would have told last from its rivals is moot now
                rival_pairs = [x for x in rival_pairs
                               if not x['about'].startswith(f'{last} vs ')]
                log(f'   -> named instead of {last} (jointly): '
                    + ' + '.join(e for e, _ in members))
                continue
        if not accepted:
            # what the trials hint at but do not settle: suspected, never named; the advice
            # gives the trial that would separate the model with it from the model without
            suspected = hinted
            for x in suspected:
                log(f"   suspected, not named: {x['summary']} (held-out gain {_pct(x['gain'])} "
                    f"± {_pct(x['gain_se'])}: the held-out trials disagree on it)")
            rival_pairs += [x.pop('rival') for x in suspected if 'rival' in x]
            break
        best = max(accepted, key=lambda c: c[0].gain)
        # the model before this cause, its optimum and each candidate's screened values: a
        # later round may fit this cause jointly with another from there
        named_from = _NamedFrom(
            model, theta, {n: th for _, n, th in screened}, [n for _, n, _ in screened],
            [c[0].effect for c in cands if c[0].significant and c[0] is not best[0]
             and c[0].effect in EFFECTS and not c[0].impossible],
            {c[0].effect: c for c in accepted if c[0].effect in EFFECTS})
        cand, model, theta, J_test = best
        # another significant effect whose gain is within the combined uncertainty explains
        # these trials about as well: say so rather than pretend to know -- unless a held-out
        # trial tells them apart (the rival clearly worse on it, by the rule that vetoes a
        # cause, and nowhere clearly better): one manoeuvre may be all that separates them
        rivals = [c[0].effect for c in accepted if c[0] is not cand
                  and cand.gain - c[0].gain < np.hypot(cand.gain_se, c[0].gain_se)
                  and not _told_apart(J_test, c[3], noise, s, objs.of(model)[1].batch.names)]
        clock('identifiability')
        se_all = standard_errors(objs.of(model)[0], model.space, theta)
        errs = {p: float(e) for p, e in zip(model.space.names, se_all) if p in cand.values}
        full_c = model.space.full_params(ship.params, theta)[0]
        for c in accepted:   # the rival models, for advice on the trial that separates them
            if c[0].effect in rivals and not model.measured_wind and not c[1].measured_wind:
                rival_pairs.append({'about': f'{cand.effect} vs {c[0].effect}',
                                    'kind': 'indistinguishable', 'params_a': full_c,
                                    'params_b': c[1].space.full_params(ship.params, c[2])[0]})
        desc = MEASURED[cand.effect][1] if cand.effect in MEASURED \
            else EFFECTS[cand.effect].description
        causes.append(Cause(cand.effect, cand.values, errs, cand.gain, cand.gain_se, rivals,
                            desc))
        remaining.remove(cand.effect)
        log(f'   -> named: {cand.effect}' + (f' (but {", ".join(rivals)} explain(s) the trials '
                                             'about as well)' if rivals else ''))
    if len(model.effects) + model.measured_wind > 1:
        clock('backward')
        model, theta, J_test = _backward_pass(ship, base, model, theta, objs, causes, s,
                                              baseline['J_test'], log, store, map_fn, J_floor,
                                              noise.get('per_trial'))
    clock('identifiability')
    o_fin, ot_fin = objs.of(model)
    if causes:  # report the final model's values (later rounds re-tuned them)
        final_vals = dict(zip(model.space.names, theta))
        o_se, th_se = o_fin, theta
        if sized_on_all and any(c.effect in sized_on_all for c in causes):
            # a member the tuning trials alone sized too small was sized on every trial: the
            # causes' values are those of the final model refitted on all of them (the held-out
            # J above stays that of the tuning trials' fit); the pair's own fit there while the
            # model is still that pair
            o_all = every.of(model)[0]
            th_all = all_fit[1] if all_fit is not None and all_fit[0] == model.space.names \
                else _tune_many([_Fit(ship, model.space, 0, o_all, theta, s.effect_evals,
                                      s.seed, False, s.retune)], store, map_fn)[0]
            final_vals = dict(zip(model.space.names, th_all))
            o_se, th_se = o_all, th_all
            log("   the causes' values: the final model refitted on all "
                f'{len(o_all.batch.names)} trials ({", ".join(sized_on_all)} sized there)')
        # Gauss-Newton's errors take the residuals as independent; along a trajectory they
        # are not, and on the tug they were 3-6 x too small (a thrust scale 0.8545 +- 0.0014
        # for 0.85): the larger of them and the trial-robust (sandwich) ones is reported
        gn, robust = trial_robust_standard_errors(o_se, model.space, th_se)
        se_final = dict(zip(model.space.names, np.fmax(gn, robust)))
        named = [p for c in causes for p in c.parameters]
        log('   standard errors of the named, trial-robust (Gauss-Newton): ' + ', '.join(
            f'{p} {se_final[p]:.3g} ({gn[model.space.names.index(p)]:.3g})' for p in named))
        for cause in causes:
            cause.parameters = {p: float(final_vals[p]) for p in cause.parameters}
            cause.uncertainty = {p: float(se_final[p]) for p in cause.parameters}
    for e in by_measurement:
        by_meas, wanted = _by_measurement(ship, EFFECTS[e], meas, model, theta, plain_objs,
                                          ot_fin, s, baseline['J_test'], J_floor, store, map_fn,
                                          log)
        if by_meas is not None:
            causes.append(by_meas)
        if wanted is not None:
            impossible_fits.append({**wanted, 'round': len(rounds)})
    advice = []
    if s.advice and (aliased or rival_pairs):
        clock('advice')
        advice = _advice(ship, base, base_theta, obj, aliased, impossible, rival_pairs,
                         list(tune_trials) + list(test_trials), log, first_screen, effects)
    clock(None)
    J_test = np.atleast_1d(J_test)
    final = {'J_tune': float(_per_trial_J(o_fin, ship, model.space, theta).sum()),
             'J_test': float(J_test.sum()),
             'J_test_per_trial': dict(zip(ot_fin.batch.names, J_test.tolist())),
             'heldout_gain_total': _gain(baseline['J_test'], float(J_test.sum()))}
    if not np.all(np.isfinite(J_test)):
        final['diverged'] = _failure_text(ot_fin, ship, model.space, theta)
    timings = {k: round(v, 3) for k, v in clock.t.items()}
    log('   time per stage: ' + ', '.join(f'{k} {v:.1f} s' for k, v in timings.items()))
    # the measured effects' values are in every model (the ship carries them): in its params
    held = {p: meas[p].value for e in by_measurement for p in EFFECTS[e].params}
    return Diagnosis(causes, baseline, final, rounds,
                     {**held, **dict(zip(model.space.names, theta.tolist()))},
                     dict(zip(base.names, base_theta.tolist())),
                     time.perf_counter() - t_start, aliased, setting,
                     {e: w for e, w in impossible.items() if e in effects or e in measured},
                     impossible_fits, measured_doc, timings, model.measured_wind, advice, noise,
                     suspected)


def suspected_effects(ship: ShipConfig, cands: Sequence[tuple[Candidate, np.ndarray | None]],
                      s: DiagnosisSettings, baseline_J: float, J_floor: float | None,
                      round_no: int, beside: Sequence[str],
                      params_now: np.ndarray | None) -> list[dict[str, Any]]:
    """
    Return the effects the last round hints at but cannot name (suspected, never named).

    ``cands``: the round's candidates, each with the full parameter vector of the model with
    it (None when it cannot be simulated apart: the measured wind drives it); ``params_now``:
    the current model's (same); ``beside``: the effects it holds. A candidate of the round
    that named nothing is suspected when its held-out gain exceeds the rule's least gain for
    its parameters and its reduction counts as evidence (min_abs_gain of the base model's
    held-out error, or noise_margin noise floors), and it is possible here, off its bounds,
    not too small and plausible: what kept it from being named is its spread over the held-out
    trials (one made worse, or the gain within its standard error). Found on the bench: a
    rudder offset beside a named wind, held-out gain 46 % +- 40 %, one held-out trial 2.6 x
    worse, the wind bent 17 deg to take its share. Each carries a rival pair ('rival': the
    model without it and with it, kind 'suspected', for the advice's trial that would separate
    them; the caller removes the key) when both can be simulated.
    """
    out: list[dict[str, Any]] = []
    for cand, params_with in cands:
        name = cand.effect
        if cand.accepted or name not in EFFECTS or cand.impossible or cand.on_bound:
            continue
        reduction = cand.J_ref - cand.J_test
        evidence = reduction > s.min_abs_gain * baseline_J or bool(
            J_floor and reduction > s.noise_margin * J_floor)
        need = s.min_gain + s.param_penalty * len(EFFECTS[name].params)
        if not (cand.gain > need and evidence):
            continue
        if EFFECTS[name].too_small(ship, cand.values) or implausible(ship, name, cand.values):
            continue
        x: dict[str, Any] = {'effect': name, 'values': dict(cand.values), 'gain': cand.gain,
                             'gain_se': cand.gain_se, 'round': round_no,
                             'summary': describe_values(EFFECTS[name], cand.values, {}),
                             'beside': list(beside)}
        if params_now is not None and params_with is not None:
            x['rival'] = {'about': name, 'kind': 'suspected', 'params_a': params_now,
                          'params_b': params_with}
        out.append(x)
    return out


def _by_measurement(ship: ShipConfig, eff: Effect, meas: dict[str, measured_mod.Measurement],
                    model: _Model, theta: np.ndarray, plain_objs: _Objectives, ot_fin: Objective,
                    s: DiagnosisSettings, baseline_J: float, J_floor: float | None,
                    store: SearchCheckpoint | None, map_fn: MapFn[_Fit, np.ndarray] | None,
                    log: Callable[[str], None]) -> tuple[Cause | None, dict[str, Any] | None]:
    """
    Return (the cause a measurement sizes or None, a contradicted fit or None).

    ``eff``'s parameters are all measured, held in every model. It is fitted once more by the
    tuning trials alone (the final model with the effect free, no prior). Named as measured
    when a sized parameter lies more than two of its standard errors and at least the smallest
    magnitude worth finding from no effect, and the trials-alone fit lies within three combined
    standard errors (its trial-robust one and the measurement's) of the measured value: a
    barely identifiable effect (why it was measured) passes with a wide fit; a wrong
    measurement of one the trials do size does not. Its held-out gain is the final model's
    against the same model at no effect (nothing re-tuned: an upper bound).

    The second value: when the trials-alone fit is significant by the held-out rule but lies
    on its bound or where the measurement rules it out, the fit the search would have weighed
    as structural evidence (a time offset on its bound beside a hull 46 % stronger), in
    ``impossible_fits``' form: the measurement says the trials want something the library
    lacks.
    """
    vals = {p: float(meas[p].value) for p in eff.params}
    ses = {p: float(meas[p].se) for p in eff.params}
    src = '; '.join(sorted({meas[p].source or 'a measurement' for p in eff.params}))
    words = describe_values(eff, vals, ses)
    # the trials alone: the final model with the effect free, without the measurements' prior
    m = _Model(ship, model.base, model.effects + [eff], model.measured_wind)
    o, ot = plain_objs.of(m)
    x0 = np.concatenate([theta, [vals[p] for p in eff.params]])
    th = _tune_many([_Fit(ship, m.space, 0, o, x0, s.effect_evals, s.seed, False, s.retune)],
                    store, map_fn)[0]
    gn, robust = trial_robust_standard_errors(o, m.space, th)
    k = [m.space.names.index(p) for p in eff.params]
    fit = {p: float(th[i]) for p, i in zip(eff.params, k)}
    se_fit = {p: float(max(gn[i], robust[i])) for p, i in zip(eff.params, k)}
    alone = describe_values(eff, fit, se_fit)
    z = [abs(fit[p] - vals[p]) / math.hypot(se_fit[p], ses[p])
         for p, per in zip(eff.params, eff.periodic) if not per]
    contradicted = any(not math.isfinite(x) or x > 3.0 for x in z)
    J_with = _per_trial_J(ot_fin, ship, model.space, theta)
    v = acceptance(J_with, _per_trial_J(ot, ship, m.space, th), len(eff.params), baseline_J, s,
                   J_floor)
    pinned = pinned_on_bound(m.space, th, eff.params, s.bound_tol)
    wanted = None
    if v.significant and (contradicted or pinned):
        wanted = {'effect': eff.name, 'gain': float(v.gain), 'gain_se': float(v.gain_se),
                  'reason': f'measured {words}, the trials alone fit {alone}'
                            + (' on its bound' if pinned else ''),
                  'values': fit, 'on_bound': pinned}   # the caller adds its 'round'
        log(f'   {eff.name}: the trials alone fit {alone}, a held-out gain of {_pct(v.gain)}, '
            f'but it was measured: {words}; the trials want what the library lacks')
    apart = [p for p, n, per in zip(eff.params, eff.neutral, eff.periodic)
             if not per and abs(vals[p] - n) > 2.0 * ses[p]]
    if not apart or eff.too_small(ship, vals):
        log(f'   {eff.name}: measured {words}: not apart from no effect (within two standard '
            'errors of it, or smaller than the smallest magnitude worth finding); held in the '
            'model, not named')
        return None, wanted
    if contradicted:
        log(f'   {eff.name}: measured {words}, but the trials alone fit {alone}: more than '
            'three combined standard errors apart; held in the model, not named: check the '
            'measurement')
        return None, wanted
    without = ship.with_params(dict(zip(eff.params, eff.neutral)))
    J_without = _per_trial_J(ot_fin, without, model.space, theta)
    gain = _gain(float(J_without.sum()), float(J_with.sum()))
    se = float(jackknife_se(J_without, J_with)) \
        if np.all(np.isfinite(J_without)) and np.all(np.isfinite(J_with)) else math.nan
    log(f'   -> named (measured: {src}): {eff.name}, {words} (the trials alone: {alone}); '
        f'held-out gain against the same model at no {eff.name.replace("_", " ")} {_pct(gain)}'
        f' ± {_pct(se)}')
    return Cause(eff.name, vals, ses, gain, se, [], eff.description, src), wanted


def _with_measurements(objs: _Objectives, meas: dict[str, measured_mod.Measurement], s2: float
                       ) -> _Objectives:
    """Return the objectives with the measurements' prior on the tuning sides (s2: J/residual)."""
    pr = measured_mod.prior(meas, s2)
    return _Objectives((measured_mod.with_prior(objs.plain[0], pr), objs.plain[1]),
                       None if objs.wind is None
                       else (measured_mod.with_prior(objs.wind[0], pr), objs.wind[1]))


def _causes_from_fit(cand: Candidate, model: _Model, theta: np.ndarray, objs: _Objectives,
                     members: list[tuple[str, dict[str, float]]],
                     rivals: Sequence[str] = ()) -> list[Cause]:
    """
    Return the causes a fitted model names: each member effect (with its fitted values).

    Each with its standard errors in that model's fit and the candidate's held-out gain (a
    pair's members were accepted together, so they share it); rivals: the effects the trials
    cannot tell from them.
    """
    se = dict(zip(model.space.names, standard_errors(objs.of(model)[0], model.space, theta)))
    return [Cause(e, vals, {p: float(se[p]) for p in vals}, cand.gain, cand.gain_se,
                  list(rivals), EFFECTS[e].description) for e, vals in members]


def _pair_round(ship: ShipConfig, base: ParameterSpace, model: _Model, theta: np.ndarray,
                objs: _Objectives, screened: list[tuple[float, str, np.ndarray]],
                J_ref: np.ndarray, baseline: dict[str, Any], s: DiagnosisSettings,
                impossible: dict[str, str], noise: dict[str, Any],
                singles: dict[bool, list[Objective]], store: SearchCheckpoint | None,
                map_fn: MapFn[_Fit, np.ndarray] | None, log: Callable[[str], None],
                every: _Objectives | None = None) -> _Joint | None:
    """
    Fit the plausible pairs of the top screened candidates jointly; return the best accepted.

    Each pair is re-tuned with the base targets (and the named effects) from the current
    optimum and each member's screened values, and judged by the same rule as one effect:
    :func:`acceptance` against the current model re-tuned (``J_ref``; parameters: both
    members'), no member on a bound, too small for the reduction, implausible or
    inconsistent, no held-out trial clearly worse (``every``: the objectives on every trial,
    where a member sized too small by the tuning trials is sized; :func:`_joint_objections`).
    Returns (Candidate, model, theta, J_test, [(effect, values)], [effects sized on every
    trial], the parameters they were sized at) or None.
    """
    top = [(n, th) for _, n, th in screened
           if n in EFFECTS and n not in impossible][:s.pairs]
    J_floor = noise.get('J')
    options = []
    for (a, tha), (b, thb) in combinations(top, 2):
        m = _Model(ship, base, model.effects + [EFFECTS[a], EFFECTS[b]], model.measured_wind)
        x0 = np.concatenate([theta, tha[len(theta):], thb[len(theta):]])
        options.append(((a, b), m, x0))
    fits = [_Fit(ship, m.space, 0, objs.of(m)[0], x0, s.effect_evals, s.seed, False, s.retune)
            for _, m, x0 in options]
    best: _Joint | None = None
    for ((a, b), m, _), th in zip(options, _tune_many(fits, store, map_fn)):
        o_m, ot_m = objs.of(m)
        Jt = _per_trial_J(ot_m, ship, m.space, th)
        n_par = len(EFFECTS[a].params) + len(EFFECTS[b].params)
        v = acceptance(J_ref, Jt, n_par, baseline['J_test'], s, J_floor,
                       noise.get('per_trial'))
        vals = {p: float(x) for p, x in zip(m.space.names, th)}
        members = [(e, {p: vals[p] for p in EFFECTS[e].params}) for e in (a, b)]
        why, members, on_all, th_all = _joint_objections(
            ship, m, th, members, v, J_ref, Jt, noise, s, ot_m, singles,
            _refit_on(every, ship, m, th, s, store, map_fn))
        log(f'   pair {a} + {b}: held-out gain {_pct(v.gain)} ± {_pct(v.gain_se)} '
            + _pair_outcome(members, on_all, why))
        cand = _pair_candidate(a, b, Jt, J_ref, v, members, why)
        if not why and (best is None or v.gain > best[0].gain):
            best = (cand, m, th, Jt, members, on_all, th_all)
    return best


def _pair_outcome(members: _Members, on_all: list[str], why: list[str]) -> str:
    """End of a pair's log line: how it was sized and whether it was accepted."""
    return ((f'(sized on every trial: {_shown(members)}) ' if on_all else '')
            + ('significant' if not why else 'not accepted (' + '; '.join(why) + ')'))


def _pair_candidate(a: str, b: str, Jt: np.ndarray, J_ref: np.ndarray, v: Verdict,
                    members: _Members, why: list[str]) -> Candidate:
    """Return the pair a+b as a Candidate: held-out J, gains, fitted values, objections."""
    return Candidate(f'{a}+{b}', float(Jt.sum()), v.per_trial_gain.tolist(),
                     float(v.gain), v.gain_se, not why, {**members[0][1], **members[1][1]},
                     J_ref=float(J_ref.sum()), significant=bool(v.significant),
                     inconsistent='; '.join(why) if v.significant else '')


def _shown(members: _Members) -> str:
    return ', '.join(describe_values(EFFECTS[e], ev, {}) for e, ev in members)


def _joint_objections(ship: ShipConfig, m: _Model, th: np.ndarray, members: _Members,
                      v: Verdict, J_ref: np.ndarray, Jt: np.ndarray, noise: dict[str, Any],
                      s: DiagnosisSettings, ot_m: Objective, singles: dict[bool, list[Objective]],
                      refit: Callable[[], np.ndarray] | None = None
                      ) -> tuple[list[str], _Members, list[str], np.ndarray]:
    """
    Return why a joint fit is not accepted ([] if it is): the rule of one effect, per member.

    Not significant (:func:`acceptance`'s verdict ``v``); a member on a bound, too small,
    implausible, or inconsistent over the held-out trials; a held-out trial clearly worse.
    ``refit``: the pair model tuned on every trial (tuning and held-out), called when the pair
    is significant and a member comes out smaller than the smallest worth finding: the members
    are then sized (bounds, size, plausibility) from that fit. Returns (why, the members'
    (effect, values) as judged, the effects sized on every trial, the parameters they were
    judged at: ``th`` or the fit on every trial).
    """
    why = [] if v.significant else [v.reason]
    th_size, on_all = th, []
    if v.significant and refit is not None \
            and any(EFFECTS[e].too_small(ship, ev) for e, ev in members) \
            and not any(pinned_on_bound(m.space, th, EFFECTS[e].params, s.bound_tol)
                        for e, _ in members):
        # The held-out rule found the pair, but the tuning trials alone may leave a member's
        # size in a flat valley along which the tuned coefficients trade with it (a 1.5 deg
        # rudder offset beside a 9 m/s wind: every size from 0.7 to 1.5 deg fits the five
        # tuning trials within 2 %, and the re-tune stops at 0.68 deg); the held-out trials
        # (other rudder angles) settle it, so the size comes from all the recordings
        th_size = refit()
        on_all = [e for e, ev in members if EFFECTS[e].too_small(ship, ev)]
        vals = dict(zip(m.space.names, th_size))
        members = [(e, {p: float(vals[p]) for p in ev}) for e, ev in members]
    for e, ev in members:
        pinned = pinned_on_bound(m.space, th_size, EFFECTS[e].params, s.bound_tol)
        if pinned:
            why.append(f"{', '.join(pinned)} on its bound")
        elif EFFECTS[e].too_small(ship, ev):
            why.append(f'{e} smaller than the smallest worth finding')
        elif implausible(ship, e, ev):
            why.append(f'{e} implausible: ' + implausible(ship, e, ev))
    if not why:
        worse = _clearly_worse(J_ref, Jt, noise, s, ot_m.batch.names)
        why += [worse] if worse else []
    if not why:
        for e, ev in members:
            est = per_trial(ship, m.space, th, EFFECTS[e].params, singles[m.measured_wind])
            bad = disagreement(ship, e, est, ev)
            if bad:
                why.append(f'{e}: {bad}')
    return why, members, on_all, th_size


def _refit_on(every: _Objectives | None, ship: ShipConfig, m: _Model, th: np.ndarray,
              s: DiagnosisSettings, store: SearchCheckpoint | None,
              map_fn: MapFn[_Fit, np.ndarray] | None) -> Callable[[], np.ndarray] | None:
    """Return a call that re-tunes model ``m`` from ``th`` on every trial (None without)."""
    if every is None:
        return None
    return lambda: _tune_many([_Fit(ship, m.space, 0, every.of(m)[0], th, s.effect_evals,
                                    s.seed, False, s.retune)], store, map_fn)[0]


def _joint_round(ship: ShipConfig, base: ParameterSpace, named_from: _NamedFrom, last: str,
                 pairs: list[tuple[str, str]], objs: _Objectives, J_ref: np.ndarray,
                 baseline: dict[str, Any], s: DiagnosisSettings, noise: dict[str, Any],
                 singles: dict[bool, list[Objective]], store: SearchCheckpoint | None,
                 map_fn: MapFn[_Fit, np.ndarray] | None, log: Callable[[str], None],
                 every: _Objectives | None = None, before: bool = False
                 ) -> tuple[_Joint | None, list[str]]:
    """
    Fit pairs of effects jointly, from before the last named effect was named.

    ``named_from``: the round that named ``last`` (:class:`_NamedFrom`); ``pairs``: (a, b)
    to fit: ``last`` with a new candidate, or a rival of ``last`` (as good alone) with a
    partner, to take its place. Each pair starts from the optimum before ``last`` with both
    members at their screened values (the last named one has not yet bent toward the other)
    and is re-tuned with the base targets; it is judged by the rule of one effect
    (:func:`_joint_objections`; ``every``: the objectives on every trial, where a member sized
    too small by the tuning trials is sized) against ``J_ref``: the current model (with
    ``last``; parameters: the new member's) or, ``before``, the model before ``last`` (as
    the candidates of the round that named it; parameters: both members').
    Returns ((Candidate, model, theta, J_test, [(effect, its values)] of both members,
    [effects sized on every trial], the parameters they were sized at) or None, [the new
    effects beside which the tuning fit leaves ``last`` below its smallest magnitude worth
    finding, at nothing (:func:`_at_nothing`), while they are not]).
    """
    model0, theta0, screened0 = named_from.model, named_from.theta, named_from.screened
    absorbed: list[str] = []

    n0 = len(theta0)
    options = []
    for a, b in pairs:
        if a == b or b not in screened0 or a not in screened0:
            continue
        m = _Model(ship, base, model0.effects + [EFFECTS[a], EFFECTS[b]],
                   model0.measured_wind)
        x0 = np.concatenate([theta0, screened0[a][n0:], screened0[b][n0:]])
        options.append((a, b, m, x0))
    fits = [_Fit(ship, m.space, 0, objs.of(m)[0], x0, s.effect_evals, s.seed, False, s.retune)
            for _, _, m, x0 in options]
    best: _Joint | None = None
    for (a, b, m, _), th in zip(options, _tune_many(fits, store, map_fn)):
        ot_m = objs.of(m)[1]
        Jt = _per_trial_J(ot_m, ship, m.space, th)
        added = len(EFFECTS[b].params) + (len(EFFECTS[a].params) if before else 0)
        v = acceptance(J_ref, Jt, added, baseline['J_test'], s,
                       noise.get('J'), noise.get('per_trial'))
        vals = {p: float(x) for p, x in zip(m.space.names, th)}
        members = [(e, {p: vals[p] for p in EFFECTS[e].params}) for e in (a, b)]
        shown = _shown(members)
        why, members, on_all, th_all = _joint_objections(
            ship, m, th, members, v, J_ref, Jt, noise, s, ot_m, singles,
            _refit_on(every, ship, m, th, s, store, map_fn))
        log(f'   joint {a} + {b}' + (f' in place of {last}' if a != last else '')
            + f' ({shown}): held-out gain over '
            + (f'the model before {last}' if before else f'{last} alone')
            + f' {_pct(v.gain)} ± {_pct(v.gain_se)} ' + _pair_outcome(members, on_all, why))
        cand = _pair_candidate(a, b, Jt, J_ref, v, members, why)
        if not why and (best is None or v.gain > best[0].gain):
            best = (cand, m, th, Jt, members, on_all, th_all)
        fitted = [{p: vals[p] for p in EFFECTS[e].params} for e in (a, b)]
        # (at nothing implies too small)
        if a == last and _at_nothing(ship, EFFECTS[last], fitted[0]) \
                and not EFFECTS[b].too_small(ship, fitted[1]):
            absorbed.append(b)
    return best, absorbed


def _at_nothing(ship: ShipConfig, e: Effect, values: Mapping[str, float]) -> bool:
    """
    Tell whether a fit leaves an effect at nothing: well below the smallest worth finding.

    Every sized parameter within AT_NOTHING of the smallest magnitude worth finding from
    neutral. Two effects that mimic each other share the error in a joint fit; that one comes
    out under the smallest magnitude worth finding is no sign the other is the real one (a real
    rudder offset of -1.53 deg kept -0.68 deg beside a yaw moment bias and -0.90 deg beside a
    propeller side force, which was then named in its place: a false cause). Left at nothing,
    it is: a wind named for a yaw moment bias fits at 0 m/s beside the bias, a yaw moment bias
    named for a rudder offset of 2.27 deg at 1.4e-4 (0.28 of the 5e-4 worth finding) beside
    the offset.
    """
    sized = [(p, n, sm) for p, n, sm in zip(e.params, e.neutral, e.smallest_for(ship))
             if sm > 0]
    return bool(sized) and all(abs(values[p] - n) < AT_NOTHING * sm for p, n, sm in sized)


def _clearly_worse(J_ref: np.ndarray, J_new: np.ndarray, noise: dict[str, Any],
                   s: DiagnosisSettings,
                   names: Sequence[str]) -> str:
    """
    Return which held-out trial a candidate makes clearly worse ('' if none).

    Worse by more than clearly_worse (J ratio - 1) and by more than the trial's noise floor
    (what sensor noise alone leaves on it; without a floor, any such ratio counts).
    """
    floor = noise.get('per_trial') or [0.0] * len(J_ref)
    ratio = J_new / np.maximum(J_ref, 1e-300)
    bad = (ratio > 1 + s.clearly_worse) & (J_new - J_ref > np.asarray(floor))
    if not bad.any():
        return ''
    k = int(np.flatnonzero(bad)[np.argmax(ratio[bad])])
    return (f'it makes held-out trial {names[k]} clearly worse ({100 * (ratio[k] - 1):+.0f} %, '
            'more than its noise floor)')


def _told_apart(J_best: np.ndarray, J_rival: np.ndarray, noise: dict[str, Any],
                s: DiagnosisSettings,
                names: Sequence[str]) -> bool:
    """Return whether a held-out trial shows the rival clearly worse and none clearly better."""
    return bool(_clearly_worse(J_best, J_rival, noise, s, names)) \
        and not _clearly_worse(J_rival, J_best, noise, s, names)


def _noise(ship: ShipConfig, params: np.ndarray, test_trials: Sequence[Trial],
           s: DiagnosisSettings, weights: np.ndarray, log: Callable[[str], None]
           ) -> dict[str, Any]:
    """
    Estimate the sensor noise and the held-out J it alone leaves with the base model.

    diagnosis/noise.py; {} when the noise cannot be estimated (every simulation failed).
    """
    sigma = sensor_noise(test_trials, simulate_trials(ship, params, list(test_trials),
                                                      s.integrator))
    if sigma is None:
        return {}
    floor = noise_floor(ship, params, test_trials, sigma, s.integrator, weights, seed=s.seed,
                        restart_every_s=s.restart_every_s)
    log(f"   sensor noise from the held-out recordings: position {sigma['x']:.2g}/"
        f"{sigma['y']:.2g} m, heading {math.degrees(sigma['psi']):.2g} deg; the held-out J "
        f"noise alone leaves: {floor['J']:.4g} ± {floor['J_se']:.2g}")
    return {'sigma': sigma, **floor}


def _advice(ship: ShipConfig, base: ParameterSpace, base_theta: np.ndarray, obj: Objective,
            aliased: dict[str, dict[str, Any]], impossible: dict[str, str],
            rival_pairs: list[dict[str, Any]], trials: Sequence[Trial],
            log: Callable[[str], None], screen_drop: dict[str, float] | None = None,
            effects: Sequence[str] = ()) -> list[dict[str, Any]]:
    """
    Advise the trial that would settle each barely identifiable effect and rival pair.

    First one trial for all of them jointly (advice.advise_all: a crew sails one, and which
    suspect is real is unknown), then most pressing first: rival causes named, then the barely
    identifiable effects by how much each alone lowered the tuning error in the first screen
    (the suspects first; a trial for an effect that explains nothing is the least worth
    sailing). An effect no trial can settle says so, with the measurement that would.
    """
    from mmg_tuner.diagnosis.advice import advise_all, joint_text, residual_scale

    drop = screen_drop or {}

    def rank(e: str) -> float:
        d = drop.get(e, -math.inf)
        return -d if math.isfinite(d) else math.inf

    # rival causes by the separation of their outputs; a barely identifiable effect by the
    # information a trial adds (a trial the base targets mimic once tuned on settles nothing),
    # linearised where the flag was raised: every single-parameter effect at its smallest
    tuned = base.full_params(ship.params, base_theta)[0]
    sigma = residual_scale(ship, tuned, trials) if rival_pairs else None
    suspects = [e for e in aliased if e not in impossible]
    out = advise_all(ship, base, base_theta, obj, effects, trials, suspects, rival_pairs, sigma,
                     rank)
    for a in out:
        rec = a['separation_recorded']
        what = ('resolution (smallest worth finding / 2 standard errors)'
                if 'se_with' in a else 'separation')
        if a['kind'] == 'joint':
            log(f"   advice (one trial for all: {a['about']}): {a['instruction']} -- "
                + joint_text(a))
        elif a.get('degenerate'):
            log(f"   advice ({a['kind']}: {a['about']}): {a['instruction']}")
        else:
            log(f"   advice ({a['kind']}: {a['about']}): " + (
                f"{a['instruction']} -- predicted {what} {a['separation']:.3g}"
                + (f' (recorded trials {rec:.3g})' if rec is not None else '') if a['settles']
                else f'no trial of the repertoire raises the {what} above 1 and clearly above '
                f"the recorded trials' (best: {a['instruction']}, {a['separation']:.3g} vs "
                f"{'-' if rec is None else f'{rec:.3g}'}): degenerate for these manoeuvres; "
                'fix one from another source'))
    return out


def _backward_pass(ship: ShipConfig, base: ParameterSpace, model: _Model, theta: np.ndarray,
                   objs: _Objectives, causes: list[Cause], s: DiagnosisSettings,
                   J_base_test: float, log: Callable[[str], None],
                   store: SearchCheckpoint | None, map_fn: MapFn[_Fit, np.ndarray] | None,
                   J_floor: float | None = None, floors: Sequence[float] | None = None
                   ) -> tuple[_Model, np.ndarray, np.ndarray]:
    """
    Stepwise regression's backward step.

    A named effect that the later ones made redundant (e.g. a yaw moment bias named first, then the
    rudder offset that explains it better) is dropped when it fails the same :func:`acceptance`
    rule as the forward step against the model without it, but for the veto of a held-out trial
    made worse: redundancy is a question of gain, and the veto is a test for naming, which the
    effect passed when it was named. (With it, a rudder offset named jointly with a current,
    whose removal makes the held-out error 5 x larger, was dropped because the current alone
    fits one zigzag at 0.4 of what noise alone leaves there, luckier than the truth, 6 x better
    than beside the offset.) Both sides are re-tuned with the same warm start and budget; the
    removals of one pass are independent tunings, mapped together.
    """
    theta = _tune_many([_Fit(ship, model.space, 0, objs.of(model)[0], theta, s.effect_evals,
                             s.seed, False, s.retune)], store, map_fn)[0]
    J_full = _per_trial_J(objs.of(model)[1], ship, model.space, theta)
    while len(model.effects) + model.measured_wind > 1:
        # what can be removed: each named effect, and the measured wind when it was named
        options = [(e.name, _Model(ship, base, [x for x in model.effects if x is not e],
                                   model.measured_wind), len(e.params))
                   for e in model.effects]
        if model.measured_wind:
            options.append(('measured_wind', _Model(ship, base, model.effects, False), 0))
        fits = []
        for _, m, _ in options:
            idx = [model.space.names.index(n) for n in m.space.names]
            fits.append(_Fit(ship, m.space, 0, objs.of(m)[0], theta[idx], s.effect_evals,
                             s.seed, False, s.retune))
        checks = []
        for (name, m, n_par), th in zip(options, _tune_many(fits, store, map_fn)):
            Jt = _per_trial_J(objs.of(m)[1], ship, m.space, th)
            v = acceptance(Jt, J_full, n_par, J_base_test, s, J_floor, floors, veto=False)
            checks.append((v, name, m, th, Jt))
        v, name, m, th, Jt = min(checks, key=lambda x: x[0].gain)
        log(f'   backward check: without {name} the held-out error is '
            f'{_pct_change(J_full.sum(), Jt.sum())} '
            f'({"keep" if v.significant else "redundant: dropped (" + v.reason + ")"})')
        if v.significant:
            break
        causes[:] = [c for c in causes if c.effect != name]
        model, theta, J_full = m, th, Jt
    return model, theta, J_full


def _pct(x: float) -> str:
    """Return a fraction as a percentage for messages; never 'nan %'."""
    if math.isnan(x):
        return 'undefined'
    return f'{100 * x:.1f} %' if math.isfinite(x) else ('inf' if x > 0 else '-inf')


def _gain(ref: float, new: float) -> float:
    """1 - new/ref; -inf when the new model diverges, nan when the reference does."""
    if not math.isfinite(new):
        return -math.inf
    if not math.isfinite(ref) or ref <= 0:
        return math.nan
    return 1 - new / ref


def _aliased_effects(ship: ShipConfig, base: ParameterSpace, theta: np.ndarray, obj: Objective,
                     effects: list[str]) -> dict[str, dict[str, Any]]:
    """
    Return the single-parameter effects the trials cannot see at a realistic magnitude.

    Single-parameter effects the trials cannot see at a realistic magnitude while the base targets
    are tuned: twice the parameter's standard error (base targets free, at the base optimum)
    exceeds the smallest magnitude worth finding. They stay candidates (the gain decides); the
    report says why one may go unnamed.
    """
    probe = [e for e in effects if len(EFFECTS[e].params) == 1]
    if not probe:
        return {}
    m = _Model(ship, base, [EFFECTS[e] for e in probe])
    # linearise at the smallest magnitude worth finding (at zero a lag has no first-order
    # signature in the sampled model)
    th = np.concatenate([theta, [EFFECT_NEUTRAL[EFFECTS[e].params[0]]
                                 + EFFECTS[e].smallest_for(ship)[0] for e in probe]])
    res = aliasing(obj, m.space, th, [EFFECTS[e].params[0] for e in probe])
    out = {}
    for e in probe:
        a = res[EFFECTS[e].params[0]]
        smallest = EFFECTS[e].smallest_for(ship)[0]
        if 2 * a['se'] > smallest:
            out[e] = {**a, 'smallest': smallest}
    return out
