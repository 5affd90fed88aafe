"""
Export an identified model for model-predictive control: numbers, CasADi functions, (A, B).

``export`` (the command) and :func:`export_model` write, for a ship of a family driven by the
``twin_azimuth`` actuator (the tugs: ``surge_decoupled``, ``simplified6``), into a new folder:

- ``model.json``: M (3 x 3), the coefficients of C(nu) and D(nu) with the formulas they enter,
  the thruster map (positions, thrust curve, azimuth drive, limits), state and input names,
  units and frames;
- ``dynamics.casadi``: a CasADi function ``dynamics(x, u, dt) -> (x_next, x_dot)``: the
  package's simulator step over ``dt`` (its integrator: RK4 or Euler, the azimuth drive
  integrated exactly as the simulator does) and the continuous-time right-hand side;
- ``nu_dot.casadi``: ``nu_dot(nu, a) -> nu_dot``, the 3-DOF equations of motion
  nu_dot = M^-1 (tau(a) - C(nu) nu - D(nu) nu) for the actuator values acting
  a = (n_port, n_stbd, azimuth_port, azimuth_stbd) (the angles acting as inputs, no drive);
- ``linear.json``: A, B of the continuous and of the discrete model at an operating point
  (default: the service speed straight ahead), by ``casadi.jacobian``;
- ``README.md``: how to load them with CasADi alone (do-mpc, acados).

The CasADi expressions are not a transcription of the hull model: the family's own force and
motion functions (``forces``, ``motion`` of ``core/models/<family>.py``, the actuator's
``forces`` and the azimuth transition of ``core/actuators/twin_azimuth.py``, the shared
``effect_forces``) are plain arithmetic on scalars and are called here with CasADi symbols
(their Python source, ``py_func``, with ``math`` bound to CasADi's functions). Only the parts
that branch on a value (the sign-aware thrust curve, the rate-limited azimuth step) and the
integrators' few lines are written out again, with ``casadi.if_else``; test/api/test_export.py
holds them to the simulator's step.

Calm water only: the exported model has no wind or current (a ship whose parameters set
them is refused), and its state is the model's (the reference point, velocities through the
water), not the antenna's.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import json
import math
from pathlib import Path
import tempfile
import types
from typing import Any, Callable, Mapping, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.core.actuators import actuator
from mmg_tuner.core.actuators import twin_azimuth as _az
from mmg_tuner.core.dynamics import effect_forces, mmg_motion
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.limits import command_limits
from mmg_tuner.core.models import REGISTRY
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import ConfigError, MissingDependencyError
import numpy as np

ACTUATOR = 'twin_azimuth'
STATES = ('x', 'y', 'psi', 'u', 'v', 'r', 'alpha_port', 'alpha_rate_port', 'alpha_stbd',
          'alpha_rate_stbd')
STATE_UNITS = ('m', 'm', 'rad', 'm/s', 'm/s', 'rad/s', 'rad', 'rad/s', 'rad', 'rad/s')
INPUTS = ('n_port', 'n_stbd', 'azimuth_cmd_port', 'azimuth_cmd_stbd')
INPUT_UNITS = ('rev/s', 'rev/s', 'rad', 'rad')
ACTING = ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
INTEGRATORS = ('rk4', 'euler')
SERVICE_FRACTION = 0.8
"""The default operating point: the steady straight-ahead speed with both thrusters at this
fraction of ``steering.max_thruster_rps`` (the qiuxin_tug: 9.6 rev/s, about 1.26 m/s)."""
OPERATING_KEYS = ('u', 'v', 'r', 'psi') + ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
FILES = ('model.json', 'dynamics.casadi', 'nu_dot.casadi', 'linear.json', 'README.md')
_CALM = ('current_speed', 'wind_speed')


def supported_families() -> tuple[str, ...]:
    """Return the registered families export covers: those driven by ``twin_azimuth`` alone."""
    from mmg_tuner.core.models import family
    return tuple(n for n in REGISTRY if family(n).actuators == (ACTUATOR,))


def _casadi() -> Any:
    try:
        import casadi
    except ImportError:
        raise MissingDependencyError('export needs casadi (pip install casadi==3.8.2, as in '
                                     'requirements.txt)') from None
    return casadi


def _symbolic(fn: Callable[..., Any], ca: Any) -> Callable[..., Any]:
    """Return a compiled function's Python source with ``math`` bound to CasADi's functions."""
    py = getattr(fn, 'py_func', fn)
    shim = types.SimpleNamespace(cos=ca.cos, sin=ca.sin, sqrt=ca.sqrt, exp=ca.exp,
                                 cosh=ca.cosh, sinh=ca.sinh, atan2=ca.atan2, tanh=ca.tanh,
                                 pi=math.pi, isfinite=lambda x: True)
    g = dict(py.__globals__)
    g['math'] = shim
    return types.FunctionType(py.__code__, g, py.__name__, py.__defaults__, py.__closure__)


@dataclass
class OperatingPoint:
    """A state and the actuator values acting there (``linear.json``)."""

    state: dict[str, float]
    inputs: dict[str, float]
    trimmed: list[str] = field(default_factory=list)
    residual: float = 0.0   # |nu_dot| there [SI]: 0 at an equilibrium


class SymbolicTug:
    """The exported model as CasADi SX expressions, from the family's own declarations."""

    def __init__(self, ship: ShipConfig, integrator: str = 'rk4') -> None:
        supported = supported_families()
        if ship.model not in supported:
            raise ConfigError(f'export: the {ship.model!r} family of {ship.name} is not '
                              f'supported; supported families: {", ".join(supported)} (ships '
                              f'driven by twin azimuth thrusters)')
        if integrator not in INTEGRATORS:
            raise ConfigError(f'export: integrator {integrator!r}; use one of '
                              f'{", ".join(INTEGRATORS)}')
        moving = [f'{k} = {ship[k]:g}' for k in _CALM if ship[k] != 0.0]
        if moving:
            raise ConfigError(f'export: the exported model is for calm water; {ship.name} sets '
                              f'{", ".join(moving)} (set them 0 in the params file)')
        self.ca = ca = _casadi()
        self.ship = ship
        self.integrator = integrator
        fam = ship.family
        self.family = fam
        self.p = [float(v) for v in ship.params]
        self._forces = _symbolic(fam.forces, ca)
        self._motion = _symbolic(fam.motion if fam.motion is not None else mmg_motion, ca)
        self._effects = _symbolic(effect_forces, ca)
        self._act_forces = _symbolic(actuator(ACTUATOR).forces, ca)
        self._transition = _symbolic(_az.transition, ca)

    # ------------------------------------------------------------------ pieces
    def param(self, name: str) -> float:
        return self.p[PARAM_INDEX[name]]

    def thrust(self, n: Any, side: str) -> Any:
        """Sign-aware thrust [N] of one thruster (twin_azimuth.thrust, times its scale)."""
        ca = self.ca
        a = ca.fabs(n)
        c = [self.param(f'thrust_p{k}') for k in range(6)]
        f = c[0] + a * (c[1] + a * (c[2] + a * (c[3] + a * (c[4] + a * c[5]))))
        f = ca.if_else(n > 0.0, f, ca.if_else(n < 0.0, -f * self.param('thrust_astern_ratio'),
                                              0.0))
        return f * self.param(f'thrust_scale_{side}')

    def nu_dot(self, nu: Sequence[Any], acting: Sequence[Any]) -> tuple[Any, Any, Any]:
        """Accelerations for nu = (u, v, r) and acting = (n_port, n_stbd, alpha_p, alpha_s)."""
        u, v, r = nu
        act = (self.thrust(acting[0], 'port'), self.thrust(acting[1], 'stbd'),
               acting[2] + self.param('azimuth_offset_port'),
               acting[3] + self.param('azimuth_offset_stbd'))
        return self._nu_dot(u, v, r, act)

    def _nu_dot(self, u: Any, v: Any, r: Any, act: tuple[Any, ...]) -> tuple[Any, Any, Any]:
        """dynamics.accelerations: family forces, effects, actuator forces, motion."""
        p = self.p
        X, Y, N = self._forces(p, u, v, r, act)
        X, Y, N = self._effects(p, u, v, X, Y, N)
        aX, aY, aN = self._act_forces(p, u, v, r, act, 0)
        return self._motion(p, u, v, r, X + aX, Y + aY, N + aN)

    def _rhs(self, s: Sequence[Any], act: tuple[Any, ...]) -> tuple[Any, ...]:
        """dynamics.rhs in calm water: (dx, dy, dpsi, du, dv, dr)."""
        ca = self.ca
        psi, u, v, r = s[2], s[3], s[4], s[5]
        c = ca.cos(psi)
        sn = ca.sin(psi)
        du, dv, dr = self._nu_dot(u, v, r, act)
        return u * c - v * sn, u * sn + v * c, r, du, dv, dr

    def _follow(self, angle: Any, rate: Any, cmd: Any, phi: tuple[Any, ...],
                h: Any) -> tuple[Any, Any]:
        """twin_azimuth._follow: one thruster's (angle, rate) over a step h."""
        ca = self.ca
        e = angle - cmd
        new = cmd + phi[0] * e + phi[1] * rate
        w = phi[2] * e + phi[3] * rate
        rmax = self.param('azimuth_rate_max')
        if rmax > 0.0:
            k1, k2 = self.param('azimuth_k1'), self.param('azimuth_k2')
            if k1 > 0.0 and k2 > 0.0:   # the loop asks the motor for more than its top rate
                lag = ca.exp(-k2 * h)
                s = ca.if_else(e > 0.0, -rmax, rmax)
                sat = ca.fabs(k1 / k2 * e) > rmax
                w = ca.if_else(sat, s + (rate - s) * lag, w)
                slew = angle + s * h + (rate - s) * (1.0 - lag) / k2
                slew = ca.if_else((slew - cmd) * e < 0.0, cmd, slew)   # not past the command
                new = ca.if_else(sat, slew, new)
            w = ca.if_else(w > rmax, rmax, ca.if_else(w < -rmax, -rmax, w))
            lim = rmax * h
            move = new - angle
            new = ca.if_else(move > lim, angle + lim, ca.if_else(move < -lim, angle - lim, new))
        return new, w

    def step(self, x: Any, u: Any, dt: Any) -> list[Any]:
        """Return x_next after one integration step of dt, as integrate.advance takes it."""
        k1 = self.param('azimuth_k1')
        phi = self._transition(k1, self.param('azimuth_k2'), dt) if k1 > 0.0 else (0.0,) * 4
        ap, wp = self._follow(x[6], x[7], u[2], phi, dt)
        ast, ws = self._follow(x[8], x[9], u[3], phi, dt)
        if k1 > 0.0:   # acting over the step: the mean of its start and end
            ap_act, ast_act = 0.5 * (x[6] + ap), 0.5 * (x[8] + ast)
        else:   # no drive: the command acts at once
            ap_act, ast_act = ap, ast
        act = (self.thrust(u[0], 'port'), self.thrust(u[1], 'stbd'),
               ap_act + self.param('azimuth_offset_port'),
               ast_act + self.param('azimuth_offset_stbd'))
        s = [x[i] for i in range(6)]
        d1 = self._rhs(s, act)
        if self.integrator == 'euler':
            nxt = [s[i] + dt * d1[i] for i in range(6)]
        else:
            c = 0.5 * dt
            d2 = self._rhs([s[i] + c * d1[i] for i in range(6)], act)
            d3 = self._rhs([s[i] + c * d2[i] for i in range(6)], act)
            d4 = self._rhs([s[i] + dt * d3[i] for i in range(6)], act)
            nxt = [s[i] + dt / 6.0 * (d1[i] + 2.0 * d2[i] + 2.0 * d3[i] + d4[i])
                   for i in range(6)]
        return nxt + [ap, wp, ast, ws]

    def x_dot(self, x: Any, u: Any) -> list[Any]:
        """Return x_dot, the continuous-time model: the hull's rhs, the azimuth drive's ODE."""
        ca = self.ca
        k1, k2 = self.param('azimuth_k1'), self.param('azimuth_k2')
        rmax = self.param('azimuth_rate_max')
        if k1 > 0.0:
            ap, ast = x[6], x[8]
            rates = []
            for a, w, c in ((x[6], x[7], u[2]), (x[8], x[9], u[3])):
                if rmax > 0.0 and k2 > 0.0:   # the rate asked of the motor is limited
                    ask = ca.fmin(ca.fmax(k1 / k2 * (c - a), -rmax), rmax)
                    rates += [w, k2 * (ask - w)]
                elif rmax > 0.0:   # no motor lag: the rate itself is clipped
                    rates += [ca.fmin(ca.fmax(w, -rmax), rmax), k1 * (c - a) - k2 * w]
                else:
                    rates += [w, k1 * (c - a) - k2 * w]
        else:   # no drive: the angle follows its command at once
            ap, ast = u[2], u[3]
            rates = [0.0, 0.0, 0.0, 0.0]
        act = (self.thrust(u[0], 'port'), self.thrust(u[1], 'stbd'),
               ap + self.param('azimuth_offset_port'), ast + self.param('azimuth_offset_stbd'))
        return list(self._rhs([x[i] for i in range(6)], act)) + rates

    # ------------------------------------------------------------------ functions
    def functions(self) -> tuple[Any, Any]:
        """Return (dynamics, nu_dot) as CasADi SX functions."""
        ca = self.ca
        x = ca.SX.sym('x', len(STATES))
        u = ca.SX.sym('u', len(INPUTS))
        dt = ca.SX.sym('dt')
        dyn = ca.Function('dynamics', [x, u, dt],
                          [ca.vertcat(*self.step(x, u, dt)), ca.vertcat(*self.x_dot(x, u))],
                          ['x', 'u', 'dt'], ['x_next', 'x_dot'])
        nu = ca.SX.sym('nu', 3)
        a = ca.SX.sym('a', len(ACTING))
        nd = ca.Function('nu_dot', [nu, a], [ca.vertcat(*self.nu_dot([nu[0], nu[1], nu[2]],
                                                                     [a[i] for i in range(4)]))],
                         ['nu', 'a'], ['nu_dot'])
        return dyn, nd


# ------------------------------------------------------------------ model.json
def _mass_matrix(sym: SymbolicTug, nd: Any) -> np.ndarray:
    """M = (d nu_dot / d tau)^-1, read off the family's equations of motion (no formula)."""
    ca = sym.ca
    tau = ca.SX.sym('tau', 3)
    z = ca.SX.zeros(1)
    acc = ca.vertcat(*sym._motion(sym.p, z, z, z, tau[0], tau[1], tau[2]))
    Minv = np.array(ca.Function('Minv', [tau], [ca.jacobian(acc, tau)])(np.zeros(3)))
    return np.linalg.inv(Minv)


def _hull_description(ship: ShipConfig) -> dict[str, Any]:
    """Return the family's M, C(nu) and D(nu) in the form of its module docstring."""
    g = ship.__getitem__
    if ship.model == 'simplified6':
        return {
            'equations': 'M nu_dot + C(nu) nu + D nu = tau, tau_v = 0 drops the sway thrust',
            'M': [[g('m11'), 0.0, 0.0], [0.0, g('m22'), 0.0], [0.0, 0.0, g('m33')]],
            'C': {'form': 'C(nu) = [[0, 0, -m22 v], [0, 0, m11 u], [m22 v, -m11 u, 0]]',
                  'coefficients': {'m11': g('m11'), 'm22': g('m22')}},
            'D': {'form': 'D = diag(d11, d22, d33)',
                  'coefficients': {k: g(k) for k in ('d11', 'd22', 'd33')}},
            'switches': {'tau_v': g('tau_v')}}
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


def model_document(sym: SymbolicTug, M: np.ndarray, limits: Mapping[str, float],
                   params_file: str | None) -> dict[str, Any]:
    ship = sym.ship
    g = ship.__getitem__
    hull = _hull_description(ship)
    if not np.allclose(np.array(hull['M']), M, rtol=1e-9, atol=1e-12):
        raise ConfigError(f'export: the documented M of {ship.model} differs from its '
                          f'equations of motion ({M.tolist()}); report this as a bug')
    from mmg_tuner import __version__
    return {
        'format': 'mmg_tuner MPC export 1',
        'ship': ship.name, 'family': ship.model, 'description': ship.family.description,
        'source': ship.source, 'params_file': params_file, 'mmg_tuner_version': __version__,
        'units': 'SI: m, s, rad, kg, N; shaft speed rev/s',
        'frames': {
            'earth': 'x north, y east [m]; psi heading from north, clockwise + [rad]',
            'body': 'x forward, y to starboard; r clockwise + [rad/s]; about the model '
                    "reference point (the tug's CO), velocities through the water",
            'environment': 'calm water: no wind, no current'},
        'state': [{'name': n, 'unit': un} for n, un in zip(STATES, STATE_UNITS)],
        'input': [{'name': n, 'unit': un} for n, un in zip(INPUTS, INPUT_UNITS)],
        'nu_dot_input': {'names': list(ACTING), 'units': ['rev/s', 'rev/s', 'rad', 'rad'],
                         'meaning': 'shaft speeds and the azimuth angles acting (no drive)'},
        'hull': hull,
        'thrusters': {
            'positions_m': {'port': [g('thruster_x_port'), g('thruster_y_port')],
                            'stbd': [g('thruster_x_stbd'), g('thruster_y_stbd')]},
            'tau': 'X = sum F cos(a), Y = sum F sin(a), N = sum F (l_x sin(a) - l_y cos(a)); '
                   'a = alpha + azimuth_offset, 0 = thrust ahead, + = thrust to starboard',
            'thrust_curve': {
                'form': 'F(n) = s (p0 + p1 |n| + ... + p5 |n|^5) for n > 0, -s astern_ratio '
                        '(...) for n < 0, 0 at n = 0; s = thrust_scale of the side [N]',
                'p': [g(f'thrust_p{k}') for k in range(6)],
                'astern_ratio': g('thrust_astern_ratio'),
                'thrust_scale': {'port': g('thrust_scale_port'),
                                 'stbd': g('thrust_scale_stbd')}},
            'azimuth_offset_rad': {'port': g('azimuth_offset_port'),
                                   'stbd': g('azimuth_offset_stbd')},
            'azimuth_drive': {
                'form': "alpha'' = k1 (alpha_cmd - alpha) - k2 alpha', |alpha'| <= rate_max "
                        '(0: no limit); the discrete step integrates the linear part exactly '
                        'and applies the angle at the end of the step over it, as the '
                        'simulator does; k1 <= 0: the angle follows its command at once',
                'k1': g('azimuth_k1'), 'k2': g('azimuth_k2'),
                'rate_max_rad_s': g('azimuth_rate_max')},
            'limits': dict(limits)},
        'casadi': {
            'dynamics.casadi': 'dynamics(x[10], u[4], dt) -> (x_next[10], x_dot[10]); x_next: '
                               f'the simulator step ({sym.integrator}, one step of dt)',
            'nu_dot.casadi': 'nu_dot(nu[3], a[4]) -> nu_dot[3]',
            'integrator': sym.integrator},
    }


# ------------------------------------------------------------------ operating point
def parse_operating_point(text: str | None) -> dict[str, float]:
    """Parse ``u=1.2,v=0,r=0`` (keys OPERATING_KEYS; SI, rad); ConfigError naming the problem."""
    out: dict[str, float] = {}
    for item in (text or '').split(','):
        if not item.strip():
            continue
        key, sep, val = item.partition('=')
        key = key.strip()
        if not sep or key not in OPERATING_KEYS:
            raise ConfigError(f'--at: {item.strip()!r} is not KEY=VALUE with KEY one of '
                              f'{", ".join(OPERATING_KEYS)}')
        try:
            x = float(val)
        except ValueError:
            x = math.nan
        if not math.isfinite(x):
            raise ConfigError(f'--at: {key} = {val.strip()!r} is not a finite number')
        if key in out:
            raise ConfigError(f'--at: {key} given twice')
        out[key] = x
    return out


def operating_point(sym: SymbolicTug, nd: Any, given: Mapping[str, float],
                    limits: Mapping[str, float]) -> OperatingPoint:
    """
    Complete ``given`` to an operating point: the missing inputs trimmed to nu_dot = 0.

    No u given: the service speed (both thrusters at SERVICE_FRACTION of the limit, straight
    ahead). Inputs not given are solved for by least squares on nu_dot within the command
    limits (from equal shaft speeds and azimuths 0); the residual says how far from an
    equilibrium the point is (nonzero: no trim within the limits).
    """
    from scipy.optimize import brentq, least_squares
    state = {'psi': 0.0, 'u': 0.0, 'v': 0.0, 'r': 0.0}
    inputs = {k: given[k] for k in ACTING if k in given}
    n_max = limits['n_max_rev_s']

    def surge(n: float, u: float) -> float:
        return float(nd([u, 0.0, 0.0], [n, n, 0.0, 0.0])[0])

    if 'u' not in given:
        n0 = SERVICE_FRACTION * n_max
        try:
            state['u'] = brentq(lambda uu: surge(n0, uu), 0.0, 20.0, xtol=1e-12)
        except ValueError:
            raise ConfigError(f'export: no steady speed with both thrusters at {n0:g} rev/s; '
                              'give the operating point with --at u=...') from None
    state.update({k: given[k] for k in ('psi', 'u', 'v', 'r') if k in given})
    free = [k for k in ACTING if k not in inputs]
    nu = [state['u'], state['v'], state['r']]
    start = {'n_port': 0.0, 'n_stbd': 0.0, 'azimuth_port': 0.0, 'azimuth_stbd': 0.0}
    if state['u'] != 0.0:
        s = 1.0 if state['u'] > 0 else -1.0
        try:
            n_eq = brentq(lambda n: surge(n, state['u']), 0.0, s * 4.0 * n_max, xtol=1e-12)
            start['n_port'] = start['n_stbd'] = n_eq
        except ValueError:
            pass
    start.update(inputs)

    def resid(z: np.ndarray) -> np.ndarray:
        a = dict(start)
        a.update(zip(free, z))
        return np.array(nd(nu, [a[k] for k in ACTING])).ravel()

    if free:
        bound = {'n_port': n_max, 'n_stbd': n_max, 'azimuth_port': limits['azimuth_max_rad'],
                 'azimuth_stbd': limits['azimuth_max_rad']}
        hi = np.array([bound[k] for k in free])
        z0 = np.clip([start[k] for k in free], -0.999 * hi, 0.999 * hi)
        sol = least_squares(resid, z0, bounds=(-hi, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15,
                            max_nfev=2000)
        inputs.update(zip(free, (float(v) for v in sol.x)))
    res = float(np.linalg.norm(resid(np.array([inputs[k] for k in free]))
                               if free else resid(np.zeros(0))))
    return OperatingPoint(state, {k: float(inputs[k]) for k in ACTING}, free, res)


def linearise(sym: SymbolicTug, dyn: Any, op: OperatingPoint, dt: float) -> dict[str, Any]:
    """Return A, B of x_dot = f(x, u) and of x_next = F(x, u, dt) at the operating point."""
    ca = sym.ca
    x = ca.SX.sym('x', len(STATES))
    u = ca.SX.sym('u', len(INPUTS))
    xn, xd = dyn(x, u, dt)
    jac = ca.Function('linearisation', [x, u],
                      [xd, ca.jacobian(xd, x), ca.jacobian(xd, u), xn, ca.jacobian(xn, x),
                       ca.jacobian(xn, u)])
    k1 = sym.param('azimuth_k1')
    ap, ast = op.inputs['azimuth_port'], op.inputs['azimuth_stbd']
    x0 = [0.0, 0.0, op.state['psi'], op.state['u'], op.state['v'], op.state['r'],
          ap, 0.0, ast, 0.0]
    u0 = [op.inputs['n_port'], op.inputs['n_stbd'], ap, ast]
    f0, Ac, Bc, F0, Ad, Bd = (np.array(m) for m in jac(x0, u0))

    def mat(a: np.ndarray) -> list[list[float]]:
        return [[float(v) for v in row] for row in np.atleast_2d(a)]

    return {
        'format': 'mmg_tuner MPC export 1',
        'states': list(STATES), 'inputs': list(INPUTS),
        'x_op': x0, 'u_op': u0,
        'operating_point': {'state': op.state, 'acting': op.inputs,
                            'trimmed': op.trimmed, 'nu_dot_residual': op.residual,
                            'azimuth_drive': 'k1 > 0: alpha = alpha_cmd at rest' if k1 > 0
                            else 'no drive'},
        'continuous': {'form': 'x_dot = f0 + A (x - x_op) + B (u - u_op)',
                       'f0': [float(v) for v in f0.ravel()], 'A': mat(Ac), 'B': mat(Bc)},
        'discrete': {'form': 'x_next = F0 + A (x - x_op) + B (u - u_op)', 'dt': dt,
                     'integrator': sym.integrator,
                     'F0': [float(v) for v in F0.ravel()], 'A': mat(Ad), 'B': mat(Bd)},
        'note': 'x and y enter nothing but their own kinematics: drop them (rows and columns '
                '0, 1) for a heading or speed controller',
    }


def export_limits(ship: ShipConfig) -> dict[str, float]:
    lim = command_limits(ship, ('n_port', 'azimuth_port'))
    return {'n_max_rev_s': lim['n_port'].limit, 'azimuth_max_rad': lim['azimuth_port'].limit,
            'azimuth_rate_max_rad_s': ship['azimuth_rate_max']}


_README = """# {ship}: the identified model for MPC

Written by `export` (mmg_tuner {version}). Load without mmg_tuner, with CasADi and numpy:

```python
import casadi as ca, json, numpy as np
dyn = ca.Function.load('dynamics.casadi')    # dynamics(x, u, dt) -> (x_next, x_dot)
nu_dot = ca.Function.load('nu_dot.casadi')   # nu_dot(nu, a) -> nu_dot
lin = json.load(open('linear.json'))
A, B = np.array(lin['discrete']['A']), np.array(lin['discrete']['B'])
```

x = ({states}); u = ({inputs}); SI units, rad. x_next is one {integrator} step of the package's
simulator (call it twice with dt/2 for two substeps). model.json holds M, C(nu), D(nu), the
thruster map and the limits.

do-mpc: `model.set_rhs('x', dyn(x, u, {dt})[0])` (a discrete model) or `dyn(x, u, 0)[1]`
(continuous).
acados: `AcadosModel().f_expl_expr = dyn(x, u, 0)[1]` with x, u CasADi SX symbols.
"""


@dataclass
class ExportResult:
    """What :func:`export_model` wrote."""

    out: Path
    files: list[Path]
    operating_point: OperatingPoint
    linear: dict[str, Any]
    model: dict[str, Any]


def _function_bytes(fn: Any) -> bytes:
    """Return the file ``casadi.Function.save`` writes (saved to a temporary folder)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'f.casadi'
        fn.save(str(path))
        return path.read_bytes()


def export_model(ship: str | Path | ShipConfig, out: str | Path, *,
                 params: str | Path | None = None, at: Mapping[str, float] | None = None,
                 dt: float = 0.2, integrator: str = 'rk4') -> ExportResult:
    """
    Write the MPC export of ``ship`` (with ``params`` overlaid) into the new folder ``out``.

    ``at``: the operating point of the linearisation (keys OPERATING_KEYS; default the
    service speed straight ahead); ``dt`` [s]: the discrete model's step; ``integrator``: the
    simulator's ('rk4', the node's and the API's default, or 'euler').
    """
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 1e-4 <= dt <= 60.0):
        raise ConfigError(f'export: dt = {dt!r} s must be in [1e-4, 60]')
    if not isinstance(ship, ShipConfig):
        ship = load_ship_with_params(ship, params)
    sym = SymbolicTug(ship, integrator)
    dyn, nd = sym.functions()
    limits = export_limits(ship)
    model = model_document(sym, _mass_matrix(sym, nd), limits,
                           None if params is None else str(params))
    op = operating_point(sym, nd, dict(at or {}), limits)
    lin = linearise(sym, dyn, op, float(dt))
    readme = _README.format(ship=ship.name, version=model['mmg_tuner_version'],
                            states=', '.join(STATES), inputs=', '.join(INPUTS),
                            integrator=integrator, dt=float(dt))
    blobs = {'dynamics.casadi': _function_bytes(dyn), 'nu_dot.casadi': _function_bytes(nd)}
    folder = OutputDir.open(out)
    try:
        files = [folder.write_text('model.json', json.dumps(model, indent=1) + '\n')]
        files += [folder.write_bytes(name, data) for name, data in blobs.items()]
        files.append(folder.write_text('linear.json', json.dumps(lin, indent=1) + '\n'))
        files.append(folder.write_text('README.md', readme))
    finally:
        folder.close()
    return ExportResult(Path(out), files, op, lin, model)
