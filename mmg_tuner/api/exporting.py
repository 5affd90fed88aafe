"""
Export an identified model for model-predictive control: numbers, CasADi functions, (A, B).

``export`` (the command) and :func:`export_model` write, for a ship of a family driven by one
actuator that declares its CasADi form (``SYMBOLIC``, ``core/actuators/__init__.py``) and whose
module describes its hull (``hull_document``) -- today the twin-azimuth tugs'
``surge_decoupled`` and ``simplified6`` -- into a new folder:

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
``forces``, the shared ``effect_forces``) are plain arithmetic on scalars and are called here
with CasADi symbols (their Python source, ``py_func``, with ``math`` bound to CasADi's
functions). What branches on a value is written out again by the actuator's symbolic module,
with ``casadi.if_else``, and the integrators' few lines here; test/api/test_export.py holds them
to the simulator's step.

Calm water only: the exported model has no wind or current (a ship whose parameters set
them is refused), and its state is the model's (the reference point, velocities through the
water), not the antenna's.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import importlib
import json
import math
from pathlib import Path
import tempfile
import types
from typing import Any, Callable, cast, Mapping, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.core.actuators import actuator, load_companion
from mmg_tuner.core.dynamics import effect_forces, mmg_motion
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.models import family, module_of, REGISTRY
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import ConfigError, MissingDependencyError
import numpy as np

BODY_STATES = ('x', 'y', 'psi', 'u', 'v', 'r')
BODY_UNITS = ('m', 'm', 'rad', 'm/s', 'm/s', 'rad/s')
INTEGRATORS = ('rk4', 'euler')
SERVICE_FRACTION = 0.8
"""The default operating point: the steady straight-ahead speed at this fraction of the
actuator's largest propulsion level (a tug's ``steering.max_thruster_rps``)."""
BODY_KEYS = ('u', 'v', 'r', 'psi')
FILES = ('model.json', 'dynamics.casadi', 'nu_dot.casadi', 'linear.json', 'README.md')
_CALM = ('current_speed', 'wind_speed')


def _kit(name: str) -> tuple[types.ModuleType, types.ModuleType] | None:
    """Return (the family module, its actuator's symbolic module), or None: not exportable."""
    fam = family(name)
    if len(fam.actuators) != 1:
        return None
    symbolic = load_companion(fam.actuators[0], 'SYMBOLIC')
    hull = importlib.import_module(module_of(name))
    if symbolic is None or not hasattr(hull, 'hull_document'):
        return None
    return hull, symbolic


def supported_families() -> tuple[str, ...]:
    """Return the registered families export covers (module docstring)."""
    return tuple(n for n in REGISTRY if _kit(n) is not None)


def operating_keys(ship: ShipConfig) -> tuple[str, ...]:
    """Return the keys an operating point may give for ``ship`` (``--at``)."""
    kit = _kit(ship.model)
    return BODY_KEYS + (tuple(kit[1].ACTING) if kit is not None else ())


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


class SymbolicModel:
    """The exported model as CasADi SX expressions, from the family's own declarations."""

    def __init__(self, ship: ShipConfig, integrator: str = 'rk4') -> None:
        kit = _kit(ship.model)
        if kit is None:
            supported = supported_families()
            raise ConfigError(f'export: the {ship.model!r} family of {ship.name} is not '
                              f'supported; supported families: {", ".join(supported)} (one '
                              'actuator with a SYMBOLIC module, a hull_document)')
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
        self.hull, self.kit = kit
        self.states = BODY_STATES + tuple(self.kit.STATES)
        self.state_units = BODY_UNITS + tuple(self.kit.STATE_UNITS)
        self.inputs = tuple(self.kit.INPUTS)
        self.p = [float(v) for v in ship.params]
        self._forces = _symbolic(fam.forces, ca)
        self._motion = _symbolic(fam.motion if fam.motion is not None else mmg_motion, ca)
        self._effects = _symbolic(effect_forces, ca)
        # (an exportable actuator, one with a SYMBOLIC form, has forces of its own)
        self._act_forces = _symbolic(cast(Callable[..., Any], actuator(fam.actuators[0]).forces),
                                     ca)

    # ------------------------------------------------------------------ pieces
    def param(self, name: str) -> float:
        """Return the value of parameter ``name``."""
        return self.p[PARAM_INDEX[name]]

    def symbolic(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        """Return a compiled function's Python source on CasADi symbols."""
        return _symbolic(fn, self.ca)

    def nu_dot(self, nu: Sequence[Any], acting: Sequence[Any]) -> tuple[Any, Any, Any]:
        """Accelerations for nu = (u, v, r) and the actuator's values acting (``ACTING``)."""
        u, v, r = nu
        return self._nu_dot(u, v, r, self.kit.outputs(self, acting))

    def _nu_dot(self, u: Any, v: Any, r: Any, act: tuple[Any, ...]) -> tuple[Any, Any, Any]:
        """dynamics.accelerations: family forces, effects, actuator forces, motion."""
        p = self.p
        X, Y, N = self._forces(p, u, v, r, act)
        X, Y, N = self._effects(p, u, v, X, Y, N)
        aX, aY, aN = self._act_forces(p, u, v, r, act, 0)
        # (the motion's three accelerations; _symbolic's functions return Any)
        return cast('tuple[Any, Any, Any]', self._motion(p, u, v, r, X + aX, Y + aY, N + aN))

    def _rhs(self, s: Sequence[Any], act: tuple[Any, ...]) -> tuple[Any, ...]:
        """dynamics.rhs in calm water: (dx, dy, dpsi, du, dv, dr)."""
        ca = self.ca
        psi, u, v, r = s[2], s[3], s[4], s[5]
        c = ca.cos(psi)
        sn = ca.sin(psi)
        du, dv, dr = self._nu_dot(u, v, r, act)
        return u * c - v * sn, u * sn + v * c, r, du, dv, dr

    def _advance(self, s: list[Any], act: tuple[Any, ...], dt: Any) -> list[Any]:
        """Return the body states after one step of dt with the actuator's outputs held."""
        d1 = self._rhs(s, act)
        if self.integrator == 'euler':
            return [s[i] + dt * d1[i] for i in range(6)]
        c = 0.5 * dt
        d2 = self._rhs([s[i] + c * d1[i] for i in range(6)], act)
        d3 = self._rhs([s[i] + c * d2[i] for i in range(6)], act)
        d4 = self._rhs([s[i] + dt * d3[i] for i in range(6)], act)
        return [s[i] + dt / 6.0 * (d1[i] + 2.0 * d2[i] + 2.0 * d3[i] + d4[i]) for i in range(6)]

    def step(self, x: Any, u: Any, dt: Any) -> list[Any]:
        """Return x_next after one integration step of dt, as integrate.advance takes it."""
        n = len(self.states)
        xa, act = self.kit.step(self, [x[i] for i in range(6, n)], u, dt)
        return self._advance([x[i] for i in range(6)], act, dt) + list(xa)

    def x_dot(self, x: Any, u: Any) -> list[Any]:
        """Return x_dot, the continuous-time model: the hull's rhs, the actuator's states'."""
        n = len(self.states)
        rates, act = self.kit.rates(self, [x[i] for i in range(6, n)], u)
        return list(self._rhs([x[i] for i in range(6)], act)) + list(rates)

    # ------------------------------------------------------------------ functions
    def functions(self) -> tuple[Any, Any]:
        """Return (dynamics, nu_dot) as CasADi SX functions."""
        ca = self.ca
        x = ca.SX.sym('x', len(self.states))
        u = ca.SX.sym('u', len(self.inputs))
        dt = ca.SX.sym('dt')
        dyn = ca.Function('dynamics', [x, u, dt],
                          [ca.vertcat(*self.step(x, u, dt)), ca.vertcat(*self.x_dot(x, u))],
                          ['x', 'u', 'dt'], ['x_next', 'x_dot'])
        nu = ca.SX.sym('nu', 3)
        k = len(self.kit.ACTING)
        a = ca.SX.sym('a', k)
        nd = ca.Function('nu_dot', [nu, a], [ca.vertcat(*self.nu_dot([nu[0], nu[1], nu[2]],
                                                                     [a[i] for i in range(k)]))],
                         ['nu', 'a'], ['nu_dot'])
        return dyn, nd


# ------------------------------------------------------------------ model.json
def _mass_matrix(sym: SymbolicModel, nd: Any) -> np.ndarray:
    """M = (d nu_dot / d tau)^-1, read off the family's equations of motion (no formula)."""
    ca = sym.ca
    tau = ca.SX.sym('tau', 3)
    z = ca.SX.zeros(1)
    acc = ca.vertcat(*sym._motion(sym.p, z, z, z, tau[0], tau[1], tau[2]))
    Minv = np.array(ca.Function('Minv', [tau], [ca.jacobian(acc, tau)])(np.zeros(3)))
    return np.linalg.inv(Minv)


def model_document(sym: SymbolicModel, M: np.ndarray, limits: Mapping[str, float],
                   params_file: str | None) -> dict[str, Any]:
    """Return model.json: the hull, the actuator, the state and inputs, the files."""
    ship = sym.ship
    kit = sym.kit
    hull = sym.hull.hull_document(ship.__getitem__)
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
                    f'reference point ({kit.REFERENCE_POINT}), velocities through the water',
            'environment': 'calm water: no wind, no current'},
        'state': [{'name': n, 'unit': un} for n, un in zip(sym.states, sym.state_units)],
        'input': [{'name': n, 'unit': un} for n, un in zip(sym.inputs, kit.INPUT_UNITS)],
        'nu_dot_input': {'names': list(kit.ACTING), 'units': list(kit.ACTING_UNITS),
                         'meaning': kit.ACTING_MEANING},
        'hull': hull,
        **kit.document(ship, limits),
        'casadi': {
            'dynamics.casadi': f'dynamics(x[{len(sym.states)}], u[{len(sym.inputs)}], dt) -> '
                               f'(x_next[{len(sym.states)}], x_dot[{len(sym.states)}]); '
                               f'x_next: the simulator step ({sym.integrator}, one step of dt)',
            'nu_dot.casadi': f'nu_dot(nu[3], a[{len(kit.ACTING)}]) -> nu_dot[3]',
            'integrator': sym.integrator},
    }


# ------------------------------------------------------------------ operating point
def parse_operating_point(text: str | None) -> dict[str, float]:
    """
    Parse ``u=1.2,v=0,r=0`` (SI, rad); ConfigError naming the problem.

    The keys are checked against the ship's (:func:`operating_keys`) by :func:`operating_point`.
    """
    out: dict[str, float] = {}
    for item in (text or '').split(','):
        if not item.strip():
            continue
        key, sep, val = item.partition('=')
        key = key.strip()
        if not sep or not key.isidentifier():
            raise ConfigError(f'--at: {item.strip()!r} is not KEY=VALUE (e.g. u=1.2)')
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


def operating_point(sym: SymbolicModel, nd: Any, given: Mapping[str, float],
                    limits: Mapping[str, float]) -> OperatingPoint:
    """
    Complete ``given`` to an operating point: the missing inputs trimmed to nu_dot = 0.

    No u given: the service speed (the actuator straight ahead at SERVICE_FRACTION of its
    largest propulsion level). Values acting not given are solved for by least squares on
    nu_dot within the command limits (from straight ahead); the residual says how far from an
    equilibrium the point is (nonzero: no trim within the limits).
    """
    from scipy.optimize import brentq, least_squares
    kit = sym.kit
    acting_names = tuple(kit.ACTING)
    unknown = [k for k in given if k not in BODY_KEYS + acting_names]
    if unknown:
        raise ConfigError(f'--at: {", ".join(unknown)} is not one of '
                          f'{", ".join(BODY_KEYS + acting_names)}')
    state = {'psi': 0.0, 'u': 0.0, 'v': 0.0, 'r': 0.0}
    inputs = {k: given[k] for k in acting_names if k in given}
    n_max = kit.propulsion_max(limits)

    def surge(n: float, u: float) -> float:
        return float(nd([u, 0.0, 0.0], kit.ahead(n))[0])

    if 'u' not in given:
        n0 = SERVICE_FRACTION * n_max
        try:
            state['u'] = brentq(lambda uu: surge(n0, uu), 0.0, 20.0, xtol=1e-12)
        except ValueError:
            raise ConfigError(f'export: no steady speed straight ahead at propulsion {n0:g}; '
                              'give the operating point with --at u=...') from None
    state.update({k: given[k] for k in BODY_KEYS if k in given})
    free = [k for k in acting_names if k not in inputs]
    nu = [state['u'], state['v'], state['r']]
    start = dict(zip(acting_names, kit.ahead(0.0)))
    if state['u'] != 0.0:
        s = 1.0 if state['u'] > 0 else -1.0
        try:
            n_eq = brentq(lambda n: surge(n, state['u']), 0.0, s * 4.0 * n_max, xtol=1e-12)
            start = dict(zip(acting_names, kit.ahead(n_eq)))
        except ValueError:
            pass
    start.update(inputs)

    def resid(z: np.ndarray) -> np.ndarray:
        a = dict(start)
        a.update(zip(free, z))
        return np.array(nd(nu, [a[k] for k in acting_names])).ravel()

    bound = kit.bounds(limits)
    for k in [k for k in free if bound[k] == 0.0]:   # a fixed thruster: its angle stays 0
        inputs[k] = start[k] = 0.0
        free.remove(k)
    if free:
        hi = np.array([bound[k] for k in free])
        z0 = np.clip([start[k] for k in free], -0.999 * hi, 0.999 * hi)
        sol = least_squares(resid, z0, bounds=(-hi, hi), xtol=1e-15, ftol=1e-15, gtol=1e-15,
                            max_nfev=2000)
        inputs.update(zip(free, (float(v) for v in sol.x)))
    res = float(np.linalg.norm(resid(np.array([inputs[k] for k in free]))
                               if free else resid(np.zeros(0))))
    return OperatingPoint(state, {k: float(inputs[k]) for k in acting_names}, free, res)


def linearise(sym: SymbolicModel, dyn: Any, op: OperatingPoint, dt: float) -> dict[str, Any]:
    """Return A, B of x_dot = f(x, u) and of x_next = F(x, u, dt) at the operating point."""
    ca = sym.ca
    x = ca.SX.sym('x', len(sym.states))
    u = ca.SX.sym('u', len(sym.inputs))
    xn, xd = dyn(x, u, dt)
    jac = ca.Function('linearisation', [x, u],
                      [xd, ca.jacobian(xd, x), ca.jacobian(xd, u), xn, ca.jacobian(xn, x),
                       ca.jacobian(xn, u)])
    xa0, u0, rest = sym.kit.at_rest(sym, op.inputs)
    x0 = [0.0, 0.0, op.state['psi'], op.state['u'], op.state['v'], op.state['r'], *xa0]
    f0, Ac, Bc, F0, Ad, Bd = (np.array(m) for m in jac(x0, u0))

    def mat(a: np.ndarray) -> list[list[float]]:
        return [[float(v) for v in row] for row in np.atleast_2d(a)]

    return {
        'format': 'mmg_tuner MPC export 1',
        'states': list(sym.states), 'inputs': list(sym.inputs),
        'x_op': x0, 'u_op': u0,
        'operating_point': {'state': op.state, 'acting': op.inputs,
                            'trimmed': op.trimmed, 'nu_dot_residual': op.residual,
                            **rest},
        'continuous': {'form': 'x_dot = f0 + A (x - x_op) + B (u - u_op)',
                       'f0': [float(v) for v in f0.ravel()], 'A': mat(Ac), 'B': mat(Bc)},
        'discrete': {'form': 'x_next = F0 + A (x - x_op) + B (u - u_op)', 'dt': dt,
                     'integrator': sym.integrator,
                     'F0': [float(v) for v in F0.ravel()], 'A': mat(Ad), 'B': mat(Bd)},
        'note': 'x and y enter nothing but their own kinematics: drop them (rows and columns '
                '0, 1) for a heading or speed controller',
    }


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

    ``at``: the operating point of the linearisation (keys :func:`operating_keys`; default the
    service speed straight ahead); ``dt`` [s]: the discrete model's step; ``integrator``: the
    simulator's ('rk4', the node's and the API's default, or 'euler').
    """
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 1e-4 <= dt <= 60.0):
        raise ConfigError(f'export: dt = {dt!r} s must be in [1e-4, 60]')
    if not isinstance(ship, ShipConfig):
        ship = load_ship_with_params(ship, params)
    sym = SymbolicModel(ship, integrator)
    dyn, nd = sym.functions()
    limits = sym.kit.limits(ship)
    model = model_document(sym, _mass_matrix(sym, nd), limits,
                           None if params is None else str(params))
    op = operating_point(sym, nd, dict(at or {}), limits)
    lin = linearise(sym, dyn, op, float(dt))
    readme = _README.format(ship=ship.name, version=model['mmg_tuner_version'],
                            states=', '.join(sym.states), inputs=', '.join(sym.inputs),
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
