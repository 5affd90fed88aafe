"""
Actuator ``tunnel_thrusters``: a bow and a stern tunnel thruster, commanded speeds acting at once.

Inputs and outputs are the thruster speeds [rev/s] (+ pushes to starboard); the family's force
formulas turn them into side force and moment (the Esso Osaka's, ``core/models/lowspeed.py``).
A trial that did not record them runs with the thrusters stopped (the channels' default 0).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

PARAMS = ()
INPUTS = ('bow_thruster', 'stern_thruster')
CHANNELS: dict[str, tuple[str, str, str | None]] = {}   # base channels (core/channels.py)
OUTPUTS = ('n_bow', 'n_stern')
STATES = ()
DESCRIPTION = 'bow and stern tunnel thrusters [rev/s], no lag'

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations)
from mmg_tuner.core.layout import OK  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray


@njit(cache=True, fastmath=FASTMATH, inline='always')
def start(p: FloatArray, cmd: tuple[float, ...], a: FloatArray, i: int) -> None:
    """No internal state."""
    return


@njit(cache=True, fastmath=FASTMATH, inline='always')
def hold(p: FloatArray, cmd: tuple[float, ...], h: float,
         astern: bool) -> tuple[int, tuple[float, ...]]:
    """Return the held speeds."""
    return OK, cmd


@njit(cache=True, fastmath=FASTMATH, inline='always')
def output(p: FloatArray, held: tuple[float, ...], a: FloatArray, i: int) -> tuple[float, ...]:
    """Return the held speeds: they act for the whole step."""
    return held
