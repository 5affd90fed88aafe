"""The search space: which parameters are tuned and inside which box."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import TuningError
import numpy as np


@dataclass(frozen=True)
class ParameterSpace:
    """
    Tuned parameters with their pre-determined values and box bounds.

    The optimiser works in the unit box: z = (theta - lower) / (upper - lower).
    """

    names: tuple[str, ...]
    pre: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def around(cls, ship: ShipConfig, names: Sequence[str] | None = None, a_r: float | None = None,
               overrides: Mapping[str, float | tuple[float, float]] | None = None
               ) -> 'ParameterSpace':
        """
        Return the box theta_pre +- a_r |theta_pre| per parameter, or the ship's own box.

        Box theta_pre +- a_r |theta_pre| per parameter (paper section 4), or the ship's own
        absolute box where its YAML gives one (``tuning.bounds``, ``ship.tuning_bounds``: it keeps
        a coefficient's physical sign, which +-a_r around a small value may not). overrides maps a
        name to its own a_r, or to explicit (lower, upper) bounds; they win over both.
        """
        names = tuple(names or ship.tuning_targets)
        if not names:
            raise TuningError(f'{ship.name}: no tuning targets given or configured')
        a_r = ship.a_r if a_r is None else float(a_r)
        if not 0 < a_r:
            raise TuningError(f'a_r must be positive, got {a_r}')
        overrides = dict(overrides or {})
        pre, lo, hi = [], [], []
        for n in names:
            if n not in PARAM_INDEX:
                raise TuningError(f'unknown tuning target {n!r}')
            v = ship[n]
            o = overrides.pop(n, None)
            if isinstance(o, tuple):
                low, up = float(o[0]), float(o[1])
            elif o is None and n in ship.tuning_bounds:
                low, up = (float(b) for b in ship.tuning_bounds[n])
            else:
                a = a_r if o is None else float(o)
                low, up = v - a * abs(v), v + a * abs(v)
            if not up > low:
                raise TuningError(f'{n}: empty box [{low}, {up}] (pre-determined value {v}); '
                                  'give explicit bounds for parameters that are zero')
            if not low <= v <= up:
                raise TuningError(f'{n}: pre-determined value {v} outside its box [{low}, {up}]')
            pre.append(v)
            lo.append(low)
            hi.append(up)
        if overrides:
            raise TuningError('bounds given for parameters that are not tuned: '
                              f'{sorted(overrides)}')
        if len(set(names)) != len(names):
            raise TuningError(f'duplicate tuning targets in {names}')
        return cls(names, np.array(pre), np.array(lo), np.array(hi))

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def indices(self) -> np.ndarray:
        return np.array([PARAM_INDEX[n] for n in self.names])

    def to_unit(self, theta: np.ndarray) -> np.ndarray:
        z: np.ndarray = (theta - self.lower) / (self.upper - self.lower)
        return z

    def from_unit(self, z: np.ndarray) -> np.ndarray:
        theta: np.ndarray = self.lower + np.clip(z, 0.0, 1.0) * (self.upper - self.lower)
        return theta

    def full_params(self, base: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """
        Return parameter vectors (N, N_PARAMS).

        They are base with the tuned entries replaced by theta (N, d).
        """
        theta = np.atleast_2d(theta)
        out = np.tile(base, (theta.shape[0], 1))
        out[:, self.indices] = theta
        return out

    def on_bound(self, theta: np.ndarray, tol: float = 1e-3) -> list[str]:
        """Names whose value lies within tol (fraction of the box width) of a bound."""
        z = self.to_unit(theta)
        return [n for n, zi in zip(self.names, z) if zi < tol or zi > 1 - tol]


def moved_truth(ship: ShipConfig, seed: int = 5, spread: float = 0.6,
                extra: Mapping[str, float] | None = None, space: ParameterSpace | None = None
                ) -> tuple[ShipConfig, ParameterSpace, np.ndarray]:
    """
    Return (truth, space, theta): the ship with its targets moved inside their box.

    A synthetic truth for tuning benchmarks and tests: each target of ``space`` (default
    ``ParameterSpace.around(ship)``) moved by a uniform draw of up to ``spread`` times the
    box's upper half-width (seeded), so a tuner starting from the pre-determined values has
    something to find. ``extra`` sets further parameters of the truth the model does not tune
    (e.g. a hidden ``rudder_lag_tau``).
    """
    space = ParameterSpace.around(ship) if space is None else space
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-spread, spread, space.dim)
    values = dict(zip(space.names, theta))
    values.update(extra or {})
    return ship.with_params(values), space, theta
