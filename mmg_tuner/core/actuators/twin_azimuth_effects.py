"""
The effects of ``twin_azimuth``: a thruster's angle indicator off, a fouled propeller.

Declared here (``EFFECTS`` in ``twin_azimuth.py`` names this module) and collected into the
effect table (``core/effects.py``) after the library's own, so the layout's slots keep their
order; each acts in the actuator's kernel (``azimuth_offset_<side>``, ``thrust_scale_<side>``).
"""
from __future__ import annotations

import math

from mmg_tuner.core.effect import Effect, pm

EFFECTS: tuple[Effect, ...] = tuple(
    # an azimuth thruster whose angle indicator is off: the angle that acts is the recorded
    # (or commanded) one plus the offset; one effect per thruster, as a fault is on one
    Effect(f'azimuth_offset_{side}', (f'azimuth_offset_{side}',), ('rad',),
           f'constant error between the recorded and the actual angle of the {side} azimuth '
           'thruster (actual = recorded + offset)',
           smallest=(math.radians(1.0),), neutral=(0.0,),
           boxes=((-math.radians(5), math.radians(5)),), periodic=(False,),
           words=lambda v, e, side=side: (  # type: ignore[misc]  # side= defeats inference
               f'{side} azimuth offset '
               f"{pm(v, e, f'azimuth_offset_{side}', math.degrees(1), '.2f')} deg"),
           settle_by=f'point the {side} thruster ahead (its indicator at 0) and check the '
                     'thrust direction, or log the bollard pull at 0 and +-90 deg')
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
               f"{side} thrust scale {pm(v, e, f'thrust_scale_{side}', fmt='.3f')} "
               '(of the bollard-pull curve)'),
           settle_by=f'repeat the bollard-pull test of the {side} thruster (or inspect its '
                     'propeller for fouling)')
    for side in ('port', 'stbd')
)
