"""
Effects: small physical model extensions, each declared once, in one table.

An effect is one :class:`Effect` (``core/effect.py``) entry in :data:`EFFECTS`: the
library's own below, then those the registered actuators declare beside themselves
(``EFFECTS`` modules, ``core/actuators/__init__.py``; a twin-azimuth thruster's angle offset
and thrust scale). It declares, for each of its
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

Adding an effect: an entry here (or in an actuator's ``EFFECTS`` module), and its hook in the
kernels (``core/dynamics.py`` for forces and the current/wind kinematics, ``core/integrate.py``
for inputs and observations); the generator and the diagnosis pick it up from this table. Keep
this module free of kernel imports: ``layout`` reads it.
"""
from __future__ import annotations

from dataclasses import replace
import math

from mmg_tuner.core.effect import Box, direction, Effect, froude_factor, pm

__all__ = ['Box', 'EFFECTS', 'Effect', 'PARAM_NEUTRAL', 'describe_values', 'froude_factor']


def _declared_by_actuators() -> list[Effect]:
    """
    Return the effects the registered actuators declare (``EFFECTS`` modules), theirs marked.

    After the library's own in registry order: a new one appends slots to the layout, the
    existing slots keep their places.
    """
    from mmg_tuner.core.actuators import load_companion, REGISTRY   # the registry, no kernel

    out: list[Effect] = []
    taken = {p: e.name for e in EFFECTS.values() for p in e.params}
    for name in REGISTRY:
        module = load_companion(name, 'EFFECTS')
        if module is None:
            continue
        for e in module.EFFECTS:
            clash = ([e.name] if e.name in EFFECTS or e.name in {o.name for o in out} else []) \
                + [f'parameter {p} (of {taken[p]})' for p in e.params if p in taken]
            if clash:   # a second declaration would silently replace the first one's slots
                raise ImportError(f'actuator {name!r}: its effect {e.name!r} ({module.__name__}) '
                                  f'takes a name already taken: {", ".join(clash)}')
            taken.update(dict.fromkeys(e.params, e.name))
            out.append(replace(e, actuator=name))
    return out


_PI = (-math.pi, math.pi)

EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect('current', ('current_speed', 'current_dir'), ('m/s', 'rad'),
           'uniform steady current; hull, propeller and rudder see the velocity through the '
           'water, positions move with the water',
           smallest=(0.1, 0.0), neutral=(0.0, 0.0), boxes=((0.0, 1.5), _PI),
           periodic=(False, True),
           words=lambda v, e: (f"current {pm(v, e, 'current_speed', fmt='.2f')} m/s toward "
                               + direction(v, e, 'current_dir'))),
    Effect('rudder_offset', ('rudder_offset',), ('rad',),
           'constant error between indicated and actual rudder angle (actual = indicated + '
           'offset)',
           smallest=(math.radians(1.0),), neutral=(0.0,),
           boxes=((-math.radians(5), math.radians(5)),), periodic=(False,),
           words=lambda v, e: f"rudder offset {pm(v, e, 'rudder_offset', math.degrees(1), '.2f')}"
                              ' deg',
           settle_by='check the rudder indicator against the blade (amidships and hard over '
                     'each side) in port', actuator='screw_rudder'),
    Effect('rudder_lag', ('rudder_lag_tau',), ('s',),
           'first-order steering-gear lag between the recorded rudder and the actual angle',
           smallest=(2.0,), neutral=(0.0,), boxes=((0.0, 20.0),), periodic=(False,),
           words=lambda v, e: f"steering-gear lag {pm(v, e, 'rudder_lag_tau', fmt='.1f')} s",
           settle_by='log the rudder-angle feedback (the actual blade angle) beside the '
                     'order, or time a hard-over test of the steering gear',
           actuator='screw_rudder'),
    Effect('rpm_scale', ('rpm_scale',), ('-',),
           'shaft-speed measurement scale error (actual = scale x recorded)',
           smallest=(0.03,), neutral=(1.0,), boxes=((0.85, 1.15),), periodic=(False,),
           words=lambda v, e: f"rpm scale {pm(v, e, 'rpm_scale', fmt='.3f')}",
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
           words=lambda v, e: f"yaw moment bias N'_0 = {pm(v, e, 'yaw_moment_bias', fmt='.2e')}",
           settle_by='hold a straight course at several speeds and rpm: the mean rudder '
                     'angle it takes, against speed and rpm, measures the bias'),
    Effect('antenna_offset', ('antenna_x', 'antenna_y'), ('m', 'm'),
           'positions recorded at a GNSS antenna away from midship and not moved there',
           smallest=(5.0, 1.0), neutral=(0.0, 0.0),
           boxes=(lambda s: (-0.5 * s.L_pp, 0.5 * s.L_pp),      # forward of midship
                  lambda s: (-0.5 * s['B'], 0.5 * s['B'])),     # to starboard
           periodic=(False, False),
           words=lambda v, e: (f"GNSS antenna {pm(v, e, 'antenna_x', fmt='.1f')} m forward, "
                               f"{pm(v, e, 'antenna_y', fmt='.1f')} m to starboard of midship")),
    Effect('time_offset', ('time_offset',), ('s',),
           'delay between the command topics and the state topic (commands act time_offset '
           'seconds after their stamps)',
           smallest=(0.5,), neutral=(0.0,), boxes=((-3.0, 3.0),), periodic=(False,),
           words=lambda v, e: ('commands lag the state by '
                               f"{pm(v, e, 'time_offset', fmt='.2f')} s"),
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
                               f"{pm(v, e, 'prop_side_force', fmt='.2e')} "
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
           words=lambda v, e: (f"wind {pm(v, e, 'wind_speed', fmt='.1f')} m/s from "
                               + direction(v, e, 'wind_dir'))),
)}
EFFECTS.update({e.name: e for e in _declared_by_actuators()})

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
