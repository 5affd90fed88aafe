"""Name the cause: extend the model with each candidate effect, re-tune (effect parameters plus
the base targets, warm-started), and keep the effect whose held-out gain is significant.

Selection rule (stepwise, like forward-backward regression):
* held-out gain G = 1 - J_test(extended) / J_test(current model), summed over test trials;
  its uncertainty is the jackknife standard error over test trials;
* an effect is accepted when G > min_gain + param_penalty x (number of its parameters) and
  G > min_gain_z x its standard error, the
  reduction is at least min_abs_gain of the base model's held-out error, and no test trial
  gets worse by more than worse_tol (an effect shows in some trials more than in others, but a
  wrong one makes some trials worse). Gains are measured against the current model re-tuned
  with the same warm start and budget (a null candidate), so extra tuning is not mistaken for
  an effect. Nothing significant: nothing is named (clean data must name nothing);
* an estimate smaller than the effect's smallest magnitude worth finding (e.g. a 0.02 m/s
  current) is not accepted: such an effect fits noise or bends to mimic another;
* an estimate pinned on its box (a non-periodic parameter within bound_tol of the box width of
  a bound that is not its neutral value) is not accepted: the optimiser is using the effect to
  absorb something else, as the paper's tuned coefficients pinned on their bounds do;
* the best accepted effect joins the model and the search repeats, up to max_effects; another
  significant effect within the combined uncertainty is reported as indistinguishable;
* backward step: with two or more named, one whose removal loses no significant gain is
  dropped (a yaw moment bias named first is made redundant by the rudder offset named next);
* cheap ranking first: each candidate is fitted with the base targets held at their tuned
  values and the named effects free (a few hundred evaluations); only the top `screen`
  candidates are re-tuned fully;
* single-parameter effects whose standard error at the base optimum (base targets free)
  exceeds half the smallest magnitude worth finding are reported as barely identifiable
  from these trials (e.g. rpm_scale against w_P0 and t_P), so that a miss is explained.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from mmg_tuner.core.effects import EFFECTS, Effect
from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import DiagnosisError
from mmg_tuner.tuning.identifiability import aliasing, standard_errors
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.tuner import Tuner


@dataclass
class DiagnosisSettings:
    targets: Sequence[str] | None = None     # base targets (default: the ship's)
    a_r: float | None = None
    effects: Sequence[str] = tuple(EFFECTS)
    integrator: str = 'rk4'
    base_evals: int = 20_000
    screen_evals: int = 400
    effect_evals: int = 6_000
    screen: int = 4
    max_effects: int = 3
    min_gain: float = 0.10
    param_penalty: float = 0.02
    # and the reduction must be this fraction of the base model's held-out error: below it
    # lies what no effect explains (discretisation, the noise's own drift)
    min_abs_gain: float = 0.05
    # a real effect helps where it shows and hurts nowhere: no test trial may get worse by more
    worse_tol: float = 0.5
    # the gain must also exceed this many jackknife standard errors (the spread over trials)
    min_gain_z: float = 1.0
    # an effect parameter this close to a bound (fraction of the box width) is suspect
    bound_tol: float = 0.01
    seed: int = 0


@dataclass
class Candidate:
    effect: str
    J_test: float
    per_trial_gain: list[float]
    gain: float
    gain_se: float
    accepted: bool
    values: dict[str, float]
    screen_drop: float = 0.0
    on_bound: list[str] = field(default_factory=list)


@dataclass
class Diagnosis:
    causes: list[dict]
    baseline: dict
    final: dict
    rounds: list[list[Candidate]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)
    base_params: dict[str, float] = field(default_factory=dict)
    wall_s: float = 0.0
    aliased: dict[str, dict] = field(default_factory=dict)


class _Model:
    """A model structure under test: base targets + effect parameters with their boxes."""

    def __init__(self, ship: ShipConfig, base: ParameterSpace, effects: list[Effect]):
        names = list(base.names)
        lo, hi, pre = list(base.lower), list(base.upper), list(base.pre)
        for e in effects:
            for p, (a, b) in zip(e.params, e.bounds(ship)):
                names.append(p)
                lo.append(a)
                hi.append(b)
                pre.append(min(max(EFFECT_NEUTRAL[p], a), b))
        self.effects = effects
        self.space = ParameterSpace(tuple(names), np.array(pre), np.array(lo), np.array(hi))


def _tune(ship, model: _Model, obj: Objective, x0: np.ndarray, evals: int, seed: int,
          fixed_base: bool = False) -> np.ndarray:
    space = model.space
    if fixed_base:  # screening: the base held, the effect parameters (new and named) move
        n_base = len(x0) - sum(len(e.params) for e in model.effects)
        base_vals = x0[:n_base]
        sub = ParameterSpace(space.names[n_base:], space.pre[n_base:], space.lower[n_base:],
                             space.upper[n_base:])
        shipb = ship.with_params(dict(zip(space.names[:n_base], base_vals)))
        o = Objective(shipb, obj.batch, obj.weights, 0.0,
                      {0: 'euler', 1: 'rk4'}[obj.method], obj.substeps)
        res = Tuner(sub, o, seed=seed, max_evaluations=evals, max_popsize=24,
                    sigma0=0.3).run()
        return np.concatenate([base_vals, res.theta])
    res = Tuner(space, obj, seed=seed, max_evaluations=evals, max_popsize=48, sigma0=0.1,
                x0=x0).run()
    return res.theta


def _backward_pass(ship, base: ParameterSpace, model: '_Model', theta, obj: Objective,
                   obj_test: Objective, causes: list[dict], s: DiagnosisSettings,
                   J_base_test: float, log):
    """Stepwise regression's backward step: a named effect that the later ones made redundant
    (e.g. a yaw moment bias named first, then the rudder offset that explains it better) is
    dropped when removing it loses no significant held-out gain. Both sides are re-tuned with
    the same warm start and budget."""
    theta = _tune(ship, model, obj, theta, s.effect_evals, s.seed)
    J_full = _per_trial_J(obj_test, ship, model.space, theta)
    while len(model.effects) > 1:
        trials = []
        for e in model.effects:
            keep = [x for x in model.effects if x is not e]
            m = _Model(ship, base, keep)
            idx = [model.space.names.index(n) for n in m.space.names]
            th = _tune(ship, m, obj, theta[idx], s.effect_evals, s.seed)
            Jt = _per_trial_J(obj_test, ship, m.space, th)
            loss = 1 - J_full.sum() / Jt.sum()   # the gain the effect brings on top of the rest
            need = s.min_gain + s.param_penalty * len(e.params)
            absolute = (Jt.sum() - J_full.sum()) / J_base_test
            trials.append((loss, e, m, th, Jt, loss > need and absolute > s.min_abs_gain))
        loss, e, m, th, Jt, significant = min(trials, key=lambda x: x[0])
        log(f'   backward check: without {e.name} the held-out error is '
            f'{100 * (Jt.sum() / J_full.sum() - 1):+.1f} % '
            f'({"keep" if significant else "redundant: dropped"})')
        if significant:
            break
        causes[:] = [c for c in causes if c['effect'] != e.name]
        model, theta, J_full = m, th, Jt
    return model, theta, J_full


_PERIODIC = {'current_dir', 'wind_dir'}


def pinned_on_bound(space: ParameterSpace, theta: np.ndarray, names: Sequence[str],
                    tol: float) -> list[str]:
    """Effect parameters whose estimate sits on a bound of its box (periodic angles and bounds
    equal to the neutral value excepted: there the effect merely vanishes)."""
    out = []
    for i, n in enumerate(space.names):
        if n not in names or n in _PERIODIC:
            continue
        lo, hi, v = space.lower[i], space.upper[i], theta[i]
        w = tol * (hi - lo)
        if (v - lo < w and lo != EFFECT_NEUTRAL[n]) or (hi - v < w and hi != EFFECT_NEUTRAL[n]):
            out.append(n)
    return out


def jackknife_se(J_ref: np.ndarray, J_new: np.ndarray) -> float:
    """Standard error of the pooled gain 1 - sum(J_new)/sum(J_ref), leaving out one test trial
    at a time (trials weigh as much as their error)."""
    n = len(J_ref)
    if n < 2:
        return float('inf')
    loo = np.array([1 - (J_new.sum() - J_new[i]) / max(J_ref.sum() - J_ref[i], 1e-300)
                    for i in range(n)])
    return float(np.sqrt((n - 1) / n * np.sum((loo - loo.mean()) ** 2)))


def _per_trial_J(obj: Objective, ship: ShipConfig, space: ParameterSpace, theta) -> np.ndarray:
    J, _ = obj.per_trial(space.full_params(ship.params, theta))
    return J[0]


def diagnose(ship: ShipConfig, tune_trials: list[Trial], test_trials: list[Trial],
             settings: DiagnosisSettings | None = None,
             log: Callable[[str], None] = print) -> Diagnosis:
    s = settings or DiagnosisSettings()
    if not tune_trials or not test_trials:
        raise DiagnosisError('the diagnosis needs tuning trials and held-out test trials')
    unknown = [e for e in s.effects if e not in EFFECTS]
    if unknown:
        raise DiagnosisError(f'unknown effects {unknown}; known: {sorted(EFFECTS)}')
    effects = list(s.effects)
    if 'wind' in effects and not ship.has_windage:
        effects.remove('wind')
        log(f'   wind left out: {ship.source or ship.name} has no windage section (A_F, A_L, '
            'L_OA, CD_t, rho_air)')
    t_start = time.perf_counter()
    obj = Objective(ship, TrialBatch.from_trials(tune_trials), integrator=s.integrator)
    obj_test = Objective(ship, TrialBatch.from_trials(test_trials), integrator=s.integrator)
    base = ParameterSpace.around(ship, s.targets, s.a_r)

    log(f'1/3 tuning the base model ({base.dim} parameters) on {len(tune_trials)} trial(s)')
    model = _Model(ship, base, [])
    theta = Tuner(base, obj, seed=s.seed, max_evaluations=s.base_evals).run().theta
    J_test = _per_trial_J(obj_test, ship, model.space, theta)
    baseline = {'J_tune': float(_per_trial_J(obj, ship, model.space, theta).sum()),
                'J_test': float(J_test.sum()),
                'J_test_per_trial': dict(zip(obj_test.batch.names, J_test.tolist())),
                'params': dict(zip(base.names, theta.tolist()))}
    base_theta = theta.copy()
    log(f'   base model: J_test = {J_test.sum():.4g}')
    aliased = _aliased_effects(ship, base, theta, obj, effects)
    for name, a in aliased.items():
        log(f"   {name} is barely identifiable here: its standard error {a['se']:.3g} with the "
            f"base targets free is over half the smallest magnitude worth finding "
            f"({a['smallest']:.3g}); {', '.join(a['mimicked_by'])} mimic "
            f"{100 * a['r2']:.2f} % of its signature")

    log('2/3 searching the effects library')
    causes, rounds = [], []
    remaining = effects
    while remaining and len(causes) < s.max_effects:
        cands = []
        # cheap screen: the effect alone, base held at its tuned values
        screened = []
        J_now = _per_trial_J(obj, ship, model.space, theta).sum()
        for name in remaining:
            m = _Model(ship, base, model.effects + [EFFECTS[name]])
            x0 = np.concatenate([theta, m.space.pre[len(theta):]])
            th = _tune(ship, m, obj, x0, s.screen_evals, s.seed, fixed_base=True)
            drop = 1 - _per_trial_J(obj, ship, m.space, th).sum() / J_now
            screened.append((drop, name, th))
        screened.sort(key=lambda x: -x[0])
        log('   screen (tuning-J drop, effect alone): ' +
            ', '.join(f'{n} {100 * d:.0f}%' for d, n, _ in screened))
        # the null candidate: the current model re-tuned with the same warm start and budget,
        # so that a gain measures the effect, not the extra tuning
        theta = _tune(ship, model, obj, theta, s.effect_evals, s.seed)
        J_test = _per_trial_J(obj_test, ship, model.space, theta)
        for drop, name, th0 in screened[:s.screen]:
            m = _Model(ship, base, model.effects + [EFFECTS[name]])
            th = _tune(ship, m, obj, th0, s.effect_evals, s.seed)
            Jt = _per_trial_J(obj_test, ship, m.space, th)
            g = 1 - Jt / np.maximum(J_test, 1e-300)
            gain = 1 - Jt.sum() / J_test.sum()
            se = jackknife_se(J_test, Jt)
            need = s.min_gain + s.param_penalty * len(EFFECTS[name].params)
            absolute = (J_test.sum() - Jt.sum()) / baseline['J_test']
            worst = float(np.max(Jt / np.maximum(J_test, 1e-300)))
            vals = {p: float(v) for p, v in zip(m.space.names[base.dim:], th[base.dim:])
                    if p in EFFECTS[name].params}
            pinned = pinned_on_bound(m.space, th, EFFECTS[name].params, s.bound_tol)
            significant = bool(gain > need and gain > s.min_gain_z * se
                               and absolute > s.min_abs_gain and worst < 1 + s.worse_tol)
            tiny = EFFECTS[name].too_small(ship, vals)
            ok = significant and not pinned and not tiny
            cands.append((Candidate(name, float(Jt.sum()), g.tolist(), float(gain), se, ok,
                                    vals, float(drop), pinned), m, th, Jt))
            verdict = 'significant' if ok else 'not significant'
            if significant and pinned:
                verdict = ('significant but rejected: ' + ', '.join(
                    f'{p} = {vals[p]:.4g} on its bound' for p in pinned)
                    + ' (a likely mis-attribution)')
            elif significant and tiny:
                verdict = ('significant but rejected: smaller than the smallest magnitude worth '
                           'finding (noise-fitting)')
            log(f'   {name}: held-out gain {100 * gain:.1f} % ± {100 * se:.1f} '
                f'({100 * absolute:.1f} % of the base error; per trial '
                f'{", ".join(f"{100 * x:+.0f}%" for x in g)}) {verdict}')
        rounds.append([c[0] for c in cands])
        accepted = [c for c in cands if c[0].accepted]
        if not accepted:
            break
        best = max(accepted, key=lambda c: c[0].gain)
        cand, model, theta, J_test = best
        # another significant effect whose gain is within the combined uncertainty explains
        # these trials about as well: say so rather than pretend to know
        rivals = [c[0].effect for c in accepted if c[0] is not cand
                  and cand.gain - c[0].gain < np.hypot(cand.gain_se, c[0].gain_se)]
        se_all = standard_errors(obj, model.space, theta)
        errs = {p: float(e) for p, e in zip(model.space.names, se_all) if p in cand.values}
        causes.append({'effect': cand.effect, 'parameters': cand.values, 'uncertainty': errs,
                       'heldout_gain': cand.gain, 'heldout_gain_se': cand.gain_se,
                       'indistinguishable_from': rivals,
                       'description': EFFECTS[cand.effect].description})
        remaining.remove(cand.effect)
        log(f'   -> named: {cand.effect}' + (f' (but {", ".join(rivals)} explain(s) the trials '
                                             'about as well)' if rivals else ''))
    if len(model.effects) > 1:
        model, theta, J_test = _backward_pass(ship, base, model, theta, obj, obj_test, causes,
                                              s, baseline['J_test'], log)
    if causes:  # report the final model's values (later rounds re-tuned them)
        final_vals = dict(zip(model.space.names, theta))
        se_all = dict(zip(model.space.names, standard_errors(obj, model.space, theta)))
        for c in causes:
            c['parameters'] = {p: float(final_vals[p]) for p in c['parameters']}
            c['uncertainty'] = {p: float(se_all[p]) for p in c['parameters']}
    final = {'J_tune': float(_per_trial_J(obj, ship, model.space, theta).sum()),
             'J_test': float(J_test.sum()),
             'J_test_per_trial': dict(zip(obj_test.batch.names, np.atleast_1d(J_test).tolist())),
             'heldout_gain_total': float(1 - J_test.sum() / baseline['J_test'])}
    return Diagnosis(causes, baseline, final, rounds, dict(zip(model.space.names,
                                                               theta.tolist())),
                     dict(zip(base.names, base_theta.tolist())),
                     time.perf_counter() - t_start, aliased)


def _aliased_effects(ship, base: ParameterSpace, theta, obj: Objective, effects: list[str]
                     ) -> dict[str, dict]:
    """Single-parameter effects the trials cannot see at a realistic magnitude while the base
    targets are tuned: twice the parameter's standard error (base targets free, at the base
    optimum) exceeds the smallest magnitude worth finding. They stay candidates (the gain
    decides); the report says why one may go unnamed."""
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
