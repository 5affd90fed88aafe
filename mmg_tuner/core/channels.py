"""
Named input channels: what drives a simulation, one column each.

A recorded or planned input array ``ctrl`` has shape (T, n) with its columns in
:data:`CHANNELS` order; trailing channels may be left out (n = 2 is rpm and rudder only):

* a left-out or NaN wind channel means "not measured": the wind parameters act instead;
* a left-out thruster channel means "no thruster" (0 rev/s).

A model family lists the channels it reads in its ``INPUTS``; adding an actuator is one more
name here (appended, so existing column positions never move) and the family that reads it.
The kernels turn the recorded channels into the *actuator vector* acting on the ship (after the
input effects: rpm scale, rudder offset and steering-gear lag), a tuple indexed by ``ACT_*``.
"""
from __future__ import annotations

CHANNELS: tuple[str, ...] = ('rpm', 'rudder', 'wind_n', 'wind_e', 'bow_thruster',
                             'stern_thruster')
"""rpm: propeller revolutions [rev/min] (+ ahead); rudder [rad] (+ turns to starboard);
wind_n, wind_e: measured true wind, the air's velocity over ground north/east [m/s];
bow_thruster, stern_thruster: thruster revolutions [rev/s] (+ pushes the ship to starboard)."""
UNITS = {'rpm': 'rev/min', 'rudder': 'rad', 'wind_n': 'm/s', 'wind_e': 'm/s',
         'bow_thruster': 'rev/s', 'stern_thruster': 'rev/s'}
CHANNEL_INDEX = {name: i for i, name in enumerate(CHANNELS)}

RPM = 0
RUDDER = 1
WIND_N = 2
WIND_E = 3
BOW_THRUSTER = 4
STERN_THRUSTER = 5

CONTROL_NAMES = CHANNELS[:2]
"""The two channels every trial has (the columns of ``Trial.controls``)."""

# Actuator vector handed to a family's forces (a tuple, so it lives in registers):
ACT_N = 0       # propeller revolutions n_P [rev/s] after the rpm scale
ACT_DELTA = 1   # actual rudder angle [rad] after offset and steering-gear lag
ACT_BOW = 2     # bow thruster [rev/s]
ACT_STERN = 3   # stern thruster [rev/s]
N_ACT = 4


def n_columns(names) -> int:
    """Columns an input array needs to hold the given channels (their highest position + 1)."""
    return max(CHANNEL_INDEX[n] for n in names) + 1
