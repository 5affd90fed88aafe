"""
Actuator ``screw_rudder``: one propeller and one rudder behind a steering gear.

Inputs: the logged propeller revolutions [rev/min] and rudder angle [rad]. Outputs, what the
MMG formulas read: n_P [rev/s] and the actual rudder angle delta [rad]. Its internal state is
that actual angle. The effects acting between the log and the ship live here: rpm_scale (the
logged revolutions are off by a factor), rudder_offset (the rudder's zero is off) and
rudder_lag_tau (a first-order steering gear, exact over each integration step for a held
order), and the propeller's side force (prop_side_force, the paddle-wheel effect).
"""
from __future__ import annotations

PARAMS = ()   # its parameters are effects (core/effects.py): rpm_scale, rudder_offset, ...
INPUTS = ('rpm', 'rudder')
CHANNELS: dict[str, tuple[str, str, str | None]] = {}   # both are base channels (core/channels.py)
OUTPUTS = ('n_P', 'delta')
STATES = ('delta_actual',)
DESCRIPTION = 'propeller [rev/min] and rudder [rad] behind a first-order steering gear'

import math  # noqa: E402  (below the declarations the layout reads)
from typing import TYPE_CHECKING  # noqa: E402

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100
from mmg_tuner.core.layout import OK, PARAM_INDEX, RPM_NOT_POSITIVE  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

# the slots of its effects, then of the particulars the propeller's side force reads
_doff, _tau, _nscale, _CYP = (PARAM_INDEX[k] for k in (
    'rudder_offset', 'rudder_lag_tau', 'rpm_scale', 'prop_side_force'))
_rho, _DP, _xR, _L = (PARAM_INDEX[k] for k in ('rho', 'D_P', 'x_R', 'L_pp'))


@njit(cache=True, fastmath=FASTMATH, inline='always')
def rpm_status(n_rps: float, astern: bool) -> int:
    """OK or RPM_NOT_POSITIVE: n_P <= 0 (or NaN) is refused unless the family covers astern."""
    if n_rps > 0.0 or (astern and n_rps == n_rps):
        return OK
    return RPM_NOT_POSITIVE


@njit(cache=True, fastmath=FASTMATH, inline='always')
def start(p: FloatArray, cmd: tuple[float, ...], a: FloatArray, i: int) -> None:
    """Start the gear where the first logged angle (plus the offset) puts it."""
    a[i] = cmd[1] + p[_doff]


@njit(cache=True, fastmath=FASTMATH, inline='always')
def hold(p: FloatArray, cmd: tuple[float, ...], h: float,
         astern: bool) -> tuple[int, tuple[float, float, float]]:
    """(status, (n_P [rev/s], rudder order [rad], gear decay over h)) for the held inputs."""
    n_rps = cmd[0] * p[_nscale] / 60.0
    tau = p[_tau]
    decay = math.exp(-h / tau) if tau > 0.0 else 0.0
    return rpm_status(n_rps, astern), (n_rps, cmd[1] + p[_doff], decay)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def output(p: FloatArray, held: tuple[float, float, float], a: FloatArray,
           i: int) -> tuple[float, float]:
    """Steering gear: exact first-order response to the held order over one step."""
    delta_cmd = held[1]
    delta_act = delta_cmd + (a[i] - delta_cmd) * held[2]
    a[i] = delta_act
    return (held[0], delta_act)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float, act: tuple[float, ...],
           k: int) -> tuple[float, float, float]:
    """Propeller side force at the stern, scaling with n^2 like the thrust (0 by default)."""
    if p[_CYP] == 0.0:
        return 0.0, 0.0, 0.0
    n = act[k]
    YPS = p[_CYP] * p[_rho] * n * n * p[_DP] ** 4   # Y_PS = C_YPS rho n^2 D^4 at x_R
    return 0.0, YPS, YPS * p[_xR] * p[_L]
