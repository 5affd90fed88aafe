"""
How much of an error is sensor noise: the noise estimated from the recordings, and its floor.

A model's simulation is smooth; the recorded states carry white sensor noise. So the second
differences of the residuals (simulated - recorded) are the noise's alone, up to a small
remainder of the model's error: for white noise of standard deviation sigma they have the
variance 6 sigma^2. :func:`sensor_noise` takes a robust estimate (the median absolute
deviation, so that a manoeuvre's few sharp corners do not count) per state, pooled over trials
(SUZAKU's generated trials: 0.46 and 0.54 m against the 0.5 m drawn, 0.0034 rad against 0.0035).

The held-out J of even the true model is not the white noise's share alone: the simulation
starts from a state fitted to noisy samples and drifts from there (on 200 s SUZAKU trials the
truth's J is about 15 x the white-noise part). :func:`noise_floor` measures that floor by a
parametric bootstrap: the model's own simulation, plus noise drawn with the estimated sigma,
is a recording the model explains perfectly; its J against the model (new start state fitted,
as the objective does) is what noise alone leaves. That J varies much from one noise draw to
the next (the start state's yaw-rate error dominates it: on SUZAKU's five 200 s held-out
trials the draws spread by about 60 % of their mean, and the truth's own J on one draw was
half the mean), so an error is noise when it lies within the draws' mean + NOISE_Z standard
deviations (about their 95th percentile); above it, something systematic remains.
"""
from __future__ import annotations

from dataclasses import replace
import math
from typing import Any, Sequence

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.residuals import residual_series, simulate_trials
from mmg_tuner.tuning.objective import Objective, TrialBatch
import numpy as np

NOISE_Z = 2.0      # a held-out J up to the draws' mean + NOISE_Z standard deviations is noise
DRAWS = 16         # bootstrap draws of the floor (the mean's standard error ~ 15 % of it)


def sensor_noise(trials: Sequence[Trial], sims: Sequence[np.ndarray]) -> dict[str, float] | None:
    """
    Return the sensor noise per state (SI units, radians) from the residuals' second differences.

    ``sims``: a model's simulation of each trial (NaN after a failure). None when no trial
    has five finite samples.
    """
    d2 = []
    for tr, sim in zip(trials, sims):
        if sim is None:
            continue
        e = residual_series(tr, sim)
        e = e[np.all(np.isfinite(e), axis=1)]
        if len(e) >= 5:
            d2.append(np.diff(e, 2, axis=0))
    if not d2:
        return None
    d = np.concatenate(d2)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return {n: float(1.4826 * m / math.sqrt(6.0)) for n, m in zip(STATE_NAMES, mad)}


def noise_floor(ship: ShipConfig, params: np.ndarray, trials: Sequence[Trial],
                sigma: dict[str, float], integrator: str = 'rk4',
                weights: np.ndarray | None = None, draws: int = DRAWS, seed: int = 0,
                restart_every_s: float = 0.0) -> dict[str, Any]:
    """
    Return the held-out J that noise alone leaves with this model on these trials.

    ``params``: the model's full parameter vector; ``sigma``: :func:`sensor_noise`. Each draw
    replaces the recorded states by the model's simulation plus white noise of ``sigma`` and
    takes the objective's J of the model on them (start state fitted as for a recording).
    Returns {'J': mean over draws (summed over trials), 'J_se': its standard error,
    'J_bound': mean + NOISE_Z standard deviations of the draws (what noise alone reaches),
    'J_white': the white noise's own share, 'per_trial': mean J per trial}.
    """
    sims = simulate_trials(ship, params, list(trials), integrator)
    sd = np.array([sigma[n] for n in STATE_NAMES])
    rng = np.random.default_rng(seed)
    fake = []
    for _ in range(draws):
        for tr, sim in zip(trials, sims):
            ok = np.all(np.isfinite(sim), axis=1)
            if not ok.all():      # a model that fails on a trial: no floor from it
                sim = np.where(ok[:, None], sim, tr.states)
            fake.append(replace(tr, states=sim + rng.normal(0.0, 1.0, sim.shape) * sd))
    obj = Objective(ship, TrialBatch.from_trials(fake), weights, restart_every_s,
                    integrator=integrator)
    J = obj.per_trial(np.asarray(params, float)[None])[0][0].reshape(draws, len(trials))
    per_draw = J.sum(axis=1)
    w = obj.weights
    white = sum((len(tr) - 1) * float(np.sum(w * sd ** 2)) for tr in trials)
    sd_draw = float(per_draw.std(ddof=1)) if draws > 1 else math.inf
    return {'J': float(per_draw.mean()), 'J_se': sd_draw / math.sqrt(draws),
            'J_bound': float(per_draw.mean()) + NOISE_Z * sd_draw,
            'J_white': float(white), 'per_trial': J.mean(axis=0).tolist()}


def describe(J: float, floor: dict[str, Any] | None) -> tuple[bool | None, str]:
    """
    Say whether a held-out J is noise: (is_noise, sentence); (None, ...) without a floor.

    Noise when J <= the floor's J_bound (mean + NOISE_Z standard deviations of the draws).
    """
    if not floor or not (floor.get('J') or 0) > 0 or not math.isfinite(J) \
            or not math.isfinite(floor.get('J_bound', math.inf)):
        return None, 'the remaining error could not be compared with the sensor noise'
    ratio, top = J / floor['J'], floor['J_bound'] / floor['J']
    if J <= floor['J_bound']:
        return True, (f'what remains is noise: {ratio:.1f} x the mean held-out error sensor '
                      f'noise alone leaves (noise alone reaches {top:.1f} x)')
    return False, (f'what remains is not noise: {ratio:.1f} x the mean held-out error sensor '
                   f'noise alone leaves (noise alone reaches {top:.1f} x)')
