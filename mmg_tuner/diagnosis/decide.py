"""
The verdict: which of the fitted effects are causes, and how the held-out error divides.

One procedure, run after the search has fitted its final model F (the base targets re-tuned
with the effects E_1 .. E_k in it; B is the tuned base model, without effects). No rule about
the rest of the model vetoes an effect: each stands or falls on its own evidence, and what the
causes leave is reported beside them.

1. **Contribution** (evidence for). Per held-out trial t, l_t = log(J_t(F without E_i) /
   J_t(F)); "without E_i": E_i at its neutral value, everything else as in F (a measured
   signal: the trials without it). A trial is the unit of independent evidence (samples along
   one trajectory are correlated), and on the log scale each trial weighs the same whatever
   its size (a turning circle's J is many times a zigzag's). E_i has evidence for it when the
   mean of l_t exceeds Z_FOR of its standard errors (sd / sqrt(n), a one-sided t-test over the
   held-out trials). Its size is reported as d_i = sum_t [J_t(F without E_i) - J_t(F)] /
   sum_t J_t(B), the held-out error lost without it (fraction of the base model's), with its
   jackknife standard error.
2. **Consistency** (the test of a mimic). E_i's parameters are fitted on each recorded trial
   alone, tuning and held-out, F's other parameters held. A physical effect has one value over
   the trials of a day; an effect bending to absorb a force the model lacks takes a value that
   follows each manoeuvre. In the effect's physical components (a current or a wind as its
   north/east velocity, an antenna as its position, any other effect as its value from
   neutral), the dispersion is D_i = RMS_k |x_k - median| / max(|median|, smallest worth
   finding). Consistent when D_i <= D_MAX. Trials whose own estimate runs to a far edge of the
   box (that trial alone does not determine it) are left out; with fewer than MIN_TRIALS left
   the test cannot be made and says so. A measured signal is a fact: no consistency test.
3. **Named**: evidence for and consistent, unless other evidence is against it (implausible for
   the ship, or an equally good rival: the search's undecided sets, results.split_undecided).
   Fitted but inconsistent: listed as mimicking what the model lacks, not named.
4. **Apportioned**: the held-out error of B divides into what each cause explains (exact
   Shapley values of the effects over the subsets of F, scaled to the total explained,
   1 - J(F)/J(B)) and what remains, J(F)/J(B): noise (what sensor noise alone leaves), and the
   rest systematic -- structural when the structure check shows where it lives (a learnable
   share, an asymmetry, coefficients on their bounds in F), else unexplained.

Every J here is the diagnosis's own: with the evidence verdict the simulation restarts from the
recorded state every settings.restart_period (the prediction error over about two ship lengths,
not a whole run's drift from a noisy start), as in the search that fitted F.

5. **Beyond a hull change** (evidence against: the structural rival). Every regression-based
   model's least certain part is its hull's linear derivatives (Y_v, Y_r, N_v, N_r; HULL_RIVAL,
   those that are not base targets already), and a hull that differs from the regression is
   what the effects most often mimic (a yaw damping 50 % stronger fitted as a GNSS antenna 6 m
   aft, one value over every trial). F+ is F re-tuned with them free as well; R_i is F+
   re-tuned without E_i (its neutral value). E_i is withdrawn, listed as what a hull change
   explains, when the rival explains the held-out trials better than F (the mean per-trial
   log(J_t(F) / J_t(R_i)) above Z_FOR of its standard errors) and E_i adds nothing beside it:
   the mean per-trial log(J_t(R_i) / J_t(F+)) within Z_FOR standard errors of zero, or E_i's
   value in F+ below its smallest size worth finding. A rival only as good as F leaves E_i
   named (a steering-gear lag and a stronger yaw damping can fit the same turns; the trials
   cannot reject the lag). A measured signal is a fact: not tested.

Z_FOR = 2 and D_MAX = 0.5 were set before any benchmark ran (two standard errors; a scatter
half the effect's size) and checked on the development seeds of
bench/bench_diagnosis_mismatch.py, then on fresh seeds registered before they were run.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from itertools import combinations
import math
from typing import Any, Mapping, Sequence

from mmg_tuner.core.effects import EFFECTS, froude_factor
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.plausible import per_trial
from mmg_tuner.diagnosis.settings import MEASURED
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

Z_FOR = 2.0          # mean per-trial log ratio above this many standard errors: evidence for
D_MAX = 0.5          # dispersion of the per-trial estimates above this: a mimic
MIN_TRIALS = 3       # per-trial estimates needed for the consistency test
FAR_EDGE = 0.01      # a per-trial estimate this close (box fraction) to a non-neutral edge
HULL_RIVAL = ('Y_v', 'Y_r', 'N_v', 'N_r')   # the structural rival's free derivatives (5.)
RIVAL_SIMS = 800     # simulations per re-tune of the rival test (local, warm-started)


@dataclass
class Evidence:
    """What decided one fitted effect: its contribution, consistency and verdict."""

    effect: str
    contribution: float            # d_i: held-out J lost without it, fraction of J(B)
    contribution_se: float         # jackknife over held-out trials
    log_ratio: float               # mean over held-out trials of log(J without / J with)
    log_ratio_se: float            # its standard error (sd / sqrt(n))
    share: float                   # Shapley share of J(B) explained (apportioned)
    dispersion: float | None       # D_i (None: not testable, or a measured signal)
    trials_used: int               # per-trial estimates that entered D_i
    per_trial: list[dict[str, Any]] = field(default_factory=list)  # {trial, components}
    verdict: str = ''              # 'cause' | 'mimic' | 'weak' | 'hull'
    why: str = ''
    # 5.: mean per-trial log(J without it / J with it) beside a free hull, its standard error
    beside_hull: float | None = None
    beside_hull_se: float | None = None
    # 5.: mean per-trial log(J(F) / J(R_i)): how much better the hull rival without it is
    rival: float | None = None
    rival_se: float | None = None
    beside_hull_size: float | None = None   # its size in F+, in smallest sizes worth finding

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _components(effect: str, values: Mapping[str, float]) -> np.ndarray:
    """Return an effect's values as physical components from neutral (see the docstring)."""
    e = EFFECTS[effect]
    if any(e.periodic) and len(e.params) == 2:   # (speed, direction): a velocity vector
        sp, dr = e.params
        return np.array([values[sp] * math.cos(values[dr]), values[sp] * math.sin(values[dr])])
    return np.array([values[p] - n for p, n, per in zip(e.params, e.neutral, e.periodic)
                     if not per])


def _smallest(ship: ShipConfig, effect: str) -> float:
    """Return the smallest magnitude worth finding at the ship's scale (first sized param)."""
    e = EFFECTS[effect]
    for sm, unit, per in zip(e.smallest, e.units, e.periodic):
        if not per and sm > 0:
            return float(sm) * froude_factor(unit, ship.scale_ratio)
    return 0.0


def _far_edge(ship: ShipConfig, effect: str, est: Mapping[str, float]) -> bool:
    """Whether a per-trial estimate ran to an edge of its box that is not its neutral value."""
    e = EFFECTS[effect]
    for p, n, per, (lo, hi) in zip(e.params, e.neutral, e.periodic, e.bounds(ship)):
        if per:
            continue
        w = FAR_EDGE * (hi - lo)
        if (est[p] - lo < w and lo != n) or (hi - est[p] < w and hi != n):
            return True
    return False


def dispersion(ship: ShipConfig, effect: str, estimates: Sequence[Mapping[str, float]]
               ) -> tuple[float | None, int]:
    """Return (D, trials used) of per-trial estimates (None when fewer than MIN_TRIALS)."""
    used = [_components(effect, x) for x in estimates if not _far_edge(ship, effect, x)]
    if len(used) < MIN_TRIALS:
        return None, len(used)
    X = np.array(used)
    centre = np.median(X, axis=0)
    spread = float(np.sqrt(np.mean(np.sum((X - centre) ** 2, axis=1))))
    scale = max(float(np.linalg.norm(centre)), _smallest(ship, effect), 1e-12)
    return spread / scale, len(used)


def _per_trial_J(ship: ShipConfig, trials: Sequence[Trial], params: np.ndarray,
                 integrator: str, restart_every_s: float) -> np.ndarray:
    obj = Objective(ship, TrialBatch.from_trials(list(trials)), shoot_every_s=restart_every_s,
                    integrator=integrator)
    J, _ = obj.per_trial(params)
    first: np.ndarray = J[0]
    return first


def _jackknife(num: np.ndarray, den: np.ndarray) -> float:
    """Return the jackknife standard error over trials of sum(num) / sum(den)."""
    n = len(num)
    if n < 2 or not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        return math.inf
    loo = np.array([(num.sum() - num[i]) / max(den.sum() - den[i], 1e-300) for i in range(n)])
    return float(np.sqrt((n - 1) / n * np.sum((loo - loo.mean()) ** 2)))


def _x(log_ratio: float) -> str:
    """Return a mean log ratio as a factor ('x 1.8')."""
    return f'x {math.exp(log_ratio):.2f}' if math.isfinite(log_ratio) else 'an undefined factor'


def _neutral(effect: str) -> dict[str, float]:
    e = EFFECTS[effect]
    return dict(zip(e.params, e.neutral))


def decide(ship: ShipConfig, params: Mapping[str, float], effects: Sequence[str],
           tune_trials: Sequence[Trial], test_trials: Sequence[Trial],
           J_base: np.ndarray, integrator: str = 'rk4',
           test_without_wind: Sequence[Trial] | None = None,
           restart_every_s: float = 0.0,
           base_targets: Sequence[str] | None = None) -> list[Evidence]:
    """
    Weigh every effect of the final model (see the module docstring).

    ``params``: the final model's parameters (base targets and effects); ``effects``: the
    effects in it (a measured signal such as 'measured_wind' included); ``J_base``: the tuned
    base model's held-out J per trial (as the search measured it); ``test_without_wind``: the
    held-out trials without their measured wind (the model without 'measured_wind');
    ``base_targets``: the base model's tuned coefficients (the rival test frees them with the
    hull's; None: no rival test).
    Returns one :class:`Evidence` per effect, in the order given.
    """
    final = ship.with_params(dict(params))
    J_base = np.asarray(J_base, float)
    signals = [e for e in effects if e in MEASURED]
    no_wind = list(test_without_wind) if test_without_wind is not None else list(test_trials)

    def J_of(dropped: Sequence[str]) -> np.ndarray:
        over: dict[str, float] = {}
        for e in dropped:
            if e in EFFECTS:
                over.update(_neutral(e))
        trials = no_wind if any(e in signals for e in dropped) else test_trials
        return _per_trial_J(final, trials, final.with_params(over).params, integrator,
                            restart_every_s)

    # every subset of the effects dropped: k <= max_effects (2-3), so 2^k held-out simulations
    names = list(effects)
    J_sub = {frozenset(s): J_of(s) for r in range(len(names) + 1)
             for s in combinations(names, r)}
    J_F = J_sub[frozenset()]
    Jb = float(J_base.sum())
    shap = {}
    k = len(names)
    for e in names:   # exact Shapley value of e in the held-out J lost when effects are dropped
        v = 0.0
        others = [x for x in names if x != e]
        for r in range(k):
            for s in combinations(others, r):
                kept = frozenset(s)   # the effects kept besides e
                drop_with = frozenset(x for x in names if x not in kept)
                drop_without = drop_with - {e}
                w = math.factorial(r) * math.factorial(k - r - 1) / math.factorial(k)
                v += w * float(J_sub[drop_with].sum() - J_sub[drop_without].sum())
        shap[e] = v
    explained = max(0.0, 1.0 - float(J_F.sum()) / Jb) if Jb > 0 else 0.0
    total = sum(max(v, 0.0) for v in shap.values())
    out = []
    for e in names:
        delta = J_sub[frozenset([e])] - J_F
        d = float(delta.sum()) / Jb if Jb > 0 else math.nan
        se = _jackknife(delta, J_base)
        share = explained * max(shap[e], 0.0) / total if total > 0 else 0.0
        lr = np.log(np.maximum(J_sub[frozenset([e])], 1e-300) / np.maximum(J_F, 1e-300))
        n = len(lr)
        lr_mean = float(np.mean(lr)) if n else math.nan
        lr_se = float(np.std(lr, ddof=1) / math.sqrt(n)) if n > 1 else math.inf
        ev = Evidence(e, d, se, lr_mean, lr_se, share, None, 0)
        if e in EFFECTS:
            ev.per_trial = _estimates(final, e, list(tune_trials) + list(test_trials),
                                      integrator, restart_every_s)
            ev.dispersion, ev.trials_used = dispersion(ship, e, ev.per_trial)
        for_it = bool(np.all(np.isfinite(lr))) and lr_mean > Z_FOR * lr_se and d > 0
        if not for_it:
            ev.verdict = 'weak'
            ev.why = (f'without it the held-out trials lose {_x(lr_mean)} on average, within '
                      f'{Z_FOR:g} standard errors (x {math.exp(lr_se):.2f}) of nothing')
        elif ev.dispersion is not None and ev.dispersion > D_MAX:
            ev.verdict = 'mimic'
            ev.why = (f'its value fitted on each trial alone scatters by {ev.dispersion:.2f} of '
                      f'its size over {ev.trials_used} trials (a physical effect has one value; '
                      f'at most {D_MAX:g}): it follows the manoeuvre, as a missing force does')
        else:
            ev.verdict = 'cause'
            ev.why = ('measured, not fitted' if e in MEASURED else
                      'one value over the trials: dispersion '
                      + (f'{ev.dispersion:.2f}' if ev.dispersion is not None else
                         f'not testable ({ev.trials_used} trials determine it alone)'))
        out.append(ev)
    fitted = [ev for ev in out if ev.verdict == 'cause' and ev.effect in EFFECTS]
    if fitted and base_targets is not None:
        rival = beside_hull(ship, final, [e for e in names if e in EFFECTS], base_targets,
                            tune_trials, test_trials, integrator, restart_every_s, J_F)
        for ev in fitted:
            if ev.effect not in rival:
                continue
            h = rival[ev.effect]
            ev.beside_hull, ev.beside_hull_se, ev.rival, ev.rival_se, ev.beside_hull_size = (
                h.beside, h.beside_se, h.rival, h.rival_se, h.size)
            better = ev.rival > Z_FOR * ev.rival_se
            needed = ev.beside_hull > Z_FOR * ev.beside_hull_se
            if better and not (needed and ev.beside_hull_size >= 1.0):
                ev.verdict = 'hull'
                ev.why = (f'a change of the hull ({", ".join(h.free)} free) without it explains '
                          f'the held-out trials better ({_x(ev.rival)} +- '
                          f'{math.exp(ev.rival_se):.2f}), and beside that change it '
                          + (f'adds {_x(ev.beside_hull)}, within {Z_FOR:g} standard errors '
                             f'(x {math.exp(ev.beside_hull_se):.2f}) of nothing' if not needed
                             else f'shrinks to {ev.beside_hull_size:.2f} of the smallest size '
                             'worth finding'))
    return out


@dataclass
class HullRival:
    """Step 5 for one effect E_i: F+ (a free hull) and R_i (F+ without E_i) on held-out trials."""

    beside: float       # mean per-trial log(J(R_i) / J(F+)): what E_i adds beside the hull
    beside_se: float
    rival: float        # mean per-trial log(J(F) / J(R_i)): how much better the rival is
    rival_se: float
    size: float         # E_i's size in F+, in smallest sizes worth finding
    free: list[str]     # the hull's derivatives freed


def _mean_log_ratio(J_num: np.ndarray, J_den: np.ndarray) -> tuple[float, float]:
    """Return the mean over trials of log(J_num / J_den) (-inf if undefined), its SE."""
    lr = np.log(np.maximum(J_num, 1e-300) / np.maximum(J_den, 1e-300))
    n = len(lr)
    se = float(np.std(lr, ddof=1) / math.sqrt(n)) if n > 1 else math.inf
    return (float(np.mean(lr)) if np.all(np.isfinite(lr)) else -math.inf), se


def beside_hull(ship: ShipConfig, final: ShipConfig, effects: Sequence[str],
                base_targets: Sequence[str], tune_trials: Sequence[Trial],
                test_trials: Sequence[Trial], integrator: str, restart_every_s: float,
                J_F: np.ndarray) -> dict[str, HullRival]:
    """
    Return {effect: HullRival} (step 5 of the module docstring) for the effects of F.

    F+ (the base targets, the hull's linear derivatives and the effects, re-tuned from F on
    the tuning trials) against R_i (F+ re-tuned without E_i) and against F (held-out J per
    trial ``J_F``). Empty when every derivative of HULL_RIVAL is a base target already, or the
    ship has none free.
    """
    base = ParameterSpace.around(ship, list(base_targets))
    values = ship.as_dict()
    # a derivative the family lacks, or at zero without bounds, has no box (+- a_r |0|)
    free = [n for n in HULL_RIVAL if n not in base_targets and n in values
            and (values[n] != 0.0 or n in ship.tuning_bounds)]
    if not free:
        return {}
    hull = ParameterSpace.around(ship, free)
    names = list(base.names) + free
    lo = list(base.lower) + list(hull.lower)
    hi = list(base.upper) + list(hull.upper)
    n_struct = len(names)
    for e in effects:
        for p, (a, b) in zip(EFFECTS[e].params, EFFECTS[e].bounds(ship)):
            names.append(p)
            lo.append(a)
            hi.append(b)
    lo_a, hi_a = np.array(lo, float), np.array(hi, float)
    x0 = np.clip(np.array([final[n] for n in names], float), lo_a, hi_a)
    space = ParameterSpace(tuple(names), x0.copy(), lo_a, hi_a)

    tune = Objective(final, TrialBatch.from_trials(list(tune_trials)),
                     shoot_every_s=restart_every_s, integrator=integrator)
    plus = local_least_squares(space, tune, x0, RIVAL_SIMS, method='lm').theta
    J_plus = _per_trial_J(final, test_trials, space.full_params(final.params, plus),
                          integrator, restart_every_s)
    out = {}
    for e in effects:
        drop = set(EFFECTS[e].params)
        idx = [i for i, n in enumerate(names) if n not in drop or i < n_struct]
        sub = ParameterSpace(tuple(names[i] for i in idx), plus[idx], lo_a[idx], hi_a[idx])
        start = final.with_params({**dict(zip(names, plus.tolist())), **_neutral(e)})
        fit = local_least_squares(sub, Objective(start, tune.batch, shoot_every_s=restart_every_s,
                                                 integrator=integrator),
                                  plus[idx], RIVAL_SIMS, method='lm').theta
        J_r = _per_trial_J(start, test_trials, sub.full_params(start.params, fit), integrator,
                           restart_every_s)
        beside, beside_se = _mean_log_ratio(J_r, J_plus)
        rival, rival_se = _mean_log_ratio(J_F, J_r)
        size = float(np.linalg.norm(_components(e, dict(zip(names, plus.tolist()))))
                     ) / max(_smallest(ship, e), 1e-12)
        out[e] = HullRival(beside, beside_se, rival, rival_se, size, free)
    return out


def _estimates(final: ShipConfig, effect: str, trials: Sequence[Trial], integrator: str,
               restart_every_s: float) -> list[dict[str, Any]]:
    """Fit the effect's parameters on each trial alone, the rest of the model held."""
    e = EFFECTS[effect]
    lo, hi = (np.array(b, float) for b in zip(*e.bounds(final)))
    theta = np.array([final[p] for p in e.params], float)
    theta = np.clip(theta, lo, hi)
    space = ParameterSpace(tuple(e.params), theta.copy(), lo, hi)
    objs = [Objective(final, TrialBatch.from_trials([t]), shoot_every_s=restart_every_s,
                      integrator=integrator) for t in trials]
    est = per_trial(final, space, theta, e.params, objs)
    return [{**{p: x[p] for p in e.params}, 'trial': t.name} for x, t in zip(est, trials)]
