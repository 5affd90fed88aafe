"""
The effect type: one small physical model extension, declared as data (``core/effects.py``).

Kept apart from the table so that an actuator's own effects (``EFFECTS`` in a module its
actuator names, ``core/actuators/__init__.py``) can be declared beside the actuator without
importing the table that collects them. Free of kernel imports: ``layout`` reads the table.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Callable, TYPE_CHECKING, Union

if TYPE_CHECKING:
    from mmg_tuner.core.ship import ShipConfig

# A box: (lo, hi) at full scale (Froude-scaled by unit), or a function of the ship.
Box = Union[tuple[float, float], Callable[['ShipConfig'], tuple[float, float]]]

_FROUDE_EXPONENT = {'m': 1.0, 's': 0.5, 'm/s': 0.5}  # value_model = value_full / ratio**exp


def froude_factor(unit: str, ratio: float) -> float:
    """Factor taking a full-scale value in this unit to a model of scale 1:ratio."""
    return float(ratio ** -_FROUDE_EXPONENT.get(unit, 0.0))  # typeshed: float ** float is Any


@dataclass(frozen=True)
class Effect:
    """
    One effect.

    Per-parameter tuples run parallel to ``params``.

    Attributes
    ----------
    name: effect name (what ``diagnose --effects`` takes).
    params: names of its slots in the flat parameter vector.
    units: unit of each parameter ('m', 's', 'm/s' are Froude-scaled; 'rad', '-' are not).
    description: the physics, in one sentence.
    smallest: smallest magnitude worth finding, full scale, measured from neutral (0 for
        directions: they have no size).
    neutral: values at which the effect vanishes.
    boxes: search box of each parameter (see :data:`Box`).
    periodic: whether the parameter is a direction (wraps at +-pi).
    words: formats values (and optional standard errors) for people.
    settle_by: the independent measurement that settles the effect when no manoeuvre can
        (it is degenerate with the base targets for every trial); the diagnosis' advice
        quotes it. Empty: a trial is the way.
    pinned_by: the base coefficients that measurement fixes, when it is one (rpm_scale: a
        self-propulsion test gives t_P and w_P0): held at the measured values and dropped from
        the tuning targets, they can no longer absorb the effect. Empty when the measurement
        settles the effect itself (a tachometer, a common clock) rather than a coefficient.
    actuator: the actuator model (``core/actuators``) the effect acts in, whose kernel reads
        its slots (rudder_offset: ``screw_rudder``); a family without that actuator cannot show
        it, so the diagnosis leaves it out there. Empty: every family (a current, an antenna).

    """

    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    description: str
    smallest: tuple[float, ...]
    neutral: tuple[float, ...]
    boxes: tuple[Box, ...]
    periodic: tuple[bool, ...]
    words: Callable[[dict[str, float], dict[str, float]], str]
    settle_by: str = ''
    pinned_by: tuple[str, ...] = ()
    actuator: str = ''

    def __post_init__(self) -> None:
        n = len(self.params)
        for what in ('units', 'smallest', 'neutral', 'boxes', 'periodic'):
            if len(getattr(self, what)) != n:
                raise ValueError(f'effect {self.name}: {what} needs {n} entries')

    def bounds(self, ship: 'ShipConfig') -> list[tuple[float, float]]:
        """Return the search box of each parameter at the ship's scale."""
        out = []
        for box, unit in zip(self.boxes, self.units):
            if callable(box):
                lo, hi = box(ship)
                out.append((float(lo), float(hi)))
            else:
                f = froude_factor(unit, ship.scale_ratio)
                out.append((box[0] * f, box[1] * f))
        return out

    def smallest_for(self, ship: 'ShipConfig') -> tuple[float, ...]:
        """
        Return the smallest magnitudes Froude-scaled to the ship's scale.

        The smallest magnitudes Froude-scaled to the ship's scale (times and speeds by
        1/sqrt(ratio), lengths by 1/ratio).
        """
        return tuple(v * froude_factor(u, ship.scale_ratio)
                     for v, u in zip(self.smallest, self.units))

    def too_small(self, ship: 'ShipConfig', values: dict[str, float]) -> bool:
        """
        Tell whether every sized parameter is below the smallest magnitude worth finding.

        Whether every sized parameter is below the smallest magnitude worth finding (an effect that
        small is noise-fitting, not a cause).
        """
        sized = [(p, s, n) for p, s, n in zip(self.params, self.smallest_for(ship), self.neutral)
                 if s > 0]
        return bool(sized) and all(abs(values[p] - n) < s for p, s, n in sized)

    @property
    def neutral_values(self) -> dict[str, float]:
        return dict(zip(self.params, self.neutral))


def pm(values: dict[str, float], errors: dict[str, float], name: str, scale: float = 1.0,
        fmt: str = '.3g') -> str:
    v = values[name] * scale
    e = errors.get(name)
    return f'{v:{fmt}}' + (f' ± {abs(e * scale):.2g}' if e is not None else '')


def direction(values: dict[str, float], errors: dict[str, float], name: str) -> str:
    e = errors.get(name)
    return (f'{math.degrees(values[name]) % 360.0:.0f}'
            + (f' ± {math.degrees(abs(e)):.2g}' if e is not None else '') + ' deg')
