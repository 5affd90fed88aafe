"""Synthetic trials: the core's manoeuvres with realistic sensor noise, as rosbag2 + CSV."""
from __future__ import annotations

from dataclasses import dataclass, fields
import math
from typing import Iterable, Mapping, Self, TYPE_CHECKING

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, SimulationError
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.core.models import Family


@dataclass(frozen=True)
class _Sigmas:
    """1-sigma noise levels, each a finite number >= 0: the fields of a noise model below."""

    def __post_init__(self) -> None:
        for k, v in self.__dict__.items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f'sensor noise {k} = {v!r}: must be a finite number >= 0')

    @classmethod
    def none(cls) -> Self:
        """Return the noise model with every sigma 0 (exact measurements)."""
        return cls(*(0.0 for _ in fields(cls)))


@dataclass(frozen=True)
class SensorNoise(_Sigmas):
    """1-sigma white noise of the usual trial sensors (SI units, radians)."""

    position_m: float = 0.5          # GNSS (standalone/SBAS class)
    heading_rad: float = math.radians(0.2)   # GNSS compass / gyrocompass
    speed_ms: float = 0.02           # body velocities from a GNSS/INS navigation filter
    yaw_rate_rad_s: float = math.radians(0.05)  # rate gyro
    rudder_rad: float = math.radians(0.1)    # rudder angle indicator
    rpm: float = 0.2                 # shaft tachometer
    wind_ms: float = 0.5             # anemometer, per velocity component (gusts not modelled)
    thruster_rps: float = 0.05       # thruster tachometer [rev/s]

    def apply(self, trial: Trial, rng: np.random.Generator) -> Trial:
        st = trial.states.copy()
        ctrl = trial.controls.copy()
        n = len(trial)
        st[:, 0:2] += rng.normal(0, self.position_m, (n, 2))
        st[:, 2] += rng.normal(0, self.heading_rad, n)
        st[:, 3:5] += rng.normal(0, self.speed_ms, (n, 2))
        st[:, 5] += rng.normal(0, self.yaw_rate_rad_s, n)
        ctrl[:, 0] += rng.normal(0, self.rpm, n)
        ctrl[:, 1] += rng.normal(0, self.rudder_rad, n)
        wind = thr = None
        if trial.wind is not None:
            wind = trial.wind + rng.normal(0, self.wind_ms, (n, 2))
        if trial.thrusters is not None:  # drawn last: trials without keep their noise
            thr = trial.thrusters + rng.normal(0, self.thruster_rps, (n, 2))
        return Trial(trial.t, st, ctrl, trial.name, trial.source,
                     trial.notes + ['sensor noise added: ' + ', '.join(
                         f'{k}={v:.4g}' for k, v in self.__dict__.items())], wind=wind,
                     thrusters=thr)


# The polynomial hull's coefficients (paper eqs. 14-15, standard method eq. 8): the hull force
# and moment of the container and standard families are 1/2 rho L d U^2 (or L^2 d U^2) times a
# polynomial in v' and r' with these coefficients, so scaling all of them by k scales X_H, Y_H
# and N_H by k at every state (as shallow water roughly does); no effect of the library can.
HULL_COEFFICIENTS = ('R_0', 'X_vv', 'X_vr', 'X_rr', 'X_vvvr', 'X_vvvv',
                     'Y_v', 'Y_r', 'Y_vvv', 'Y_vvr', 'Y_vrr', 'Y_rrr',
                     'N_v', 'N_r', 'N_vvv', 'N_vvr', 'N_vrr', 'N_rrr')


def out_of_library(ship: ShipConfig, hull_scale: float = 1.0,
                   scale: Mapping[str, float] | None = None) -> ShipConfig:
    """
    Return the ship changed where no effect of the library reaches (a truth for tests).

    hull_scale: every hull force and moment multiplied by this factor (the polynomial hull's
    coefficients, :data:`HULL_COEFFICIENTS`; the family must have that hull); scale: single
    parameters multiplied by their factors (e.g. ``{'N_r': 1.45}``: one derivative only).
    Raises ConfigError naming the parameter when the family lacks it or a factor is not a
    finite number.
    """
    factors = dict.fromkeys(HULL_COEFFICIENTS, float(hull_scale)) if hull_scale != 1.0 else {}
    for k, f in (scale or {}).items():
        factors[k] = factors.get(k, 1.0) * float(f)
    own = set(ship.family.params)
    for k, f in factors.items():
        if not math.isfinite(f):
            raise ConfigError(f'{ship.name}: scale factor of {k} = {f!r}: must be finite')
        if k not in own:
            raise ConfigError(f'{ship.name}: the {ship.model} family has no parameter {k} to '
                              'scale' + (' (hull_scale needs the polynomial hull of the '
                                         'container or standard family)'
                                         if k in HULL_COEFFICIENTS else ''))
    return ship.with_params({k: ship[k] * f for k, f in factors.items()}) if factors else ship


def parse_maneuver(text: str) -> tuple[str, float, float | None]:
    """
    Parse a manoeuvre such as 'zigzag:20/10' into (manoeuvre, rudder_deg, check_deg).

    'turning:35', 'zigzag:20' or 'zigzag:20/10', 'pullout:20', 'random:30', and for a low-speed
    family 'berthing:20' (helm of the approach; its sign is the berth's side) and
    'random_astern:30' -> (manoeuvre, rudder_deg, check_deg).
    """
    kind, _, arg = text.partition(':')
    if kind not in mv.ALL_MANEUVERS:
        raise SimulationError(f'unknown manoeuvre {text!r}; use e.g. turning:35, zigzag:20/20, '
                              'pullout:20, random:30 or, for a low-speed family, berthing:20, '
                              'random_astern:30')
    rud, _, chk = (arg or '35').partition('/')
    try:
        rud_deg, chk_deg = float(rud), float(chk) if chk else None
    except ValueError:
        raise SimulationError(f'bad manoeuvre spec {text!r}; use e.g. turning:35, '
                              'zigzag:20/10') from None
    if not math.isfinite(rud_deg) or abs(rud_deg) > 90:
        raise SimulationError(f'manoeuvre {text!r}: rudder {rud} deg must be finite, |rudder| '
                              '<= 90')
    if chk_deg is not None and not (math.isfinite(chk_deg) and 0 < abs(chk_deg) <= 90):
        raise SimulationError(f'manoeuvre {text!r}: check angle {chk} deg must be finite, '
                              '0 < |angle| <= 90')
    if kind == 'zigzag' and rud_deg == 0:
        raise SimulationError(f'manoeuvre {text!r}: a zigzag needs a non-zero rudder angle')
    if chk_deg is not None and kind != 'zigzag':
        raise SimulationError(f'manoeuvre {text!r}: only a zigzag takes a check angle')
    return kind, rud_deg, chk_deg


def generate_trial(ship: ShipConfig, maneuver: str, rudder_deg: float, check_deg: float | None,
                   rpm: float, speed_ms: float, duration_s: float, rate_hz: float,
                   noise: SensorNoise, seed: int, name: str, approach_s: float = 10.0,
                   record_wind: bool = False, thruster_rps: float = 20.0,
                   hull_scale: float = 1.0, scale: Mapping[str, float] | None = None
                   ) -> tuple[Trial, Trial]:
    """
    (truth, measured) for one manoeuvre.

    Truth is integrated with RK4 at <= 0.1 s. record_wind: the trial carries the (steady) true wind
    as a measurement. thruster_rps: the thrusters' speed of the low-speed manoeuvres [rev/s]
    (mv.LOWSPEED_MANEUVERS). hull_scale, scale: a change outside the effects library, see
    :func:`out_of_library` (the truth sails with it; the notes say so).
    """
    changed = out_of_library(ship, hull_scale, scale)
    if changed is not ship:
        truth, measured = generate_trial(changed, maneuver, rudder_deg, check_deg, rpm,
                                         speed_ms, duration_s, rate_hz, noise, seed, name,
                                         approach_s, record_wind, thruster_rps)
        note = 'out of library: ' + ', '.join(
            ([f'hull forces x {hull_scale:g}'] if hull_scale != 1.0 else [])
            + [f'{k} x {f:g}' for k, f in (scale or {}).items()])
        truth.notes.append(note)
        measured.notes.append(note)
        return truth, measured
    for what, v in (('rate_hz', rate_hz), ('duration_s', duration_s), ('rpm', rpm),
                    ('speed_ms', speed_ms)):
        if not (math.isfinite(v) and v > 0):
            raise SimulationError(f'{name}: {what} = {v}: must be a finite number > 0')
    dt = 1.0 / rate_hz
    substeps = max(1, int(math.ceil(dt / 0.1)))
    spec = mv.ManeuverSpec(maneuver, rudder_deg=rudder_deg, check_deg=check_deg, rpm=rpm,
                           speed_ms=speed_ms, duration_s=duration_s, dt=dt,
                           approach_s=approach_s, integrator='rk4', substeps=substeps,
                           seed=seed, random_rpm_frac=0.1 if maneuver == 'random' else 0.0,
                           thruster_rps=thruster_rps)
    traj = mv.run(ship, spec)
    if not traj.ok:
        raise SimulationError(f'{name}: generation stopped at t = {traj.fail_time_s:.1f} s: '
                              f'{traj.status}')
    controls, thrusters = traj.controls, traj.thrusters
    toff = ship['time_offset']
    if toff != 0.0:  # commands stamped toff seconds early: recorded(t) = actual(t + toff)
        def shift(a: np.ndarray) -> np.ndarray:
            return np.column_stack([np.interp(traj.t + toff, traj.t, a[:, i])
                                    for i in range(a.shape[1])])
        controls = shift(controls)
        thrusters = None if thrusters is None else shift(thrusters)
    wind = None
    if record_wind:  # the air's velocity north/east: it blows toward wind_dir + pi
        to = ship['wind_dir'] + math.pi
        wind = np.tile([ship['wind_speed'] * math.cos(to), ship['wind_speed'] * math.sin(to)],
                       (traj.t.size, 1))
    truth = Trial(traj.t, traj.states, controls, name=name, wind=wind, thrusters=thrusters,
                  notes=[f'generated: {ship.name} {maneuver} {rudder_deg:+g} deg, {rpm:g} rpm, '
                         f'{speed_ms:.3f} m/s, seed {seed}'])
    return truth, noise.apply(truth, np.random.default_rng(seed + 1))


# ------------------------------------------------------------- twin thrusters (issue 24)
TWIN_ACTUATOR = 'twin_azimuth'


@dataclass(frozen=True)
class TwinNoise(_Sigmas):
    """
    1-sigma white noise of a small craft's sensors, RTK class (SI units, radians).

    ASSUMPTION (doc/reference/mbpe_logo_tug.md §4 A: "RTK noise of 1-2 cm with 0.3 deg on
    heading"): positions 1.5 cm, heading 0.3 deg; body velocities and yaw rate as a GNSS/INS
    filter gives them (1 cm/s, 0.2 deg/s); shaft tachometers 0.02 rev/s; azimuth feedback
    0.2 deg; bollard-pull load cell 0.3 N. Commands (azimuth_cmd_*) are exact.
    """

    position_m: float = 0.015
    heading_rad: float = math.radians(0.3)
    speed_ms: float = 0.01
    yaw_rate_rad_s: float = math.radians(0.2)
    shaft_rps: float = 0.02
    azimuth_rad: float = math.radians(0.2)
    bollard_n: float = 0.3

    def apply(self, trial: Trial, rng: np.random.Generator) -> Trial:
        """Return the trial as its sensors record it (commands untouched)."""
        n = len(trial)
        st = trial.states.copy()
        st[:, 0:2] += rng.normal(0, self.position_m, (n, 2))
        st[:, 2] += rng.normal(0, self.heading_rad, n)
        st[:, 3:5] += rng.normal(0, self.speed_ms, (n, 2))
        st[:, 5] += rng.normal(0, self.yaw_rate_rad_s, n)
        inputs = dict(trial.inputs)
        for c, sd in (('n_port', self.shaft_rps), ('n_stbd', self.shaft_rps),
                      ('azimuth_port', self.azimuth_rad), ('azimuth_stbd', self.azimuth_rad)):
            inputs[c] = trial.inputs[c] + rng.normal(0, sd, n)
        notes = trial.notes + ['sensor noise added: ' + ', '.join(
            f'{k}={v:.4g}' for k, v in self.__dict__.items())]
        return Trial(trial.t, st, name=trial.name, source=trial.source, notes=notes,
                     inputs=inputs)


@dataclass(frozen=True)
class TwinManeuver:
    """
    One manoeuvre of a twin-thruster craft, open loop or closed on heading (zigzag).

    kind: 'straight', 'zigzag', 'turning', 'random' or 'differential'; n_rps: shaft speed of
    both thrusters [rev/s]; steer: azimuth of both thrusters [deg] (+ = thrust toward starboard:
    the stern goes to starboard, the craft turns to port), or for a craft whose azimuths are
    fixed (``steering.max_azimuth_deg: 0``) the differential fraction s in n (1 +- s)
    (+ = port faster: a turn to starboard); check_deg: a zigzag's heading change that reverses
    the steer; approach_s: straight ahead before the steer starts; duration_s: the whole
    trial; seed: the random command sequence's; role: 'identification' (the paper's Table 2)
    or 'validation'.
    """

    name: str
    kind: str
    n_rps: float
    steer: float = 0.0
    check_deg: float = 20.0
    approach_s: float = 20.0
    duration_s: float = 100.0
    seed: int = 0
    role: str = 'validation'


def is_twin(ship: ShipConfig) -> bool:
    """Whether the ship is driven by the twin-thruster actuator (generated by this section)."""
    return TWIN_ACTUATOR in ship.family.actuators


def max_azimuth_rad(ship: ShipConfig) -> float:
    """Return the azimuth command limit of the YAML (``steering.max_azimuth_deg``; 0: fixed)."""
    return math.radians(float((ship.extra.get('steering') or {}).get('max_azimuth_deg', 45.0)))


def max_thruster_rps(ship: ShipConfig) -> float:
    """Return the shaft speed limit of the YAML (``steering.max_thruster_rps``) [rev/s]."""
    return float((ship.extra.get('steering') or {}).get('max_thruster_rps', 10.0))


def twin_catalogue(ship: ShipConfig) -> list[TwinManeuver]:
    """
    Return the manoeuvres ``generate`` sails for a twin-thruster craft (identification first).

    Azimuth craft: the paper's 12 identification manoeuvres (Table 2: straight lines from rest at
    3, 5, 7, 10 rev/s; +20/20 zigzags at those speeds; turning circles at 10, 15, 20, 30 deg of
    azimuth at 7 rev/s, the speed an ASSUMPTION: the paper gives only "10-30 deg"), then the
    validation set: the mirrored zigzags (-20/20), turns to the other side, four random command
    sequences and two differential-thrust runs. A craft with fixed thrusters sails the same
    with differential thrust (fractions 0.3, 0.2-0.5) in place of the azimuths.
    """
    fixed = max_azimuth_rad(ship) == 0.0
    top = max_thruster_rps(ship)
    speeds = [s for s in (3.0, 5.0, 7.0, 10.0) if s <= top] or [top]
    zz, turns = (0.3, (0.2, 0.3, 0.4, 0.5)) if fixed else (20.0, (10.0, 15.0, 20.0, 30.0))
    n_turn = 7.0 if 7.0 <= top else speeds[-1]
    unit = '' if fixed else 'deg'
    out = [TwinManeuver(f'straight_{n:g}rps', 'straight', n, approach_s=0.0, duration_s=60.0,
                        role='identification') for n in speeds]
    out += [TwinManeuver(f'zigzag_p{zz:g}{unit}_{n:g}rps'.replace('.', '_'), 'zigzag', n, zz,
                         role='identification') for n in speeds]
    out += [TwinManeuver(f'turning_p{a:g}{unit}_{n_turn:g}rps'.replace('.', '_'), 'turning',
                         n_turn, a, role='identification') for a in turns]
    out += [TwinManeuver(f'zigzag_m{zz:g}{unit}_{n:g}rps'.replace('.', '_'), 'zigzag', n, -zz)
            for n in speeds]
    out += [TwinManeuver(f'turning_m{a:g}{unit}_{n_turn:g}rps'.replace('.', '_'), 'turning',
                         n_turn, -a) for a in turns[::2]]
    out += [TwinManeuver(f'random_{k}', 'random', speeds[-1], zz, duration_s=180.0, seed=k)
            for k in range(1, 5)]
    out += [TwinManeuver(f'differential_{k}', 'differential', speeds[min(k, len(speeds) - 1)],
                         0.3 * (-1) ** k, seed=k) for k in range(1, 3)]
    return out


def _twin_commands(ship: ShipConfig, m: TwinManeuver, t: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n_port, n_stbd, azimuth order (T, 2) [rad]) of an open-loop manoeuvre (zigzag: +steer)."""
    T = t.size
    fixed = max_azimuth_rad(ship) == 0.0
    steer = np.where(t >= m.approach_s, 1.0, 0.0)
    n = np.full(T, m.n_rps)
    diff = np.zeros(T)
    az = np.zeros(T)
    if m.kind in ('zigzag', 'turning'):
        if fixed:
            diff = steer * m.steer
        else:
            az = steer * math.radians(m.steer)
    elif m.kind == 'differential':
        # thrust steps on one side: 4 holds of 15-25 s
        rng = np.random.default_rng(m.seed)
        edges = np.cumsum(rng.uniform(15.0, 25.0, 8))
        level = rng.uniform(0.1, 1.0, 9) * m.steer * np.sign(rng.uniform(-1, 1, 9))
        diff = steer * level[np.searchsorted(edges, t - m.approach_s)]
    elif m.kind == 'random':
        # piecewise-constant shaft speeds and azimuths held 3-10 s (PRBS-like), both thrusters
        # on their own: it excites sway and yaw the Table 2 set leaves out
        rng = np.random.default_rng(1000 + m.seed)
        edges = np.cumsum(rng.uniform(3.0, 10.0, int(m.duration_s // 3) + 2))
        k = np.searchsorted(edges, t)
        lo = min(3.0, m.n_rps)
        n_p = rng.uniform(lo, m.n_rps, k.max() + 1)[k]
        n_s = rng.uniform(lo, m.n_rps, k.max() + 1)[k]
        if fixed:
            return n_p, n_s, np.zeros((T, 2))
        lim = math.radians(abs(m.steer) * 1.5)
        a_p = rng.uniform(-lim, lim, k.max() + 1)[k]
        a_s = np.clip(a_p + rng.normal(0, 0.3 * lim, k.max() + 1)[k], -lim, lim)
        return n_p, n_s, np.column_stack([a_p, a_s])
    return n * (1.0 + diff), n * (1.0 - diff), np.column_stack([az, az])


def _twin_inputs(ship: ShipConfig, n_p: np.ndarray, n_s: np.ndarray, order: np.ndarray
                 ) -> dict[str, np.ndarray]:
    """Channel arrays for the truth run: orders as commands, the first angle as measured."""
    return {'n_port': n_p, 'n_stbd': n_s,
            'azimuth_port': np.full(n_p.size, order[0, 0]),
            'azimuth_stbd': np.full(n_p.size, order[0, 1]),
            'azimuth_cmd_port': order[:, 0], 'azimuth_cmd_stbd': order[:, 1]}


def generate_twin_trial(ship: ShipConfig, m: TwinManeuver, rate_hz: float, noise: TwinNoise,
                        seed: int) -> tuple[Trial, Trial]:
    """
    (truth, measured) of one twin-thruster manoeuvre, sampled at rate_hz (the paper's 5 Hz).

    The truth is integrated with RK4, one step per sample; a zigzag reverses its steer at the
    first sample whose heading change from the start of the steer passes +-check_deg (found by
    re-simulating after each reversal). Recorded: the commands (shaft speeds, azimuth orders as
    azimuth_cmd_*) and, as azimuth_port/_stbd, the actual angle acting over each sample
    interval (what the actuator hands the hull), so that a simulation driven by the recorded
    angles without the commands reproduces the truth.
    """
    from mmg_tuner.core.integrate import actuator_outputs
    from mmg_tuner.core.simulate import kernel_inputs, simulate

    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise SimulationError(f'{m.name}: rate_hz = {rate_hz}: must be a finite number > 0')
    dt = 1.0 / rate_hz
    t = dt * np.arange(int(round(m.duration_s * rate_hz)) + 1)
    n_p, n_s, order = _twin_commands(ship, m, t)
    top, az_max = max_thruster_rps(ship), max_azimuth_rad(ship)
    n_p, n_s = np.clip(n_p, -top, top), np.clip(n_s, -top, top)
    order = np.clip(order, -az_max, az_max)
    x0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def run() -> tuple[Trial, Family]:
        fam = ship.family
        trial = simulate(ship, x0, _twin_inputs(ship, n_p, n_s, order), dt, 'rk4')
        if not trial.ok:
            raise SimulationError(f'{m.name}: generation stopped at t = '
                                  f'{trial.fail_time_s:.1f} s: {trial.status}')
        return trial, fam

    truth, fam = run()
    if m.kind == 'zigzag':
        k0 = int(np.searchsorted(t, m.approach_s))
        chk = math.radians(m.check_deg)
        start, sign = k0, 0.0
        for _ in range(200):   # one re-simulation per reversal
            dpsi = truth.states[start:, 2] - truth.states[k0, 2]
            hit = (np.abs(dpsi) >= chk) if sign == 0.0 else (dpsi * sign >= chk)
            if not hit.any():
                break
            k = start + int(np.argmax(hit))
            sign = -np.sign(dpsi[k - start])   # the next reversal: the other side
            fixed = az_max == 0.0
            if fixed:
                cur = n_p[k] / m.n_rps - 1.0
                n_p[k + 1:] = m.n_rps * (1.0 - cur)
                n_s[k + 1:] = m.n_rps * (1.0 + cur)
            else:
                order[k + 1:] = -order[k]
            truth, fam = run()
            start = k + 1
    ctrl = kernel_inputs(fam, truth)
    act = np.empty((len(t), len(fam.outputs)))
    actuator_outputs(ship.kind, ship.params, ctrl, len(t), dt, act)
    j = fam.outputs.index('alpha_port')
    inputs = dict(truth.inputs)
    inputs['azimuth_port'] = act[:, j] - ship['azimuth_offset_port']   # what a sensor reads
    inputs['azimuth_stbd'] = act[:, j + 1] - ship['azimuth_offset_stbd']
    steer_unit = '' if az_max == 0.0 else ' deg'
    truth = Trial(truth.t, truth.states, name=m.name, inputs=inputs, notes=[
        f'generated: {ship.name} {m.kind} {m.steer:+g}{steer_unit} at {m.n_rps:g} rev/s '
        f'({m.role}), {rate_hz:g} Hz, seed {seed}'])
    return truth, noise.apply(truth, np.random.default_rng(seed + 1))


def bollard_pull_table(ship: ShipConfig, noise: TwinNoise, seed: int,
                       step_rps: float = 0.5) -> np.ndarray:
    """
    (n [rev/s], thrust [N per thruster]) of a bollard-pull test, 0 to the shaft speed limit.

    The thrust is the ship's curve (``thrust_p0..p5``: for qiuxin_tug the ASSUMPTION stand-in
    F = 0.4 n|n|) plus the load cell's noise; ahead only, as the paper's test.
    """
    from mmg_tuner.core.actuators.twin_azimuth import thrust

    n = np.arange(0.0, max_thruster_rps(ship) + 1e-9, step_rps)
    f = np.array([thrust(ship.params, float(x)) for x in n])
    rng = np.random.default_rng(seed + 7)
    return np.column_stack([n, f + rng.normal(0, noise.bollard_n, n.size)])


PAPER_TUNE_DEG = (10, -20, 35, -40)
"""Rudder angles of the tuning turns of Suyama et al. 2023 (section 4) [deg]."""
PAPER_TEST_DEG = (-10, 20, -35, 40)
"""Rudder angles of its test turns [deg]."""


def paper_turning_trials(truth: ShipConfig, angles_deg: Iterable[int], duration_s: float = 800.0,
                         seed: int = 0, noise: SensorNoise | None = None) -> list[Trial]:
    """
    Return turning tests at 6 kn and 106 rpm sampled at 1 s, as the paper's data.

    One trial per rudder angle (``PAPER_TUNE_DEG``, ``PAPER_TEST_DEG``), named ``turn+10`` etc.,
    sailed by ``truth`` with RK4 (10 substeps) and the steering gear's rate limit after a 10 s
    approach, with sensor noise (default :class:`SensorNoise`; seeded ``seed + i`` per trial).
    """
    noise = SensorNoise() if noise is None else noise
    out = []
    for i, a in enumerate(angles_deg):
        tr = mv.run(truth, mv.ManeuverSpec('turning', rudder_deg=a, rpm=106.0,
                                           speed_ms=6 * mv.KNOT, duration_s=duration_s, dt=1.0,
                                           approach_s=10.0, integrator='rk4', substeps=10))
        out.append(noise.apply(Trial(tr.t, tr.states, tr.controls, name=f'turn{a:+d}'),
                               np.random.default_rng(seed + i)))
    return out
