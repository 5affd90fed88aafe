"""
Family ``simplified6``: the 6-coefficient underactuated model of MBPE-LOGO's Remark 2.1.

After Chen (2020) and Yuan (2021), as doc/reference/mbpe_logo_tug.md §1 restates it (SI
units, body axes x forward, y to starboard, r clockwise):

  m11 u_dot - m22 v r + d11 u = tau_u
  m22 v_dot + m11 u r + d22 v = tau_v
  m33 r_dot + (m22 - m11) u v + d33 r = tau_r

The thrust comes from the ``twin_azimuth`` actuator. Whether the paper keeps tau_v (the
classic underactuated form sets it to 0) is not known, so ``tau_v`` is a switch: 1 (default)
keeps the thrusters' sway force, 0 drops it. The paper's Table 4 values are in
``config/qiuxin_tug_simplified6.yaml``, for the comparison with ``surge_decoupled``.
"""
from __future__ import annotations

from typing import Any, Callable, TYPE_CHECKING

PARAMS = ('m11', 'm22', 'm33', 'd11', 'd22', 'd33', 'tau_v')
COEFFICIENTS = PARAMS[:6]
"""The 6 model coefficients, in the reference's Table 4 order (``tau_v`` is a switch)."""
REQUIRED = ('rho', 'L_pp', 'B', 'd', 'm', 'I_zG') + COEFFICIENTS + (
    'thrust_p2', 'azimuth_k1', 'azimuth_k2', 'thruster_x_port', 'thruster_y_port',
    'thruster_x_stbd', 'thruster_y_stbd')
ACTUATORS = ('twin_azimuth',)
ASTERN_RPM = True
ASTERN_SURGE = True
DESCRIPTION = ('6-coefficient underactuated 3-DOF model (MBPE-LOGO Remark 2.1, Table 4; '
               'Chen 2020, Yuan 2021)')

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations)
from mmg_tuner.core.actuators.twin_azimuth import DEFAULTS as _ACTUATOR_DEFAULTS  # noqa: E402
from mmg_tuner.core.layout import PARAM_INDEX  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

DEFAULTS: dict[str, float] = {'x_G': 0.0, 'tau_v': 1.0, **_ACTUATOR_DEFAULTS}

_m11, _m22, _m33, _d11, _d22, _d33, _tauv = (PARAM_INDEX[k] for k in PARAMS)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """Return the linear damping -(d11 u, d22 v, d33 r) [N, N, N m]."""
    return -p[_d11] * u, -p[_d22] * v, -p[_d33] * r


@njit(cache=True, fastmath=FASTMATH, inline='always')
def motion(p: FloatArray, u: float, v: float, r: float, X: float, Y: float,
           N: float) -> tuple[float, float, float]:
    """(du, dv, dr) for the forces X, Y, N: damping, thrust and effects (no inertia)."""
    m11 = p[_m11]
    m22 = p[_m22]
    if p[_tauv] == 0.0:
        # Y is the damping plus every sway force acting (thrust, effects); the form without
        # tau_v keeps the damping alone
        Y = -p[_d22] * v
    return ((X + m22 * v * r) / m11, (Y - m11 * u * r) / m22,
            (N - (m22 - m11) * u * v) / p[_m33])


@njit(cache=True, fastmath=FASTMATH, inline='always')
def mass_solve(p: FloatArray, X: float, Y: float, N: float) -> tuple[float, float, float]:
    """diag(m11, m22, m33)^-1 (X, Y, N) for external forces (wind)."""
    return X / p[_m11], Y / p[_m22], N / p[_m33]


def hull_document(g: Callable[[str], float]) -> dict[str, Any]:
    """Return M, C(nu) and D in the form above, for ``export``'s model.json (g: a parameter)."""
    return {
        'equations': 'M nu_dot + C(nu) nu + D nu = tau, tau_v = 0 drops the sway thrust',
        'M': [[g('m11'), 0.0, 0.0], [0.0, g('m22'), 0.0], [0.0, 0.0, g('m33')]],
        'C': {'form': 'C(nu) = [[0, 0, -m22 v], [0, 0, m11 u], [m22 v, -m11 u, 0]]',
              'coefficients': {'m11': g('m11'), 'm22': g('m22')}},
        'D': {'form': 'D = diag(d11, d22, d33)',
              'coefficients': {k: g(k) for k in ('d11', 'd22', 'd33')}},
        'switches': {'tau_v': g('tau_v')}}
