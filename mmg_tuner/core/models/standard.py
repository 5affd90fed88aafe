"""
Family ``standard``: the MMG standard method, Yasukawa & Yoshimura 2015 (KVLCC2).

Polynomial hull (eq. 8), propeller thrust from K_T(J_P) with the wake fraction's drift-angle
dependence (eqs. 11-16), rudder inflow and normal force (eqs. 17-26). Ahead revolutions and
ahead speed only.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from numba import njit

PARAMS = ('R_0', 'X_vv', 'X_vr', 'X_rr', 'X_vvvr', 'X_vvvv',
          'Y_v', 'Y_r', 'Y_vvv', 'Y_vvr', 'Y_vrr', 'Y_rrr',
          'N_v', 'N_r', 'N_vvv', 'N_vvr', 'N_vrr', 'N_rrr',
          't_P', 'w_P0', 'k_0', 'k_1', 'k_2', 'C_1', 'C_2p', 'C_2n', 'x_P',
          't_R', 'a_H', 'x_H', 'epsilon', 'kappa', 'l_R', 'gamma_Rp', 'gamma_Rn', 'f_alpha')
REQUIRED = ('L_pp', 'B', 'd', 'x_G', 'D_P', 'H_R', 'A_R', 'rho', 'x_R', 'm_x', 'm_y', 'J_z',
            'R_0', 'Y_v', 'N_v', 't_P', 'w_P0', 'k_0', 'C_1', 'C_2p', 'C_2n', 'x_P', 't_R',
            'a_H', 'x_H', 'epsilon', 'kappa', 'l_R', 'gamma_Rp', 'gamma_Rn', 'f_alpha')
DEFAULTS: dict[str, float] = {}
ACTUATORS = ('screw_rudder',)
ASTERN_RPM = False
ASTERN_SURGE = False
DESCRIPTION = 'MMG standard method, Yasukawa & Yoshimura 2015 (KVLCC2)'

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations layout reads)
from mmg_tuner.core.layout import PARAM_INDEX  # noqa: E402
from mmg_tuner.core.models._mmg_hull import hull, rudder_forces  # noqa: E402
from mmg_tuner.core.models._mmg_hull import sin_attack, slipstream  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

ACT_N, ACT_DELTA = 0, 1   # the actuator tuple: screw_rudder's (n_P [rev/s], delta [rad])
_rho = PARAM_INDEX['rho']
_DP = PARAM_INDEX['D_P']
_HR = PARAM_INDEX['H_R']
_tP = PARAM_INDEX['t_P']
_wP0 = PARAM_INDEX['w_P0']
_k0 = PARAM_INDEX['k_0']
_k1 = PARAM_INDEX['k_1']
_k2 = PARAM_INDEX['k_2']
_C1 = PARAM_INDEX['C_1']
_C2p = PARAM_INDEX['C_2p']
_C2n = PARAM_INDEX['C_2n']
_xP = PARAM_INDEX['x_P']
_eps = PARAM_INDEX['epsilon']
_kap = PARAM_INDEX['kappa']
_lR = PARAM_INDEX['l_R']
_gRp = PARAM_INDEX['gamma_Rp']
_gRn = PARAM_INDEX['gamma_Rn']
_fa = PARAM_INDEX['f_alpha']


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """Hull + propeller + rudder force [N] and moment [N m]; act[ACT_N] = n_P > 0 [rev/s]."""
    n_rps = act[ACT_N]
    delta = act[ACT_DELTA]
    rho = p[_rho]
    X, Y, N, U, vp, rp, beta = hull(p, u, v, r)
    DP = p[_DP]
    eta = DP / p[_HR]
    # Propeller (standard method eqs. 11-13, 15-16)
    beta_P = beta - p[_xP] * rp
    C2 = p[_C2p] if beta_P > 0.0 else p[_C2n]
    one_minus_wP = (1.0 - p[_wP0]) * (1.0 + (1.0 - math.exp(-p[_C1] * abs(beta_P)))
                                      * (C2 - 1.0))
    uP = one_minus_wP * u
    JP = uP / (n_rps * DP)
    KT = p[_k0] + JP * (p[_k1] + JP * p[_k2])
    X += (1.0 - p[_tP]) * rho * n_rps * n_rps * DP ** 4 * KT
    # Rudder inflow (eqs. 23-26)
    a = 1.0 + p[_kap] * slipstream(KT, JP)
    uR = p[_eps] * uP * math.sqrt(eta * a * a + (1.0 - eta))
    beta_R = beta - p[_lR] * rp
    gam = p[_gRp] if beta_R > 0.0 else p[_gRn]
    vR = U * gam * beta_R
    coef = p[_fa] * sin_attack(delta, uR, vR)
    # Rudder forces (standard eqs. 17-20)
    XR, YR, NR = rudder_forces(p, delta, uR, vR, coef)
    return X + XR, Y + YR, N + NR
