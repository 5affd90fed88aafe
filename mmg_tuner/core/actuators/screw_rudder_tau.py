"""
Actuator ``screw_rudder_tau``: one propeller and one rudder as control-oriented forces tau.

For the control-oriented families (M nu_dot + C(nu) nu + D(nu) nu = tau): the propeller and
rudder forces written as a few products of the recorded inputs and the surge speed, each with
one coefficient, so that tau is *linear in its coefficients* and the local step of
``tuning/lo_go.py`` identifies them together with the hull's, in one least-squares problem.
The form follows the MMG model's leading terms (doc/reference/esso_osaka_lowspeed_mmg.md
§5, §6) with everything that is not a product of a coefficient and the inputs dropped:

- surge thrust: X_P = T_nn n|n| + T_absn_u |n| u, the open-water K_T(J) = k_0 + k_1 J with
  J = (1 - w_P) u / (n D_P) multiplied out: T = (1 - t_P) rho D_P^4 (k_0 n^2 + k_1 n u
  (1 - w_P) / D_P); the k_2 J^2 term, proportional to u^2, is the hull's X_absu_u;
- rudder: the normal force grows with the inflow speed squared, which the ship's speed and the
  propeller's slipstream make up (u|u| and n_+^2 with n_+ = max(n, 0): a propeller turning
  astern blows no slipstream onto the rudder), times the angle:
  Y_R = (Y_uud u|u| + Y_nnd n_+^2) delta, N_R = (N_uud u|u| + N_nnd n_+^2) delta and its drag
  X_R = X_uudd u^2 delta^2.

Inputs: the logged propeller revolutions ``rpm`` [rev/min, signed] and rudder angle
``rudder`` [rad, + = starboard helm, which turns the ship to starboard: conventions.md], both
taken as acting (no steering gear: the Esso Osaka's pond runs log the actual angle).
Outputs: n [rev/s] and delta [rad]. Forces about the model's reference point (midship for the
Esso Osaka), body axes x forward, y to starboard, N clockwise. Expected signs: T_nn > 0
(thrust ahead at positive revolutions), Y_uud, Y_nnd < 0 and N_uud, N_nnd > 0 (a rudder aft
pushed to starboard pushes the stern to port: the bow turns to starboard), X_uudd < 0.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

PARAMS = ('T_nn', 'T_absn_u', 'X_uudd', 'Y_uud', 'Y_nnd', 'N_uud', 'N_nnd')
INPUTS = ('rpm', 'rudder')
CHANNELS: dict[str, tuple[str, str, str | None]] = {}   # both are base channels (core/channels.py)
OUTPUTS = ('n_P', 'delta')
STATES = ()
DESCRIPTION = ('one propeller and one rudder, tau linear in 7 coefficients: thrust in n|n| '
               'and |n| u, rudder force in u|u| delta and n^2 delta (control-oriented)')

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations)
from mmg_tuner.core.layout import OK, PARAM_INDEX  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

(_Tnn, _Tnu, _Xdd, _Yud, _Ynd, _Nud, _Nnd) = (PARAM_INDEX[k] for k in PARAMS)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def start(p: FloatArray, cmd: tuple[float, ...], a: FloatArray, i: int) -> None:
    """No internal state."""
    return


@njit(cache=True, fastmath=FASTMATH, inline='always')
def hold(p: FloatArray, cmd: tuple[float, ...], h: float,
         astern: bool) -> tuple[int, tuple[float, float]]:
    """(OK, (n [rev/s], delta [rad])): the logged revolutions and angle act as they are."""
    return OK, (cmd[0] / 60.0, cmd[1])


@njit(cache=True, fastmath=FASTMATH, inline='always')
def output(p: FloatArray, held: tuple[float, float], a: FloatArray, i: int) -> tuple[float, float]:
    """Return the held (n, delta): they act for the whole step."""
    return held


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float, act: tuple[float, ...],
           k: int) -> tuple[float, float, float]:
    """Return tau (X [N], Y [N], N [N m]) of the propeller and the rudder (module docstring)."""
    n = act[k]
    delta = act[k + 1]
    an = abs(n)
    npos = n if n > 0.0 else 0.0
    uu = u * abs(u)
    X = p[_Tnn] * n * an + p[_Tnu] * an * u + p[_Xdd] * u * u * delta * delta
    Y = (p[_Yud] * uu + p[_Ynd] * npos * npos) * delta
    N = (p[_Nud] * uu + p[_Nnd] * npos * npos) * delta
    return X, Y, N
