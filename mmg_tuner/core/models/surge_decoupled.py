"""
Family ``surge_decoupled``: the 22-coefficient control-oriented 3-DOF model (Pedersen 2019).

M nu_dot + C(nu) nu + D(nu) nu = tau in SI units about the model's reference point (the
MBPE-LOGO tug's CO; doc/reference/mbpe_logo_tug.md §1), nu = (u, v, r), body axes x
forward, y to starboard, r clockwise:

- M = [[m11, 0, 0], [0, m22, m23], [0, m32, m33]] (m23 != m32 allowed: fitted, effective
  values that already hold the rigid body and the added mass);
- C(nu) = [[0, 0, -m22 v - m23c r], [0, 0, m11 u], [m22 v + m23c r, -m11 u, 0]], where
  ``coriolis_form`` 0 takes m23c = m23 (Pedersen's and Bitar's form, the default) and 1 takes
  m23c = (m23 + m32) / 2 (Fossen's m2c, ASVSim): the paper's own equation was lost in
  extraction, so this is a switch;
- D(nu) = [[d11, 0, 0], [0, d22, d23], [0, d32, d33]] with
  d11 = -X_u - X_absu_u |u| - X_uuu u^2,
  d22 = -Y_v - Y_absv_v |v| - Y_absr_v |r| - Y_vvv v^2,
  d23 = -Y_r - Y_absv_r |v| - Y_absr_r |r|,
  d32 = -N_v - N_absv_v |v| - N_absr_v |r|,
  d33 = -N_r - N_absv_r |v| - N_absr_r |r| - N_rrr r^2.

``X_absu_u`` is the reference's X_|u|u, and so on (``abs<q>`` for |q|). The thrust tau comes
from the ``twin_azimuth`` actuator. 5 + 3 + 7 + 7 = 22 coefficients; the published values of
the Qiuxin No.5 (Table 3) are in ``config/qiuxin_tug.yaml``. Wind loads (Blendermann's, when
the ship file gives the windage) act through M^-1; a current through the kinematics.
"""
from __future__ import annotations

from typing import Any, Callable, TYPE_CHECKING

PARAMS = ('m11', 'm22', 'm23', 'm32', 'm33',
          'X_u', 'X_absu_u', 'X_uuu',
          'Y_v', 'Y_absv_v', 'Y_absr_v', 'Y_vvv', 'Y_r', 'Y_absv_r', 'Y_absr_r',
          'N_v', 'N_absv_v', 'N_absr_v', 'N_r', 'N_absr_r', 'N_rrr', 'N_absv_r',
          'coriolis_form')
COEFFICIENTS = PARAMS[:22]
"""The 22 model coefficients, in the reference's Table 3 order (``coriolis_form`` is a switch)."""
REQUIRED = ('rho', 'L_pp', 'B', 'd', 'm', 'I_zG') + COEFFICIENTS + (
    'thrust_p2', 'azimuth_k1', 'azimuth_k2', 'thruster_x_port', 'thruster_y_port',
    'thruster_x_stbd', 'thruster_y_stbd')
ACTUATORS = ('twin_azimuth',)
ASTERN_RPM = True
ASTERN_SURGE = True
DESCRIPTION = ('surge-decoupled 3-DOF model, 22 coefficients (Pedersen 2019; MBPE-LOGO, '
               'arXiv 2312.05644, Table 3)')

from mmg_tuner.core._jit import FASTMATH  # noqa: E402, I100  (below the declarations)
from mmg_tuner.core.actuators.twin_azimuth import DEFAULTS as _ACTUATOR_DEFAULTS  # noqa: E402
from mmg_tuner.core.layout import PARAM_INDEX  # noqa: E402
from numba import njit  # noqa: E402

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray

DEFAULTS: dict[str, float] = {'x_G': 0.0, 'coriolis_form': 0.0, **_ACTUATOR_DEFAULTS}
CORIOLIS_FORMS = {'pedersen': 0.0, 'fossen': 1.0}
"""The values of ``coriolis_form``: raw m23 (Pedersen, Bitar) or (m23 + m32) / 2 (Fossen)."""

(_m11, _m22, _m23, _m32, _m33, _Xu, _Xuu, _Xuuu, _Yv, _Yvv, _Yrv, _Yvvv, _Yr, _Yvr, _Yrr,
 _Nv, _Nvv, _Nrv, _Nr, _Nrr, _Nrrr, _Nvr, _cform) = (PARAM_INDEX[k] for k in PARAMS)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def forces(p: FloatArray, u: float, v: float, r: float,
           act: tuple[float, ...]) -> tuple[float, float, float]:
    """-D(nu) nu [N, N, N m] (the thrust is the actuator's; inertia and C(nu) in motion)."""
    au = abs(u)
    av = abs(v)
    ar = abs(r)
    d11 = -p[_Xu] - p[_Xuu] * au - p[_Xuuu] * u * u
    d22 = -p[_Yv] - p[_Yvv] * av - p[_Yrv] * ar - p[_Yvvv] * v * v
    d23 = -p[_Yr] - p[_Yvr] * av - p[_Yrr] * ar
    d32 = -p[_Nv] - p[_Nvv] * av - p[_Nrv] * ar
    d33 = -p[_Nr] - p[_Nvr] * av - p[_Nrr] * ar - p[_Nrrr] * r * r
    return -d11 * u, -(d22 * v + d23 * r), -(d32 * v + d33 * r)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def motion(p: FloatArray, u: float, v: float, r: float, X: float, Y: float,
           N: float) -> tuple[float, float, float]:
    """(du, dv, dr) = M^-1 (X, Y, N - C(nu) nu) for the forces X, Y, N (all but inertia)."""
    m11 = p[_m11]
    m22 = p[_m22]
    m23 = p[_m23]
    m32 = p[_m32]
    m33 = p[_m33]
    m23c = m23 if p[_cform] == 0.0 else 0.5 * (m23 + m32)
    a = m22 * v + m23c * r
    fX = X + a * r
    fY = Y - m11 * u * r
    fN = N - a * u + m11 * u * v
    det = m22 * m33 - m23 * m32
    return fX / m11, (m33 * fY - m23 * fN) / det, (m22 * fN - m32 * fY) / det


@njit(cache=True, fastmath=FASTMATH, inline='always')
def mass_solve(p: FloatArray, X: float, Y: float, N: float) -> tuple[float, float, float]:
    """M^-1 (X, Y, N) for external forces (wind)."""
    m22 = p[_m22]
    m23 = p[_m23]
    m32 = p[_m32]
    m33 = p[_m33]
    det = m22 * m33 - m23 * m32
    return X / p[_m11], (m33 * Y - m23 * N) / det, (m22 * N - m32 * Y) / det


def hull_document(g: Callable[[str], float]) -> dict[str, Any]:
    """Return M, C(nu), D(nu) in the form above, for ``export``'s model.json (g: a parameter)."""
    m23c = g('m23') if g('coriolis_form') == 0.0 else 0.5 * (g('m23') + g('m32'))
    coef = ('X_u', 'X_absu_u', 'X_uuu', 'Y_v', 'Y_absv_v', 'Y_absr_v', 'Y_vvv', 'Y_r',
            'Y_absv_r', 'Y_absr_r', 'N_v', 'N_absv_v', 'N_absr_v', 'N_r', 'N_absr_r', 'N_rrr',
            'N_absv_r')
    return {
        'equations': 'M nu_dot + C(nu) nu + D(nu) nu = tau',
        'M': [[g('m11'), 0.0, 0.0], [0.0, g('m22'), g('m23')], [0.0, g('m32'), g('m33')]],
        'C': {'form': 'C(nu) = [[0, 0, -(m22 v + m23c r)], [0, 0, m11 u], '
                      '[m22 v + m23c r, -m11 u, 0]]',
              'coefficients': {'m11': g('m11'), 'm22': g('m22'), 'm23c': m23c},
              'm23c': 'm23 (coriolis_form 0, Pedersen) or (m23 + m32)/2 (1, Fossen)',
              'coriolis_form': g('coriolis_form')},
        'D': {'form': 'D(nu) = [[d11, 0, 0], [0, d22, d23], [0, d32, d33]]',
              'entries': {
                  'd11': '-X_u - X_absu_u |u| - X_uuu u^2',
                  'd22': '-Y_v - Y_absv_v |v| - Y_absr_v |r| - Y_vvv v^2',
                  'd23': '-Y_r - Y_absv_r |v| - Y_absr_r |r|',
                  'd32': '-N_v - N_absv_v |v| - N_absr_v |r|',
                  'd33': '-N_r - N_absv_r |v| - N_absr_r |r| - N_rrr r^2'},
              'coefficients': {k: g(k) for k in coef},
              'naming': 'X_absu_u is X_|u|u (abs<q> for |q|)'}}
