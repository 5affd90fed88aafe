"""
Manoeuvre programmes with a steering gear in the loop.

Turning circle, IMO zigzag, pull-out and random rudder/rpm sequences (the most informative input
for identification according to Wakita et al. 2022). Each returns a
:class:`~mmg_tuner.core.trial.Trial` whose rudder column is the actual (rate-limited) rudder angle,
as a rudder-angle sensor would record it.

Low-speed programmes (:data:`LOWSPEED_MANEUVERS`, for a family that covers astern propeller,
u <= 0 and thrusters, e.g. ``lowspeed``): ``berthing`` (approach, helm toward the berth, slow
down, astern propeller until the ship gathers sternway, then thrusters push it sideways and
turn it in place) and ``random_astern`` (random rudder, propeller ahead and astern, and
thruster steps, seeded). Their inputs are recorded as they act, so replaying a generated
trial with the same ship reproduces it exactly.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Callable

from mmg_tuner.core.integrate import run_maneuver
from mmg_tuner.core.layout import OK, STATUS_TEXT
from mmg_tuner.core.models import family
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code, simulate
from mmg_tuner.core.trial import input_array, Trial
from mmg_tuner.errors import SimulationError
import numpy as np
import numpy.typing as npt

KNOT = 1852.0 / 3600.0  # m/s

MANEUVERS = ('turning', 'zigzag', 'pullout', 'random')
LOWSPEED_MANEUVERS = ('berthing', 'random_astern')
"""Need a family that covers astern propeller and u <= 0 and reads the thruster channels."""
ALL_MANEUVERS = MANEUVERS + LOWSPEED_MANEUVERS


@dataclass(frozen=True)
class ManeuverSpec:
    """
    What to run.

    Angles in degrees here because that is how trials are specified.

    rudder_deg: turning/pull-out rudder, or zigzag amplitude (sign = first rudder direction,
    + starboard). check_deg: zigzag heading check angle. approach_s: straight run before the
    rudder is executed. pullout_s: for 'pullout', time the rudder is held before returning to 0.
    rudder_rate_deg_s: steering-gear rate (None: the ship's; 0: instantaneous).
    thruster_rps: berthing / random_astern: the thrusters' speed [rev/s] (berthing pushes
    toward the side of rudder_deg's sign; random_astern draws within +-thruster_rps).
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
    thruster_rps: float = 20.0


def check_lowspeed(ship: ShipConfig, maneuver: str) -> None:
    """
    Refuse a low-speed manoeuvre for a ship whose family cannot run it.

    Such a family must cover astern propeller, u <= 0 and read the thrusters; the message
    says which of them is missing.
    """
    fam = family(ship.model)
    missing = [what for what, ok in (
        ('astern propeller (rpm <= 0)', fam.astern_rpm), ('u <= 0', fam.astern_surge),
        ('thrusters', 'bow_thruster' in fam.inputs and 'stern_thruster' in fam.inputs))
        if not ok]
    if missing:
        raise SimulationError(
            f'manoeuvre {maneuver!r} needs a model family that covers astern propeller, u <= 0 '
            f'and thrusters; {ship.name} is of the {fam.name!r} family, which does not cover '
            f'{", ".join(missing)} (use a lowspeed ship, e.g. esso_osaka_3m)')


def run(ship: ShipConfig, spec: ManeuverSpec, x0: npt.ArrayLike | None = None) -> Trial:
    """Run one manoeuvre from a straight run at spec.speed_ms (or from x0)."""
    if spec.maneuver not in ALL_MANEUVERS:
        raise SimulationError(f'unknown manoeuvre {spec.maneuver!r}; one of {ALL_MANEUVERS}')
    if spec.dt <= 0 or spec.duration_s <= 0:
        raise SimulationError('dt and duration must be positive')
    fam = family(ship.model)
    if spec.maneuver in LOWSPEED_MANEUVERS:
        check_lowspeed(ship, spec.maneuver)
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
    if spec.maneuver in LOWSPEED_MANEUVERS:
        return _run_lowspeed(ship, spec, x0, t, rate)
    status, k_fail, out, rudder = steered(ship, x0, rpm, orders, zz_amp, zz_check, rate,
                                          spec.dt, spec.substeps, spec.integrator,
                                          spec.maneuver)
    controls = np.column_stack([rpm, rudder])
    if status != OK:
        return Trial(t, out, controls, name=spec.maneuver, status=STATUS_TEXT[status],
                     fail_time_s=float(t[min(k_fail, T - 1)]))
    return Trial(t, out, controls, name=spec.maneuver)


def steered(ship: ShipConfig, x0: np.ndarray, rpm: np.ndarray, orders: np.ndarray,
            zigzag_amp: float, zigzag_check: float, rate_rad_s: float, dt: float,
            substeps: int, integrator: str, what: str = 'manoeuvre'
            ) -> tuple[int, int, np.ndarray, np.ndarray]:
    """
    Run rudder orders [rad] through a steering gear of rate_rad_s (``integrate.run_maneuver``).

    rpm, orders: (T,) per sample; zigzag_amp != 0 closes the orders on heading (IMO zigzag).
    Returns (status, k_fail, observed states (T, 6), logged rudder angle (T,)).
    """
    fam = family(ship.model)
    if fam.inputs[:2] != ('rpm', 'rudder'):
        raise SimulationError(f'{what} drives a screw and rudder; the {fam.name!r} family '
                              f'reads {", ".join(fam.inputs)}')
    T = rpm.size
    out = np.empty((T, 6))
    rudder = np.empty(T)
    ctrl = input_array(fam.channels, {'rpm': rpm, 'rudder': orders}, T, what)
    status, k_fail = run_maneuver(ship.kind, ship.params, np.asarray(x0, dtype=float), ctrl,
                                  fam.inputs.index('rudder'), zigzag_amp, zigzag_check,
                                  rate_rad_s, T, float(dt), int(substeps),
                                  integrator_code(integrator), out, rudder)
    return status, k_fail, out, rudder


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


# ------------------------------------------------------------------ low-speed programmes
def _rate_limited(orders: np.ndarray, rate_rad_s: float, dt: float) -> np.ndarray:
    """
    Return the rudder angle at each sample of a rate-limited steering gear.

    The gear starts amidships and moves toward the order of each sample at rate_rad_s
    (<= 0: instantaneous) during the following interval.
    """
    step = rate_rad_s * dt if rate_rad_s > 0 else math.inf
    out = np.empty_like(orders)
    d = 0.0
    for k in range(orders.size):
        out[k] = d
        d += min(step, max(-step, orders[k] - d))
    return out


class _Programme:
    """
    Inputs of a manoeuvre, built phase by phase.

    Each phase's end is found by simulating the whole programme so far (deterministic, so the
    final run passes exactly through those states).
    """

    def __init__(self, ship: ShipConfig, spec: ManeuverSpec, x0: np.ndarray, t: np.ndarray,
                 rate: float) -> None:
        self.ship, self.spec, self.x0, self.t, self.rate = ship, spec, x0, t, rate
        self.orders = np.zeros(t.size)
        # the commands by channel (the wind not measured: the wind parameters act)
        self.ctrl = {'rpm': np.full(t.size, float(spec.rpm)), 'rudder': np.zeros(t.size),
                     'bow_thruster': np.zeros(t.size), 'stern_thruster': np.zeros(t.size)}

    def sample(self, time_s: float) -> int:
        """Return the sample index of a time [s] (the last one at most)."""
        return min(self.t.size - 1, int(round(time_s / self.spec.dt)))

    def simulate(self) -> Trial:
        """Simulate the programme as it stands (rudder rate-limited from the orders)."""
        self.ctrl['rudder'] = _rate_limited(self.orders, self.rate, self.spec.dt)
        return simulate(self.ship, self.x0, self.ctrl, self.spec.dt, self.spec.integrator,
                        self.spec.substeps)

    def until(self, k0: int, max_s: float,
              done: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> int:
        """Return the first sample after k0 (at most max_s later) where done holds."""
        run = self.simulate()
        k1 = min(self.t.size - 1, k0 + max(1, int(round(max_s / self.spec.dt))))
        hit = np.nonzero(done(run.states[k0 + 1:k1 + 1], run.states[k0]))[0]
        return k0 + 1 + int(hit[0]) if hit.size else k1

    def trial(self) -> Trial:
        """Return the finished programme's trial, thrusters included."""
        run = self.simulate()
        return Trial(self.t, run.states, inputs=self.ctrl, name=self.spec.maneuver,
                     status=run.status, fail_time_s=run.fail_time_s)


def _run_lowspeed(ship: ShipConfig, spec: ManeuverSpec, x0: np.ndarray, t: np.ndarray,
                  rate: float) -> Trial:
    if not spec.rpm > 0:
        raise SimulationError(f'{spec.maneuver}: the approach rpm must be > 0, got {spec.rpm}')
    if not (math.isfinite(spec.thruster_rps) and spec.thruster_rps >= 0):
        raise SimulationError(f'{spec.maneuver}: thruster_rps = {spec.thruster_rps}: must be '
                              'a finite number >= 0')
    pg = _Programme(ship, spec, x0, t, rate)
    if spec.maneuver == 'berthing':
        _berthing(pg)
    else:
        _random_astern(pg)
    return pg.trial()


def _berthing(pg: _Programme) -> None:
    """
    Set the inputs of a berthing-like manoeuvre.

    Approach at spec.rpm; helm spec.rudder_deg until the heading has changed 20 deg, then
    amidships and the propeller stopped until the speed is down to 60 %; full astern (-rpm)
    until the ship makes 10 % of the approach speed astern; propeller stopped, both thrusters
    push toward the berth (the side of rudder_deg's sign) for 60 % of the time left, then
    check the swing (bow and stern thrusters opposite) for 15 %; all stopped to the end.
    The first three phases end at their condition or after 6, 8 and 15 ship lengths' time at
    the approach speed (L_pp / u0), so a short run simply ends earlier in the programme.
    """
    spec = pg.spec
    side = 1.0 if spec.rudder_deg >= 0 else -1.0
    u0 = pg.x0[3]
    t_L = pg.ship.L_pp / u0
    k = pg.sample(spec.approach_s)
    pg.orders[k:] = math.radians(spec.rudder_deg)
    k = pg.until(k, 6 * t_L, lambda s, s0: np.abs(s[:, 2] - s0[2]) >= math.radians(20.0))
    pg.orders[k:] = 0.0
    pg.ctrl['rpm'][k:] = 0.0
    k = pg.until(k, 8 * t_L, lambda s, s0: s[:, 3] <= 0.6 * u0)
    pg.ctrl['rpm'][k:] = -spec.rpm
    k = pg.until(k, 15 * t_L, lambda s, s0: s[:, 3] <= -0.1 * u0)
    pg.ctrl['rpm'][k:] = 0.0
    left = pg.t[-1] - pg.t[k]
    k_check = pg.sample(pg.t[k] + 0.6 * left)
    k_stop = pg.sample(pg.t[k] + 0.75 * left)
    pg.ctrl['bow_thruster'][k:k_check] = side * spec.thruster_rps
    pg.ctrl['stern_thruster'][k:k_check] = side * spec.thruster_rps
    pg.ctrl['bow_thruster'][k_check:k_stop] = -side * spec.thruster_rps
    pg.ctrl['stern_thruster'][k_check:k_stop] = side * spec.thruster_rps


def _random_astern(pg: _Programme) -> None:
    """
    Set random inputs with astern propeller and thruster steps (seeded).

    After the approach, orders held 10..60 s each (uniform): rudder within +-rudder_deg,
    propeller within [-0.8, 1] x rpm (astern about 40 % of the time) and, in half of the
    holds, thrusters within +-thruster_rps each.
    """
    spec = pg.spec
    rng = np.random.default_rng(spec.seed)
    amp = abs(spec.rudder_deg)
    k = pg.sample(spec.approach_s)
    T = pg.t.size
    while k < T:
        hold = max(1, int(rng.uniform(10.0, 60.0) / spec.dt))
        pg.orders[k:k + hold] = math.radians(rng.uniform(-amp, amp))
        pg.ctrl['rpm'][k:k + hold] = spec.rpm * rng.uniform(-0.8, 1.0)
        bow, stern = rng.uniform(-1.0, 1.0, 2) * spec.thruster_rps
        if rng.uniform() < 0.5:
            pg.ctrl['bow_thruster'][k:k + hold] = bow
            pg.ctrl['stern_thruster'][k:k + hold] = stern
        k += hold
