"""The tuning objective J (Suyama et al. 2023, eq. 43), vectorised over candidates and trials."""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, cast, Sequence

from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.integrate import cost_many
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.trial import common_dt, fitted_first_state, fitted_state_at
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
import numpy as np


@dataclass
class TrialBatch:
    """
    Trials packed for the compiled kernels, padded to the longest.

    meas (M, T, 6) and the input channels the trials have, by name (``channels``, the columns
    of ctrls (M, T, n)); a channel a trial lacks holds its default (thrusters 0, wind NaN =
    not measured).
    """

    names: list[str]
    meas: np.ndarray
    ctrls: np.ndarray
    lengths: np.ndarray
    dt: float
    channels: tuple[str, ...] = ('rpm', 'rudder')
    x0_window_s: float = 10.0
    """The window the first state is fitted over [s]; a restart's state too (0: raw)."""

    @classmethod
    def from_trials(cls, trials: Sequence[Trial], x0_window_s: float = 10.0) -> 'TrialBatch':
        """
        Pack trials.

        The first state, from which each simulation starts, is estimated by a quadratic fit over
        the first x0_window_s seconds (0: the raw first sample): a noisy start would otherwise
        drift the whole simulation and bias the tuned parameters.
        """
        dt = common_dt(trials, 'the objective')
        T = max(len(t) for t in trials)
        M = len(trials)
        channels = tuple(dict.fromkeys(n for t in trials for n in t.inputs))
        missing = [(t.name, n) for t in trials for n in channels
                   if n not in t.inputs and TABLE[n].default is None]
        if missing:
            raise TuningError(f'trial {missing[0][0]}: no input channel {missing[0][1]!r}, '
                              'which other trials of the batch have')
        meas = np.zeros((M, T, 6))
        ctrls = np.empty((M, T, len(channels)))
        for j, tr in enumerate(trials):
            n = len(tr)
            inputs = tr.input_array(channels)
            measured = [c for i, c in enumerate(channels) if not math.isnan(
                cast(float, TABLE[c].default) if TABLE[c].default is not None else 0.0)]
            if not np.all(np.isfinite(tr.states)) or not all(
                    np.all(np.isfinite(tr.inputs[c])) for c in measured if c in tr.inputs):
                raise TuningError(f'trial {tr.name}: non-finite values')
            meas[j, :n] = tr.states
            meas[j, 0] = initial_state(tr, x0_window_s)
            ctrls[j, :n] = inputs
            meas[j, n:] = tr.states[-1]
            ctrls[j, n:] = inputs[-1]
        return cls([t.name for t in trials], meas, ctrls,
                   np.array([len(t) for t in trials], dtype=np.int64), dt,
                   channels, float(x0_window_s))

    def inputs_for(self, channels: Sequence[str], ship: str = 'the ship') -> np.ndarray:
        """
        Return ctrls (M, T, n) with the given channels (a family's), in that order.

        Channels the trials lack take their defaults; a required one is a TuningError naming it.
        """
        M, T = self.meas.shape[:2]
        out = np.empty((M, T, len(channels)))
        for i, c in enumerate(channels):
            if c in self.channels:
                out[:, :, i] = self.ctrls[:, :, self.channels.index(c)]
            elif c in TABLE and TABLE[c].default is not None:
                out[:, :, i] = TABLE[c].default
            else:
                raise TuningError(f'{ship} needs the input channel {c!r}, which the trials do '
                                  f'not have (they have {", ".join(self.channels)})')
        return np.ascontiguousarray(out)


def initial_state(trial: Trial, window_s: float) -> np.ndarray:
    """Fit the start state over the first window_s seconds (``core.trial.fitted_first_state``)."""
    return fitted_first_state(trial, window_s)


def restart_states(batch: TrialBatch, shoot_every: int) -> np.ndarray:
    """
    Return batch.meas with the state at every restart (k = shoot_every, 2 shoot_every, ...).

    Fitted over the batch's first-state window centred on it (``core.trial.fitted_state_at``:
    a restart starts as the first sample does); batch.meas itself without restarts or with a
    window of 0. The error at a restart sample is then taken against the fitted state too
    (one sample in shoot_every).
    """
    window_s = batch.x0_window_s
    if shoot_every <= 0 or window_s <= 0:
        return batch.meas
    meas = batch.meas.copy()
    for j, n in enumerate(batch.lengths):
        t = batch.dt * np.arange(n)
        for k in range(shoot_every, n - 1, shoot_every):
            meas[j, k] = fitted_state_at(t, batch.meas[j, :n], k, window_s)
    return meas


def paper_weights(L_pp: float) -> np.ndarray:
    """Q = diag(L_pp, L_pp, 0.25 pi) on (x, y, psi) as printed in the paper; zero on u, v, r."""
    return np.array([L_pp, L_pp, 0.25 * math.pi, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class Prior:
    """
    A quadratic pull toward reference values (e.g. captive-test ones), added to J.

    penalty = weight * sum(((theta - centre) / scale)^2) over the parameter slots ``indices``;
    weight in J units. Parameters the trials do not excite then stay at their reference values
    instead of drifting to wherever they compensate something else.
    """

    indices: np.ndarray   # (d,) slots in the flat parameter vector
    centre: np.ndarray    # (d,) reference values
    scale: np.ndarray     # (d,) > 0, e.g. the width of each parameter's box
    weight: float         # [J units] per unit squared scaled distance

    def __call__(self, params: np.ndarray) -> np.ndarray:
        """Return the penalty (N,) of parameter vectors (N, N_PARAMS)."""
        z = (np.atleast_2d(params)[:, self.indices] - self.centre) / self.scale
        penalty: np.ndarray = self.weight * np.sum(z * z, axis=1)
        return penalty


@dataclass(frozen=True)
class TrialFailure:
    """
    Where a simulation of one trial stopped.

    It diverged (non-finite state) or left the model's range (u <= 0, rpm <= 0). Its J is infinite:
    the samples after it are unexplained, so a partial sum would make a diverging model look better
    than a working one.
    """

    trial: str
    sample: int | None   # first sample the model could not produce (None: not detected,
    t_s: float | None    # only J overflowed); its time from the trial's start [s]

    def __str__(self) -> str:
        if self.t_s is None:
            return f'diverged on trial {self.trial} (non-finite J; failure time not detected)'
        return f'diverged on trial {self.trial} at t = {self.t_s:.6g} s'

    def to_dict(self) -> dict[str, Any]:
        return {'trial': self.trial, 'sample': self.sample, 't_s': self.t_s}


@dataclass(frozen=True, eq=False)
class Evaluation:
    """
    J of one parameter vector on a batch.

    Per trial (inf where the run failed), the total (inf when any trial failed) and the failures,
    first by trial order.
    """

    names: tuple[str, ...]
    J: np.ndarray                       # (M,) per trial [J units], inf for a failed trial
    failures: tuple[TrialFailure, ...]

    @property
    def total(self) -> float:
        return float(self.J.sum())

    @property
    def diverged(self) -> bool:
        return bool(self.failures)

    def describe(self) -> str:
        """'1.234e+05', or 'diverged on trial X at t = 12 s' (never a partial sum)."""
        return str(self.failures[0]) if self.failures else f'{self.total:.4g}'

    def total_json(self) -> float | None:
        """Return the total for JSON (which has no inf): None when a trial failed."""
        return None if self.failures else self.total

    def per_trial_json(self) -> dict[str, dict[str, Any]]:
        """{trial: {'J': float or None, 'diverged': {'sample', 't_s'} or None}}."""
        failed = {f.trial: f for f in self.failures}
        return {n: {'J': None if n in failed else float(j),
                    'diverged': ({'sample': failed[n].sample, 't_s': failed[n].t_s}
                                 if n in failed else None)}
                for n, j in zip(self.names, self.J)}


class Objective:
    """
    J(params) summed over a batch of trials; one compiled call per population.

    ``per_trial`` and ``evaluate`` give a failed run (diverged or out of the model's range) an
    infinite J and say where it failed. The call used by the optimiser ranks such a candidate
    with a finite penalty larger than any finite J of its population, growing with how early
    it failed (CMA-ES needs an order among failures too), never a crash.
    """

    def __init__(self, ship: ShipConfig, batch: TrialBatch, weights: np.ndarray | None = None,
                 shoot_every_s: float = 0.0, integrator: str = 'euler', substeps: int = 1,
                 trial_weights: np.ndarray | None = None, prior: Prior | None = None):
        self.ship = ship
        # per-trial factors on J in the optimiser's total (tuning/segments.py balances
        # segments with them); the per-trial J and evaluate() stay unweighted
        self.trial_weights = (None if trial_weights is None
                              else np.asarray(trial_weights, dtype=float))
        if self.trial_weights is not None and (
                self.trial_weights.shape != (batch.meas.shape[0],)
                or not np.all(np.isfinite(self.trial_weights)) or np.any(self.trial_weights < 0)):
            raise TuningError(f'trial_weights must be {batch.meas.shape[0]} finite numbers >= 0 '
                              '(one per trial)')
        self.prior = prior
        self.batch = batch
        # the batch's channels in the ship family's kernel order
        self.ctrls = batch.inputs_for(ship.family.channels, ship.name)
        self.weights = paper_weights(ship.L_pp) if weights is None else np.asarray(weights, float)
        if self.weights.shape != (6,) or np.any(self.weights < 0):
            raise TuningError('weights must be 6 non-negative numbers (x, y, psi, u, v, r)')
        self.shoot_every = int(round(shoot_every_s / batch.dt)) if shoot_every_s > 0 else 0
        self.shoot_every_s = float(shoot_every_s) if self.shoot_every else 0.0
        # what the kernel reads: the batch, each restart's state fitted over a window as the
        # first one is (the batch itself stays as measured: other objectives share it)
        self.kernel_meas = restart_states(batch, self.shoot_every)
        self.method = integrator_code(integrator)
        self.substeps = int(substeps)
        self.evaluations = 0

    def _raw(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the kernel's J (N, M) and the failure sample (N, M).

        The kernel's J (N, M), summed over the samples before a failure, and the failure sample (N,
        M; == length when the run completed).
        """
        params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
        N, M = params.shape[0], self.batch.meas.shape[0]
        J = np.empty((N, M))
        k_fail = np.empty((N, M), dtype=np.int64)
        cost_many(self.ship.kind, params, self.kernel_meas, self.ctrls, self.batch.lengths,
                  self.batch.dt, self.substeps, self.method, self.weights, self.shoot_every, J,
                  k_fail)
        self.evaluations += N
        return J, k_fail

    def per_trial(self, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """
        Return J (N, M), inf where the run failed, and the failure sample (N, M).

        J (N, M), inf where the run failed, and the failure sample (N, M; == the trial's length
        when the run completed).
        """
        J, k_fail = self._raw(params)
        return np.where((k_fail < self.batch.lengths[None, :]) | ~np.isfinite(J), math.inf, J), \
            k_fail

    def failures(self, k_fail: np.ndarray, J: np.ndarray | None = None
                 ) -> tuple[TrialFailure, ...]:
        """
        Return the failures in one candidate's rows of failure samples and J (M,), in trial order.

        A non-finite J of a run that completed counts too (time unknown).
        """
        J = np.zeros(len(k_fail)) if J is None else J
        return tuple(TrialFailure(n, int(k), float(k * self.batch.dt)) if k < T
                     else TrialFailure(n, None, None)
                     for n, k, T, j in zip(self.batch.names, k_fail, self.batch.lengths, J)
                     if k < T or not math.isfinite(j))

    def evaluate(self, params: np.ndarray) -> Evaluation:
        """J of one parameter vector (N_PARAMS,) per trial, with where any run failed."""
        J, k_fail = self.per_trial(np.asarray(params, dtype=float).reshape(1, -1))
        return Evaluation(tuple(self.batch.names), J[0], self.failures(k_fail[0], J[0]))

    def __call__(self, params: np.ndarray) -> np.ndarray:
        """Penalised total J per candidate (N,): finite, for ranking (see the class)."""
        J, k_fail = self._raw(params)
        failed = k_fail < self.batch.lengths[None, :]
        total: np.ndarray = (J if self.trial_weights is None
                             else J * self.trial_weights).sum(axis=1)
        if self.prior is not None:
            total = total + self.prior(params)
        bad = failed.any(axis=1) | ~np.isfinite(total)  # (an overflow to inf counts as failed)
        if bad.any():
            ok = total[~bad]
            ceiling = 10.0 * (ok.max() if ok.size else 1.0) + 1.0
            missing = (self.batch.lengths[None, :] - k_fail).clip(min=0).sum(axis=1)
            total[bad] = ceiling * (1.0 + missing[bad] / self.batch.lengths.sum())
        return total
