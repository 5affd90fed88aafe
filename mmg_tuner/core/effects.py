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

from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.core.ship import ShipConfig


@dataclass(frozen=True)
class Effect:
    name: str
    params: tuple[str, ...]
    units: tuple[str, ...]
    description: str
    # the smallest magnitude of each parameter worth finding (a realistic small error) at full
    # scale, measured from the neutral value; 0 for directions
    smallest: tuple[float, ...] = ()

    def bounds(self, ship: ShipConfig) -> list[tuple[float, float]]:
        return [_BOUNDS[p](ship) for p in self.params]

    def smallest_for(self, ship: ShipConfig) -> tuple[float, ...]:
        """The smallest magnitudes Froude-scaled to the ship's scale (times and speeds by
        1/sqrt(ratio), lengths by 1/ratio)."""
        r = ship.scale_ratio
        scale = {'s': 1 / math.sqrt(r), 'm/s': 1 / math.sqrt(r), 'm': 1 / r}
        return tuple(v * scale.get(u, 1.0) for v, u in zip(self.smallest, self.units))

    def too_small(self, ship: ShipConfig, values: dict[str, float]) -> bool:
        """Whether every sized parameter is below the smallest magnitude worth finding (an
        effect that small is noise-fitting, not a cause)."""
        sized = [(p, s) for p, s in zip(self.params, self.smallest_for(ship)) if s > 0]
        return bool(sized) and all(abs(values[p] - EFFECT_NEUTRAL[p]) < s for p, s in sized)


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
    # up to Beaufort 7 at full scale (Froude-scaled for a model)
    'wind_speed': lambda s: (0.0, 17.0 / math.sqrt(s.scale_ratio)),  # m/s
    'wind_dir': lambda s: (-math.pi, math.pi),                  # rad, from, clockwise from N
    'prop_side_force': lambda s: (-0.03, 0.03),                 # C_YPS, ~15 % of K_T at most
}

EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect('current', ('current_speed', 'current_dir'), ('m/s', 'rad'),
           'uniform steady current; hull, propeller and rudder see the velocity through the '
           'water, positions move with the water',
           smallest=(0.1, 0.0)),
    Effect('rudder_offset', ('rudder_offset',), ('rad',),
           'constant error between indicated and actual rudder angle (actual = indicated + '
           'offset)',
           smallest=(math.radians(1.0),)),
    Effect('rudder_lag', ('rudder_lag_tau',), ('s',),
           'first-order steering-gear lag between the recorded rudder and the actual angle',
           smallest=(2.0,)),
    Effect('rpm_scale', ('rpm_scale',), ('-',),
           'shaft-speed measurement scale error (actual = scale x recorded)',
           smallest=(0.03,)),
    Effect('yaw_moment_bias', ('yaw_moment_bias',), ('-',),
           "constant yaw moment N'_0 (x 1/2 rho L^2 d U^2): asymmetry not in the model, e.g. "
           'propeller side force',
           smallest=(0.0005,)),
    Effect('antenna_offset', ('antenna_x', 'antenna_y'), ('m', 'm'),
           'positions recorded at a GNSS antenna away from midship and not moved there',
           smallest=(5.0, 1.0)),
    Effect('time_offset', ('time_offset',), ('s',),
           'delay between the command topics and the state topic (commands act time_offset '
           'seconds after their stamps)',
           smallest=(0.5,)),
    Effect('prop_side_force', ('prop_side_force',), ('-',),
           'propeller side force (paddle-wheel effect) Y = C_YPS rho n^2 D_P^4 at the stern: '
           'a turning asymmetry that grows with the propeller load, not with speed',
           smallest=(0.003,)),
    Effect('wind', ('wind_speed', 'wind_dir'), ('m/s', 'rad'),
           'steady true wind on the above-water ship; loads from the windage areas with '
           "Blendermann's (1994) coefficients",
           smallest=(5.0, 0.0)),
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
    if n == 'prop_side_force':
        return (f"propeller side force C_YPS = {pm('prop_side_force', fmt='.2e')} "
                f"(+: stern pushed to starboard)")
    if n == 'wind':
        e = errors.get('wind_dir')
        return (f"wind {pm('wind_speed', fmt='.1f')} m/s from "
                f"{math.degrees(values['wind_dir']) % 360.0:.0f}"
                + (f' ± {math.degrees(abs(e)):.2g}' if e is not None else '') + ' deg')
    if n == 'time_offset':
        return f"commands lag the state by {pm('time_offset', fmt='.2f')} s"
    return n
