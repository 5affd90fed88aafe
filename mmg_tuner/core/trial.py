"""
One time-history type for everything: a recorded, generated or simulated trial.

``simulate()`` and the manoeuvres return it, the readers produce it, the objective and the
diagnosis consume it, so a prediction compares with a recording sample by sample. Its inputs
are keyed by channel name (``core/channels.py``: units and defaults in one table); a ship's
kernels take them as one array in its family's channel order (:meth:`Trial.input_array`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Any, Callable, Mapping, Sequence

from mmg_tuner.core.channels import CONTROL_NAMES, ENVIRONMENT, TABLE
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.errors import TrialDataError, TuningError
import numpy as np
import numpy.typing as npt

_UNSET: Any = object()
_PAIRS = {'controls': CONTROL_NAMES, 'wind': ENVIRONMENT,
          'thrusters': ('bow_thruster', 'stern_thruster')}
"""The two-column views of screw-and-rudder trials and the channels behind them."""


@dataclass(init=False)
class Trial:
    """
    A time history on a uniform grid, in the model frame, SI units.

    t [s] (T,); states (T, 6) = x_E, y_E [m], psi [rad, unwrapped], u, v [m/s over ground],
    r [rad/s]; inputs: channel name -> (T,) values in the channel's unit
    (``core/channels.TABLE``: rpm [rev/min], rudder [rad, + to starboard], bow_thruster,
    stern_thruster [rev/s], wind_n, wind_e: the measured true wind as the air's velocity over
    ground [m/s], ...). status is 'ok' or, for a simulation, why it stopped; fail_time_s is
    when (NaN after it).

    Screw-and-rudder trials may be built and read through two-column views: ``controls``
    (rpm, rudder), ``wind`` (north, east; None if not measured) and ``thrusters`` (bow,
    stern; None if not recorded). Given to the constructor (or to ``dataclasses.replace``) they
    set those channels; ``None`` removes them.
    """

    t: np.ndarray
    states: np.ndarray
    inputs: dict[str, np.ndarray]
    name: str = 'trial'
    source: str = ''
    notes: list[str] = field(default_factory=list)
    start_s: float = 0.0  # where t = 0 lies in the recording it came from [s]
    status: str = 'ok'
    fail_time_s: float | None = None

    def __init__(self, t: npt.ArrayLike, states: npt.ArrayLike, controls: Any = _UNSET,
                 name: str = 'trial', source: str = '',
                 notes: list[str] | None = None, start_s: float = 0.0, wind: Any = _UNSET,
                 thrusters: Any = _UNSET, status: str = 'ok', fail_time_s: float | None = None,
                 inputs: Mapping[str, Any] | None = None) -> None:
        self.t = np.asarray(t, dtype=float)
        self.states = np.asarray(states, dtype=float)
        self.name, self.source, self.start_s = name, source, start_s
        self.notes = [] if notes is None else notes
        self.status, self.fail_time_s = status, fail_time_s
        T = self.t.size
        where = self.source or self.name
        if self.states.shape != (T, 6):
            raise TrialDataError(f'{where}: inconsistent shapes t {self.t.shape}, '
                                 f'states {self.states.shape}')
        merged = dict(inputs or {})
        for what, value in (('controls', controls), ('wind', wind), ('thrusters', thrusters)):
            if value is _UNSET:
                continue
            names = _PAIRS[what]
            if value is None:
                for n in names:
                    merged.pop(n, None)
                continue
            a = np.asarray(value, dtype=float)
            if a.shape != (T, 2):
                raise TrialDataError(f'{where}: {what} must be (T, 2) = ({", ".join(names)}) '
                                     f'with T = {T}, got {a.shape}')
            merged.update({n: a[:, i] for i, n in enumerate(names)})
        self.inputs = {}
        for n, v in merged.items():
            if n not in TABLE:
                raise TrialDataError(f'{where}: unknown input channel {n!r}; known: '
                                     f'{", ".join(TABLE)}')
            a = np.asarray(v, dtype=float)   # no copy, as the arrays a trial is built from
            if a.shape != (T,):
                raise TrialDataError(f'{where}: channel {n!r} must have {T} samples (one per '
                                     f'time), got shape {a.shape}')
            self.inputs[n] = a
        if 'wind_n' in self.inputs and 'wind_e' in self.inputs \
                and np.all(np.isnan(self.inputs['wind_n'])) \
                and np.all(np.isnan(self.inputs['wind_e'])):
            del self.inputs['wind_n'], self.inputs['wind_e']   # "not measured" is no channel

    @classmethod
    def from_array(cls, t: npt.ArrayLike, states: npt.ArrayLike, array: npt.ArrayLike,
                   channels: Sequence[str], **kw: Any) -> 'Trial':
        """Return a trial from an input array whose columns are the named channels."""
        array = np.asarray(array, dtype=float)
        return cls(t, states, inputs={n: array[:, j] for j, n in enumerate(channels)}, **kw)

    def _pair(self, what: str) -> np.ndarray | None:
        names = _PAIRS[what]
        if not all(n in self.inputs for n in names):
            return None
        return np.column_stack([self.inputs[n] for n in names])

    @property
    def controls(self) -> np.ndarray:
        """(T, 2) rpm [rev/min], rudder [rad] (NaN where the trial has no such channel)."""
        return np.column_stack([self.inputs.get(n, np.full(len(self), np.nan))
                                for n in CONTROL_NAMES])

    @property
    def wind(self) -> np.ndarray | None:
        """(T, 2) measured wind north, east [m/s], or None if not measured."""
        return self._pair('wind')

    @property
    def thrusters(self) -> np.ndarray | None:
        """(T, 2) bow, stern thrusters [rev/s], or None if not recorded."""
        return self._pair('thrusters')

    def input_array(self, channels: Sequence[str]) -> np.ndarray:
        """
        Return the named channels as one (T, n) array, in the order given.

        A channel the trial lacks takes its default (``channels.TABLE``: thrusters 0, wind
        NaN = not measured); a required one without a default is a TrialDataError naming it.
        """
        return input_array(channels, self.inputs, len(self), self.source or self.name)

    @property
    def ok(self) -> bool:
        return self.status == 'ok'

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else float('nan')

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0])

    def __len__(self) -> int:
        return self.t.size

    def segments(self, restart_every_s: float | None) -> list[tuple[int, int]]:
        """
        Return the samples [a, b) of each run restarted from the measured state every N s.

        Restarts at t = 0, N, 2N, ... s (N = ``restart_every_s`` rounded to whole samples, at
        least one; 0 or None: one run); the last may be one sample long (the restart itself).
        """
        T = len(self)
        K = T if not restart_every_s else max(1, int(round(restart_every_s / self.dt)))
        return [(a, min(T, a + K)) for a in range(0, T, K)]

    def __getitem__(self, name: str) -> np.ndarray:
        if name == 't':
            return self.t
        if name in STATE_NAMES:
            return self.states[:, STATE_NAMES.index(name)]
        if name in self.inputs:
            return self.inputs[name]
        raise KeyError(name)

    def _map_inputs(self, fn: Callable[[np.ndarray], np.ndarray]) -> dict[str, np.ndarray]:
        return {n: fn(v) for n, v in self.inputs.items()}

    def slice(self, start_s: float, end_s: float | None = None,  # noqa: A003  public API name
              name: str | None = None
              ) -> 'Trial':
        """Return the part between start_s and end_s (trial time, inclusive)."""
        end_s = self.t[-1] if end_s is None else end_s
        k = (self.t >= start_s - 1e-9) & (self.t <= end_s + 1e-9)
        return replace(self, t=self.t[k], states=self.states[k],
                       inputs=self._map_inputs(lambda a: a[k]), name=name or self.name,
                       notes=list(self.notes))

    def froude_scaled(self, ratio: float) -> 'Trial':
        """
        Scale by 1/ratio in length (ratio = L_from / L_to), Froude similarity.

        Time and velocity by 1/sqrt(ratio), yaw rate, rpm and thruster revolutions by sqrt(ratio).
        """
        s = math.sqrt(ratio)
        st = self.states.copy()
        st[:, :2] /= ratio
        st[:, 3:5] /= s
        st[:, 5] *= s
        factor = {'rev/min': s, 'rev/s': s, 'm/s': 1.0 / s, 'rad/s': s}
        inputs = {n: v * factor.get(TABLE[n].unit, 1.0) for n, v in self.inputs.items()}
        return replace(self, t=self.t / s, states=st, inputs=inputs,
                       notes=self.notes + [f'Froude-scaled by 1/{ratio:g}'])

    def resampled(self, dt: float) -> 'Trial':
        """Return the trial resampled to step dt (linear interpolation, heading unwrapped)."""
        n = int(math.floor(self.duration_s / dt + 1e-9)) + 1
        grid = self.t[0] + dt * np.arange(n)

        states = np.column_stack([np.interp(grid, self.t, self.states[:, i]) for i in range(6)])
        return replace(self, t=grid, states=states,
                       inputs=self._map_inputs(lambda a: np.interp(grid, self.t, a)),
                       notes=self.notes + [f'resampled on dt = {dt:g} s (linear)'])


def common_dt(trials: Sequence[Trial], where: str) -> float:
    """
    Return the one sample step [s] of ``trials`` (to 1 ns), for a batch simulated on one grid.

    TuningError, prefixed by ``where``, when there are none or their steps differ.
    """
    if not trials:
        raise TuningError(f'{where}: no trials given')
    dts = {round(t.dt, 9) for t in trials}
    if len(dts) != 1:
        raise TuningError(f'{where}: the trials have different sample steps {sorted(dts)} s; '
                          'resample them on one grid (--dt)')
    return float(dts.pop())


def input_array(channels: Sequence[str], values: Mapping[str, Any], T: int, where: str = 'inputs'
                ) -> np.ndarray:
    """
    Stack the named channels of ``values`` (name -> (T,) array) into one (T, n) array.

    Absent channels take their default (``channels.TABLE``); required ones missing are a
    TrialDataError naming each of them and what the trial has.
    """
    out = np.empty((T, len(channels)))
    missing = []
    for j, n in enumerate(channels):
        if n in values:
            out[:, j] = values[n]
            continue
        ch = TABLE.get(n)
        if ch is None or ch.default is None:
            what = f'{ch.description} [{ch.unit}]' if ch else 'an unknown channel'
            missing.append(f'{n!r} ({what})')
            continue
        out[:, j] = ch.default
    if missing:   # every one named: a user fixes the file once
        raise TrialDataError(f'{where}: no input channel {", ".join(missing)}; the ship needs '
                             f'{", ".join(channels)}, the trial has '
                             f'{", ".join(values) or "none"}')
    return out


START_Z = 4.0            # a half window's start this many of its standard errors away: shorten
START_MIN_SAMPLES = 8    # the shortest window the start is fitted on (5 residual dof)


def _quadratic_start(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (value at t = 0, its standard error) of a quadratic fit of each column of x."""
    A = np.column_stack([np.ones(len(t)), t, t * t])
    coef, *_ = np.linalg.lstsq(A, x, rcond=None)
    e = x - A @ coef
    dof = max(len(t) - 3, 1)
    s2 = np.sum(e ** 2, axis=0) / dof
    var00 = float(np.linalg.pinv(A.T @ A)[0, 0])
    # correlated residuals (filtered or smoothed recordings) carry fewer independent samples
    # than they number: the error grows by sqrt((1 + rho) / (1 - rho)), rho their lag-1
    # autocorrelation
    den = np.sum(e * e, axis=0)
    rho = np.clip(np.sum(e[1:] * e[:-1], axis=0) / np.where(den > 0, den, 1.0), 0.0, 0.99)
    return np.asarray(coef[0], dtype=float), np.sqrt(s2 * var00 * (1 + rho) / (1 - rho))


def fitted_state_at(t: np.ndarray, states: np.ndarray, k: int, window_s: float) -> np.ndarray:
    """
    Return the state at sample k of a recording, fitted over a window centred on it.

    A restart of a simulation (multiple shooting) starts from it, as the first start starts
    from :func:`fitted_first_state`: the raw sample carries the sensors' noise, and a start
    0.2 deg off in heading moves a 58 s run's end by metres. A quadratic least-squares fit of
    each state over t[k] +- window_s / 2 (clipped to the recording), evaluated at t[k]; the
    window halves while a quadratic does not describe it, by :func:`fitted_first_state`'s rule
    (a helm order at t[k] is a kink, not a curve). The raw sample when window_s <= 0 or too few
    samples lie in the window.
    """
    half = 0.5 * window_s
    tk = t[k]
    while True:
        lo = int(np.searchsorted(t, tk - half, side='left'))
        hi = int(np.searchsorted(t, tk + half, side='right'))
        if window_s <= 0 or hi - lo < START_MIN_SAMPLES:
            return np.array(states[k], dtype=float)
        x, _ = _quadratic_start(t[lo:hi] - tk, states[lo:hi])
        lo2 = int(np.searchsorted(t, tk - 0.5 * half, side='left'))
        hi2 = int(np.searchsorted(t, tk + 0.5 * half, side='right'))
        if hi2 - lo2 < START_MIN_SAMPLES:
            return x
        xh, se = _quadratic_start(t[lo2:hi2] - tk, states[lo2:hi2])
        if not np.any(np.abs(x - xh) > START_Z * se):
            return x
        half *= 0.5


def fitted_first_state(trial: Trial, window_s: float) -> np.ndarray:
    """
    Return the state a simulation of a recorded trial starts from.

    A quadratic least-squares fit of each state over the first window_s seconds, evaluated at
    t0 (the raw first sample when window_s <= 0 or fewer than 4 samples lie in the window): the
    one initial-state rule of the objective, the reports, ``mt.simulate`` and the hybrid.

    The window halves while a quadratic does not describe it: while the fit over its first
    half gives a start more than START_Z of that fit's standard errors away (in any state),
    down to START_MIN_SAMPLES samples. A ship that starts a manoeuvre at the first sample is
    not quadratic over 10 s: a 1:20 tug put to full differential thrust from rest reaches
    0.24 rad/s in 0.6 s, the 10 s fit started it at 0.2 rad/s, and its heading error of
    0.26 rad then made the trial's held-out J 10^4 x the others' (the diagnosis named a false
    cause on it). A steady start (every SUZAKU trial, the pond runs' straight approach) keeps
    the whole window.
    """
    k = int(np.searchsorted(trial.t, trial.t[0] + window_s, side='right'))
    if window_s <= 0 or k < 4:
        return np.array(trial.states[0], dtype=float)
    t = trial.t - trial.t[0]
    x0, _ = _quadratic_start(t[:k], trial.states[:k])
    while True:
        window_s *= 0.5
        h = int(np.searchsorted(t, window_s, side='right'))
        if h < START_MIN_SAMPLES:
            return x0
        xh, se = _quadratic_start(t[:h], trial.states[:h])
        if not np.any(np.abs(x0 - xh) > START_Z * se):
            return x0
        x0 = xh
