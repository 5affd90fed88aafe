"""
Family-blind dynamics.

Dispatch to the model family's forces, the effects that act as forces, wind loads (the family's own
wind model, or Blendermann's), and the equations of motion (paper eq. 7 / Yasukawa & Yoshimura 2015
eq. 4) solved for the accelerations; ds/dt with the current's kinematics.

The model state is (x_E, y_E, psi, u, v_m, r) with u, v_m relative to the water; with a
current, kinematics add the current and outputs report velocities over ground.

Every kernel's ``kind`` is either the family code (an int: one compiled kernel that branches
on it at run time, for callers that only know the code at run time) or the family's tag
``FAMILY_TAGS[code]`` (a tuple whose length is the code + 1, so that the family is part of the
argument's numba type: each family gets its own kernel with only its forces inlined and no
branch; the entry points of ``core/integrate.py`` pass tags).
"""
from __future__ import annotations

import math
import warnings

from mmg_tuner.core._jit import FASTMATH, U_MIN
from mmg_tuner.core.channels import ACT_N
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.models import families
from numba import literal_unroll, njit, types
from numba.core.errors import NumbaExperimentalFeatureWarning
from numba.extending import overload

# literal_unroll over a tuple of dispatchers reports numba's first-class-function machinery as
# experimental; each call in the unrolled loop is a static, inlined call.
warnings.filterwarnings('ignore', 'First-class function type feature is experimental',
                        NumbaExperimentalFeatureWarning)

_FAMILIES = families()
_FORCES = tuple(f.forces for f in _FAMILIES)
ASTERN_RPM = tuple(f.astern_rpm for f in _FAMILIES)
ASTERN_SURGE = tuple(f.astern_surge for f in _FAMILIES)
AIR_DRAG = tuple(f.air_drag for f in _FAMILIES)

FAMILY_TAGS = tuple((0,) * (f.code + 1) for f in _FAMILIES)
"""The compile-time form of each family code (see the module docstring)."""


def family_tag(kind: int) -> tuple:
    """Return the tag of family code ``kind`` (ValueError if no family has that code)."""
    if not 0 <= kind < len(FAMILY_TAGS):
        raise ValueError(f'no model family with code {kind!r}; codes are 0..'
                         f'{len(FAMILY_TAGS) - 1} (core/models REGISTRY)')
    return FAMILY_TAGS[kind]


def _tag_code(kind):
    """Return the family code a tag's numba type fixes (at compile time); None for an int."""
    if isinstance(kind, types.UniTuple):
        return kind.count - 1
    if isinstance(kind, types.Integer):
        return None
    raise TypeError(f'kind must be a family code (int) or a FAMILY_TAGS entry, got {kind}')


def _family_flag(flags):
    """Make an njit-callable ``flag(kind)``: ``flags[code]``, a constant when kind is a tag."""
    def flag(kind):
        raise NotImplementedError('compiled only (numba overload)')

    @overload(flag, inline='always')
    def _flag(kind):
        code = _tag_code(kind)
        if code is None:
            return lambda kind: flags[kind]
        value = flags[code]
        return lambda kind: value
    return flag


astern_rpm = _family_flag(ASTERN_RPM)
astern_surge = _family_flag(ASTERN_SURGE)
air_drag = _family_flag(AIR_DRAG)


# The family hooks, dispatched on kind: a direct, inlined call when kind is a tag, else a
# branch over the families (literal_unroll: one static call per family).
def _forces_of(kind, p, u, v, r, act):
    raise NotImplementedError('compiled only (numba overload)')


@overload(_forces_of, inline='always', jit_options={'fastmath': FASTMATH})
def _forces_of_impl(kind, p, u, v, r, act):
    code = _tag_code(kind)
    if code is not None:
        forces = _FORCES[code]
        return lambda kind, p, u, v, r, act: forces(p, u, v, r, act)

    def branch(kind, p, u, v, r, act):
        X = 0.0
        Y = 0.0
        N = 0.0
        i = 0
        for f in literal_unroll(_FORCES):
            if i == kind:
                X, Y, N = f(p, u, v, r, act)
            i += 1
        return X, Y, N
    return branch


_rho = PARAM_INDEX['rho']
_L = PARAM_INDEX['L_pp']
_d = PARAM_INDEX['d']
_m = PARAM_INDEX['m']
_xG = PARAM_INDEX['x_G']
_IzG = PARAM_INDEX['I_zG']
_DP = PARAM_INDEX['D_P']
_xR = PARAM_INDEX['x_R']
_mx = PARAM_INDEX['m_x']
_my = PARAM_INDEX['m_y']
_Jz = PARAM_INDEX['J_z']
_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_Nbias = PARAM_INDEX['yaw_moment_bias']
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


@njit(cache=True, fastmath=FASTMATH, inline='always')
def family_forces(kind, p, u, v, r, act):
    """Return the forces of family ``kind`` (code or tag): (X [N], Y [N], N [N m])."""
    return _forces_of(kind, p, u, v, r, act)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def effect_forces(p, u, v, act, X, Y, N):
    """Effect hooks that act as forces, added to the family's (each vanishes at neutral)."""
    if p[_Nbias] != 0.0:
        # yaw_moment_bias: N'_0 x 1/2 rho L^2 d U^2
        U = math.sqrt(u * u + v * v)
        if U < U_MIN:
            U = U_MIN
        N += 0.5 * p[_rho] * p[_L] * p[_d] * U * U * p[_L] * p[_Nbias]
    if p[_CYP] != 0.0:
        # propeller side force (paddle-wheel effect) at the stern, scaling with n^2 like the
        # thrust: Y_PS = C_YPS rho n^2 D^4 at x_R
        n = act[ACT_N]
        YPS = p[_CYP] * p[_rho] * n * n * p[_DP] ** 4
        Y += YPS
        N += YPS * p[_xR] * p[_L]
    return X, Y, N


@njit(cache=True, fastmath=FASTMATH, inline='always')
def accelerations(kind, p, u, v, r, act):
    """(du/dt, dv_m/dt, dr/dt) for velocities through the water and the actuator tuple act."""
    X, Y, N = family_forces(kind, p, u, v, r, act)
    X, Y, N = effect_forces(p, u, v, act, X, Y, N)
    # Equations of motion (paper eq. 7), solved for the accelerations
    rho = p[_rho]
    L = p[_L]
    m = p[_m]
    xG = p[_xG]
    q2 = 0.5 * rho * L * L * p[_d]
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


@njit(cache=True, fastmath=FASTMATH)
def wind_loads(p, psi, u_g, v_g):
    """
    Wind force and moment (X [N], Y [N], N [N m]) on the above-water ship, Blendermann (1994).

    A steady true wind of p[wind_speed] m/s blows *from* p[wind_dir] (rad, clockwise from north,
    the meteorological convention); u_g, v_g is the ship's velocity over ground (body axes).
    """
    rel = p[_dirw] - psi
    return blendermann(p, -p[_Vw] * math.cos(rel) - u_g, -p[_Vw] * math.sin(rel) - v_g)


@njit(cache=True, fastmath=FASTMATH)
def blendermann(p, ua, va):
    """
    Blendermann (1994) wind loads (X [N], Y [N], N [N m]) from the apparent wind (ua, va).

    The air's velocity relative to the ship in body axes [m/s].

    gamma is the apparent wind's angle *from* the bow, + from starboard, so the formulas read
    (Blendermann 1994 eqs. for C_X, C_Y, C_N as given in Fossen 2011 sec. 8.1, with that
    book's gamma_rw = -gamma and |gamma| in the moment arm so port and starboard are mirror
    images):
      C_X = -CD_lAF cos(gamma) / D,  C_Y = -CD_t sin(gamma) / D,
      D = 1 - delta/2 (1 - CD_l/CD_t) sin^2(2 gamma),  CD_l = CD_lAF A_F / A_L,
      C_N = C_Y (s_L/L_OA - 0.18 (|gamma| - pi/2)),
    X = C_X q A_F, Y = C_Y q A_L, N = C_N q A_L L_OA, q = 1/2 rho_air V_A^2.
    """
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


_WINDS = tuple(blendermann if f.wind is None else f.wind for f in _FAMILIES)


def _wind_of(kind, p, ua, va):
    raise NotImplementedError('compiled only (numba overload)')


@overload(_wind_of, inline='always', jit_options={'fastmath': FASTMATH})
def _wind_of_impl(kind, p, ua, va):
    code = _tag_code(kind)
    if code is not None:
        wind = _WINDS[code]
        return lambda kind, p, ua, va: wind(p, ua, va)

    def branch(kind, p, ua, va):
        X = 0.0
        Y = 0.0
        N = 0.0
        i = 0
        for f in literal_unroll(_WINDS):
            if i == kind:
                X, Y, N = f(p, ua, va)
            i += 1
        return X, Y, N
    return branch


@njit(cache=True, fastmath=FASTMATH, inline='always')
def family_wind(kind, p, ua, va):
    """
    Compute the wind loads of family ``kind``'s wind model from the apparent wind.

    Wind loads (X [N], Y [N], N [N m]) of family ``kind``'s wind model (its own, else
    Blendermann's) from the apparent wind (ua, va), the air's velocity relative to the ship in body
    axes [m/s].
    """
    return _wind_of(kind, p, ua, va)


@njit(cache=True, fastmath=FASTMATH)
def external_accelerations(p, X, Y, N):
    """Accelerations from external forces through the same mass matrix as eq. 7."""
    m = p[_m]
    xG = p[_xG]
    q2 = 0.5 * p[_rho] * p[_L] * p[_L] * p[_d]
    a11 = m + p[_my] * q2
    a12 = xG * m
    a22 = p[_IzG] + xG * xG * m + p[_Jz] * q2 * p[_L] * p[_L]
    det = a11 * a22 - a12 * a12
    return X / (m + p[_mx] * q2), (a22 * Y - a12 * N) / det, (a11 * N - a12 * Y) / det


@njit(cache=True, fastmath=FASTMATH, inline='always')
def rhs(kind, p, s, act, out):
    """
    Write ds/dt for s = (x, y, psi, u, v, r) into out; u, v through the water.

    Inlined into the integrators: a compiled call passing arrays costs an atomic
    reference-count update per array argument and exit, about 40 % of an Euler step.
    """
    psi = s[2]
    u = s[3]
    v = s[4]
    r = s[5]
    c = math.cos(psi)
    sn = math.sin(psi)
    du, dv, dr = accelerations(kind, p, u, v, r, act)
    out[0] = u * c - v * sn
    out[1] = u * sn + v * c
    Vc = p[_Vc]
    if Vc != 0.0:
        out[0] += Vc * math.cos(p[_dirc])
        out[1] += Vc * math.sin(p[_dirc])
    Vw = p[_Vw]
    if Vw != 0.0 or air_drag(kind):  # a family with AIR_DRAG feels its own motion's air drag
        ug = u
        vg = v
        if Vc != 0.0:
            ug += Vc * math.cos(p[_dirc] - psi)
            vg += Vc * math.sin(p[_dirc] - psi)
        rel = p[_dirw] - psi
        Xw, Yw, Nw = family_wind(kind, p, -Vw * math.cos(rel) - ug, -Vw * math.sin(rel) - vg)
        au, av, ar = external_accelerations(p, Xw, Yw, Nw)
        du += au
        dv += av
        dr += ar
    out[2] = r
    out[3] = du
    out[4] = dv
    out[5] = dr


@njit(cache=True, fastmath=FASTMATH)
def derivative(kind, p, s, act, out):
    """ds/dt for s = (x, y, psi, u, v, r) with u, v through the water (current added here)."""
    rhs(kind, p, s, act, out)
