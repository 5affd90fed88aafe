"""
Statistics of the diagnosis: the one acceptance rule, the jackknife, estimates on a bound.

Moved from ``select.py`` unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.diagnosis.settings import DiagnosisSettings
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np


@dataclass(frozen=True)
class Verdict:
    """What :func:`acceptance` decided, and on which numbers."""

    significant: bool
    gain: float          # pooled held-out gain 1 - sum(J_new) / sum(J_ref)
    gain_se: float       # its jackknife standard error
    per_trial_gain: np.ndarray
    absolute: float      # the reduction as a fraction of the base model's held-out error
    worst: float         # the largest J_new / J_ref over test trials
    reason: str          # why not significant ('' when significant)


def acceptance(J_ref: np.ndarray, J_new: np.ndarray, n_params: int, J_base_test: float,
               s: DiagnosisSettings, J_floor: float | None = None,
               floor_per_trial: Sequence[float] | None = None, veto: bool = True) -> Verdict:
    """
    Return the one acceptance rule, used by the forward and the backward step.

    The one acceptance rule, used by the forward step (ref: the current model re-tuned, new: with
    the candidate effect) and by the backward step (ref: the model without a named effect, new: the
    model with it; not significant -> the effect is dropped).

    Significant when the gain exceeds min_gain + param_penalty x n_params and min_gain_z
    jackknife standard errors, the reduction is at least min_abs_gain of the base model's
    held-out error (or, given the noise floor J_floor of the held-out trials, the reduction
    exceeds noise_margin x J_floor), and no test trial gets worse both by a factor above
    1 + worse_tol and by more than worse_abs of the total held-out J without it (sum(J_ref))
    and, given ``floor_per_trial`` (the held-out J sensor noise alone leaves on each test
    trial, diagnosis/noise.py), by more than that trial's floor: near the noise a trial
    getting worse by less than noise leaves is no evidence against an effect (a wind and a
    rudder offset at their true values made one held-out trial 2.6 x worse, +10 % of the
    held-out error, than a wind bent to take the offset's share: 0.7 of that trial's floor).
    With ``s.held_out_test_only`` (the evidence verdict's search) the gain need only exceed
    min_gain_z standard errors, and no trial may get clearly worse: no fixed sizes.
    A run that diverges (infinite J) on either side is never significant. ``veto=False``
    (the backward step: is a named effect redundant beside the others?) leaves out the test
    of a trial getting worse: that is a test for naming, which the effect passed when named.
    """
    J_ref = np.asarray(J_ref, float)
    J_new = np.asarray(J_new, float)
    if not np.all(np.isfinite(J_new)) or not np.all(np.isfinite(J_ref)):
        side = 'with' if not np.all(np.isfinite(J_new)) else 'without'
        return Verdict(False, -math.inf, math.inf, np.full(J_new.shape, np.nan), -math.inf,
                       math.inf, f'the model {side} it diverges on a test trial')
    ratio = J_new / np.maximum(J_ref, 1e-300)
    gain = float(1 - J_new.sum() / max(J_ref.sum(), 1e-300))
    se = jackknife_se(J_ref, J_new)
    need = 0.0 if s.held_out_test_only else s.min_gain + s.param_penalty * n_params
    absolute = float((J_ref.sum() - J_new.sum()) / max(J_base_test, 1e-300))
    # worse by the factor and by an amount that matters against the total
    increase = (J_new - J_ref) / max(J_ref.sum(), 1e-300)
    bad = (ratio >= 1 + s.worse_tol) & (increase > s.worse_abs)
    if floor_per_trial is not None and len(floor_per_trial) == len(J_ref):
        bad &= J_new - J_ref > np.asarray(floor_per_trial, float)
    worst = float(np.max(ratio))
    reasons = []
    if not gain > need:
        reasons.append(f'gain {100 * gain:.1f} % <= {100 * need:.1f} %')
    if not gain > s.min_gain_z * se:
        reasons.append(f'gain within {s.min_gain_z:g} standard error(s) ({100 * se:.1f} %)')
    above_noise = bool(J_floor and J_floor > 0
                       and J_ref.sum() - J_new.sum() > s.noise_margin * J_floor)
    if not (absolute > s.min_abs_gain or above_noise or s.held_out_test_only):
        reasons.append(f'{100 * absolute:.1f} % of the base error <= '
                       f'{100 * s.min_abs_gain:.0f} %'
                       + (f' and the reduction within {s.noise_margin:g} noise floor(s)'
                          if J_floor else ''))
    if veto and bad.any():
        k = int(np.flatnonzero(bad)[np.argmax(ratio[bad])])
        reasons.append(f'a test trial gets worse ({ratio[k]:.2f} x, +{100 * increase[k]:.1f} % '
                       'of the held-out error)')
    return Verdict(not reasons, gain, se, 1 - ratio, absolute, worst, '; '.join(reasons))


_PERIODIC = {'current_dir', 'wind_dir'}


def pinned_on_bound(space: ParameterSpace, theta: np.ndarray, names: Sequence[str],
                    tol: float) -> list[str]:
    """
    Return the effect parameters whose estimate sits on a bound of its box.

    Effect parameters whose estimate sits on a bound of its box (periodic angles and bounds equal
    to the neutral value excepted: there the effect merely vanishes).
    """
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
    """
    Return the jackknife standard error of the pooled gain.

    Standard error of the pooled gain 1 - sum(J_new)/sum(J_ref), leaving out one test trial at a
    time (trials weigh as much as their error). Infinite with fewer than two trials.
    """
    n = len(J_ref)
    if n < 2 or not (np.all(np.isfinite(J_ref)) and np.all(np.isfinite(J_new))):
        return float('inf')
    loo = np.array([1 - (J_new.sum() - J_new[i]) / max(J_ref.sum() - J_ref[i], 1e-300)
                    for i in range(n)])
    return float(np.sqrt((n - 1) / n * np.sum((loo - loo.mean()) ** 2)))
