"""
One time-history type for everything: a recorded, generated or simulated trial.

``simulate()`` and the manoeuvres return it, the readers produce it, the objective and the
diagnosis consume it, so a prediction compares with a recording sample by sample.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

from mmg_tuner.core.channels import CHANNELS, CONTROL_NAMES, STERN_THRUSTER, WIND_E
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.errors import TrialDataError
import numpy as np


@dataclass
class Trial:
    """
    A time history on a uniform grid, in the model frame, SI units.

    t [s] (T,); states (T, 6) = x_E, y_E [m], psi [rad, unwrapped], u, v [m/s over ground],
    r [rad/s]; controls (T, 2) = rpm [rev/min], rudder [rad, + to starboard];
    wind (T, 2) or None = measured true wind as the air's velocity over ground, north and east
    components [m/s] (a vector, so it resamples without angle wrap-around);
    thrusters (T, 2) or None = bow and stern thruster revolutions [rev/s].
    status is 'ok' or, for a simulation, why it stopped; fail_time_s is when (NaN after it).
    """

    t: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    name: str = 'trial'
    source: str = ''
    notes: list[str] = field(default_factory=list)
    start_s: float = 0.0  # where t = 0 lies in the recording it came from [s]
    wind: np.ndarray | None = None
    thrusters: np.ndarray | None = None
    status: str = 'ok'
    fail_time_s: float | None = None

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.states = np.asarray(self.states, dtype=float)
        self.controls = np.asarray(self.controls, dtype=float)
        T = self.t.size
        if self.states.shape != (T, 6) or self.controls.shape != (T, 2):
            raise TrialDataError(f'{self.source or self.name}: inconsistent shapes '
                                 f't {self.t.shape}, states {self.states.shape}, '
                                 f'controls {self.controls.shape}')
        for what in ('wind', 'thrusters'):
            a = getattr(self, what)
            if a is not None:
                a = np.asarray(a, dtype=float)
                if a.shape != (T, 2):
                    raise TrialDataError(f'{self.source or self.name}: {what} must be (T, 2), '
                                         f'got {a.shape}')
                setattr(self, what, a)

    @classmethod
    def from_inputs(cls, t, states, inputs, **kw) -> 'Trial':
        """Return a trial from an input array whose columns follow ``core/channels.CHANNELS``."""
        inputs = np.asarray(inputs, dtype=float)
        n = inputs.shape[1]
        wind = inputs[:, 2:4] if n > WIND_E else None
        if wind is not None and np.all(np.isnan(wind)):
            wind = None
        thr = inputs[:, 4:6] if n > STERN_THRUSTER else None
        return cls(t, states, inputs[:, :2], wind=wind, thrusters=thr, **kw)

    @property
    def inputs(self) -> np.ndarray:
        """
        Return what drives a simulation, columns in ``CHANNELS`` order.

        (T, 2) rpm, rudder; (T, 4) with the measured wind's north/east components when the trial
        has it (the kernels then use it instead of the wind parameters); (T, 6) with thrusters
        (wind NaN if not measured).
        """
        if self.wind is None and self.thrusters is None:
            return self.controls
        cols = [self.controls,
                self.wind if self.wind is not None else np.full((len(self), 2), np.nan)]
        if self.thrusters is not None:
            cols.append(self.thrusters)
        return np.column_stack(cols)

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

    def __getitem__(self, name: str) -> np.ndarray:
        if name == 't':
            return self.t
        if name in STATE_NAMES:
            return self.states[:, STATE_NAMES.index(name)]
        if name in CONTROL_NAMES:
            return self.controls[:, CONTROL_NAMES.index(name)]
        if name in CHANNELS:
            inp = self.inputs
            j = CHANNELS.index(name)
            if j < inp.shape[1]:
                return inp[:, j]
        raise KeyError(name)

    def _map_series(self, fn) -> dict:
        return {k: None if getattr(self, k) is None else fn(getattr(self, k))
                for k in ('wind', 'thrusters')}

    def slice(self, start_s: float, end_s: float | None = None,  # noqa: A003  public API name
              name: str | None = None
              ) -> 'Trial':
        """Return the part between start_s and end_s (trial time, inclusive)."""
        end_s = self.t[-1] if end_s is None else end_s
        k = (self.t >= start_s - 1e-9) & (self.t <= end_s + 1e-9)
        return replace(self, t=self.t[k], states=self.states[k], controls=self.controls[k],
                       name=name or self.name, notes=list(self.notes),
                       **self._map_series(lambda a: a[k]))

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
        ctrl = self.controls.copy()
        ctrl[:, 0] *= s
        return replace(self, t=self.t / s, states=st, controls=ctrl,
                       wind=None if self.wind is None else self.wind / s,
                       thrusters=None if self.thrusters is None else self.thrusters * s,
                       notes=self.notes + [f'Froude-scaled by 1/{ratio:g}'])

    def resampled(self, dt: float) -> 'Trial':
        """Return the trial resampled to step dt (linear interpolation, heading unwrapped)."""
        n = int(math.floor(self.duration_s / dt + 1e-9)) + 1
        grid = self.t[0] + dt * np.arange(n)

        def interp(a):
            return np.column_stack([np.interp(grid, self.t, a[:, i]) for i in range(a.shape[1])])

        return replace(self, t=grid, states=interp(self.states), controls=interp(self.controls),
                       **self._map_series(interp),
                       notes=self.notes + [f'resampled on dt = {dt:g} s (linear)'])


Trajectory = Trial
"""The former name of a simulated history (same type)."""


def fitted_first_state(trial: Trial, window_s: float) -> np.ndarray:
    """
    Return the state a simulation of a recorded trial starts from.

    A quadratic least-squares fit of each state over the first window_s seconds, evaluated at
    t0 (the raw first sample when window_s <= 0 or fewer than 4 samples lie in the window): the
    one initial-state rule of the objective, the reports, ``mt.simulate`` and the hybrid.
    """
    k = int(np.searchsorted(trial.t, trial.t[0] + window_s, side='right'))
    if window_s <= 0 or k < 4:
        return trial.states[0].copy()
    t = trial.t[:k] - trial.t[0]
    A = np.column_stack([np.ones(k), t, t * t])
    coef, *_ = np.linalg.lstsq(A, trial.states[:k], rcond=None)
    return coef[0]
