"""
Effects: small physical model extensions, each declared once, here.

An effect is one :class:`Effect` entry in :data:`EFFECTS`. It declares, for each of its
parameters, the neutral value at which it vanishes, the search box, whether the parameter is a
direction (periodic over 2 pi), the smallest magnitude worth finding, the unit, and a
description of the physics. Everything else derives from this table: the parameter layout
(``layout.EFFECT_NEUTRAL`` and the effect slots of the flat vector), the defaults a ship file
may omit, the diagnosis' search boxes, and the contract test (test/core/test_core_contracts.py)
that checks every entry (neutral values make the simulation equal the plain model, neutral and
smallest magnitudes lie inside the box, the description formats).

Boxes and smallest magnitudes are written at full scale and Froude-scaled to the ship
(``ShipConfig.scale_ratio``): lengths by 1/ratio, times and speeds by 1/sqrt(ratio);
dimensionless values and angles are unchanged. A box that depends on the ship's size (an
antenna within the hull) is a function of the ship instead.

Adding an effect: an entry here, and its hook in the kernels (``core/dynamics.py`` for forces
and the current/wind kinematics, ``core/integrate.py`` for inputs and observations); the
generator and the diagnosis pick it up from this table. Keep this module free of kernel
imports: ``layout`` reads it.
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


def _pm(values: dict[str, float], errors: dict[str, float], name: str, scale: float = 1.0,
        fmt: str = '.3g') -> str:
    v = values[name] * scale
    e = errors.get(name)
    return f'{v:{fmt}}' + (f' ± {abs(e * scale):.2g}' if e is not None else '')


def _direction(values: dict[str, float], errors: dict[str, float], name: str) -> str:
    e = errors.get(name)
    return (f'{math.degrees(values[name]) % 360.0:.0f}'
            + (f' ± {math.degrees(abs(e)):.2g}' if e is not None else '') + ' deg')


_PI = (-math.pi, math.pi)

EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect('current', ('current_speed', 'current_dir'), ('m/s', 'rad'),
           'uniform steady current; hull, propeller and rudder see the velocity through the '
           'water, positions move with the water',
           smallest=(0.1, 0.0), neutral=(0.0, 0.0), boxes=((0.0, 1.5), _PI),
           periodic=(False, True),
           words=lambda v, e: (f"current {_pm(v, e, 'current_speed', fmt='.2f')} m/s toward "
                               + _direction(v, e, 'current_dir'))),
    Effect('rudder_offset', ('rudder_offset',), ('rad',),
           'constant error between indicated and actual rudder angle (actual = indicated + '
           'offset)',
           smallest=(math.radians(1.0),), neutral=(0.0,),
           boxes=((-math.radians(5), math.radians(5)),), periodic=(False,),
           words=lambda v, e: f"rudder offset {_pm(v, e, 'rudder_offset', math.degrees(1), '.2f')}"
                              ' deg',
           settle_by='check the rudder indicator against the blade (amidships and hard over '
                     'each side) in port', actuator='screw_rudder'),
    Effect('rudder_lag', ('rudder_lag_tau',), ('s',),
           'first-order steering-gear lag between the recorded rudder and the actual angle',
           smallest=(2.0,), neutral=(0.0,), boxes=((0.0, 20.0),), periodic=(False,),
           words=lambda v, e: f"steering-gear lag {_pm(v, e, 'rudder_lag_tau', fmt='.1f')} s",
           settle_by='log the rudder-angle feedback (the actual blade angle) beside the '
                     'order, or time a hard-over test of the steering gear',
           actuator='screw_rudder'),
    Effect('rpm_scale', ('rpm_scale',), ('-',),
           'shaft-speed measurement scale error (actual = scale x recorded)',
           smallest=(0.03,), neutral=(1.0,), boxes=((0.85, 1.15),), periodic=(False,),
           words=lambda v, e: f"rpm scale {_pm(v, e, 'rpm_scale', fmt='.3f')}",
           # n -> k n is reproduced by 1 - w_P -> (1 - w_P) / k, 1 - t_P -> k^2 (1 - t_P),
           # epsilon -> k epsilon: only the propulsion coefficients fixed elsewhere separate it
           settle_by='compare the logged rpm with a shaft tachometer (or an optical counter on '
                     'the shaft) over the rpm range, or fix R_0, t_P and w_P0 from resistance '
                     'and self-propulsion tests so the tuning cannot absorb the scale',
           # what those tests fix: the resistance, thrust deduction and wake at straight running.
           # t_P and w_P0 alone are not enough: near the propeller law (u ~ n, J near constant)
           # the mis-scaled thrust K_T(kJ) / (k^2 K_T(J)) is a near-constant factor, as is the
           # resistance's u^2, so a tuned R_0 absorbs it (resolution 0.14 -> 4.6 on two trials
           # when R_0 is held too); epsilon stays tuned: it maps only the rudder inflow
           pinned_by=('R_0', 't_P', 'w_P0'), actuator='screw_rudder'),
    Effect('yaw_moment_bias', ('yaw_moment_bias',), ('-',),
           "constant yaw moment N'_0 (x 1/2 rho L^2 d U^2): asymmetry not in the model, e.g. "
           'propeller side force',
           smallest=(0.0005,), neutral=(0.0,), boxes=((-0.005, 0.005),), periodic=(False,),
           words=lambda v, e: f"yaw moment bias N'_0 = {_pm(v, e, 'yaw_moment_bias', fmt='.2e')}",
           settle_by='hold a straight course at several speeds and rpm: the mean rudder '
                     'angle it takes, against speed and rpm, measures the bias'),
    Effect('antenna_offset', ('antenna_x', 'antenna_y'), ('m', 'm'),
           'positions recorded at a GNSS antenna away from midship and not moved there',
           smallest=(5.0, 1.0), neutral=(0.0, 0.0),
           boxes=(lambda s: (-0.5 * s.L_pp, 0.5 * s.L_pp),      # forward of midship
                  lambda s: (-0.5 * s['B'], 0.5 * s['B'])),     # to starboard
           periodic=(False, False),
           words=lambda v, e: (f"GNSS antenna {_pm(v, e, 'antenna_x', fmt='.1f')} m forward, "
                               f"{_pm(v, e, 'antenna_y', fmt='.1f')} m to starboard of midship")),
    Effect('time_offset', ('time_offset',), ('s',),
           'delay between the command topics and the state topic (commands act time_offset '
           'seconds after their stamps)',
           smallest=(0.5,), neutral=(0.0,), boxes=((-3.0, 3.0),), periodic=(False,),
           words=lambda v, e: ('commands lag the state by '
                               f"{_pm(v, e, 'time_offset', fmt='.2f')} s"),
           settle_by='put commands and positions on one clock (GNSS or PTP time stamps on '
                     'every topic), or log the rudder-angle feedback so the delay is measured '
                     'between the order and the blade'),
    Effect('prop_side_force', ('prop_side_force',), ('-',),
           'propeller side force (paddle-wheel effect) Y = C_YPS rho n^2 D_P^4 at the stern: '
           'a turning asymmetry that grows with the propeller load, not with speed',
           smallest=(0.003,), neutral=(0.0,),
           boxes=((-0.03, 0.03),),                              # ~15 % of K_T at most
           periodic=(False,),
           words=lambda v, e: (f'propeller side force C_YPS = '
                               f"{_pm(v, e, 'prop_side_force', fmt='.2e')} "
                               '(+: stern pushed to starboard)'),
           settle_by='measure the mean rudder angle that holds a straight course at several '
                     'rpm from the same speed (a side force grows with n^2, a yaw bias with '
                     'U^2), or the side force in a bollard-pull or open-water test',
           actuator='screw_rudder'),
    Effect('wind', ('wind_speed', 'wind_dir'), ('m/s', 'rad'),
           'steady true wind on the above-water ship; loads from the windage areas with '
           "the family's wind model",
           smallest=(5.0, 0.0), neutral=(0.0, 0.0),
           boxes=((0.0, 17.0), _PI),                            # up to Beaufort 7
           periodic=(False, True),
           words=lambda v, e: (f"wind {_pm(v, e, 'wind_speed', fmt='.1f')} m/s from "
                               + _direction(v, e, 'wind_dir'))),
) + tuple(
    # an azimuth thruster whose angle indicator is off: the angle that acts is the recorded
    # (or commanded) one plus the offset; one effect per thruster, as a fault is on one
    Effect(f'azimuth_offset_{side}', (f'azimuth_offset_{side}',), ('rad',),
           f'constant error between the recorded and the actual angle of the {side} azimuth '
           'thruster (actual = recorded + offset)',
           smallest=(math.radians(1.0),), neutral=(0.0,),
           boxes=((-math.radians(5), math.radians(5)),), periodic=(False,),
           words=lambda v, e, side=side: (  # type: ignore[misc]  # side= defeats inference
               f'{side} azimuth offset '
               f"{_pm(v, e, f'azimuth_offset_{side}', math.degrees(1), '.2f')} deg"),
           settle_by=f'point the {side} thruster ahead (its indicator at 0) and check the '
                     'thrust direction, or log the bollard pull at 0 and +-90 deg',
           actuator='twin_azimuth')
    for side in ('port', 'stbd')
) + tuple(
    # a fouled (or damaged) propeller: less thrust than its bollard-pull curve at the same
    # shaft speed. Above 1 only as far as the bollard table's own error: a clean propeller
    # gives no more than it did on the test (a fit pinned at 1.1 absorbs something else)
    Effect(f'thrust_scale_{side}', (f'thrust_scale_{side}',), ('-',),
           f'the {side} thruster gives this fraction of its bollard-pull thrust at the same '
           'shaft speed (below 1: a fouled or damaged propeller)',
           smallest=(0.05,), neutral=(1.0,), boxes=((0.5, 1.1),), periodic=(False,),
           words=lambda v, e, side=side: (  # type: ignore[misc]  # side= defeats inference
               f"{side} thrust scale {_pm(v, e, f'thrust_scale_{side}', fmt='.3f')} "
               '(of the bollard-pull curve)'),
           settle_by=f'repeat the bollard-pull test of the {side} thruster (or inspect its '
                     'propeller for fouling)',
           actuator='twin_azimuth')
    for side in ('port', 'stbd')
)}

PARAM_NEUTRAL: dict[str, float] = {p: n for e in EFFECTS.values()
                                   for p, n in zip(e.params, e.neutral)}
"""Every effect parameter and its neutral value, in registry order (the layout's effect slots)."""


def describe_values(effect: Effect, values: dict[str, float],
                    errors: dict[str, float] | None = None) -> str:
    """
    Human wording, e.g.

    'current 0.34 ± 0.03 m/s toward 112 ± 4 deg'.
    """
    return effect.words(values, errors or {})
