"""
Residual analysis.

Per trial and state, when and how large the errors are, and what they correlate with (heading,
speed, rudder, rudder rate, time).
"""
from __future__ import annotations

import math
from typing import Any

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.tuning.report import simulate_trial, unique_names
import numpy as np


def simulate_trials(ship: ShipConfig, params: np.ndarray, trials: list[Trial],
                    integrator: str = 'rk4') -> list[np.ndarray]:
    """Each trial simulated the way the objective does (same start-state rule)."""
    return [simulate_trial(ship, tr, params, integrator) for tr in trials]


def residual_series(trial: Trial, sim: np.ndarray) -> np.ndarray:
    """Return simulated - recorded, heading wrapped; (T, 6)."""
    e: np.ndarray = sim - trial.states
    e[:, 2] = (e[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return e


def regressors(trial: Trial) -> dict[str, np.ndarray]:
    psi = trial['psi']
    out = {'cos_heading': np.cos(psi), 'sin_heading': np.sin(psi), 'speed': trial['u']}
    if 'rudder' in trial.inputs:   # a rudder where the actuator has one (not a tug's)
        out.update(rudder=trial['rudder'], rudder_rate=np.gradient(trial['rudder'], trial.t))
    out['time'] = trial.t - trial.t[0]
    return out


def summarize(trials: list[Trial], sims: list[np.ndarray]) -> dict[str, Any]:
    """
    Return the error statistics per trial and the residuals' correlations.

    Per trial: RMS and maximum (with its time) of each state's error; pooled correlation of the
    velocity residuals with each regressor.
    """
    per_trial: dict[str, dict[str, dict[str, float] | float]] = {}
    pooled_e: list[np.ndarray] = []
    pooled_x: dict[str, list[np.ndarray]] = {k: [] for k in regressors(trials[0])}
    for tr, label, sim in zip(trials, unique_names(trials), sims):
        e = residual_series(tr, sim)
        ok = np.all(np.isfinite(e), axis=1)
        stats: dict[str, dict[str, float] | float] = {}
        for i, n in enumerate(STATE_NAMES):
            if not ok.any():
                break
            ei = e[ok, i]
            at = int(np.argmax(np.abs(ei)))
            scale = math.degrees(1) if n in ('psi', 'r') else 1.0
            stats[n] = {'rms': float(np.sqrt(np.mean(ei ** 2)) * scale),
                        'max': float(ei[at] * scale), 't_max': float(tr.t[ok][at] - tr.t[0])}
        stats['position_rms_m'] = float(np.sqrt(np.mean(e[ok, 0] ** 2 + e[ok, 1] ** 2))) \
            if ok.any() else float('nan')
        per_trial[label] = stats
        pooled_e.append(e[ok][:, 3:])
        for k, v in regressors(tr).items():
            pooled_x[k].append(v[ok])
    E = np.concatenate(pooled_e)
    corr: dict[str, dict[str, float]] = {}
    for k, parts in pooled_x.items():
        x = np.concatenate(parts)
        corr[k] = {n: _corr(x, E[:, j]) for j, n in enumerate(('u', 'v', 'r'))}
    return {'per_trial': per_trial, 'correlation': corr}


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if np.std(a) < 1e-12 or np.std(b) < 1e-12:
        return 0.0
    return float(np.corrcoef(a, b)[0, 1])
