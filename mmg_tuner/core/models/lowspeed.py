"""
Family ``lowspeed``: the low-speed, four-quadrant MMG model of the Osaka Univ.

NAOE 5th lab (Esso Osaka 3 m): Yoshimura's hull forces (valid through U -> 0 and u < 0),
four-quadrant propeller, rudder with the reverse-propeller inflow, bow/stern thrusters, and its own
wind model, Fujiwara's regression on the apparent wind (acting even without true wind: the air drag
of the ship's own motion is part of the model).

Written from the reference restatement doc/reference/esso_osaka_lowspeed_mmg.md (section
numbers below are its own); parameter values and sources in config/esso_osaka_3m.yaml.

Frames, units and signs (reference §2):
- body axes at **midship**: x forward, y to starboard; u, v = midship velocity through the
  water [m/s]; r [rad/s] > 0 turns the bow to starboard. X forward, Y starboard, N clockwise
  [N, N m], moments about midship.
- n_rps: propeller speed [rev/s], signed (< 0 astern). delta [rad], > 0 starboard helm.
- n_bt, n_st: bow/stern thruster speeds [rev/s], signed, > 0 pushes to starboard. They are
  the *actual* thruster speeds (the input channels): the lab's actuator lag (§7: first order,
  T = 0.1 s, at most 20 rps/s) is not part of the model, see :func:`actuator_rate`.
- wind_speed_rel [m/s], wind_angle_rel [rad]: apparent wind at midship, the direction it
  blows FROM, clockwise from the bow (0 = head wind, pi/2 = from starboard).

Parameters live in the package's flat vector (``core/layout.PARAM_INDEX``): the shared slots
(rho, L_pp, d, m [kg], x_G [m], I_zG [kg m^2], m_x, m_y, J_z primes, D_P, H_R, A_R, x_R = x'_R,
rho_air, A_F = the transverse area A_T, A_L) and this family's own :data:`PARAMS`. Primes are
non-dimensional on 1/2 rho L d (forces), 1/2 rho L^2 d (moments, masses), 1/2 rho L^4 d
(inertia), L (x_P, x_H, l_R, x_R). x_BT, x_ST are in metres (the lab's files).

Two ways in: the family interface the generic kernels call (:func:`forces` on the actuator
tuple, :func:`wind` on the apparent wind vector; the shared equations of motion in
``core/dynamics.py``), and the reference's standalone form (:func:`force_terms`,
:func:`accelerations` with the apparent wind as speed and angle), which
test/core/test_lowspeed_model.py checks against the reference's sanity numbers. Both use the
same component functions.
The model is discontinuous at u = 0, n = 0 and at a few branch points (§9): use fixed steps.
"""
from __future__ import annotations

PARAMS = ('g', 'X_0F', 'X_0A', 'X_vr', 'Y_v', 'Y_r', 'N_v', 'N_r', 'C_D', 'C_rY', 'C_rN',
          'pitch_ratio', 'x_P', 'w_P0', 'tau_P', 'C_P', 't_P', 'k_0', 'k_1', 'k_2',
          'A_1', 'A_2', 'A_3', 'A_4', 'A_5', 'A_6', 'A_7', 'A_8',
          'B_1', 'B_2', 'B_3', 'B_4', 'B_5', 'B_6', 'B_7', 'B_8',
          'C_3', 'C_6', 'C_7', 'C_10', 'J_syn', 'J_syn0',
          'aspect_R', 't_R', 'a_H', 'x_H', 'l_R', 'k_x', 'k_x_rev', 'epsilon', 'c_PR',
          'gamma_N', 'gamma_P',
          'D_BT', 'D_ST', 'x_BT', 'x_ST', 'u_T_max', 'K_BF', 'K_BR', 'a_YB', 'a_NB', 'K_SF',
          'K_SR', 'a_YS', 'a_NS',
          'XX0', 'XX1', 'XX3', 'XX5', 'YY1', 'YY3', 'YY5', 'NN1', 'NN2', 'NN3')
REQUIRED = ('L_pp', 'B', 'd', 'rho', 'm', 'x_G', 'I_zG', 'm_x', 'm_y', 'J_z', 'D_P', 'H_R',
            'A_R', 'x_R', 'rho_air', 'A_F', 'A_L') + PARAMS
DEFAULTS: dict[str, float] = {}
ACTUATORS = ('screw_rudder', 'tunnel_thrusters')
ASTERN_RPM = True
ASTERN_SURGE = True
AIR_DRAG = True   # its wind loads act on the apparent wind even when the true wind is zero
DESCRIPTION = ('low-speed four-quadrant MMG with thrusters and Fujiwara wind, Osaka Univ. '
               'NAOE 5th lab (Yoshimura 2009 hull; Esso Osaka 3 m)')

import math  # noqa: E402  (below the declarations the layout reads)
from typing import TYPE_CHECKING  # noqa: E402

from mmg_tuner.core.layout import PARAM_INDEX  # noqa: E402
from numba import njit  # noqa: E402
import numpy as np  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

# the actuator tuple: screw_rudder's (n_P, delta), then tunnel_thrusters' (bow, stern)
ACT_N, ACT_DELTA, ACT_BOW, ACT_STERN = 0, 1, 2, 3

# indices into the flat vector (module-level ints: numba folds them in as constants)
I_L, I_D, I_RHO, I_RHOA, I_G = (PARAM_INDEX[k] for k in ('L_pp', 'd', 'rho', 'rho_air', 'g'))
I_M, I_XG, I_MX, I_MY, I_IZG, I_JZ = (PARAM_INDEX[k] for k in
                                      ('m', 'x_G', 'm_x', 'm_y', 'I_zG', 'J_z'))
(I_X0F, I_X0A, I_XVR, I_YV, I_YR, I_NV, I_NR, I_CD, I_CRY, I_CRN) = (
    PARAM_INDEX[k] for k in ('X_0F', 'X_0A', 'X_vr', 'Y_v', 'Y_r', 'N_v', 'N_r', 'C_D',
                             'C_rY', 'C_rN'))
(I_DP, I_PR, I_XP, I_WP0, I_TAU, I_CP, I_TP, I_K0, I_K1, I_K2) = (
    PARAM_INDEX[k] for k in ('D_P', 'pitch_ratio', 'x_P', 'w_P0', 'tau_P', 'C_P', 't_P',
                             'k_0', 'k_1', 'k_2'))
I_A1, I_A2, I_A3, I_A4, I_A5, I_A6, I_A7, I_A8 = (PARAM_INDEX[f'A_{i}'] for i in range(1, 9))
I_B1, I_B2, I_B3, I_B4, I_B5, I_B6, I_B7, I_B8 = (PARAM_INDEX[f'B_{i}'] for i in range(1, 9))
I_C3, I_C6, I_C7, I_C10, I_JSYN, I_JSYN0 = (
    PARAM_INDEX[k] for k in ('C_3', 'C_6', 'C_7', 'C_10', 'J_syn', 'J_syn0'))
(I_AR, I_HR, I_LAM, I_XR, I_TR, I_AH, I_XH, I_LR, I_KX, I_KXREV, I_EPS, I_CPR, I_GN,
 I_GP) = (PARAM_INDEX[k] for k in ('A_R', 'H_R', 'aspect_R', 'x_R', 't_R', 'a_H', 'x_H', 'l_R',
                                   'k_x', 'k_x_rev', 'epsilon', 'c_PR', 'gamma_N', 'gamma_P'))
(I_DBT, I_DST, I_XBT, I_XST, I_UTMAX, I_KBF, I_KBR, I_AYB, I_ANB, I_KSF, I_KSR, I_AYS,
 I_ANS) = (PARAM_INDEX[k] for k in ('D_BT', 'D_ST', 'x_BT', 'x_ST', 'u_T_max', 'K_BF', 'K_BR',
                                    'a_YB', 'a_NB', 'K_SF', 'K_SR', 'a_YS', 'a_NS'))
(I_AT, I_AL, I_XX0, I_XX1, I_XX3, I_XX5, I_YY1, I_YY3, I_YY5, I_NN1, I_NN2, I_NN3) = (
    PARAM_INDEX[k] for k in ('A_F', 'A_L', 'XX0', 'XX1', 'XX3', 'XX5', 'YY1', 'YY3', 'YY5',
                             'NN1', 'NN2', 'NN3'))
#: rows of :func:`force_terms`
FORCE_TERMS = ('hull', 'propeller', 'rudder', 'bow_thruster', 'stern_thruster', 'wind')

EPS = 2.220446049250313e-16   # the lab's machine-epsilon guards (§9)
U_MIN = 1e-5                  # below this total speed the lab sets U, v', r' to 1e-7 (§9)


# --- components -------------------------------------------------------------------------

@njit(cache=True)
def _sgn(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@njit(cache=True)
def cross_flow_integrals(a: float, b: float) -> tuple[float, float]:
    """
    Return the cross-flow integrals (I_Y, I_N) in closed form.

    (I_Y, I_N) = integrals over xi in [-1/2, 1/2] of |a + b xi| (a + b xi) and of the same times xi
    [m^2/s^2], in closed form (reference §4; a = v, b = C r L). Without a sign change inside the
    interval the integrand is sgn(a) (a + b xi)^2: exact and free of cancellation.
    """
    if abs(b) <= 2.0 * abs(a):
        s = _sgn(a)
        return s * (a * a + b * b / 12.0), s * a * b / 6.0
    bb = b * b
    if bb == 0.0:  # |a| < |b| / 2 < 1e-154: both integrals underflow to 0 (and x / 0.0 raises)
        return 0.0, 0.0
    sp = a + 0.5 * b
    sm = a - 0.5 * b
    iy = (abs(sp) ** 3 - abs(sm) ** 3) / (3.0 * b)
    fp = sp ** 3 * abs(sp) / 4.0 - a * abs(sp) ** 3 / 3.0
    fm = sm ** 3 * abs(sm) / 4.0 - a * abs(sm) ** 3 / 3.0
    return iy, (fp - fm) / bb


@njit(cache=True)
def _speed(u: float, v: float, r: float, L: float) -> tuple[float, float, float]:
    """(U, v', r') with the lab's U -> 0 guard (§9)."""
    U = math.sqrt(u * u + v * v)
    if U < U_MIN:
        return 1e-7, 1e-7, 1e-7
    return U, v / U, r * L / U


@njit(cache=True)
def hull_forces(p: FloatArray, u: float, v: float, r: float) -> tuple[float, float, float]:
    """Yoshimura low-speed hull forces (X_H, Y_H, N_H) [N, N m] (§4)."""
    L, d, rho = p[I_L], p[I_D], p[I_RHO]
    U, _, _ = _speed(u, v, r, L)
    beta = math.atan2(v, u)   # the lab's beta-hat in (-pi, pi]; multiplied by u U = 0 at rest
    x0 = p[I_X0F] + (p[I_X0A] - p[I_X0F]) * abs(beta) / math.pi
    iy, _ = cross_flow_integrals(v, p[I_CRY] * r * L)
    _, in_ = cross_flow_integrals(v, p[I_CRN] * r * L)
    q = 0.5 * rho * L * d
    X = q * (x0 * u * U + p[I_XVR] * v * r * L)
    Y = q * (p[I_YV] * v * abs(u) + p[I_YR] * r * L * u - p[I_CD] * iy)
    N = q * L * (p[I_NV] * v * u + p[I_NR] * r * L * abs(u) - p[I_CD] * in_)
    return X, Y, N


@njit(cache=True)
def propeller_forces(p: FloatArray, u: float, v: float, r: float,
                     n: float) -> tuple[float, float, float, float]:
    """
    Four-quadrant propeller (X_P, Y_P, N_P, 1 - w_P) [N, N m, -] (§5).

    Quadrants: Q1 n >= 0, u >= 0; Q2 n >= 0, u < 0; Q3 n < 0, u >= 0; Q4 n < 0, u < 0.
    """
    L, d, rho, D = p[I_L], p[I_D], p[I_RHO], p[I_DP]
    _, vn, rn = _speed(u, v, r, L)
    bp = vn + p[I_XP] * rn
    wp = p[I_WP0] - p[I_TAU] * abs(bp) - p[I_CP] * bp * bp
    omw = 1.0 - wp if u > 0.0 else 1.0
    if omw > 1.0:
        omw = 1.0
    elif omw <= 0.0:
        omw = EPS
    if abs(n) < EPS:
        js = 1e4
    elif abs(u) < EPS:
        js = EPS
    else:
        js = u / (n * D)
    rn2d4 = rho * n * n * D ** 4
    q = 0.5 * rho * L * d
    if n >= 0.0:
        J = js * omw if u >= 0.0 else js
        kt = p[I_K0] + p[I_K1] * J + p[I_K2] * J * J
        X = (1.0 - p[I_TP]) * rn2d4 * kt
        if u >= 0.0:
            return X, 0.0, 0.0, omw
        nP2 = (n * p[I_PR] * D) ** 2
        Y = q * nP2 * (p[I_A6] * js * js + p[I_A7] * js + p[I_A8])
        N = q * L * nP2 * (p[I_B6] * js * js + p[I_B7] * js + p[I_B8])
        return X, Y, N, omw
    if js >= p[I_C10]:
        X = rn2d4 * (p[I_C6] + p[I_C7] * js)
    else:
        X = rn2d4 * p[I_C3]
    if js < p[I_JSYN]:
        cy, cn = p[I_A3] + p[I_A4] * js, p[I_B3] + p[I_B4] * js
    elif js <= p[I_JSYN0]:
        cy, cn = p[I_A1] + p[I_A2] * js, p[I_B1] + p[I_B2] * js
    else:
        cy, cn = p[I_A5], p[I_B5]
    nD2 = (n * D) ** 2
    return X, q * nD2 * cy, q * L * nD2 * cn, omw


@njit(cache=True)
def rudder_inflow(p: FloatArray, u: float, v: float, r: float, n: float, x_p: float,
                  omw: float) -> tuple[float, float]:
    """(u_R, v_R) [m/s] (§6) from the propeller thrust x_p [N] and its clipped 1 - w_P."""
    rho, D, eps = p[I_RHO], p[I_DP], p[I_EPS]
    eta = D / p[I_HR]   # H_R = sqrt(A_R Lambda) in the lab's code (the YAML gives it so)
    kappa = p[I_KX] / eps
    if n > EPS:
        kt = x_p / ((1.0 - p[I_TP]) * rho * n * n * D ** 4)
    elif abs(n) > EPS:
        kt = x_p / (rho * n * n * D ** 4)
    else:
        kt = 0.0
    up = u * omw
    if n >= 0.0 and kt > 0.0:
        jet = up + kappa * (math.sqrt(up * up + 8.0 * kt * n * n * D * D / math.pi) - up)
        ur = eps * math.sqrt(eta * jet * jet + (1.0 - eta) * up * up)
    elif u < 0.0:
        ur = u
    else:   # Kitagawa: u >= 0 with n < 0, n = 0 or K_T <= 0
        a1 = eps * omw * u + p[I_KXREV] * n * D * math.sqrt(8.0 * abs(kt) / math.pi)
        a2 = eps * omw * u
        s = eta * _sgn(a1) * a1 * a1 + (1.0 - eta) * a2 * a2 + p[I_CPR] * u * u
        ur = _sgn(s) * math.sqrt(abs(s))
    gamma = p[I_GP] if v + p[I_XR] * p[I_L] * r >= 0.0 else p[I_GN]
    vr = -gamma * (v + p[I_LR] * p[I_L] * r)
    return ur, vr


@njit(cache=True)
def rudder_forces(p: FloatArray, ur: float, vr: float, delta: float) -> tuple[float, float, float]:
    """(X_R, Y_R, N_R) [N, N m] from the inflow (u_R, v_R) (§6; Fujii's normal force)."""
    lam = p[I_LAM]
    f_alpha = 6.13 * lam / (lam + 2.25)
    alpha = delta - math.atan2(vr, ur)
    fn = 0.5 * p[I_RHO] * p[I_AR] * f_alpha * (ur * ur + vr * vr) * math.sin(alpha)
    X = -(1.0 - p[I_TR]) * fn * math.sin(delta)
    Y = -(1.0 + p[I_AH]) * fn * math.cos(delta)
    N = -(p[I_XR] + p[I_AH] * p[I_XH]) * p[I_L] * fn * math.cos(delta)
    return X, Y, N


@njit(cache=True)
def thruster_forces(p: FloatArray, u: float, n_bt: float,
                    n_st: float) -> tuple[float, float, float, float]:
    """
    (Y_BT, N_BT, Y_ST, N_ST) [N, N m] (§7).

    Thrust rho D^4 n^2 K (K by the sign of n), reduced linearly with Fr = |u| / sqrt(g L), zero
    beyond |u| > u_T_max.
    """
    if abs(u) > p[I_UTMAX]:
        return 0.0, 0.0, 0.0, 0.0
    fr = abs(u) / math.sqrt(p[I_G] * p[I_L])
    kb = p[I_KBF] if n_bt >= 0.0 else p[I_KBR]
    ks = p[I_KSF] if n_st >= 0.0 else p[I_KSR]
    tb = p[I_RHO] * p[I_DBT] ** 4 * n_bt * n_bt * kb
    ts = p[I_RHO] * p[I_DST] ** 4 * n_st * n_st * ks
    return (tb * (1.0 + p[I_AYB] * fr), tb * (1.0 + p[I_ANB] * fr) * p[I_XBT],
            ts * (1.0 + p[I_AYS] * fr), ts * (1.0 + p[I_ANS] * fr) * p[I_XST])


@njit(cache=True)
def wind_forces(p: FloatArray, wind_speed_rel: float,
                wind_angle_rel: float) -> tuple[float, float, float]:
    """
    Return Fujiwara's wind loads (X_A, Y_A, N_A) from the apparent wind.

    Fujiwara wind loads (X_A, Y_A, N_A) [N, N m] from the apparent wind (speed, FROM-angle
    clockwise from the bow) (§8); moment about midship on A_L L.
    """
    g = wind_angle_rel
    q = 0.5 * p[I_RHOA] * wind_speed_rel * wind_speed_rel
    X = q * p[I_AT] * (p[I_XX0] + p[I_XX1] * math.cos(g) + p[I_XX3] * math.cos(3.0 * g)
                       + p[I_XX5] * math.cos(5.0 * g))
    Y = -q * p[I_AL] * (p[I_YY1] * math.sin(g) + p[I_YY3] * math.sin(3.0 * g)
                        + p[I_YY5] * math.sin(5.0 * g))
    N = -q * p[I_AL] * p[I_L] * (p[I_NN1] * math.sin(g) + p[I_NN2] * math.sin(2.0 * g)
                                 + p[I_NN3] * math.sin(3.0 * g))
    return X, Y, N


@njit(cache=True)
def apparent_wind(true_speed: float, true_from: float, psi: float, u: float,
                  v: float) -> tuple[float, float]:
    """
    Return the apparent wind from the true wind and the ship's heading and velocity.

    Apparent wind (U_A [m/s], gamma_A [rad] in [0, 2 pi), FROM, clockwise from the bow) from the
    true wind (speed, FROM-direction clockwise from x_E) and the ship's heading and midship
    velocity. Vector form (§8, §13.9: no 0/0 when U_A = 0).
    """
    wx = -true_speed * math.cos(true_from - psi) - u
    wy = -true_speed * math.sin(true_from - psi) - v
    ga = math.atan2(-wy, -wx)
    if ga < 0.0:
        ga += 2.0 * math.pi
    return math.sqrt(wx * wx + wy * wy), ga


@njit(cache=True)
def apparent_wind_ne(wind_n: float, wind_e: float, psi: float, u: float,
                     v: float) -> tuple[float, float]:
    """
    Return the apparent wind from the true wind given as north/east air velocity.

    As :func:`apparent_wind` from the true wind given as the air's velocity toward north (x_E) and
    east (y_E) [m/s], the Trial.wind convention.
    """
    return apparent_wind(math.sqrt(wind_n * wind_n + wind_e * wind_e),
                         math.atan2(-wind_e, -wind_n), psi, u, v)


@njit(cache=True)
def actuator_rate(cmd: float, actual: float, time_const_s: float, max_rate: float) -> float:
    """Lab actuator lag (§7): d(actual)/dt = clip((cmd - actual) / T, -K, K)."""
    rate = (cmd - actual) / time_const_s
    return min(max(rate, -max_rate), max_rate)


# --- totals -------------------------------------------------------------------------------

@njit(cache=True)
def force_terms(p: FloatArray, u: float, v: float, r: float, n_rps: float, delta: float,
                n_bt: float, n_st: float, wind_speed_rel: float,
                wind_angle_rel: float) -> FloatArray:
    """
    Every contribution as a (6, 3) array.

    Rows :data:`FORCE_TERMS` (hull, propeller, rudder, bow thruster, stern thruster, wind), columns
    X [N], Y [N], N [N m] about midship.
    """
    out = np.zeros((6, 3))
    out[0, 0], out[0, 1], out[0, 2] = hull_forces(p, u, v, r)
    xp, yp, np_, omw = propeller_forces(p, u, v, r, n_rps)
    out[1, 0], out[1, 1], out[1, 2] = xp, yp, np_
    ur, vr = rudder_inflow(p, u, v, r, n_rps, xp, omw)
    out[2, 0], out[2, 1], out[2, 2] = rudder_forces(p, ur, vr, delta)
    yb, nb, ys, ns = thruster_forces(p, u, n_bt, n_st)
    out[3, 1], out[3, 2], out[4, 1], out[4, 2] = yb, nb, ys, ns
    out[5, 0], out[5, 1], out[5, 2] = wind_forces(p, wind_speed_rel, wind_angle_rel)
    return out


@njit(cache=True)
def total_forces(p: FloatArray, u: float, v: float, r: float, n_rps: float, delta: float,
                 n_bt: float, n_st: float, wind_speed_rel: float,
                 wind_angle_rel: float) -> tuple[float, float, float]:
    """(X, Y, N) summed over every term (no allocation)."""
    xh, yh, nh = hull_forces(p, u, v, r)
    xp, yp, np_, omw = propeller_forces(p, u, v, r, n_rps)
    ur, vr = rudder_inflow(p, u, v, r, n_rps, xp, omw)
    xr, yr, nr = rudder_forces(p, ur, vr, delta)
    yb, nb, ys, ns = thruster_forces(p, u, n_bt, n_st)
    xa, ya, na = wind_forces(p, wind_speed_rel, wind_angle_rel)
    return (xh + xp + xr + xa, yh + yp + yr + yb + ys + ya, nh + np_ + nr + nb + ns + na)


@njit(cache=True)
def mass_terms(p: FloatArray) -> tuple[float, float, float, float, float]:
    """(m [kg], m_x, m_y [kg], I_zG + J_z [kg m^2], x_G [m]); added masses from the primes (§3)."""
    L, d, rho = p[I_L], p[I_D], p[I_RHO]
    q = 0.5 * rho * L * L * d
    return p[I_M], p[I_MX] * q, p[I_MY] * q, p[I_IZG] + p[I_JZ] * q * L * L, p[I_XG]


@njit(cache=True)
def accelerations(p: FloatArray, u: float, v: float, r: float, n_rps: float, delta: float,
                  n_bt: float, n_st: float, wind_speed_rel: float,
                  wind_angle_rel: float) -> tuple[float, float, float]:
    """
    (du/dt, dv/dt [m/s^2], dr/dt [rad/s^2]) of the midship velocities through the water, body axes.

    From the equations of motion about midship (§3):

        (m + m_x) u' - (m + m_y) v r - x_G m r^2 = X
        (m + m_y) v' + x_G m r' + (m + m_x) u r = Y
        (I_zG + J_z + x_G^2 m) r' + x_G m (v' + u r) = N

    Arguments as in the module docstring. Kinematics (not here): x_E' = u cos psi - v sin psi,
    y_E' = u sin psi + v cos psi, psi' = r.
    """
    X, Y, N = total_forces(p, u, v, r, n_rps, delta, n_bt, n_st, wind_speed_rel,
                           wind_angle_rel)
    m, mx, my, iz, xg = mass_terms(p)
    du = (X + (m + my) * v * r + xg * m * r * r) / (m + mx)
    a11, a12 = m + my, xg * m
    a22 = iz + xg * xg * m
    b1 = Y - (m + mx) * u * r
    b2 = N - xg * m * u * r
    det = a11 * a22 - a12 * a12
    return du, (b1 * a22 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det


# --- the family interface (core/models/__init__.py) ----------------------------------------

@njit(cache=True)
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """
    Hull + propeller + rudder + thrusters (X [N], Y [N], N [N m]) about midship.

    For the generic kernels: act = (n_P [rev/s, signed], rudder [rad], bow, stern thruster
    [rev/s]). No wind here: the kernels add :func:`wind` on the apparent wind.
    """
    n = act[ACT_N]
    xh, yh, nh = hull_forces(p, u, v, r)
    xp, yp, np_, omw = propeller_forces(p, u, v, r, n)
    ur, vr = rudder_inflow(p, u, v, r, n, xp, omw)
    xr, yr, nr = rudder_forces(p, ur, vr, act[ACT_DELTA])
    yb, nb, ys, ns = thruster_forces(p, u, act[ACT_BOW], act[ACT_STERN])
    return xh + xp + xr, yh + yp + yr + yb + ys, nh + np_ + nr + nb + ns


@njit(cache=True)
def wind(p: FloatArray, wx: float, wy: float) -> tuple[float, float, float]:
    """
    Return Fujiwara's wind loads from the air's velocity relative to the ship.

    Fujiwara wind loads (X [N], Y [N], N [N m]) from the apparent wind given as the air's velocity
    relative to the ship in body axes (wx forward, wy starboard) [m/s].
    """
    ga = math.atan2(-wy, -wx)   # the direction it blows FROM, clockwise from the bow
    return wind_forces(p, math.sqrt(wx * wx + wy * wy), ga)
