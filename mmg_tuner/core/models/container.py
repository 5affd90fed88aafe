"""
Family ``container``: Suyama et al. 2023 (arXiv 2312.04224) section 3, M.V. SUZAKU.

Polynomial hull (eqs. 14-15), a propeller model in the advance angle phi with side force and
moment coefficients C_PY, C_PN (eqs. 16-24), a flapped rudder whose inflow is
u_R = max(u_R*, u_R**) (eqs. 25-36). Ahead revolutions and ahead speed only.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from numba import njit

PARAMS = ('R_0', 'X_vv', 'X_vr', 'X_rr', 'X_vvvr', 'X_vvvv',
          'Y_v', 'Y_r', 'Y_vvv', 'Y_vvr', 'Y_vrr', 'Y_rrr',
          'N_v', 'N_r', 'N_vvv', 'N_vvr', 'N_vrr', 'N_rrr',
          't_P', 'w_P0', 'C_w', 'l_P', 'KT_0', 'KT_1', 'KT_2', 'KT_3', 'CPY_0', 'CPY_1', 'CPY_2',
          'CPN_lo_0', 'CPN_lo_1', 'CPN_hi_0', 'CPN_hi_1', 'phi_switch',
          't_R', 'a_H', 'x_H', 'epsilon', 'kappa', 'u_R0', 'l_R', 'gamma_Rp', 'gamma_Rn',
          'f_alpha', 'f_alpha2', 'C_l01', 'C_l03', 'flap_ratio')
REQUIRED = ('L_pp', 'B', 'd', 'x_G', 'D_P', 'H_R', 'A_R', 'rho', 'x_R', 'm_x', 'm_y', 'J_z',
            'R_0', 'Y_v', 'N_v', 't_P', 'w_P0', 'C_w', 'l_P', 'KT_0', 't_R', 'a_H', 'x_H',
            'epsilon', 'kappa', 'u_R0', 'l_R', 'gamma_Rp', 'gamma_Rn', 'f_alpha')
DEFAULTS = {'flap_ratio': 1.0}
ACTUATORS = ('screw_rudder',)
ASTERN_RPM = False
ASTERN_SURGE = False
DESCRIPTION = 'container ship with flapped rudder, Suyama et al. 2023 (SUZAKU)'

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations layout reads)
from mmg_tuner.core.layout import PARAM_INDEX  # noqa: E402
from mmg_tuner.core.models._mmg_hull import hull, rudder_forces  # noqa: E402
from mmg_tuner.core.models._mmg_hull import sin_attack, slipstream  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

ACT_N, ACT_DELTA = 0, 1   # the actuator tuple: screw_rudder's (n_P [rev/s], delta [rad])
_rho = PARAM_INDEX['rho']
_L = PARAM_INDEX['L_pp']
_DP = PARAM_INDEX['D_P']
_HR = PARAM_INDEX['H_R']
_tP = PARAM_INDEX['t_P']
_wP0 = PARAM_INDEX['w_P0']
_Cw = PARAM_INDEX['C_w']
_lP = PARAM_INDEX['l_P']
_KT0 = PARAM_INDEX['KT_0']
_KT1 = PARAM_INDEX['KT_1']
_KT2 = PARAM_INDEX['KT_2']
_KT3 = PARAM_INDEX['KT_3']
_CPY0 = PARAM_INDEX['CPY_0']
_CPY1 = PARAM_INDEX['CPY_1']
_CPY2 = PARAM_INDEX['CPY_2']
_CPNl0 = PARAM_INDEX['CPN_lo_0']
_CPNl1 = PARAM_INDEX['CPN_lo_1']
_CPNh0 = PARAM_INDEX['CPN_hi_0']
_CPNh1 = PARAM_INDEX['CPN_hi_1']
_phisw = PARAM_INDEX['phi_switch']
_eps = PARAM_INDEX['epsilon']
_kap = PARAM_INDEX['kappa']
_uR0 = PARAM_INDEX['u_R0']
_lR = PARAM_INDEX['l_R']
_gRp = PARAM_INDEX['gamma_Rp']
_gRn = PARAM_INDEX['gamma_Rn']
_fa = PARAM_INDEX['f_alpha']
_fa2 = PARAM_INDEX['f_alpha2']
_Cl01 = PARAM_INDEX['C_l01']
_Cl03 = PARAM_INDEX['C_l03']
_flap = PARAM_INDEX['flap_ratio']


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """Hull + propeller + rudder force [N] and moment [N m]; act[ACT_N] = n_P > 0 [rev/s]."""
    n_rps = act[ACT_N]
    delta = act[ACT_DELTA]
    rho = p[_rho]
    L = p[_L]
    X, Y, N, U, vp, rp, beta = hull(p, u, v, r)
    DP = p[_DP]
    eta = DP / p[_HR]
    # Propeller (paper eqs. 16-24)
    beta_P = beta - p[_lP] * rp
    wP = p[_wP0] * math.exp(p[_Cw] * beta_P * beta_P)
    uP = (1.0 - wP) * u
    vt = 0.7 * math.pi * n_rps * DP           # blade-section tangential speed
    phi = math.degrees(math.atan(uP / vt))     # advance angle [deg]; vt > 0 (n_P > 0)
    KT = p[_KT0] + phi * (p[_KT1] + phi * (p[_KT2] + phi * p[_KT3]))
    CPY = p[_CPY0] + phi * (p[_CPY1] + phi * p[_CPY2])
    if phi < p[_phisw]:
        CPN = p[_CPNl0] + p[_CPNl1] * phi
    else:
        CPN = p[_CPNh0] + p[_CPNh1] * phi
    qP = 0.5 * rho * (0.25 * math.pi * DP * DP) * (uP * uP + vt * vt)
    X += qP * (1.0 - p[_tP]) * KT
    Y += qP * CPY
    N += qP * L * CPN
    # Rudder inflow (eqs. 29-33): u_R = max(u_R*, u_R**)
    JP = uP / (n_rps * DP)
    uR = uP * p[_eps] * (eta * p[_kap] * slipstream(KT, JP) + 1.0)
    uRss = vt * p[_uR0]
    if uRss > uR:
        uR = uRss
    beta_R = beta - p[_lR] * rp
    gam = p[_gRp] if beta_R > 0.0 else p[_gRn]
    vR = gam * (-v - p[_lR] * L * r)           # gamma_R (U sin(beta) - l_R r)
    df = p[_flap] * delta
    coef = (p[_fa] + p[_fa2] * df * df) * sin_attack(delta, uR, vR) \
        + df * (p[_Cl01] + p[_Cl03] * df * df)
    # Rudder forces (paper eqs. 25-28)
    XR, YR, NR = rudder_forces(p, delta, uR, vR, coef)
    return X + XR, Y + YR, N + NR
