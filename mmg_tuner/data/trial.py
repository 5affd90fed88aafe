"""The trial type used everywhere downstream."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.errors import TrialDataError

CSV_COLUMNS = ('t',) + STATE_NAMES + ('rpm', 'rudder')


@dataclass
class Trial:
    """A recorded (or generated) trial on a uniform time grid, in the model frame, SI units.

    t [s] (T,); states (T, 6) = x_E, y_E [m], psi [rad, unwrapped], u, v [m/s over ground],
    r [rad/s]; controls (T, 2) = rpm [rev/min], rudder [rad, + to starboard];
    wind (T, 2) or None = measured true wind as the air's velocity over ground, north and east
    components [m/s] (a vector, so it resamples without angle wrap-around).
    """

    t: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    name: str = 'trial'
    source: str = ''
    notes: list[str] = field(default_factory=list)
    start_s: float = 0.0  # where t = 0 lies in the recording it came from [s]
    wind: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.states = np.asarray(self.states, dtype=float)
        self.controls = np.asarray(self.controls, dtype=float)
        T = self.t.size
        if self.states.shape != (T, 6) or self.controls.shape != (T, 2):
            raise TrialDataError(f'{self.source or self.name}: inconsistent shapes t {self.t.shape},'
                                 f' states {self.states.shape}, controls {self.controls.shape}')
        if self.wind is not None:
            self.wind = np.asarray(self.wind, dtype=float)
            if self.wind.shape != (T, 2):
                raise TrialDataError(f'{self.source or self.name}: wind must be (T, 2) north/east '
                                     f'components, got {self.wind.shape}')

    @property
    def inputs(self) -> np.ndarray:
        """What drives a simulation: (T, 2) rpm, rudder, or (T, 4) with the measured wind's
        north/east components when the trial has it (the kernels then use it instead of the
        wind parameters)."""
        if self.wind is None:
            return self.controls
        return np.column_stack([self.controls, self.wind])

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
        if name in ('rpm', 'rudder'):
            return self.controls[:, 0 if name == 'rpm' else 1]
        raise KeyError(name)

    def slice(self, start_s: float, end_s: float | None = None, name: str | None = None
              ) -> 'Trial':
        """The part between start_s and end_s (trial time, inclusive)."""
        end_s = self.t[-1] if end_s is None else end_s
        k = (self.t >= start_s - 1e-9) & (self.t <= end_s + 1e-9)
        return replace(self, t=self.t[k], states=self.states[k], controls=self.controls[k],
                       name=name or self.name, notes=list(self.notes),
                       wind=None if self.wind is None else self.wind[k])

    def froude_scaled(self, ratio: float) -> 'Trial':
        """Scale by 1/ratio in length (ratio = L_from / L_to), Froude similarity: time and
        velocity by 1/sqrt(ratio), yaw rate and rpm by sqrt(ratio)."""
        s = math.sqrt(ratio)
        st = self.states.copy()
        st[:, :2] /= ratio
        st[:, 3:5] /= s
        st[:, 5] *= s
        ctrl = self.controls.copy()
        ctrl[:, 0] *= s
        return replace(self, t=self.t / s, states=st, controls=ctrl,
                       wind=None if self.wind is None else self.wind / s,
                       notes=self.notes + [f'Froude-scaled by 1/{ratio:g}'])

    def resampled(self, dt: float) -> 'Trial':
        """The trial on a uniform grid of step dt (linear interpolation, heading unwrapped)."""
        n = int(math.floor(self.duration_s / dt + 1e-9)) + 1
        grid = self.t[0] + dt * np.arange(n)
        st = np.column_stack([np.interp(grid, self.t, self.states[:, i]) for i in range(6)])
        ctrl = np.column_stack([np.interp(grid, self.t, self.controls[:, i]) for i in range(2)])
        wind = None if self.wind is None else np.column_stack(
            [np.interp(grid, self.t, self.wind[:, i]) for i in range(2)])
        return replace(self, t=grid, states=st, controls=ctrl, wind=wind,
                       notes=self.notes + [f'resampled on dt = {dt:g} s (linear)'])
