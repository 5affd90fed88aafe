"""
Family-blind dynamics.

Dispatch to the model family's forces, the effects that act as forces, wind loads (the family's own
wind model, or Blendermann's), and the equations of motion (paper eq. 7 / Yasukawa & Yoshimura 2015
eq. 4) solved for the accelerations; ds/dt with the current's kinematics.

The model state is (x_E, y_E, psi, u, v_m, r) with u, v_m relative to the water; with a
current, kinematics add the current and outputs report velocities over ground.

Every kernel's ``kind`` is the family's tag ``FAMILY_TAGS[code]`` (a tuple whose length is the
code + 1, so that the family is part of the argument's numba type: each family gets its own
kernel with only its forces, actuators and equations of motion inlined, and no branch). The
Python entry points (``core/integrate.py``) take the code (``ShipConfig.kind``) and pass the tag.

The plant of a family: its actuators (``core/actuators``) turn the input row into the actuator
tuple (:func:`actuate_start`, :func:`actuate_hold`, :func:`actuate_output`) and add their forces
(:func:`actuator_forces`); its ``forces`` give the hull's; its equations of motion (its own
``inertia`` and ``mass_solve``, else the MMG's eq. 7) give the accelerations.
"""
from __future__ import annotations

import math
from typing import Any, Callable, TYPE_CHECKING
import warnings

from mmg_tuner.core._jit import FASTMATH, U_MIN
from mmg_tuner.core.actuators import actuator
from mmg_tuner.core.inputs import commands, where
from mmg_tuner.core.layout import OK, PARAM_INDEX
from mmg_tuner.core.models import families
from numba import njit, types
from numba.core.errors import NumbaExperimentalFeatureWarning
from numba.extending import overload

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray
    from mmg_tuner.core.actuators import Actuator

# Tuples of dispatchers are reported as numba's experimental first-class functions; every call
# here is a static, inlined call on a compile-time constant.
warnings.filterwarnings('ignore', 'First-class function type feature is experimental',
                        NumbaExperimentalFeatureWarning)

_FAMILIES = families()
_FORCES = tuple(f.forces for f in _FAMILIES)
ASTERN_RPM = tuple(f.astern_rpm for f in _FAMILIES)
ASTERN_SURGE = tuple(f.astern_surge for f in _FAMILIES)
AIR_DRAG = tuple(f.air_drag for f in _FAMILIES)

FAMILY_TAGS = tuple((0,) * (f.code + 1) for f in _FAMILIES)
"""The compile-time form of each family code (see the module docstring)."""


def family_tag(kind: int) -> tuple[int, ...]:
    """Return the tag of family code ``kind`` (ValueError if no family has that code)."""
    if not 0 <= kind < len(FAMILY_TAGS):
        raise ValueError(f'no model family with code {kind!r}; codes are 0..'
                         f'{len(FAMILY_TAGS) - 1} (core/models REGISTRY)')
    return FAMILY_TAGS[kind]


def _tag_code(kind: types.Type) -> int:
    """Return the family code a tag's numba type fixes (at compile time)."""
    if isinstance(kind, types.UniTuple):
        return int(kind.count) - 1  # plain Python at compile time; numba's stubs: count Any
    raise TypeError(f'kind must be a FAMILY_TAGS entry (dynamics.family_tag(code)), got {kind}')


def _family_flag(flags: tuple[bool, ...]) -> Callable[..., Any]:
    """Make an njit-callable ``flag(kind)``: ``flags[code]``, a constant when kind is a tag."""
    def flag(kind: tuple[int, ...]) -> bool:
        raise NotImplementedError('compiled only (numba overload)')

    @overload(flag, inline='always')
    def _flag(kind):  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        value = flags[_tag_code(kind)]
        return lambda kind: value
    return flag


astern_rpm = _family_flag(ASTERN_RPM)
astern_surge = _family_flag(ASTERN_SURGE)
air_drag = _family_flag(AIR_DRAG)


# The family hooks, dispatched on the tag: a direct, inlined call of that family's function.
def _forces_of(kind: tuple[int, ...], p: FloatArray, u: float, v: float, r: float,
               act: tuple[float, ...]) -> tuple[float, float, float]:
    raise NotImplementedError('compiled only (numba overload)')


@overload(_forces_of, inline='always', jit_options={'fastmath': FASTMATH})
def _forces_of_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, u, v, r, act):
    forces = _FORCES[_tag_code(kind)]
    return lambda kind, p, u, v, r, act: forces(p, u, v, r, act)


_rho = PARAM_INDEX['rho']
_L = PARAM_INDEX['L_pp']
_d = PARAM_INDEX['d']
_m = PARAM_INDEX['m']
_xG = PARAM_INDEX['x_G']
_IzG = PARAM_INDEX['I_zG']
_mx = PARAM_INDEX['m_x']
_my = PARAM_INDEX['m_y']
_Jz = PARAM_INDEX['J_z']
_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_Nbias = PARAM_INDEX['yaw_moment_bias']
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
def family_forces(kind: tuple[int, ...], p: FloatArray, u: float, v: float, r: float,
                  act: tuple[float, ...]) -> tuple[float, float, float]:
    """Return the forces of family ``kind`` (code or tag): (X [N], Y [N], N [N m])."""
    return _forces_of(kind, p, u, v, r, act)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def effect_forces(p: FloatArray, u: float, v: float, X: float, Y: float,
                  N: float) -> tuple[float, float, float]:
    """Effect hooks on the hull that act as forces, added to the family's (0 at neutral)."""
    if p[_Nbias] != 0.0:
        # yaw_moment_bias: N'_0 x 1/2 rho L^2 d U^2
        U = math.sqrt(u * u + v * v)
        if U < U_MIN:
            U = U_MIN
        N += 0.5 * p[_rho] * p[_L] * p[_d] * U * U * p[_L] * p[_Nbias]
    return X, Y, N


@njit(cache=True, fastmath=FASTMATH, inline='always')
def mmg_motion(p: FloatArray, u: float, v: float, r: float, X: float, Y: float,
               N: float) -> tuple[float, float, float]:
    """
    Solve the MMG equations of motion (paper eq. 7) for (du/dt, dv_m/dt, dr/dt).

    X, Y, N: every force and moment but the inertia terms [N, N m]; the added masses are the
    non-dimensional m_x, m_y, J_z of the flat vector.
    """
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


@njit(cache=True, fastmath=FASTMATH, inline='always')
def mmg_mass_solve(p: FloatArray, X: float, Y: float, N: float) -> tuple[float, float, float]:
    """Accelerations from external forces through the MMG mass matrix (eq. 7)."""
    m = p[_m]
    xG = p[_xG]
    q2 = 0.5 * p[_rho] * p[_L] * p[_L] * p[_d]
    a11 = m + p[_my] * q2
    a12 = xG * m
    a22 = p[_IzG] + xG * xG * m + p[_Jz] * q2 * p[_L] * p[_L]
    det = a11 * a22 - a12 * a12
    return X / (m + p[_mx] * q2), (a22 * Y - a12 * N) / det, (a11 * N - a12 * Y) / det


_MOTION = tuple(mmg_motion if f.motion is None else f.motion for f in _FAMILIES)
_MASS_SOLVE = tuple(mmg_mass_solve if f.mass_solve is None else f.mass_solve
                    for f in _FAMILIES)


def _motion_of(kind: tuple[int, ...], p: FloatArray, u: float, v: float, r: float, X: float,
               Y: float, N: float) -> tuple[float, float, float]:
    raise NotImplementedError('compiled only (numba overload)')


@overload(_motion_of, inline='always', jit_options={'fastmath': FASTMATH})
def _motion_of_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, u, v, r, X, Y, N):
    motion = _MOTION[_tag_code(kind)]
    return lambda kind, p, u, v, r, X, Y, N: motion(p, u, v, r, X, Y, N)


def _solve_of(kind: tuple[int, ...], p: FloatArray, X: float, Y: float,
              N: float) -> tuple[float, float, float]:
    raise NotImplementedError('compiled only (numba overload)')


@overload(_solve_of, inline='always', jit_options={'fastmath': FASTMATH})
def _solve_of_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, X, Y, N):
    solve = _MASS_SOLVE[_tag_code(kind)]
    return lambda kind, p, X, Y, N: solve(p, X, Y, N)


# ----------------------------------------------------------------------------- actuators
def _plant(code: int) -> list[tuple[Actuator, int, int, int]]:
    """Return family ``code``'s actuators: [(actuator, first input, state, output)]."""
    out = []
    j = i = k = 0
    for name in _FAMILIES[code].actuators:
        a = actuator(name)
        out.append((a, j, i, k))
        j += len(a.inputs)
        i += len(a.states)
        k += len(a.outputs)
    return out


MAX_ACTUATORS = 3
N_ACT_STATES = max(1, max(sum(len(actuator(n).states) for n in f.actuators)
                          for f in _FAMILIES))
"""Length of the actuator-state array every kernel keeps (the largest plant's)."""

for _f in _FAMILIES:
    if not 1 <= len(_f.actuators) <= MAX_ACTUATORS:
        raise ImportError(f'family {_f.name!r}: ACTUATORS must list 1 to {MAX_ACTUATORS} '
                          f'actuator models, got {_f.actuators}')


def actuate_start(kind: tuple[int, ...], p: FloatArray, ctrl: FloatArray, shift: float, T: int,
                  a: FloatArray) -> None:
    """Set the actuator states ``a`` from sample 0 of ``ctrl`` (compiled only)."""
    raise NotImplementedError('compiled only (numba overload)')


@overload(actuate_start, inline='always', jit_options={'fastmath': FASTMATH})
def _actuate_start_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, ctrl, shift, T, a):
    plant = _plant(_tag_code(kind))
    s0, r0, j0, i0 = plant[0][0].start, commands(len(plant[0][0].inputs)), plant[0][1], plant[0][2]
    if len(plant) == 1:
        def start1(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
                kind, p, ctrl, shift, T, a):
            k0, k1, w = where(0, shift, T)
            s0(p, r0(ctrl, k0, k1, w, j0), a, i0)
        return start1
    s1, r1, j1, i1 = plant[1][0].start, commands(len(plant[1][0].inputs)), plant[1][1], plant[1][2]
    if len(plant) == 2:
        def start2(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
                kind, p, ctrl, shift, T, a):
            k0, k1, w = where(0, shift, T)
            s0(p, r0(ctrl, k0, k1, w, j0), a, i0)
            s1(p, r1(ctrl, k0, k1, w, j1), a, i1)
        return start2
    s2, r2, j2, i2 = plant[2][0].start, commands(len(plant[2][0].inputs)), plant[2][1], plant[2][2]

    def start3(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
            kind, p, ctrl, shift, T, a):
        k0, k1, w = where(0, shift, T)
        s0(p, r0(ctrl, k0, k1, w, j0), a, i0)
        s1(p, r1(ctrl, k0, k1, w, j1), a, i1)
        s2(p, r2(ctrl, k0, k1, w, j2), a, i2)
    return start3


def actuate_hold(kind: tuple[int, ...], p: FloatArray, ctrl: FloatArray, k: int, shift: float,
                 T: int, h: float) -> tuple[int, tuple[tuple[float, ...], ...]]:
    """(status, held) for the inputs of sample k, held over its interval (compiled only)."""
    raise NotImplementedError('compiled only (numba overload)')


@overload(actuate_hold, inline='always', jit_options={'fastmath': FASTMATH})
def _actuate_hold_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, ctrl, k, shift, T, h):
    code = _tag_code(kind)
    astern = ASTERN_RPM[code]
    plant = _plant(code)
    h0, r0, j0 = plant[0][0].hold, commands(len(plant[0][0].inputs)), plant[0][1]
    if len(plant) == 1:
        def hold1(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
                kind, p, ctrl, k, shift, T, h):
            k0, k1, w = where(k, shift, T)
            st, held = h0(p, r0(ctrl, k0, k1, w, j0), h, astern)
            return st, (held,)
        return hold1
    h1, r1, j1 = plant[1][0].hold, commands(len(plant[1][0].inputs)), plant[1][1]
    if len(plant) == 2:
        def hold2(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
                kind, p, ctrl, k, shift, T, h):
            k0, k1, w = where(k, shift, T)
            st0, held0 = h0(p, r0(ctrl, k0, k1, w, j0), h, astern)
            st1, held1 = h1(p, r1(ctrl, k0, k1, w, j1), h, astern)
            return (st0 if st0 != OK else st1), (held0, held1)
        return hold2
    h2, r2, j2 = plant[2][0].hold, commands(len(plant[2][0].inputs)), plant[2][1]

    def hold3(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
            kind, p, ctrl, k, shift, T, h):
        k0, k1, w = where(k, shift, T)
        st0, held0 = h0(p, r0(ctrl, k0, k1, w, j0), h, astern)
        st1, held1 = h1(p, r1(ctrl, k0, k1, w, j1), h, astern)
        st2, held2 = h2(p, r2(ctrl, k0, k1, w, j2), h, astern)
        st = st0 if st0 != OK else (st1 if st1 != OK else st2)
        return st, (held0, held1, held2)
    return hold3


def actuate_output(kind: tuple[int, ...], p: FloatArray, held: tuple[tuple[float, ...], ...],
                   a: FloatArray) -> tuple[float, ...]:
    """Advance the actuator states over one step; return the actuator tuple (compiled only)."""
    raise NotImplementedError('compiled only (numba overload)')


@overload(actuate_output, inline='always', jit_options={'fastmath': FASTMATH})
def _actuate_output_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, held, a):
    plant = _plant(_tag_code(kind))
    o0, i0 = plant[0][0].output, plant[0][2]
    if len(plant) == 1:
        return lambda kind, p, held, a: o0(p, held[0], a, i0)
    o1, i1 = plant[1][0].output, plant[1][2]
    if len(plant) == 2:
        return lambda kind, p, held, a: o0(p, held[0], a, i0) + o1(p, held[1], a, i1)
    o2, i2 = plant[2][0].output, plant[2][2]
    return lambda kind, p, held, a: (o0(p, held[0], a, i0) + o1(p, held[1], a, i1)
                                     + o2(p, held[2], a, i2))


def act_tuple(kind: tuple[int, ...], A: FloatArray, b: int) -> tuple[float, ...]:
    """Row b of an actuator array A (B, n) as the family's actuator tuple (compiled only)."""
    raise NotImplementedError('compiled only (numba overload)')


_ROW_TUPLES = {1: lambda kind, A, b: (A[b, 0],),
               2: lambda kind, A, b: (A[b, 0], A[b, 1]),
               3: lambda kind, A, b: (A[b, 0], A[b, 1], A[b, 2]),
               4: lambda kind, A, b: (A[b, 0], A[b, 1], A[b, 2], A[b, 3]),
               5: lambda kind, A, b: (A[b, 0], A[b, 1], A[b, 2], A[b, 3], A[b, 4]),
               6: lambda kind, A, b: (A[b, 0], A[b, 1], A[b, 2], A[b, 3], A[b, 4], A[b, 5])}


@overload(act_tuple, inline='always')
def _act_tuple_impl(kind, A, b):  # type: ignore[no-untyped-def]  # numba matches it to the impl's
    n = len(_FAMILIES[_tag_code(kind)].outputs)
    if n not in _ROW_TUPLES:
        raise TypeError(f'act_tuple: {n} actuator outputs; add a row form for it')
    return _ROW_TUPLES[n]


@njit(cache=True, fastmath=FASTMATH, inline='always')
def _no_forces(p: FloatArray, u: float, v: float, r: float, act: tuple[float, ...],
               k: int) -> tuple[float, float, float]:
    return 0.0, 0.0, 0.0


def actuator_forces(kind: tuple[int, ...], p: FloatArray, u: float, v: float, r: float,
                    act: tuple[float, ...]) -> tuple[float, float, float]:
    """Sum of the actuators' own forces (X, Y, N) (compiled only)."""
    raise NotImplementedError('compiled only (numba overload)')


@overload(actuator_forces, inline='always', jit_options={'fastmath': FASTMATH})
def _actuator_forces_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, u, v, r, act):
    plant = [(A.forces, k) for A, _, _, k in _plant(_tag_code(kind)) if A.forces is not None]
    if not plant:
        return lambda kind, p, u, v, r, act: (0.0, 0.0, 0.0)
    f0, k0 = plant[0]
    if len(plant) == 1:
        return lambda kind, p, u, v, r, act: f0(p, u, v, r, act, k0)
    f1, k1 = plant[1]
    f2, k2 = plant[2] if len(plant) > 2 else (_no_forces, 0)

    def forces(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
            kind, p, u, v, r, act):
        X, Y, N = f0(p, u, v, r, act, k0)
        X1, Y1, N1 = f1(p, u, v, r, act, k1)
        X2, Y2, N2 = f2(p, u, v, r, act, k2)
        return X + X1 + X2, Y + Y1 + Y2, N + N1 + N2
    return forces


@njit(cache=True, fastmath=FASTMATH, inline='always')
def accelerations(kind: tuple[int, ...], p: FloatArray, u: float, v: float, r: float,
                  act: tuple[float, ...]) -> tuple[float, float, float]:
    """(du/dt, dv_m/dt, dr/dt) for velocities through the water and the actuator tuple act."""
    X, Y, N = family_forces(kind, p, u, v, r, act)
    X, Y, N = effect_forces(p, u, v, X, Y, N)
    aX, aY, aN = actuator_forces(kind, p, u, v, r, act)
    if aX != 0.0 or aY != 0.0 or aN != 0.0:   # nothing added: the sums stay bit-identical
        X += aX
        Y += aY
        N += aN
    return _motion_of(kind, p, u, v, r, X, Y, N)


@njit(cache=True, fastmath=FASTMATH)
def apparent_wind(p: FloatArray, psi: float, u: float, v: float) -> tuple[float, float]:
    """
    Return the apparent wind: air velocity relative to the ship, body axes [m/s].

    For the model state's heading and velocities through the water, with p's wind (and
    current) slots.
    """
    ug = u
    vg = v
    Vc = p[_Vc]
    if Vc != 0.0:
        ug += Vc * math.cos(p[_dirc] - psi)
        vg += Vc * math.sin(p[_dirc] - psi)
    rel = p[_dirw] - psi
    Vw = p[_Vw]
    return -Vw * math.cos(rel) - ug, -Vw * math.sin(rel) - vg


@njit(cache=True, fastmath=FASTMATH)
def wind_loads(p: FloatArray, psi: float, u_g: float, v_g: float) -> tuple[float, float, float]:
    """
    Wind force and moment (X [N], Y [N], N [N m]) on the above-water ship, Blendermann (1994).

    A steady true wind of p[wind_speed] m/s blows *from* p[wind_dir] (rad, clockwise from north,
    the meteorological convention); u_g, v_g is the ship's velocity over ground (body axes).
    """
    rel = p[_dirw] - psi
    return blendermann(p, -p[_Vw] * math.cos(rel) - u_g, -p[_Vw] * math.sin(rel) - v_g)


@njit(cache=True, fastmath=FASTMATH)
def blendermann(p: FloatArray, ua: float, va: float) -> tuple[float, float, float]:
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
    if VA2 == 0.0 or not (p[_AL] > 0.0 and p[_CDt] > 0.0):
        # no wind, or a ship file without windage (the tug's gives none): no load, not 0/0
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


def _wind_of(kind: tuple[int, ...], p: FloatArray, ua: float,
             va: float) -> tuple[float, float, float]:
    raise NotImplementedError('compiled only (numba overload)')


@overload(_wind_of, inline='always', jit_options={'fastmath': FASTMATH})
def _wind_of_impl(  # type: ignore[no-untyped-def]  # numba matches it to the impl's
        kind, p, ua, va):
    wind = _WINDS[_tag_code(kind)]
    return lambda kind, p, ua, va: wind(p, ua, va)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def family_wind(kind: tuple[int, ...], p: FloatArray, ua: float,
                va: float) -> tuple[float, float, float]:
    """
    Compute the wind loads of family ``kind``'s wind model from the apparent wind.

    Wind loads (X [N], Y [N], N [N m]) of family ``kind``'s wind model (its own, else
    Blendermann's) from the apparent wind (ua, va), the air's velocity relative to the ship in body
    axes [m/s].
    """
    return _wind_of(kind, p, ua, va)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def external_accelerations(kind: tuple[int, ...], p: FloatArray, X: float, Y: float,
                           N: float) -> tuple[float, float, float]:
    """Accelerations from external forces (wind) through the family's mass matrix."""
    return _solve_of(kind, p, X, Y, N)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def rhs(kind: tuple[int, ...], p: FloatArray, s: FloatArray | tuple[float, ...],
        act: tuple[float, ...], r0: float = 0.0, r1: float = 0.0, r2: float = 0.0,
        physics: float = 1.0) -> tuple[float, float, float, float, float, float]:
    """
    Return ds/dt for s = (x, y, psi, u, v, r) as a tuple; u, v through the water.

    Plus the learned residual's accelerations (r0, r1, r2) [m/s^2, m/s^2, rad/s^2];
    physics: the weight of the family's accelerations, 1.0 for the physics and a hybrid, 0.0
    when the residual replaces them (a pure network), between for an ensemble of hybrid and
    pure networks (the members' mean: the hybrids' share times the physics, plus the mean
    network output). Without a network the callers pass zeros and 1.0: adding 0.0 changes no
    bit. s may be an
    array or a tuple (RK4's stages). A tuple, not an output array, and no wrapper layer: each
    array an inlined layer hands on costs an atomic reference count on the hot path.

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
    dx = u * c - v * sn
    dy = u * sn + v * c
    Vc = p[_Vc]
    if Vc != 0.0:
        dx += Vc * math.cos(p[_dirc])
        dy += Vc * math.sin(p[_dirc])
    Vw = p[_Vw]
    if Vw != 0.0 or air_drag(kind):  # a family with AIR_DRAG feels its own motion's air drag
        ug = u
        vg = v
        if Vc != 0.0:
            ug += Vc * math.cos(p[_dirc] - psi)
            vg += Vc * math.sin(p[_dirc] - psi)
        rel = p[_dirw] - psi
        Xw, Yw, Nw = family_wind(kind, p, -Vw * math.cos(rel) - ug, -Vw * math.sin(rel) - vg)
        au, av, ar = external_accelerations(kind, p, Xw, Yw, Nw)
        du += au
        dv += av
        dr += ar
    if physics == 1.0:
        return dx, dy, r, du + r0, dv + r1, dr + r2
    if physics == 0.0:   # not 0 * du: a pure network's run never takes the physics' inf or
        # NaN (one that reads them as features, ``core.correction.PHYSICS_FEATURES``, does)
        return dx, dy, r, r0, r1, r2
    return dx, dy, r, physics * du + r0, physics * dv + r1, physics * dr + r2


@njit(cache=True, fastmath=FASTMATH)
def derivative(kind: tuple[int, ...], p: FloatArray, s: FloatArray, act: tuple[float, ...],
               out: FloatArray) -> None:
    """ds/dt for s = (x, y, psi, u, v, r) with u, v through the water (current added here)."""
    d = rhs(kind, p, s, act)
    out[0] = d[0]
    out[1] = d[1]
    out[2] = d[2]
    out[3] = d[3]
    out[4] = d[4]
    out[5] = d[5]
