"""The 3-DOF MMG equations and fixed-step integration, compiled with numba.

Two model structures share the equations of motion (paper eq. 7 / Yasukawa & Yoshimura 2015
eq. 4) and the polynomial hull model (paper eqs. 14-15); they differ in the propeller and
rudder-inflow models:

* ``container`` (MODEL_CONTAINER): Suyama et al. 2023 section 3 (SUZAKU), eqs. 16-36.
* ``standard`` (MODEL_STANDARD): the MMG standard method, Yasukawa & Yoshimura 2015.

Everything here is scalar code over one trajectory; batching over candidates and trials is a
``prange`` over independent trajectories (``simulate_many``), which numba spreads over cores.
The model state is (x_E, y_E, psi, u, v_m, r) with u, v_m relative to the water; with a
current, kinematics add the current and outputs report velocities over ground.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from mmg_tuner.core.layout import (DIVERGED, EULER, MODEL_CONTAINER, OK, PARAM_INDEX,
                                   RPM_NOT_POSITIVE, SURGE_NOT_POSITIVE)

# Parameter indices as module constants: numba folds them in at compile time.
_rho = PARAM_INDEX['rho']
_L = PARAM_INDEX['L_pp']
_d = PARAM_INDEX['d']
_m = PARAM_INDEX['m']
_xG = PARAM_INDEX['x_G']
_IzG = PARAM_INDEX['I_zG']
_DP = PARAM_INDEX['D_P']
_HR = PARAM_INDEX['H_R']
_AR = PARAM_INDEX['A_R']
_xR = PARAM_INDEX['x_R']
_mx = PARAM_INDEX['m_x']
_my = PARAM_INDEX['m_y']
_Jz = PARAM_INDEX['J_z']
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
_k0 = PARAM_INDEX['k_0']
_k1 = PARAM_INDEX['k_1']
_k2 = PARAM_INDEX['k_2']
_C1 = PARAM_INDEX['C_1']
_C2p = PARAM_INDEX['C_2p']
_C2n = PARAM_INDEX['C_2n']
_xP = PARAM_INDEX['x_P']
_tR = PARAM_INDEX['t_R']
_aH = PARAM_INDEX['a_H']
_xH = PARAM_INDEX['x_H']
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
_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_doff = PARAM_INDEX['rudder_offset']
_tau = PARAM_INDEX['rudder_lag_tau']
_nscale = PARAM_INDEX['rpm_scale']
_Nbias = PARAM_INDEX['yaw_moment_bias']
_ax = PARAM_INDEX['antenna_x']
_ay = PARAM_INDEX['antenna_y']
_toff = PARAM_INDEX['time_offset']
_CYP = PARAM_INDEX['prop_side_force']
_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']
_rhoa = PARAM_INDEX['rho_air']
_AF = PARAM_INDEX['A_F']
_AL = PARAM_INDEX['A_L']
_LOA = PARAM_INDEX['L_OA']
_sL = PARAM_INDEX['s_L']
_CDt = PARAM_INDEX['CD_t']
_CDlb = PARAM_INDEX['CD_lAF_bow']
_CDls = PARAM_INDEX['CD_lAF_stern']
_wdel = PARAM_INDEX['wind_delta']

# Fast-math without 'nnan'/'ninf': divergence checks rely on isfinite.
_FASTMATH = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}
_U_MIN = 1e-6  # m/s, keeps r' = r L / U finite at rest (u > 0 is enforced separately)


@njit(cache=True, fastmath=_FASTMATH, inline='always')
def _sin_attack(delta, uR, vR):
    """sin(alpha_R), alpha_R = delta - atan2(v_R, u_R), without the atan2 (hot path)."""
    UR = math.sqrt(uR * uR + vR * vR)
    if UR == 0.0:
        return math.sin(delta)
    return (math.sin(delta) * uR - math.cos(delta) * vR) / UR


@njit(cache=True, fastmath=_FASTMATH)
def accelerations(kind, p, u, v, r, n_rps, delta):
    """(du/dt, dv_m/dt, dr/dt) for velocities through the water, n_P in rev/s, delta in rad."""
    rho = p[_rho]
    L = p[_L]
    d = p[_d]
    U = math.sqrt(u * u + v * v)
    if U < _U_MIN:
        U = _U_MIN
    vp = v / U                       # v'_m = -sin(beta)
    rp = r * L / U                   # r'
    beta = math.atan(-v / u) if u > 0.0 else math.atan2(-v, u)  # atan: cheaper, u > 0 here
    vp2 = vp * vp
    rp2 = rp * rp
    # Hull (paper eqs. 14-15; standard method eq. 8 with X_vvvr = 0)
    XHp = (-p[_R0] + p[_Xvv] * vp2 + p[_Xvr] * vp * rp + p[_Xrr] * rp2
           + p[_Xvvvr] * vp2 * vp * rp + p[_Xvvvv] * vp2 * vp2)
    YHp = (p[_Yv] * vp + p[_Yr] * rp + p[_Yvvv] * vp2 * vp + p[_Yvvr] * vp2 * rp
           + p[_Yvrr] * vp * rp2 + p[_Yrrr] * rp2 * rp)
    NHp = (p[_Nv] * vp + p[_Nr] * rp + p[_Nvvv] * vp2 * vp + p[_Nvvr] * vp2 * rp
           + p[_Nvrr] * vp * rp2 + p[_Nrrr] * rp2 * rp)
    qU = 0.5 * rho * L * d * U * U
    X = qU * XHp
    Y = qU * YHp
    N = qU * L * (NHp + p[_Nbias])

    DP = p[_DP]
    eta = DP / p[_HR]
    if kind == MODEL_CONTAINER:
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
        root = 1.0 + 8.0 * KT / (math.pi * JP * JP)
        if root < 0.0:
            root = 0.0
        uR = uP * p[_eps] * (eta * p[_kap] * (math.sqrt(root) - 1.0) + 1.0)
        uRss = vt * p[_uR0]
        if uRss > uR:
            uR = uRss
        beta_R = beta - p[_lR] * rp
        gam = p[_gRp] if beta_R > 0.0 else p[_gRn]
        vR = gam * (-v - p[_lR] * L * r)           # gamma_R (U sin(beta) - l_R r)
        df = p[_flap] * delta
        coef = (p[_fa] + p[_fa2] * df * df) * _sin_attack(delta, uR, vR) \
            + df * (p[_Cl01] + p[_Cl03] * df * df)
    else:
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
        root = 1.0 + 8.0 * KT / (math.pi * JP * JP)
        if root < 0.0:
            root = 0.0
        a = 1.0 + p[_kap] * (math.sqrt(root) - 1.0)
        uR = p[_eps] * uP * math.sqrt(eta * a * a + (1.0 - eta))
        beta_R = beta - p[_lR] * rp
        gam = p[_gRp] if beta_R > 0.0 else p[_gRn]
        vR = U * gam * beta_R
        coef = p[_fa] * _sin_attack(delta, uR, vR)
    if p[_CYP] != 0.0:
        # propeller side force (paddle-wheel effect) at the stern, scaling with n^2 like the
        # thrust: Y_PS = C_YPS rho n^2 D^4 at x_R (an effect, not in the standard method)
        YPS = p[_CYP] * rho * n_rps * n_rps * DP ** 4
        Y += YPS
        N += YPS * p[_xR] * L
    # Rudder forces (paper eqs. 25-28; standard eqs. 17-20)
    FN = 0.5 * rho * p[_AR] * (uR * uR + vR * vR) * coef
    sd = math.sin(delta)
    cd = math.cos(delta)
    aH = p[_aH]
    X += -(1.0 - p[_tR]) * FN * sd
    Y += -(1.0 + aH) * FN * cd
    N += -(p[_xR] + aH * p[_xH]) * L * FN * cd

    # Equations of motion (paper eq. 7), solved for the accelerations
    m = p[_m]
    xG = p[_xG]
    q2 = 0.5 * rho * L * L * d
    mx = p[_mx] * q2
    my = p[_my] * q2
    Jz = p[_Jz] * q2 * L * L
    fX = X + (m + my) * v * r + xG * m * r * r
    fY = Y - (m + mx) * u * r
    fN = N - xG * m * u * r
    a11 = m + my
    a12 = xG * m
    a22 = p[_IzG] + xG * xG * m + Jz
    det = a11 * a22 - a12 * a12
    return fX / (m + mx), (a22 * fY - a12 * fN) / det, (a11 * fN - a12 * fY) / det


@njit(cache=True, fastmath=_FASTMATH)
def wind_loads(p, psi, u_g, v_g):
    """Wind force and moment (X [N], Y [N], N [N m]) on the above-water ship, Blendermann (1994).

    A steady true wind of p[wind_speed] m/s blows *from* p[wind_dir] (rad, clockwise from north,
    the meteorological convention); u_g, v_g is the ship's velocity over ground (body axes).
    gamma is the apparent wind's angle *from* the bow, + from starboard, so the formulas read
    (Blendermann 1994 eqs. for C_X, C_Y, C_N as given in Fossen 2011 sec. 8.1, with that
    book's gamma_rw = -gamma and |gamma| in the moment arm so port and starboard are mirror
    images):
      C_X = -CD_lAF cos(gamma) / D,  C_Y = -CD_t sin(gamma) / D,
      D = 1 - delta/2 (1 - CD_l/CD_t) sin^2(2 gamma),  CD_l = CD_lAF A_F / A_L,
      C_N = C_Y (s_L/L_OA - 0.18 (|gamma| - pi/2)),
    X = C_X q A_F, Y = C_Y q A_L, N = C_N q A_L L_OA, q = 1/2 rho_air V_A^2.
    """
    rel = p[_dirw] - psi
    ua = -p[_Vw] * math.cos(rel) - u_g        # apparent wind (air relative to the ship)
    va = -p[_Vw] * math.sin(rel) - v_g
    VA2 = ua * ua + va * va
    if VA2 == 0.0:
        return 0.0, 0.0, 0.0
    gamma = math.atan2(-va, -ua)
    CDlAF = p[_CDlb] if abs(gamma) <= 0.5 * math.pi else p[_CDls]
    CDt = p[_CDt]
    s2 = math.sin(2.0 * gamma)
    D = 1.0 - 0.5 * p[_wdel] * (1.0 - CDlAF * p[_AF] / (p[_AL] * CDt)) * s2 * s2
    q = 0.5 * p[_rhoa] * VA2
    CY = -CDt * math.sin(gamma) / D
    Y = CY * q * p[_AL]
    X = -CDlAF * math.cos(gamma) / D * q * p[_AF]
    N = CY * (p[_sL] / p[_LOA] - 0.18 * (abs(gamma) - 0.5 * math.pi)) * q * p[_AL] * p[_LOA]
    return X, Y, N


@njit(cache=True, fastmath=_FASTMATH)
def _external_accelerations(p, X, Y, N):
    """Accelerations from external forces through the same mass matrix as eq. 7."""
    m = p[_m]
    xG = p[_xG]
    q2 = 0.5 * p[_rho] * p[_L] * p[_L] * p[_d]
    a11 = m + p[_my] * q2
    a12 = xG * m
    a22 = p[_IzG] + xG * xG * m + p[_Jz] * q2 * p[_L] * p[_L]
    det = a11 * a22 - a12 * a12
    return X / (m + p[_mx] * q2), (a22 * Y - a12 * N) / det, (a11 * N - a12 * Y) / det


@njit(cache=True, fastmath=_FASTMATH)
def derivative(kind, p, s, n_rps, delta, out):
    """ds/dt for s = (x, y, psi, u, v, r) with u, v through the water (current added here)."""
    psi = s[2]
    u = s[3]
    v = s[4]
    r = s[5]
    c = math.cos(psi)
    sn = math.sin(psi)
    du, dv, dr = accelerations(kind, p, u, v, r, n_rps, delta)
    out[0] = u * c - v * sn
    out[1] = u * sn + v * c
    Vc = p[_Vc]
    if Vc != 0.0:
        out[0] += Vc * math.cos(p[_dirc])
        out[1] += Vc * math.sin(p[_dirc])
    if p[_Vw] != 0.0:
        ug = u
        vg = v
        if Vc != 0.0:
            ug += Vc * math.cos(p[_dirc] - psi)
            vg += Vc * math.sin(p[_dirc] - psi)
        Xw, Yw, Nw = wind_loads(p, psi, ug, vg)
        au, av, ar = _external_accelerations(p, Xw, Yw, Nw)
        du += au
        dv += av
        dr += ar
    out[2] = r
    out[3] = du
    out[4] = dv
    out[5] = dr


@njit(cache=True, fastmath=_FASTMATH)
def step(kind, p, s, n_rps, delta, h, method, k1, k2, k3, k4, tmp):
    """Advance s in place by one step h (Euler or classic RK4), controls held over the step."""
    derivative(kind, p, s, n_rps, delta, k1)
    if method == EULER:
        for i in range(6):
            s[i] += h * k1[i]
        return
    for i in range(6):
        tmp[i] = s[i] + 0.5 * h * k1[i]
    derivative(kind, p, tmp, n_rps, delta, k2)
    for i in range(6):
        tmp[i] = s[i] + 0.5 * h * k2[i]
    derivative(kind, p, tmp, n_rps, delta, k3)
    for i in range(6):
        tmp[i] = s[i] + h * k3[i]
    derivative(kind, p, tmp, n_rps, delta, k4)
    for i in range(6):
        s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, fastmath=_FASTMATH)
def _control_at(ctrl, k, j, frac_shift, T):
    """Control channel j at sample k delayed by frac_shift samples (linear interpolation)."""
    if frac_shift == 0.0:
        return ctrl[k, j]
    t = k - frac_shift
    if t <= 0.0:
        return ctrl[0, j]
    if t >= T - 1:
        return ctrl[T - 1, j]
    i = int(t)
    w = t - i
    return (1.0 - w) * ctrl[i, j] + w * ctrl[i + 1, j]


@njit(cache=True, fastmath=_FASTMATH)
def to_water(p, s):
    """Convert a state with over-ground u, v to u, v through the water (in place)."""
    Vc = p[_Vc]
    if Vc != 0.0:
        rel = p[_dirc] - s[2]
        s[3] -= Vc * math.cos(rel)
        s[4] -= Vc * math.sin(rel)


@njit(cache=True, fastmath=_FASTMATH)
def observe(p, s, out):
    """Measured quantities from the model state: position at the antenna, velocities over
    ground (the model integrates velocities through the water)."""
    for i in range(6):
        out[i] = s[i]
    psi = s[2]
    if p[_ax] != 0.0 or p[_ay] != 0.0:
        c = math.cos(psi)
        sn = math.sin(psi)
        out[0] += p[_ax] * c - p[_ay] * sn
        out[1] += p[_ax] * sn + p[_ay] * c
    if p[_Vc] != 0.0:
        rel = p[_dirc] - psi
        out[3] += p[_Vc] * math.cos(rel)
        out[4] += p[_Vc] * math.sin(rel)


@njit(cache=True, fastmath=_FASTMATH)
def advance(kind, p, s, delta_act, rpm, rudder, dt, substeps, method, k1, k2, k3, k4, tmp):
    """Advance the model state s (in place) over one sample interval dt with the recorded or
    commanded rpm and rudder [rad] held; the one implementation used by offline simulation, the
    tuning objective and the simulator node.

    delta_act is the actual rudder angle (the steering-gear lag state); the effects act here:
    rpm_scale, rudder_offset, rudder_lag_tau. Returns (status, new delta_act).
    """
    n_rps = rpm * p[_nscale] / 60.0
    if not n_rps > 0.0:
        return RPM_NOT_POSITIVE, delta_act
    delta_cmd = rudder + p[_doff]
    h = dt / substeps
    tau = p[_tau]
    decay = math.exp(-h / tau) if tau > 0.0 else 0.0
    for _ in range(substeps):
        # steering gear: exact first-order response to the held command
        delta_act = delta_cmd + (delta_act - delta_cmd) * decay
        if method == EULER:  # the tuning hot path: keep the call chain shallow for inlining
            derivative(kind, p, s, n_rps, delta_act, k1)
            for i in range(6):
                s[i] += h * k1[i]
        else:
            step(kind, p, s, n_rps, delta_act, h, method, k1, k2, k3, k4, tmp)
    # one test for all six: NaN/inf propagate through the sum (an overflowing sum is a
    # divergence too)
    if not math.isfinite(s[0] + s[1] + s[2] + s[3] + s[4] + s[5]):
        return DIVERGED, delta_act
    if s[3] <= 0.0:
        return SURGE_NOT_POSITIVE, delta_act
    return OK, delta_act


@njit(cache=True, fastmath=_FASTMATH)
def start_state(p, x0, s):
    """Model state from a first observed state: antenna position moved to midship, velocities
    over ground turned into velocities through the water."""
    for i in range(6):
        s[i] = x0[i]
    c = math.cos(s[2])
    sn = math.sin(s[2])
    s[0] -= p[_ax] * c - p[_ay] * sn
    s[1] -= p[_ax] * sn + p[_ay] * c
    to_water(p, s)


@njit(cache=True, fastmath=_FASTMATH)
def _use_measured_wind(p, ctrl, k):
    """Set the wind parameters of p (a per-trajectory copy) from the measured wind channels
    (air velocity north/east [m/s]) at sample k; NaN keeps the parameters."""
    wn = ctrl[k, 2]
    we = ctrl[k, 3]
    if wn == wn and we == we:
        p[_Vw] = math.sqrt(wn * wn + we * we)
        p[_dirw] = math.atan2(-we, -wn)  # blows from the opposite of where the air goes


@njit(cache=True, fastmath=_FASTMATH)
def simulate_one(kind, p_in, x0, ctrl, T, dt, substeps, method, out):
    """Simulate one trajectory over T samples spaced dt, writing observed states to out[:T].

    x0 is the first observed state (antenna position, velocities over ground); ctrl[k] =
    (rpm, rudder_rad) held from sample k to k+1 (delayed by time_offset if set), optionally
    followed by the measured wind (north, east) [m/s]. Returns (status, sample index of
    failure). After a failure the remaining rows are NaN.
    """
    measured_wind = ctrl.shape[1] >= 4
    p = p_in.copy()  # private: measured wind overwrites its wind slots (one copy per run)
    s = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    start_state(p, x0, s)
    observe(p, s, out[0])
    shift = p[_toff] / dt
    delta_act = _control_at(ctrl, 0, 1, shift, T) + p[_doff]
    status = OK
    k_fail = T
    for k in range(T - 1):
        if measured_wind:
            _use_measured_wind(p, ctrl, k)
        status, delta_act = advance(kind, p, s, delta_act, _control_at(ctrl, k, 0, shift, T),
                                    _control_at(ctrl, k, 1, shift, T), dt, substeps, method,
                                    k1, k2, k3, k4, tmp)
        if status != OK:
            k_fail = k if status == RPM_NOT_POSITIVE else k + 1
            break
        observe(p, s, out[k + 1])
    if status != OK:
        for k in range(k_fail, T):
            for i in range(6):
                out[k, i] = np.nan
    return status, k_fail


@njit(cache=True, parallel=True)
def simulate_many(kind, params, x0s, ctrls, lengths, dt, substeps, method, out, status, k_fail):
    """All (candidate, trial) pairs: params (N, P), x0s (M, 6), ctrls (M, T, 2), lengths (M,),
    out (N, M, T, 6). Pairs are independent, so they run in parallel over cores."""
    N = params.shape[0]
    M = x0s.shape[0]
    for job in prange(N * M):
        i = job // M
        j = job % M
        st, kf = simulate_one(kind, params[i], x0s[j], ctrls[j], lengths[j], dt, substeps,
                              method, out[i, j])
        status[i, j] = st
        k_fail[i, j] = kf


@njit(cache=True, fastmath=_FASTMATH)
def run_maneuver(kind, p, x0, rpm, rudder_cmd, zigzag_amp, zigzag_check, rate, T, dt, substeps,
                 method, out, rudder_out):
    """Simulate a manoeuvre with a steering gear in the loop (for generating trials).

    rudder_cmd[k] is the open-loop rudder order at sample k (rad); if zigzag_amp != 0 the order
    is instead closed on heading from the first sample where rudder_cmd[k] != 0: it starts at
    zigzag_amp and reverses when the heading change passes +-zigzag_check (IMO zigzag).
    rate: steering-gear rate limit [rad/s] (<= 0: instantaneous). rpm[k] is held per sample.
    Writes observed states to out and the actual rudder angle at each sample to rudder_out.
    Returns (status, k_fail).
    """
    s = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    for i in range(6):
        s[i] = x0[i]
    to_water(p, s)
    observe(p, s, out[0])
    h = dt / substeps
    max_move = rate * h if rate > 0.0 else 1e9
    delta = 0.0  # straight approach: the rudder starts amidships and moves at the gear's rate
    rudder_out[0] = delta
    # effects between the recorded (indicated) rudder/rpm and what acts on the ship
    tau = p[_tau]
    decay = math.exp(-h / tau) if tau > 0.0 else 0.0
    delta_act = delta + p[_doff]
    zz_started = False
    zz_cmd = zigzag_amp
    psi0 = s[2]
    status = OK
    k_fail = T
    for k in range(T - 1):
        n_rps = rpm[k] * p[_nscale] / 60.0
        if not n_rps > 0.0:
            status = RPM_NOT_POSITIVE
            k_fail = k
            break
        for _ in range(substeps):
            if zigzag_amp != 0.0:
                if not zz_started and rudder_cmd[k] != 0.0:
                    zz_started = True
                    psi0 = s[2]
                if zz_started:
                    dpsi = s[2] - psi0
                    if zz_cmd > 0.0 and dpsi >= zigzag_check:
                        zz_cmd = -abs(zigzag_amp)
                    elif zz_cmd < 0.0 and dpsi <= -zigzag_check:
                        zz_cmd = abs(zigzag_amp)
                    cmd = zz_cmd
                else:
                    cmd = 0.0
            else:
                cmd = rudder_cmd[k]
            # the step sees the angle at its start (as a zero-order-hold replay of the
            # recorded angle does); the gear then moves toward the order
            delta_act = delta + p[_doff] + (delta_act - delta - p[_doff]) * decay
            step(kind, p, s, n_rps, delta_act, h, method, k1, k2, k3, k4, tmp)
            diff = cmd - delta
            if diff > max_move:
                diff = max_move
            elif diff < -max_move:
                diff = -max_move
            delta += diff
        ok = True
        for i in range(6):
            if not math.isfinite(s[i]):
                ok = False
        if not ok:
            status = DIVERGED
            k_fail = k + 1
            break
        if s[3] <= 0.0:
            status = SURGE_NOT_POSITIVE
            k_fail = k + 1
            break
        observe(p, s, out[k + 1])
        rudder_out[k + 1] = delta
    if status != OK:
        for k in range(k_fail, T):
            rudder_out[k] = np.nan
            for i in range(6):
                out[k, i] = np.nan
    return status, k_fail


@njit(cache=True, fastmath=_FASTMATH)
def _wrap_pi(a):
    # heading errors are almost always inside (-pi, pi]: skip the costly modulo then
    if -math.pi < a <= math.pi:
        return a
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, fastmath=_FASTMATH)
def trajectory_cost(kind, p_in, meas, ctrl, T, dt, substeps, method, weights, shoot_every):
    """Weighted squared error of a simulation against a measured trial (Suyama et al. eq. 43).

    The simulation starts from meas[0] and is driven by ctrl; J = sum_{k>=1} e_k' W e_k with
    e = observed - measured over (x, y, psi (wrapped), u, v, r) and W = diag(weights).
    shoot_every > 0 restarts the simulation from the measured state every shoot_every samples
    (multiple shooting). Returns (J, k_fail): k_fail < T means the run failed at that sample
    (diverged or left the model's range) and J covers only the samples before it.
    """
    measured_wind = ctrl.shape[1] >= 4
    p = p_in.copy()  # private: measured wind overwrites its wind slots (one copy per run)
    s = np.empty(6)
    o = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    shift = p[_toff] / dt
    delta_act = _control_at(ctrl, 0, 1, shift, T) + p[_doff]
    J = 0.0
    for k in range(T - 1):
        if k == 0 or (shoot_every > 0 and k % shoot_every == 0):
            start_state(p, meas[k], s)
        if measured_wind:
            _use_measured_wind(p, ctrl, k)
        status, delta_act = advance(kind, p, s, delta_act, _control_at(ctrl, k, 0, shift, T),
                                    _control_at(ctrl, k, 1, shift, T), dt, substeps, method,
                                    k1, k2, k3, k4, tmp)
        if status != OK:
            return J, (k if status == RPM_NOT_POSITIVE else k + 1)
        observe(p, s, o)
        m = meas[k + 1]
        e = o[0] - m[0]
        J += weights[0] * e * e
        e = o[1] - m[1]
        J += weights[1] * e * e
        e = _wrap_pi(o[2] - m[2])
        J += weights[2] * e * e
        if weights[3] != 0.0 or weights[4] != 0.0 or weights[5] != 0.0:
            for i in range(3, 6):
                e = o[i] - m[i]
                J += weights[i] * e * e
    return J, T


@njit(cache=True, parallel=True)
def cost_many(kind, params, meas, ctrls, lengths, dt, substeps, method, weights, shoot_every,
              J, k_fail):
    """trajectory_cost for every (candidate, trial) pair, in parallel: J and k_fail (N, M)."""
    N = params.shape[0]
    M = meas.shape[0]
    for job in prange(N * M):
        i = job // M
        j = job % M
        c, kf = trajectory_cost(kind, params[i], meas[j], ctrls[j], lengths[j], dt, substeps,
                                method, weights, shoot_every)
        J[i, j] = c
        k_fail[i, j] = kf
