"""The tuning objective J (Suyama et al. 2023, eq. 43), vectorised over candidates and trials."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mmg_tuner.core.mmg import cost_many
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError


@dataclass
class TrialBatch:
    """Trials packed for the compiled kernels: meas (M, T, 6), ctrls (M, T, 2 or 4), padded."""

    names: list[str]
    meas: np.ndarray
    ctrls: np.ndarray
    lengths: np.ndarray
    dt: float

    @classmethod
    def from_trials(cls, trials: Sequence[Trial], x0_window_s: float = 10.0) -> 'TrialBatch':
        """Pack trials. The first state, from which each simulation starts, is estimated by a
        quadratic fit over the first x0_window_s seconds (0: the raw first sample): a noisy
        start would otherwise drift the whole simulation and bias the tuned parameters."""
        if not trials:
            raise TuningError('no trials given')
        dts = {round(t.dt, 9) for t in trials}
        if len(dts) != 1:
            raise TuningError(f'trials have different sample steps {sorted(dts)}; resample them '
                              'on one grid (--dt)')
        T = max(len(t) for t in trials)
        M = len(trials)
        meas = np.zeros((M, T, 6))
        # measured wind: two more input channels, NaN for trials without (they use the wind
        # parameters)
        n_in = 4 if any(t.wind is not None for t in trials) else 2
        ctrls = np.full((M, T, n_in), np.nan)
        for j, tr in enumerate(trials):
            n = len(tr)
            inputs = tr.inputs
            if not np.all(np.isfinite(tr.states)) or not np.all(np.isfinite(inputs)):
                raise TuningError(f'trial {tr.name}: non-finite values')
            meas[j, :n] = tr.states
            meas[j, 0] = initial_state(tr, x0_window_s)
            ctrls[j, :n, :inputs.shape[1]] = inputs
            meas[j, n:] = tr.states[-1]
            ctrls[j, n:, :inputs.shape[1]] = inputs[-1]
        return cls([t.name for t in trials], meas, ctrls,
                   np.array([len(t) for t in trials], dtype=np.int64), float(dts.pop()))


def initial_state(trial: Trial, window_s: float) -> np.ndarray:
    """Quadratic least-squares fit of each state over the first window_s seconds, at t0."""
    k = int(np.searchsorted(trial.t, trial.t[0] + window_s, side='right'))
    if window_s <= 0 or k < 4:
        return trial.states[0].copy()
    t = trial.t[:k] - trial.t[0]
    A = np.column_stack([np.ones(k), t, t * t])
    coef, *_ = np.linalg.lstsq(A, trial.states[:k], rcond=None)
    return coef[0]


def paper_weights(L_pp: float) -> np.ndarray:
    """Q = diag(L_pp, L_pp, 0.25 pi) on (x, y, psi) as printed in the paper; zero on u, v, r."""
    return np.array([L_pp, L_pp, 0.25 * math.pi, 0.0, 0.0, 0.0])


class Objective:
    """J(params) summed over a batch of trials; one compiled call per population.

    A candidate whose simulation diverges or leaves the model's range gets a penalty larger
    than any finite J of its population, growing with how early it failed, never a crash.
    """

    def __init__(self, ship: ShipConfig, batch: TrialBatch, weights: np.ndarray | None = None,
                 shoot_every_s: float = 0.0, integrator: str = 'euler', substeps: int = 1):
        self.ship = ship
        self.batch = batch
        self.weights = paper_weights(ship.L_pp) if weights is None else np.asarray(weights, float)
        if self.weights.shape != (6,) or np.any(self.weights < 0):
            raise TuningError('weights must be 6 non-negative numbers (x, y, psi, u, v, r)')
        self.shoot_every = int(round(shoot_every_s / batch.dt)) if shoot_every_s > 0 else 0
        self.method = integrator_code(integrator)
        self.substeps = int(substeps)
        self.evaluations = 0

    def per_trial(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw J (N, M) and failure sample (N, M; == length when the run completed)."""
        params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
        N, M = params.shape[0], self.batch.meas.shape[0]
        J = np.empty((N, M))
        k_fail = np.empty((N, M), dtype=np.int64)
        cost_many(self.ship.kind, params, self.batch.meas, self.batch.ctrls, self.batch.lengths,
                  self.batch.dt, self.substeps, self.method, self.weights, self.shoot_every, J,
                  k_fail)
        self.evaluations += N
        return J, k_fail

    def __call__(self, params: np.ndarray) -> np.ndarray:
        """Penalised total J per candidate (N,)."""
        J, k_fail = self.per_trial(params)
        failed = k_fail < self.batch.lengths[None, :]
        total = J.sum(axis=1)
        bad = failed.any(axis=1)
        if bad.any():
            ok = total[~bad]
            ceiling = 10.0 * (ok.max() if ok.size else 1.0) + 1.0
            missing = (self.batch.lengths[None, :] - k_fail).clip(min=0).sum(axis=1)
            total[bad] = ceiling * (1.0 + missing[bad] / self.batch.lengths.sum())
        return total
