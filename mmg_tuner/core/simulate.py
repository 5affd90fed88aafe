"""
Simulation entry points.

One trajectory (:func:`simulate`) or a batch of parameter candidates x trials in one compiled call
(:func:`simulate_batch`).
"""
from __future__ import annotations

import math
from typing import Mapping

from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.integrate import simulate_many, simulate_one
from mmg_tuner.core.layout import INTEGRATORS, N_PARAMS, OK, STATUS_TEXT
from mmg_tuner.core.models import Family, family, family_of_code
from mmg_tuner.core.plausibility import bisect_rising
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import input_array, Trial
from mmg_tuner.errors import SimulationError, TrialDataError
import numpy as np
import numpy.typing as npt


REPLAY_STEP_S = 0.1
"""The longest integration step of a replay of recorded trials [s]: GO's, ``evaluate``'s
scoring and an actuator's own fit (tuning/lo_go.py)."""


def steps_per_sample(dt: float) -> int:
    """Return the integration steps per sample interval dt [s]: steps of at most REPLAY_STEP_S."""
    return max(1, math.ceil(dt / REPLAY_STEP_S - 1e-9))


def kernel_inputs(fam: Family, controls: Trial | npt.ArrayLike | Mapping[str, npt.ArrayLike],
                  what: str = 'simulation') -> np.ndarray:
    """
    Return the kernels' input array for family ``fam``: its channels, wind last.

    ``controls``: a Trial, a mapping channel name -> (T,) values (absent channels take their
    defaults; a required one is an error naming it), or an array whose last axis holds the
    family's channels (``fam.channels``: its actuators' inputs, then the measured wind north
    and east) or the first of its command channels (``fam.inputs``; the rest take their
    defaults, e.g. thrusters 0, and the wind is "not measured"). A (M, T, n) array of several
    trials is accepted the same way.
    """
    if isinstance(controls, Trial):
        return np.ascontiguousarray(controls.input_array(fam.channels))
    if isinstance(controls, Mapping):
        lengths = {np.asarray(v).shape[0] for v in controls.values()}
        if len(lengths) != 1:
            raise SimulationError(f'{what}: the input channels differ in length: '
                                  f'{sorted(lengths)}')
        try:
            return input_array(fam.channels, controls, lengths.pop(), what)
        except TrialDataError as exc:
            raise SimulationError(str(exc)) from None
    a = np.asarray(controls, dtype=float)
    n = a.shape[-1] if a.ndim in (2, 3) else -1
    n_req = max([i + 1 for i, c in enumerate(fam.inputs) if TABLE[c].default is None] or [0])
    if n == len(fam.channels):
        return np.ascontiguousarray(a)
    if not n_req <= n <= len(fam.inputs):
        raise SimulationError(f'{what}: controls must be (T, {n_req}..{len(fam.inputs)}) '
                              f'({", ".join(fam.inputs)}) or (T, {len(fam.channels)}) with the '
                              f'measured wind ({", ".join(fam.channels)}) for the {fam.name!r} '
                              f'family, or a mapping of channel names; got shape {a.shape}')
    out = np.empty(a.shape[:-1] + (len(fam.channels),))
    out[..., :n] = a
    for j, c in enumerate(fam.channels[n:], start=n):
        out[..., j] = TABLE[c].default
    return out


def integrator_code(name: str) -> int:
    try:
        return INTEGRATORS[name.lower()]
    except KeyError:
        raise SimulationError(f'unknown integrator {name!r}; use one of '
                              f'{sorted(INTEGRATORS)}') from None


def check_inputs(x0: np.ndarray, controls: np.ndarray, dt: float, t0: float = 0.0,
                 what: str = 'simulation', fam: Family | None = None) -> None:
    """
    Refuse inputs outside the model's range, with a message naming the sample time.

    ``controls``: the kernels' input array (:func:`kernel_inputs`) of family ``fam`` (its
    command channels must be finite; the wind may be NaN: not measured); astern rpm and
    u <= 0 only where the family covers them.
    """
    fam = fam or family('container')
    astern_rpm = fam.astern_rpm
    astern_surge = fam.astern_surge
    if not dt > 0:
        raise SimulationError(f'{what}: time step dt must be positive, got {dt}')
    if x0.shape != (6,) or not np.all(np.isfinite(x0)):
        raise SimulationError(f'{what}: initial state must be 6 finite numbers, got {x0}')
    if x0[3] <= 0 and not astern_surge:
        raise SimulationError(f'{what}: initial surge u = {x0[3]:.3f} m/s; the MMG model '
                              'covers u > 0 only')
    # channels whose default is NaN ("not recorded", e.g. an azimuth command) may be NaN
    n_cmd = len(fam.inputs)
    cols = [j for j, c in enumerate(fam.inputs) if not _optional(c)]
    cmd = controls[:, cols] if len(cols) < n_cmd else controls[:, :n_cmd]
    # one pass on the usual path (a sum of finite values can still overflow: then look closer)
    bad = None if np.isfinite(cmd.sum()) else ~np.all(np.isfinite(cmd), axis=1)
    if bad is not None and bad.any():
        k = int(np.argmax(bad))
        j = cols[int(np.argmax(~np.isfinite(cmd[k])))]
        raise SimulationError(f'{what}: non-finite control at t = {t0 + k * dt:.2f} s '
                              f'({fam.inputs[j]})')
    for j, c in enumerate(fam.inputs):
        if _optional(c) and np.isinf(controls[:, j]).any():
            k = int(np.argmax(np.isinf(controls[:, j])))
            raise SimulationError(f'{what}: infinite control at t = {t0 + k * dt:.2f} s ({c})')
    if 'rpm' in fam.inputs and not astern_rpm:
        rpm = controls[:-1, fam.inputs.index('rpm')]
        if rpm.min(initial=1.0) <= 0:
            k = int(np.argmax(rpm <= 0))
            raise SimulationError(f'{what}: rpm = {rpm[k]:.2f} at t = {t0 + k * dt:.2f} s;'
                                  ' the MMG model covers forward propeller revolutions only')


def _optional(channel: str) -> bool:
    """Whether a command channel may be NaN: its default says "not recorded"."""
    default = TABLE[channel].default
    return default is not None and default != default


def simulate(ship: ShipConfig, x0: npt.ArrayLike,
             controls: Trial | npt.ArrayLike | Mapping[str, npt.ArrayLike], dt: float,
             integrator: str = 'euler',
             substeps: int = 1, t0: float = 0.0, params: np.ndarray | None = None,
             check: bool = True) -> Trial:
    """
    Simulate one trajectory driven by recorded/planned controls (zero-order hold).

    Parameters
    ----------
    ship : ShipConfig
        The ship config (its parameter vector is used unless ``params`` is given).
    x0 : array_like, shape (6,)
        First observed state (x, y, psi, u, v, r), velocities over ground.
    controls : Trial, mapping or array_like, shape (T, n)
        The input channels at each sample (see :func:`kernel_inputs`); sample k is held
        until k+1. For a screw-and-rudder family: (T, 2) rpm and rudder [rad], or (T, 4)
        with the measured true wind's north/east components [m/s] (the air's velocity),
        which replace the wind parameters (NaN: not measured).
    dt : float
        Sample spacing [s]; each sample interval is split into ``substeps`` steps.
    integrator : str
        'euler' (the paper's) or 'rk4'.
    substeps : int
        Integration steps per sample interval.
    t0 : float
        Time of the first sample [s].
    params : ndarray, optional
        Parameter vector to use instead of ``ship.params``.
    check : bool
        Refuse inputs outside the model's range first (:func:`check_inputs`).

    Returns a :class:`~mmg_tuner.core.trial.Trial` (inputs as given). A run that leaves the
    model's range or diverges is returned with ``status`` saying so and NaN after
    ``fail_time_s``; it never returns NaN silently.

    Examples
    --------
    >>> ship = load_ship('suzaku')
    >>> ctrl = np.tile([106.0, np.radians(35)], (901, 1))
    >>> traj = simulate(ship, [0, 0, 0, 3.086, 0, 0], ctrl, dt=1.0)

    """
    x0 = np.asarray(x0, dtype=float)
    fam = family(ship.model)
    controls = kernel_inputs(fam, controls)
    if check:
        check_inputs(x0, controls, dt, t0, fam=fam)
    T = controls.shape[0]
    out = np.empty((T, 6))
    p = ship.params if params is None else np.asarray(params, dtype=float)
    status, k_fail = simulate_one(ship.kind, p, x0, controls, T, float(dt), int(substeps),
                                  integrator_code(integrator), out)
    t = t0 + dt * np.arange(T)
    if status != OK:
        return Trial.from_array(t, out, controls, fam.channels, name='simulation',
                                status=STATUS_TEXT[status],
                                fail_time_s=float(t[min(k_fail, T - 1)]))
    return Trial.from_array(t, out, controls, fam.channels, name='simulation')


def simulate_batch(kind: int, params: np.ndarray, x0s: np.ndarray, controls: np.ndarray,
                   dt: float, lengths: np.ndarray | None = None, integrator: str = 'euler',
                   substeps: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    N candidates x M trials in one compiled, multi-core call.

    Parameters
    ----------
    kind : int
        Model structure code (``ShipConfig.kind``).
    params : ndarray, shape (N, N_PARAMS)
        Parameter vectors.
    x0s : ndarray, shape (M, 6)
        First states.
    controls : ndarray, shape (M, T, n)
        The family's input channels (see :func:`kernel_inputs`), padded to the longest trial.
    dt : float
        Sample spacing [s].
    lengths : ndarray, shape (M,), optional
        Samples per trial (default all T).
    integrator : str
        'euler' or 'rk4'.
    substeps : int
        Integration steps per sample interval.

    Returns
    -------
    states (N, M, T, 6), status codes (N, M) and failure sample indices (N, M).

    """
    params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
    if params.shape[1] != N_PARAMS:
        raise SimulationError(f'params must have {N_PARAMS} columns, got {params.shape[1]}')
    x0s = np.ascontiguousarray(x0s, dtype=float)
    controls = kernel_inputs(family_of_code(kind), controls, 'simulate_batch')
    M, T = controls.shape[:2]
    lengths = np.full(M, T, dtype=np.int64) if lengths is None else np.asarray(lengths, np.int64)
    N = params.shape[0]
    out = np.full((N, M, T, 6), np.nan)
    status = np.zeros((N, M), dtype=np.int64)
    k_fail = np.zeros((N, M), dtype=np.int64)
    simulate_many(kind, params, x0s, controls, lengths, float(dt), int(substeps),
                  integrator_code(integrator), out, status, k_fail)
    return out, status, k_fail


def self_propulsion_rpm(ship: ShipConfig, speed_ms: float, lo: float = 1.0,
                        hi: float = 1e5) -> float:
    """
    Propeller rpm at which a straight run (rudder 0) holds speed_ms.

    The surge force balance X_H + X_P + X_R = 0, solved by bisection.
    """
    from mmg_tuner.core.dynamics import accelerations, family_tag

    tag = family_tag(ship.kind)
    n_act = len(ship.family.outputs)

    def du(rpm: float) -> float:   # screw_rudder's outputs first: (n_P, delta, ...)
        act = (rpm / 60.0, 0.0) + (0.0,) * (n_act - 2)
        return float(accelerations(tag, ship.params, speed_ms, 0.0, 0.0, act)[0])

    if du(lo) > 0 or du(hi) < 0:
        raise SimulationError(f'{ship.name}: no rpm in [{lo}, {hi}] holds {speed_ms} m/s')
    return bisect_rising(du, lo, hi)
