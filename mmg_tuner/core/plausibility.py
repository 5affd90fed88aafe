"""
Can this model be a ship? Impossible models refused, implausible ones named with the figure.

One entry point, :func:`check_model`, family by family, driven by the family's and its
actuators' declarations and by ``config/model_plausibility.yaml`` (the tolerances and their
sources; doc/concepts/plausibility.md):

- impossible (``'error'``): a non-finite parameter; a mass or inertia <= 0 (the family's
  ``positive`` names: m, I_zG, m11, m22, m33 ...); a singular or not positive mass matrix (the
  family's own M^-1, ``mass_solve``: positive diagonal, positive sway-yaw determinant); a
  negative straight-ahead resistance (R_0 < 0, X_0F > 0, d11 < 0, or a surge damping that
  pushes the ship ahead, probed with the family's own forces).
- implausible (``'warning'``): a leading hull derivative of the wrong sign (Y_v, N_r, ...);
  straight-line instability beyond the tolerance (eigenvalues of the sway-yaw system
  linearised by central differences of ``dynamics.accelerations`` about the straight run at
  the service speed); a short turn with starboard helm that does not turn to starboard
  (classic RK4 on ``dynamics.accelerations``, the integrators' own right-hand side).

:func:`impossible` is the cheap part (no simulation): ``load_ship`` and ``simulate`` refuse what
it finds (:func:`refuse_impossible`). The commands print the warnings once
(``mmg_tuner._ship_params``); the simulator node shows them on ``/diagnostics``.
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import logging
import math
from pathlib import Path
from typing import Any, Callable, Mapping, TYPE_CHECKING

from mmg_tuner._limits import load_yaml
from mmg_tuner.core.actuators import actuator
from mmg_tuner.core.dynamics import accelerations, family_tag, mmg_mass_solve
from mmg_tuner.core.layout import PARAM_INDEX, PARAM_NAMES
from mmg_tuner.core.models import Family
from mmg_tuner.errors import ConfigError
import numpy as np

if TYPE_CHECKING:
    from mmg_tuner.core.ship import ShipConfig

G = 9.80665  # m/s^2
CONFIG_NAME = 'model_plausibility.yaml'
logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Finding:
    """
    One thing wrong with a model.

    level: 'error' (impossible: refused) or 'warning' (implausible); what: the check
    ('mass matrix', 'N_r sign', 'straight-line stability', 'turn direction', ...); figure: the
    number that failed it (NaN when there is none); text: one sentence with the figure, the
    limit and what to do.
    """

    level: str
    what: str
    figure: float
    text: str

    def line(self, source: str = '') -> str:
        """Return the finding as one ``ERROR: ...`` / ``WARNING: ...`` line."""
        return f'{self.level.upper()}: {source + ": " if source else ""}{self.text}'


# ------------------------------------------------------------------------------ tolerances
def _config_path() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        for cand in (parent / 'config', parent / 'share' / 'mmg_tuner' / 'config'):
            if (cand / CONFIG_NAME).is_file():
                return cand / CONFIG_NAME
    raise ConfigError(f'{CONFIG_NAME} not found beside the ship configs: reinstall the package '
                      '(colcon build) or restore config/' + CONFIG_NAME)


@functools.lru_cache(maxsize=1)
def tolerances() -> Mapping[str, Any]:
    """Return config/model_plausibility.yaml (read once)."""
    path = _config_path()
    doc = load_yaml(path, 'plausibility tolerances')   # the one safe reader (_limits.py)
    if not isinstance(doc, Mapping) or not isinstance(doc.get('families'), Mapping):
        raise ConfigError(f'{path}: expected the keys service_froude, stability, turn, '
                          'actuators, families')
    return doc


def _family_rules(fam: Family) -> Mapping[str, Any]:
    """
    Return a family's rules: the file's entry, else the module's own ``PLAUSIBILITY``.

    A plugin family declares its rules beside its forces; one with neither gets the mass
    checks only. Either is checked once (:func:`_check_family_rules`).
    """
    rules = tolerances()['families'].get(fam.name)
    if isinstance(rules, Mapping):
        return _check_family_rules(fam, rules, f'{_config_path()}: families: {fam.name}')
    where = f'{_module(fam.name, "models")}: PLAUSIBILITY'
    return _check_family_rules(fam, fam.plausibility, where)


def _module(name: str, kind: str) -> str:
    from mmg_tuner.core import actuators, models
    try:
        module_of = models.module_of if kind == 'models' else actuators.module_of
        return module_of(name)
    except KeyError:
        return name


_LIST: Any = (list, tuple)
_FAMILY_KEYS: dict[str, Any] = {'positive': _LIST, 'non_negative': _LIST,
                                'non_positive': _LIST, 'resistance': str, 'signs': Mapping}
_ACTUATOR_KEYS: dict[str, Any] = {'propulsion': _LIST, 'helm': Mapping}
_checked: dict[str, Mapping[str, Any]] = {}
"""Rules already checked, by where they come from (the object itself: a new one is checked)."""


def _check_family_rules(fam: Family, rules: Mapping[str, Any], where: str
                        ) -> Mapping[str, Any]:
    """
    Return ``rules`` once they name only what the family has; else a ConfigError.

    A misspelt coefficient would stop a check with a KeyError deep in a command, or (an
    output name) silently switch the check off.
    """
    if _checked.get(where) is rules:
        return rules
    _check_keys(rules, _FAMILY_KEYS, where)
    names = set(PARAM_NAMES)   # the particulars (m, I_zG, ...) and every family's slots
    for k in ('positive', 'non_negative', 'non_positive', 'signs'):
        for n in rules.get(k) or ():
            if n not in names:
                raise ConfigError(f'{where}: {k}: {n!r} is not a parameter of a ship (the '
                                  f'family {fam.name!r} has {", ".join(fam.params[:10])}, '
                                  '...)')
    for n, sign in (rules.get('signs') or {}).items():
        if type(sign) is not int or sign not in (-1, 1):
            raise ConfigError(f'{where}: signs: {n}: {sign!r}: give -1 or 1')
    if rules.get('resistance') not in (None, 'params', 'probe'):
        raise ConfigError(f'{where}: resistance: {rules["resistance"]!r}: give params (the '
                          'MMG resistance coefficients) or probe (the surge force at rest)')
    _checked[where] = rules
    return rules


def _check_actuator_rules(name: str, outputs: tuple[str, ...], rules: Mapping[str, Any],
                          where: str) -> Mapping[str, Any]:
    """Return ``rules`` once they name only the actuator's outputs; else a ConfigError."""
    if _checked.get(where) is rules:
        return rules
    _check_keys(rules, _ACTUATOR_KEYS, where)
    for k in ('propulsion', 'helm'):
        for o in rules.get(k) or ():
            if o not in outputs:
                raise ConfigError(f'{where}: {k}: {o!r} is not an output of the actuator '
                                  f'{name!r} (its outputs: {", ".join(outputs)})')
    for o, v in (rules.get('helm') or {}).items():
        if v != 'rudder' and not isinstance(v, (int, float)):
            raise ConfigError(f'{where}: helm: {o}: {v!r}: give rudder (the largest rudder '
                              'angle of the ship) or a number (a fraction of the propulsion)')
    _checked[where] = rules
    return rules


def _check_keys(rules: Mapping[str, Any], keys: Mapping[str, type], where: str) -> None:
    if not isinstance(rules, Mapping):
        raise ConfigError(f'{where}: expected a mapping of {", ".join(keys)}')
    for k, v in rules.items():
        if k == 'why':
            continue
        if k not in keys:
            raise ConfigError(f'{where}: {k!r}: unknown; the rules are {", ".join(keys)}')
        if v is not None and not isinstance(v, keys[k]):
            want = 'list' if keys[k] is _LIST else keys[k].__name__.lower()
            raise ConfigError(f'{where}: {k}: {v!r}: expected a {want}')


def service_speed(ship: ShipConfig) -> float:
    """Return the straight-run speed the checks linearise about [m/s] (service_froude)."""
    return float(tolerances()['service_froude']) * math.sqrt(G * ship.L_pp)


# ------------------------------------------------------------------------------ impossible
def impossible(ship: ShipConfig) -> list[Finding]:
    """
    Return what makes ``ship`` impossible: errors only, no simulation (cheap).

    Non-finite values, masses and inertias <= 0, a mass matrix that is singular or has a
    non-positive diagonal or sway-yaw determinant, a negative straight-ahead resistance.
    """
    p = ship.params
    bad = [n for n, v in zip(PARAM_NAMES, p) if not math.isfinite(v)]
    if bad:
        return [Finding('error', 'finite', math.nan, f'{bad[0]} = {p[PARAM_INDEX[bad[0]]]} is '
                        'not finite: give a number')]
    fam = ship.family
    rules = _family_rules(fam)
    out = []
    for k in rules.get('positive', ()):
        if not ship[k] > 0:
            out.append(Finding('error', k, ship[k], f'{k} = {ship[k]:g} must be positive (a '
                               'mass or inertia): no ship has it'))
    for k in rules.get('non_negative', ()):
        if ship[k] < 0:
            out.append(Finding('error', k, ship[k], f'{k} = {ship[k]:g} must not be negative'
                               + (_RESIST if k in ('R_0', 'd11') else '')))
    for k in rules.get('non_positive', ()):
        if ship[k] > 0:
            out.append(Finding('error', k, ship[k], f'{k} = {ship[k]:g} must not be positive'
                               + _RESIST))
    if out:
        return out
    out += _mass_matrix(ship)
    if not out and rules.get('resistance') == 'probe':
        out += _resistance_probe(ship)
    return out


_RESIST = (' (the straight-ahead resistance must oppose the motion; a negative one drives '
           'the ship ahead with no thrust)')


def mass_matrix(ship: ShipConfig) -> np.ndarray | None:
    """
    Return the family's 3x3 mass matrix in SI units, None when it is singular.

    Inverted from the family's own M^-1 (its ``mass_solve``, else the MMG equations of
    motion), run as plain Python: no compilation, and a zero pivot is a ZeroDivisionError.
    """
    solve = ship.family.mass_solve or mmg_mass_solve
    solve = getattr(solve, 'py_func', solve)
    try:
        cols = [solve(ship.params, *map(float, e)) for e in np.eye(3)]
    except ZeroDivisionError:
        return None
    minv = np.array(cols, dtype=float).T
    if not np.all(np.isfinite(minv)):
        return None
    try:
        return np.linalg.inv(minv)
    except np.linalg.LinAlgError:
        return None


def _mass_matrix(ship: ShipConfig) -> list[Finding]:
    M = mass_matrix(ship)
    if M is None:
        return [Finding('error', 'mass matrix', 0.0, 'the mass matrix is singular (its '
                        'sway-yaw determinant is 0): no ship has it')]
    out = []
    for i, axis in enumerate(('surge', 'sway', 'yaw')):
        if not M[i, i] > 0:
            out.append(Finding('error', 'mass matrix', float(M[i, i]),
                               f'the {axis} mass M[{i + 1},{i + 1}] = {M[i, i]:.4g} is not '
                               'positive: no ship has it'))
    det = float(M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1])
    if not out and not det > 0:
        out.append(Finding('error', 'mass matrix', det,
                           f'the sway-yaw mass matrix has determinant {det:.4g} <= 0 '
                           f'(M22 {M[1, 1]:.4g}, M23 {M[1, 2]:.4g}, M32 {M[2, 1]:.4g}, M33 '
                           f'{M[2, 2]:.4g}): not positive definite, the model diverges at '
                           'once; no ship has it'))
    return out


def _resistance_probe(ship: ShipConfig) -> list[Finding]:
    """
    Check that the hull's surge force opposes u over (0, Fn 0.5] (family forces, no thrust).

    The family's ``forces`` run as plain Python where they are plain (no compilation).
    """
    fam = ship.family
    forces = getattr(fam.forces, 'py_func', fam.forces)
    M = mass_matrix(ship)
    m11 = float(M[0, 0]) if M is not None else 1.0
    top = 0.5 * math.sqrt(G * ship.L_pp)
    act = (0.0,) * len(fam.outputs)
    for u in np.linspace(top / 20, top, 20):
        X = float(forces(ship.params, float(u), 0.0, 0.0, act)[0])
        if not X < 0:
            return [Finding('error', 'resistance', X,
                            f'with no thrust at u = {u:.3g} m/s the hull surge force is '
                            f'{X:+.3g} N ({X / m11:+.3g} m/s^2): it pushes the ship ahead '
                            '(surge damping d11(u) <= 0; e.g. X_u, X_absu_u, X_uuu > 0); no '
                            'ship has it')]
    return []


def refuse_impossible(ship: ShipConfig, source: str = '') -> None:
    """Raise a ConfigError for an impossible model: one line, the first failure and a count."""
    errors = impossible(ship)
    if errors:
        more = f' (and {len(errors) - 1} more)' if len(errors) > 1 else ''
        raise ConfigError(f'{source or ship.source or ship.name}: {errors[0].text}{more}; '
                          'correct the value')


_CHECKED: dict[tuple[object, ...], list[Finding]] = {}
_WARNED: set[tuple[object, ...]] = set()


def checked(ship: ShipConfig) -> list[Finding]:
    """Return :func:`check_model`, remembered per family and values (commands load twice)."""
    key = (ship.kind, ship.params.tobytes(), ship.max_rudder_rad)
    if key not in _CHECKED:
        if len(_CHECKED) >= 64:
            _CHECKED.clear()
        _CHECKED[key] = check_model(ship)
    return _CHECKED[key]


def warn_once(ship: ShipConfig, source: str = '') -> list[Finding]:
    """
    Log each warning on ``ship`` as its ``WARNING:`` line, once per model; return the findings.

    The path the commands' other warnings take (the ``mmg_tuner`` loggers on stderr).
    """
    findings = checked(ship)
    key = (ship.kind, ship.params.tobytes(), ship.max_rudder_rad)
    if key not in _WARNED:
        _WARNED.add(key)
        for f in findings:
            logger.warning(f.line(source or ship.name))
    return findings


# ---------------------------------------------------------------------------- implausible
def check_model(ship: ShipConfig) -> list[Finding]:
    """
    Return every finding on ``ship``: errors (impossible), then warnings (implausible).

    Examples
    --------
    >>> from mmg_tuner.core.ship import load_ship
    >>> check_model(load_ship('suzaku'))
    []
    >>> [f.what for f in check_model(load_ship('suzaku').with_params({'N_r': 0.057}))]
    ['N_r sign', 'straight-line stability']

    """
    errors = impossible(ship)
    if errors:
        return errors
    out = _signs(ship)
    straight = _straight_run(ship)
    if isinstance(straight, Finding):
        return out + [straight]
    U, act = straight
    out += _stability(ship, U, act)
    out += _turn(ship, U, act)
    return out


def _signs(ship: ShipConfig) -> list[Finding]:
    out = []
    for k, sign in (_family_rules(ship.family).get('signs') or {}).items():
        v = ship[k]
        if not v * sign > 0:
            want = 'negative' if sign < 0 else 'positive'
            out.append(Finding('warning', f'{k} sign', v,
                               f'{k} = {v:g}: a ship has it {want} '
                               f'({_SIGN_WHY.get(k, "damping")}); check the sign'))
    return out


_SIGN_WHY = {'Y_v': 'sway damping', 'N_r': 'yaw damping', 'Y_r': "the hull's Y_r', MMG",
             'N_v': 'the Munk moment', 'd22': 'sway damping', 'd33': 'yaw damping'}


def _act_rules(ship: ShipConfig) -> tuple[list[int], dict[int, Any]]:
    """Return (positions of the propulsion outputs, {position: helm value}) in the act tuple."""
    acts = tolerances().get('actuators') or {}
    prop: list[int] = []
    helm: dict[int, Any] = {}
    k = 0
    for a in ship.family.actuators:
        model = actuator(a)
        outs = model.outputs
        if acts.get(a):   # the file's, else its own
            rules = _check_actuator_rules(a, outs, acts[a], f'{_config_path()}: actuators: {a}')
        else:
            rules = _check_actuator_rules(a, outs, model.plausibility,
                                          f'{_module(a, "actuators")}: PLAUSIBILITY')
        # checked: every name is one of its outputs
        prop += [k + outs.index(o) for o in rules.get('propulsion') or ()]
        helm.update({k + outs.index(o): v for o, v in (rules.get('helm') or {}).items()})
        k += len(outs)
    return prop, helm


def bisect_rising(f: Callable[[float], float], lo: float, hi: float) -> float:
    """
    Return where f crosses 0 upward between lo (f <= 0) and hi (f >= 0), by bisection.

    100 halvings: below a float's resolution for the brackets of its callers (up to 4e12), so
    there is no tolerance to choose.
    """
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def _straight_run(ship: ShipConfig) -> tuple[float, tuple[float, ...]] | Finding:
    """
    Return (U, the actuator tuple holding U straight ahead), or a warning why there is none.

    The propulsion outputs (all equal) found by bisection on du/dt = 0 at (U, 0, 0).
    """
    U = service_speed(ship)
    tag = family_tag(ship.kind)
    n_act = len(ship.family.outputs)
    prop, _ = _act_rules(ship)
    if not prop:
        return Finding('warning', 'straight run', math.nan, f'family {ship.model!r}: no '
                       'propulsion declared (config/model_plausibility.yaml, or PLAUSIBILITY '
                       'in its actuator modules): stability and turn direction not checked')

    def du(x: float) -> float:
        act = [0.0] * n_act
        for i in prop:
            act[i] = x
        try:
            return float(accelerations(tag, ship.params, U, 0.0, 0.0, tuple(act))[0])
        except ZeroDivisionError:
            return math.nan

    lo, hi = 1e-9, 1.0
    while du(hi) < 0 and hi < 1e12:
        hi *= 4.0
    if not (du(hi) > 0 and du(lo) < 0):
        return Finding('warning', 'straight run', U, f'no propulsion holds the service speed '
                       f'{U:.3g} m/s (Fn {tolerances()["service_froude"]}) straight ahead: '
                       'stability and turn direction not checked; check the resistance and '
                       'thrust')
    x = bisect_rising(du, lo, hi)
    act = [0.0] * n_act
    for i in prop:
        act[i] = x
    return U, tuple(act)


def sway_yaw_eigenvalues(ship: ShipConfig, U: float, act: tuple[float, ...]) -> np.ndarray:
    """Eigenvalues [1/s] of d(dv/dt, dr/dt)/d(v, r) at (U, 0, 0), central differences."""
    tag = family_tag(ship.kind)
    L = ship.L_pp
    hv, hr = 1e-4 * U, 1e-4 * U / L
    A = np.empty((2, 2))
    for j, (dv, dr) in enumerate(((hv, 0.0), (0.0, hr))):
        fp = accelerations(tag, ship.params, U, dv, dr, act)
        fm = accelerations(tag, ship.params, U, -dv, -dr, act)
        h = 2.0 * (hv if j == 0 else hr)
        A[0, j] = (fp[1] - fm[1]) / h
        A[1, j] = (fp[2] - fm[2]) / h
    return np.linalg.eigvals(A)


def _stability(ship: ShipConfig, U: float, act: tuple[float, ...]) -> list[Finding]:
    tol = float(tolerances()['stability']['max_growth_per_length'])
    try:
        lam = sway_yaw_eigenvalues(ship, U, act)
    except ZeroDivisionError:
        lam = np.array([math.nan])
    growth = float(np.max(lam.real)) * ship.L_pp / U
    if not math.isfinite(growth):
        return [Finding('warning', 'straight-line stability', growth, 'the sway-yaw system '
                        f'at {U:.3g} m/s has no finite linearisation: check the hull terms')]
    if growth > tol:
        return [Finding('warning', 'straight-line stability', growth,
                        f'straight-line unstable at {U:.3g} m/s: a yaw disturbance grows '
                        f'{growth:.3g} per ship length sailed (doubles in '
                        f'{math.log(2) / growth:.2g} ship lengths), beyond the tolerated '
                        f'{tol:g} (config/{CONFIG_NAME}); check the signs of N_r, Y_v, N_v')]
    return []


def _turn(ship: ShipConfig, U: float, act: tuple[float, ...]) -> list[Finding]:
    """
    Full starboard helm from the straight run: the ship must yaw to starboard.

    Classic RK4 on the family's own accelerations (``dynamics.accelerations``, as the
    integrators' right-hand side), heading psi' = r; actuators held (no steering gear).
    """
    cfg = tolerances()['turn']
    _, helm = _act_rules(ship)
    if not helm:
        return []
    a = list(act)
    for i, v in helm.items():
        a[i] = ship.max_rudder_rad if v == 'rudder' else act[i] * (1.0 + float(v))
    turned = tuple(a)
    T = float(cfg['duration_lengths']) * ship.L_pp / U
    n = int(cfg['steps'])
    h = T / n
    tag = family_tag(ship.kind)
    p = ship.params

    def f(x: np.ndarray) -> np.ndarray:
        du, dv, dr = accelerations(tag, p, float(x[0]), float(x[1]), float(x[2]), turned)
        return np.array([du, dv, dr, x[2]])

    x = np.array([U, 0.0, 0.0, 0.0])   # u, v, r, psi
    try:
        for _ in range(n):
            k1 = f(x)
            k2 = f(x + 0.5 * h * k1)
            k3 = f(x + 0.5 * h * k2)
            k4 = f(x + h * k3)
            x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            if not np.all(np.isfinite(x)):
                break
    except ZeroDivisionError:
        x[:] = math.nan
    r, psi = float(x[2]), float(x[3])
    what = ', '.join(f'{ship.family.outputs[i]} {turned[i]:.3g}' for i in helm)
    if not (math.isfinite(psi) and math.isfinite(r)):
        return [Finding('warning', 'turn direction', psi, f'a {T:.0f} s turn with {what} from '
                        f'{U:.3g} m/s diverges: check the hull and rudder terms')]
    if not (psi > 0 and r > 0):
        return [Finding('warning', 'turn direction', math.degrees(psi),
                        f'turns the wrong way: {T:.0f} s of starboard helm ({what}) from '
                        f'{U:.3g} m/s give a heading change of {math.degrees(psi):+.1f} deg '
                        f'(yaw rate {math.degrees(r):+.2f} deg/s); + helm must turn to '
                        'starboard: check the signs of the rudder and hull terms')]
    return []
