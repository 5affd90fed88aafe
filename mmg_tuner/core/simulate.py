"""
Simulation entry points.

One trajectory (:func:`simulate`) or a batch of parameter candidates x trials in one compiled call
(:func:`simulate_batch`).
"""
from __future__ import annotations

from mmg_tuner.core.channels import CHANNELS, N_ACT
from mmg_tuner.core.integrate import simulate_many, simulate_one
from mmg_tuner.core.layout import INTEGRATORS, N_PARAMS, OK, STATUS_TEXT
from mmg_tuner.core.models import Family, family
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import Trajectory, Trial  # noqa: F401  (Trajectory: former name)
from mmg_tuner.errors import SimulationError
import numpy as np


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

    Refuse, with a message naming the sample time, inputs outside the model's range (the family's:
    astern rpm and u <= 0 only where it covers them; default: neither).
    """
    astern_rpm = fam is not None and fam.astern_rpm
    astern_surge = fam is not None and fam.astern_surge
    if not dt > 0:
        raise SimulationError(f'{what}: time step dt must be positive, got {dt}')
    if x0.shape != (6,) or not np.all(np.isfinite(x0)):
        raise SimulationError(f'{what}: initial state must be 6 finite numbers, got {x0}')
    if x0[3] <= 0 and not astern_surge:
        raise SimulationError(f'{what}: initial surge u = {x0[3]:.3f} m/s; the MMG model '
                              'covers u > 0 only')
    if controls.ndim != 2 or controls.shape[1] not in (2, 4, len(CHANNELS)):
        raise SimulationError(f'{what}: controls must be (T, 2) rpm, rudder, (T, 4) with the '
                              f'wind north/east components or (T, {len(CHANNELS)}) with the '
                              f'thrusters too ({", ".join(CHANNELS)}), got shape '
                              f'{controls.shape}')
    cols = [0, 1] + list(range(4, controls.shape[1]))  # wind may be NaN: not measured
    bad = ~np.all(np.isfinite(controls[:, cols]), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise SimulationError(f'{what}: non-finite control at t = {t0 + k * dt:.2f} s')
    neg = controls[:, 0] <= 0
    if neg[:-1].any() and not astern_rpm:
        k = int(np.argmax(neg))
        raise SimulationError(f'{what}: rpm = {controls[k, 0]:.2f} at t = {t0 + k * dt:.2f} s;'
                              ' the MMG model covers forward propeller revolutions only')


def simulate(ship: ShipConfig, x0, controls, dt: float, integrator: str = 'euler',
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
    controls : array_like, shape (T, n)
        Input channels (``core/channels.CHANNELS`` order) at each sample;
        sample k is held until k+1. (T, 2): rpm and rudder [rad]; two more columns are the
        measured true wind's north/east components [m/s] (the air's velocity), which
        replace the wind parameters (NaN: not measured); two more the bow and stern
        thrusters [rev/s].
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
    controls = np.ascontiguousarray(controls, dtype=float)
    if check:
        check_inputs(x0, controls, dt, t0, fam=family(ship.model))
    T = controls.shape[0]
    out = np.empty((T, 6))
    p = ship.params if params is None else np.asarray(params, dtype=float)
    status, k_fail = simulate_one(ship.kind, p, x0, controls, T, float(dt), int(substeps),
                                  integrator_code(integrator), out)
    t = t0 + dt * np.arange(T)
    if status != OK:
        return Trial.from_inputs(t, out, controls, name='simulation',
                                 status=STATUS_TEXT[status],
                                 fail_time_s=float(t[min(k_fail, T - 1)]))
    return Trial.from_inputs(t, out, controls, name='simulation')


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
        Input channels (see ``core/channels.py``), padded to the longest trial.
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
    controls = np.ascontiguousarray(controls, dtype=float)
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
    from mmg_tuner.core.dynamics import accelerations

    def du(rpm: float) -> float:
        act = (rpm / 60.0, 0.0) + (0.0,) * (N_ACT - 2)
        return accelerations(ship.kind, ship.params, speed_ms, 0.0, 0.0, act)[0]

    if du(lo) > 0 or du(hi) < 0:
        raise SimulationError(f'{ship.name}: no rpm in [{lo}, {hi}] holds {speed_ms} m/s')
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if du(mid) > 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)
