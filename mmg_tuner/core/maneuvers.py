"""Manoeuvre programmes with a steering gear in the loop: turning circle, IMO zigzag, pull-out
and random rudder/rpm sequences (the most informative input for identification according to
Wakita et al. 2022). Each returns a :class:`~mmg_tuner.core.trial.Trial` whose rudder
column is the actual (rate-limited) rudder angle, as a rudder-angle sensor would record it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mmg_tuner.core.layout import OK, STATUS_TEXT
from mmg_tuner.core.models import family
from mmg_tuner.core.integrate import run_maneuver
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import SimulationError

KNOT = 1852.0 / 3600.0  # m/s

MANEUVERS = ('turning', 'zigzag', 'pullout', 'random')


@dataclass(frozen=True)
class ManeuverSpec:
    """What to run. Angles in degrees here because that is how trials are specified.

    rudder_deg: turning/pull-out rudder, or zigzag amplitude (sign = first rudder direction,
    + starboard). check_deg: zigzag heading check angle. approach_s: straight run before the
    rudder is executed. pullout_s: for 'pullout', time the rudder is held before returning to 0.
    rudder_rate_deg_s: steering-gear rate (None: the ship's; 0: instantaneous).
    """

    maneuver: str = 'turning'
    rudder_deg: float = 35.0
    check_deg: float | None = None
    rpm: float = 106.0
    speed_ms: float = 6 * KNOT
    duration_s: float = 900.0
    dt: float = 1.0
    approach_s: float = 0.0
    pullout_s: float = 300.0
    rudder_rate_deg_s: float | None = None
    integrator: str = 'euler'
    substeps: int = 1
    seed: int = 0
    # random manoeuvres: rudder orders held 10..60 s (uniform), up to +-rudder_deg;
    # rpm varied by up to +-random_rpm_frac around rpm
    random_rpm_frac: float = 0.0


def run(ship: ShipConfig, spec: ManeuverSpec, x0=None) -> Trial:
    """Run one manoeuvre from a straight run at spec.speed_ms (or from x0)."""
    if spec.maneuver not in MANEUVERS:
        raise SimulationError(f'unknown manoeuvre {spec.maneuver!r}; one of {MANEUVERS}')
    if spec.dt <= 0 or spec.duration_s <= 0:
        raise SimulationError('dt and duration must be positive')
    fam = family(ship.model)
    if spec.rpm <= 0 and not fam.astern_rpm:
        raise SimulationError(f'rpm = {spec.rpm}: the MMG model covers forward propeller '
                              'revolutions only')
    if abs(spec.rudder_deg) > math.degrees(ship.max_rudder_rad) + 1e-9:
        raise SimulationError(f'rudder {spec.rudder_deg} deg exceeds the {ship.name} limit '
                              f'of {math.degrees(ship.max_rudder_rad):.1f} deg')
    T = int(round(spec.duration_s / spec.dt)) + 1
    t = np.arange(T) * spec.dt
    rpm = np.full(T, float(spec.rpm))
    orders = np.zeros(T)
    executed = t >= spec.approach_s
    amp = math.radians(spec.rudder_deg)
    zz_amp, zz_check = 0.0, 0.0
    if spec.maneuver == 'turning':
        orders[executed] = amp
    elif spec.maneuver == 'pullout':
        orders[executed & (t < spec.approach_s + spec.pullout_s)] = amp
    elif spec.maneuver == 'zigzag':
        if amp == 0:
            raise SimulationError('zigzag needs a non-zero rudder angle')
        zz_amp = amp
        zz_check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                                    else spec.rudder_deg))
        orders[executed] = amp
    else:
        orders, rpm = _random_orders(t, spec)
    rate = ship.rudder_rate_rad_s if spec.rudder_rate_deg_s is None \
        else math.radians(spec.rudder_rate_deg_s)
    x0 = np.array([0.0, 0.0, 0.0, spec.speed_ms, 0.0, 0.0]) if x0 is None \
        else np.asarray(x0, dtype=float)
    if x0[3] <= 0 and not fam.astern_surge:
        raise SimulationError(f'approach speed {x0[3]} m/s: the MMG model covers u > 0 only')
    out = np.empty((T, 6))
    rudder = np.empty(T)
    status, k_fail = run_maneuver(ship.kind, ship.params, x0, rpm, orders, zz_amp, zz_check,
                                  rate, T, float(spec.dt), int(spec.substeps),
                                  integrator_code(spec.integrator), out, rudder)
    controls = np.column_stack([rpm, rudder])
    if status != OK:
        return Trial(t, out, controls, name=spec.maneuver, status=STATUS_TEXT[status],
                     fail_time_s=float(t[min(k_fail, T - 1)]))
    return Trial(t, out, controls, name=spec.maneuver)


def _random_orders(t: np.ndarray, spec: ManeuverSpec) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise-constant random rudder (and optionally rpm) orders, seeded."""
    rng = np.random.default_rng(spec.seed)
    T = t.size
    orders = np.zeros(T)
    rpm = np.full(T, float(spec.rpm))
    k = int(np.searchsorted(t, spec.approach_s))
    amp = abs(spec.rudder_deg)
    while k < T:
        hold = max(1, int(rng.uniform(10.0, 60.0) / spec.dt))
        orders[k:k + hold] = math.radians(rng.uniform(-amp, amp))
        if spec.random_rpm_frac > 0:
            rpm[k:k + hold] = spec.rpm * (1 + rng.uniform(-1, 1) * spec.random_rpm_frac)
        k += hold
    return orders, rpm
