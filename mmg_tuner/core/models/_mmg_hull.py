"""
Pieces the container and standard families share (not a family: not in the registry).

The polynomial hull model in v'_m, r' (paper eqs. 14-15; standard method eq. 8 with
X_vvvr = 0), the propeller slipstream's speed-up, the rudder angle of attack and the rudder
forces from its normal force.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from mmg_tuner.core._jit import FASTMATH, U_MIN
from mmg_tuner.core.layout import PARAM_INDEX
from numba import njit

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

_rho = PARAM_INDEX['rho']
_L = PARAM_INDEX['L_pp']
_d = PARAM_INDEX['d']
_AR = PARAM_INDEX['A_R']
_xR = PARAM_INDEX['x_R']
_tR = PARAM_INDEX['t_R']
_aH = PARAM_INDEX['a_H']
_xH = PARAM_INDEX['x_H']
_R0 = PARAM_INDEX['R_0']
_Xvv = PARAM_INDEX['X_vv']
_Xvr = PARAM_INDEX['X_vr']
_Xrr = PARAM_INDEX['X_rr']
_Xvvvr = PARAM_INDEX['X_vvvr']
_Xvvvv = PARAM_INDEX['X_vvvv']
_Yv = PARAM_INDEX['Y_v']
_Yr = PARAM_INDEX['Y_r']
_Yvvv = PARAM_INDEX['Y_vvv']
_Yvvr = PARAM_INDEX['Y_vvr']
_Yvrr = PARAM_INDEX['Y_vrr']
_Yrrr = PARAM_INDEX['Y_rrr']
_Nv = PARAM_INDEX['N_v']
_Nr = PARAM_INDEX['N_r']
_Nvvv = PARAM_INDEX['N_vvv']
_Nvvr = PARAM_INDEX['N_vvr']
_Nvrr = PARAM_INDEX['N_vrr']
_Nrrr = PARAM_INDEX['N_rrr']


@njit(cache=True, fastmath=FASTMATH, inline='always')
def hull(p: FloatArray, u: float, v: float,
         r: float) -> tuple[float, float, float, float, float, float, float]:
    """
    Hull force and moment [N, N, N m] and the kinematics the other parts reuse.

    (X_H, Y_H, N_H, U, v'_m, r', beta).
    """
    L = p[_L]
    U = math.sqrt(u * u + v * v)
    if U < U_MIN:
        U = U_MIN
    vp = v / U                       # v'_m = -sin(beta)
    rp = r * L / U                   # r'
    beta = math.atan(-v / u) if u > 0.0 else math.atan2(-v, u)  # atan: cheaper, u > 0 here
    vp2 = vp * vp
    rp2 = rp * rp
    XHp = (-p[_R0] + p[_Xvv] * vp2 + p[_Xvr] * vp * rp + p[_Xrr] * rp2
           + p[_Xvvvr] * vp2 * vp * rp + p[_Xvvvv] * vp2 * vp2)
    YHp = (p[_Yv] * vp + p[_Yr] * rp + p[_Yvvv] * vp2 * vp + p[_Yvvr] * vp2 * rp
           + p[_Yvrr] * vp * rp2 + p[_Yrrr] * rp2 * rp)
    NHp = (p[_Nv] * vp + p[_Nr] * rp + p[_Nvvv] * vp2 * vp + p[_Nvvr] * vp2 * rp
           + p[_Nvrr] * vp * rp2 + p[_Nrrr] * rp2 * rp)
    qU = 0.5 * p[_rho] * L * p[_d] * U * U
    return qU * XHp, qU * YHp, qU * L * NHp, U, vp, rp, beta


@njit(cache=True, fastmath=FASTMATH, inline='always')
def sin_attack(delta: float, uR: float, vR: float) -> float:
    """sin(alpha_R), alpha_R = delta - atan2(v_R, u_R), without the atan2 (hot path)."""
    UR = math.sqrt(uR * uR + vR * vR)
    if UR == 0.0:
        return math.sin(delta)
    return (math.sin(delta) * uR - math.cos(delta) * vR) / UR


@njit(cache=True, fastmath=FASTMATH, inline='always')
def slipstream(KT: float, JP: float) -> float:
    """Return sqrt(1 + 8 K_T / (pi J_P^2)) - 1, the propeller race's speed-up (root >= 0)."""
    root = 1.0 + 8.0 * KT / (math.pi * JP * JP)
    if root < 0.0:
        root = 0.0
    return math.sqrt(root) - 1.0


@njit(cache=True, fastmath=FASTMATH, inline='always')
def rudder_forces(p: FloatArray, delta: float, uR: float, vR: float,
                  coef: float) -> tuple[float, float, float]:
    """
    Return the rudder force and moment [N, N, N m] (paper eqs. 25-28; standard eqs. 17-20).

    From the normal force F_N = 1/2 rho A_R (u_R^2 + v_R^2) coef.
    """
    FN = 0.5 * p[_rho] * p[_AR] * (uR * uR + vR * vR) * coef
    sd = math.sin(delta)
    cd = math.cos(delta)
    aH = p[_aH]
    return (-(1.0 - p[_tR]) * FN * sd, -(1.0 + aH) * FN * cd,
            -(p[_xR] + aH * p[_xH]) * p[_L] * FN * cd)
