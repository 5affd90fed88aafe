"""
Whether a fitted effect is plausible for the ship, and whether it is one value for all trials.

Plausible ranges are data: ``config/effect_plausibility.yaml`` (full scale, sources cited
there), Froude-scaled to the ship like the effects' boxes (``core/effects.py``), lengths as
fractions of L_pp or B; ``max_floor`` (unscaled) keeps an upper limit from shrinking below what
a model meets in the real water it sails in. A fit outside its range is "implausible": the
effect bends to absorb something else, and it is never named.

Consistency: a physical effect has one value for the whole recording. :func:`per_trial` fits
the effect's parameters on each held-out trial alone (the rest of the model held at the
joint fit) with their Gauss-Newton standard errors; :func:`disagreement` says when a trial's
own estimate points the other way than the joint fit (beyond the smallest magnitude worth
finding and DISAGREE_Z standard errors). Sizes alone are not compared: a single trial's
estimate moves with its start-state error (a real 1.5 deg rudder offset came out 1.3 deg
apart on two 200 s trials, "42 standard errors"). A (speed, direction) effect is compared
along the joint fit's direction.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

from mmg_tuner._limits import load_yaml
from mmg_tuner.core.effects import EFFECTS, froude_factor
from mmg_tuner.core.ship import resolve_config_path, ShipConfig
from mmg_tuner.errors import ConfigError
from mmg_tuner.tuning.identifiability import standard_errors
from mmg_tuner.tuning.lsq import local_least_squares
from mmg_tuner.tuning.objective import Objective
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

RANGES_FILE = 'effect_plausibility'
DISAGREE_Z = 3.0
PER_TRIAL_SIMS = 60      # least-squares simulations per trial (1-2 parameters from the fit)
ON_BOUND = 0.01          # a per-trial estimate this close to its box's edge (fraction of width)
_PERIODIC = {p for e in EFFECTS.values() for p, per in zip(e.params, e.periodic) if per}
_KEYS = {'min', 'max', 'max_abs', 'max_abs_deg', 'max_abs_L', 'max_abs_B', 'max_floor', 'why'}
_cache: dict[str, dict[str, Any]] = {}


def _table() -> dict[str, Any]:
    if 'table' not in _cache:
        path = resolve_config_path(RANGES_FILE)
        doc = load_yaml(path, 'ranges file') or {}
        known = {p for e in EFFECTS.values() for p in e.params}
        for p, entry in doc.items():
            if p not in known:
                raise ConfigError(f'{path}: {p}: not a parameter of the effects library')
            if not isinstance(entry, Mapping) or set(entry) - _KEYS:
                raise ConfigError(f'{path}: {p}: expected a mapping with keys from '
                                  f'{sorted(_KEYS)}')
        _cache['table'] = {'path': str(path), 'ranges': doc}
    return _cache['table']


def plausible_range(ship: ShipConfig, param: str) -> tuple[float, float, str] | None:
    """Return (lo, hi, why) of an effect parameter at the ship's scale; None if unlimited."""
    entry = _table()['ranges'].get(param)
    if entry is None:
        return None
    unit = next(u for e in EFFECTS.values() for p, u in zip(e.params, e.units) if p == param)
    f = froude_factor(unit, ship.scale_ratio)
    lo, hi = -math.inf, math.inf
    if 'min' in entry:
        lo = float(entry['min']) * (f if unit != '-' else 1.0)
    if 'max' in entry:
        hi = float(entry['max']) * (f if unit != '-' else 1.0)
    for key, scale in (('max_abs', f), ('max_abs_deg', math.radians(1.0)),
                       ('max_abs_L', ship.L_pp), ('max_abs_B', ship['B'])):
        if key in entry:
            lo, hi = max(lo, -float(entry[key]) * scale), min(hi, float(entry[key]) * scale)
    if 'max_floor' in entry:   # unscaled: the real water a model sails in
        hi = max(hi, float(entry['max_floor']))
    return lo, hi, str(entry.get('why', ''))


def implausible(ship: ShipConfig, effect: str, values: Mapping[str, float],
                se: Mapping[str, float] | None = None) -> str:
    """
    Return why an effect's fitted values are implausible for the ship ('' if plausible).

    se: standard errors of poorly determined estimates; a value within two of them of the
    plausible range is not called implausible (an 8 s gear lag estimated at 16 +- 6 s is).
    """
    out = []
    for p in EFFECTS[effect].params if effect in EFFECTS else ():
        r = plausible_range(ship, p)
        if r is None or p not in values:
            continue
        lo, hi, why = r
        v = float(values[p])
        margin = 2.0 * float((se or {}).get(p, 0.0))
        if not lo - margin <= v <= hi + margin:
            out.append(f'{p} = {v:.4g} outside the plausible {lo:.4g} .. {hi:.4g} ({why})')
    return '; '.join(out)


def per_trial(ship: ShipConfig, space: ParameterSpace, theta: np.ndarray,
              params: Sequence[str], trial_objs: Sequence[Objective]) -> list[dict[str, Any]]:
    """
    Fit an effect's parameters on each trial alone, the rest of the model held at theta.

    ``space``/``theta``: the joint fit; ``params``: the effect's parameters; ``trial_objs``:
    one objective per trial (the model's inputs). Returns per trial {param: estimate},
    {param + '_se': standard error} and 'on_bound': whether a (non-periodic) estimate ran to
    an edge of its box (one trial alone may not determine it: such an estimate says nothing).
    """
    idx = [space.names.index(p) for p in params]
    held = {n: float(v) for i, (n, v) in enumerate(zip(space.names, theta)) if i not in idx}
    sub = ParameterSpace(tuple(params), theta[idx].copy(), space.lower[idx], space.upper[idx])
    out = []
    for o in trial_objs:
        shipb = o.ship.with_params(held)
        ob = Objective(shipb, o.batch, o.weights, o.shoot_every_s,
                       {0: 'euler', 1: 'rk4'}[o.method], o.substeps)
        x = local_least_squares(sub, ob, theta[idx], PER_TRIAL_SIMS).theta
        se = standard_errors(ob, sub, x)
        w = ON_BOUND * (sub.upper - sub.lower)
        edge = [bool(x[i] - sub.lower[i] < w[i] or sub.upper[i] - x[i] < w[i])
                for i, p in enumerate(params) if p not in _PERIODIC]
        out.append({**{p: float(v) for p, v in zip(params, x)},
                    **{p + '_se': float(e) for p, e in zip(params, se)},
                    'on_bound': any(edge)})
    return out


def _along(effect: str, est: list[dict[str, Any]], joint: Mapping[str, float]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """
    Per-trial estimates and the joint fit measured from neutral along the joint fit's sense.

    Returns (x (n, k), se (n, k), joint (k,), smallest (k,), full scale) with every component
    signed so that
    the joint fit is positive; a (speed, direction) effect as one component, the speed
    projected on the joint fit's direction (its error: the speed's, or speed x direction's).
    """
    e = EFFECTS[effect]
    if any(e.periodic) and len(e.params) == 2:
        sp, dr = e.params
        x = np.array([[v[sp] * math.cos(v[dr] - joint[dr])] for v in est])
        se = np.array([[max(v[sp + '_se'], v[sp] * v[dr + '_se'])] for v in est])
        return x, se, np.array([joint[sp]]), np.array([e.smallest[0]])
    sized = [(p, n, sm) for p, n, sm, per in zip(e.params, e.neutral, e.smallest, e.periodic)
             if not per and sm > 0]
    sign = np.array([1.0 if joint[p] >= n else -1.0 for p, n, _ in sized])
    x = np.array([[v[p] - n for p, n, _ in sized] for v in est]) * sign
    se = np.array([[v[p + '_se'] for p, _, _ in sized] for v in est])
    j = np.array([joint[p] - n for p, n, _ in sized]) * sign
    return x, se, j, np.array([sm for _, _, sm in sized])


def disagreement(ship: ShipConfig, effect: str, est: list[dict[str, Any]],
                 joint: Mapping[str, float]) -> str:
    """
    Return why per-trial estimates contradict the joint fit ('' when they do not).

    A trial contradicts it when its own estimate points the other way (opposite side of
    neutral) by more than the smallest magnitude worth finding (Froude-scaled) and by more
    than DISAGREE_Z standard errors, while the joint fit is at least that smallest magnitude:
    one trial says the rudder is offset to port, another to starboard. Differences of size
    alone are not judged: the Gauss-Newton errors of one trial omit its start-state error,
    which moves a single trial's estimate by more than they say. A trial whose estimate ran
    to its box's edge (``on_bound``) is left out: alone it does not determine the effect.
    """
    est = [x for x in est if not x.get('on_bound')]   # undetermined by its trial alone
    if effect not in EFFECTS or len(est) < 2:
        return ''
    x, se, j, smallest = _along(effect, est, joint)
    smallest *= froude_factor(EFFECTS[effect].units[0], ship.scale_ratio)
    against = (x < -smallest[None, :]) & (-x > DISAGREE_Z * se) & (j >= smallest)[None, :]
    if not against.any():
        return ''
    i, k = np.unravel_index(int(np.argmin(np.where(against, x, np.inf))), x.shape)
    return (f'the estimate on held-out trial {i + 1} points the other way ({x[i, k]:+.3g} '
            f'against {j[k]:+.3g} jointly, along the joint fit; more than the smallest worth '
            'finding and its error)')
