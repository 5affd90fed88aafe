"""Effects: small physical model extensions with named parameters, bounds and units.

Each effect's parameters are slots of the flat parameter vector (layout.py) that the compiled
kernels already honour; at their neutral values the effect vanishes. Rules for a new effect:
1. its parameters get slots in layout._EFFECTS with a neutral value in EFFECT_NEUTRAL;
2. the kernels (mmg.advance / accelerations / observe / start_state) implement it;
3. it is registered here with bounds that cover realistic magnitudes;
4. generation applies it (core/maneuvers.py via the kernels, data/generate.py for recording
   effects such as time_offset), and a test hides it and requires the diagnosis to find it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from mmg_tuner.core.ship import ShipConfig


@dataclass(frozen=True)
class Effect:
    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    description: str

    def bounds(self, ship: ShipConfig) -> list[tuple[float, float]]:
        return [_BOUNDS[p](ship) for p in self.params]


_BOUNDS = {
    'current_speed': lambda s: (0.0, 1.5),                      # m/s
    'current_dir': lambda s: (-math.pi, math.pi),               # rad, toward, clockwise from N
    'rudder_offset': lambda s: (-math.radians(5), math.radians(5)),
    'rudder_lag_tau': lambda s: (0.0, 20.0),                    # s
    'rpm_scale': lambda s: (0.85, 1.15),
    'yaw_moment_bias': lambda s: (-0.005, 0.005),               # N'_0
    'antenna_x': lambda s: (-0.5 * s.L_pp, 0.5 * s.L_pp),       # m, forward of midship
    'antenna_y': lambda s: (-0.5 * s['B'], 0.5 * s['B']),       # m, to starboard
    'time_offset': lambda s: (-3.0, 3.0),                       # s, commands lag the state
}

EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect('current', ('current_speed', 'current_dir'), ('m/s', 'rad'),
           'uniform steady current; hull, propeller and rudder see the velocity through the '
           'water, positions move with the water'),
    Effect('rudder_offset', ('rudder_offset',), ('rad',),
           'constant error between indicated and actual rudder angle (actual = indicated + '
           'offset)'),
    Effect('rudder_lag', ('rudder_lag_tau',), ('s',),
           'first-order steering-gear lag between the recorded rudder and the actual angle'),
    Effect('rpm_scale', ('rpm_scale',), ('-',),
           'shaft-speed measurement scale error (actual = scale x recorded)'),
    Effect('yaw_moment_bias', ('yaw_moment_bias',), ('-',),
           "constant yaw moment N'_0 (x 1/2 rho L^2 d U^2): asymmetry not in the model, e.g. "
           'propeller side force'),
    Effect('antenna_offset', ('antenna_x', 'antenna_y'), ('m', 'm'),
           'positions recorded at a GNSS antenna away from midship and not moved there'),
    Effect('time_offset', ('time_offset',), ('s',),
           'delay between the command topics and the state topic (commands act time_offset '
           'seconds after their stamps)'),
)}


def describe_values(effect: Effect, values: dict[str, float],
                    errors: dict[str, float] | None = None) -> str:
    """Human wording, e.g. 'current 0.34 +- 0.03 m/s toward 112 +- 4 deg'."""
    errors = errors or {}

    def pm(name, scale=1.0, fmt='.3g'):
        v = values[name] * scale
        e = errors.get(name)
        return f'{v:{fmt}}' + (f' ± {abs(e * scale):.2g}' if e is not None else '')

    n = effect.name
    if n == 'current':
        d = dict(values)
        d['current_dir'] = math.degrees(values['current_dir']) % 360.0
        e = dict(errors)
        if 'current_dir' in e:
            e['current_dir'] = math.degrees(e['current_dir'])
        return (f"current {pm('current_speed', fmt='.2f')} m/s toward "
                f"{d['current_dir']:.0f}" + (f" ± {abs(e['current_dir']):.2g}" if 'current_dir' in e
                                              else '') + ' deg')
    if n == 'rudder_offset':
        return f"rudder offset {pm('rudder_offset', math.degrees(1), '.2f')} deg"
    if n == 'rudder_lag':
        return f"steering-gear lag {pm('rudder_lag_tau', fmt='.1f')} s"
    if n == 'rpm_scale':
        return f"rpm scale {pm('rpm_scale', fmt='.3f')}"
    if n == 'yaw_moment_bias':
        return f"yaw moment bias N'_0 = {pm('yaw_moment_bias', fmt='.2e')}"
    if n == 'antenna_offset':
        return (f"GNSS antenna {pm('antenna_x', fmt='.1f')} m forward, "
                f"{pm('antenna_y', fmt='.1f')} m to starboard of midship")
    if n == 'time_offset':
        return f"commands lag the state by {pm('time_offset', fmt='.2f')} s"
    return n
