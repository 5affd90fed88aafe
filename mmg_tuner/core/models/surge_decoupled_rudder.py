"""
Family ``surge_decoupled_rudder``: the surge-decoupled model driven by a propeller and a rudder.

The equations of ``surge_decoupled`` (M nu_dot + C(nu) nu + D(nu) nu = tau, the same 22
coefficient slots and the same compiled functions) for a conventional single-screw,
single-rudder ship: tau from the ``screw_rudder_tau`` actuator (thrust and rudder force linear
in 7 coefficients) and from bow and stern tunnel thrusters (``tunnel_thrusters``: the speeds
recorded, or 0). The thrusters' side force and moment are the low-speed MMG model's
(``lowspeed.thruster_forces``, doc/reference/esso_osaka_lowspeed_mmg.md §7) with the
ship's pre-determined values: they are not identified (a run without thrusters carries no
information on them; the Esso Osaka's pond runs recorded none).
Ship: ``config/esso_osaka_3m_control.yaml``; the coefficients identified are the ship's
tuning targets (its mass matrix is kept at the published values).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

PARAMS = ('m11', 'm22', 'm23', 'm32', 'm33',
          'X_u', 'X_absu_u', 'X_uuu',
          'Y_v', 'Y_absv_v', 'Y_absr_v', 'Y_vvv', 'Y_r', 'Y_absv_r', 'Y_absr_r',
          'N_v', 'N_absv_v', 'N_absr_v', 'N_r', 'N_absr_r', 'N_rrr', 'N_absv_r',
          'coriolis_form')
REQUIRED = ('rho', 'L_pp', 'B', 'd', 'm', 'I_zG') + PARAMS[:22] + (
    'T_nn', 'T_absn_u', 'Y_uud', 'N_uud')
ACTUATORS = ('screw_rudder_tau', 'tunnel_thrusters')
ASTERN_RPM = True
ASTERN_SURGE = True
DESCRIPTION = ('surge-decoupled 3-DOF model (Pedersen 2019) with a propeller, a rudder and '
               'tunnel thrusters in tau (control-oriented single-screw ship)')

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations)
from mmg_tuner.core.models import surge_decoupled as _sd  # noqa: E402
from mmg_tuner.core.models.lowspeed import thruster_forces  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

# a ship without tunnel thrusters: no thrust at any speed (lowspeed's slots, 0: no force)
DEFAULTS: dict[str, float] = {
    'x_G': 0.0, 'coriolis_form': 0.0, 'X_uudd': 0.0, 'Y_nnd': 0.0, 'N_nnd': 0.0,
    'D_BT': 0.0, 'D_ST': 0.0, 'x_BT': 0.0, 'x_ST': 0.0, 'u_T_max': 0.0, 'K_BF': 0.0,
    'K_BR': 0.0, 'a_YB': 0.0, 'a_NB': 0.0, 'K_SF': 0.0, 'K_SR': 0.0, 'a_YS': 0.0,
    'a_NS': 0.0, 'g': 9.80665}
CORIOLIS_FORMS = _sd.CORIOLIS_FORMS
_BOW = 2   # act: (n_P, delta) of screw_rudder_tau, then (n_bow, n_stern)
motion = _sd.motion
mass_solve = _sd.mass_solve


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """-D(nu) nu plus the tunnel thrusters' side force and moment [N, N, N m]."""
    X, Y, N = _sd.forces(p, u, v, r, act)
    yb, nb, ys, ns = thruster_forces(p, u, act[_BOW], act[_BOW + 1])
    return X, Y + yb + ys, N + nb + ns
