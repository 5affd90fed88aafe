"""Synthetic trials: the core's manoeuvres with realistic sensor noise, as rosbag2 + CSV."""
from __future__ import annotations

from dataclasses import dataclass
import math
from types import ModuleType
from typing import Iterable, Mapping

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.noise import Sigmas
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, SimulationError
import numpy as np


@dataclass(frozen=True)
class SensorNoise(Sigmas):
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
                     trial.notes + ['sensor noise added: ' + self.describe()], wind=wind,
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


# ------------------------------------------------- a craft with its own catalogue
def trial_kit(ship: ShipConfig) -> ModuleType | None:
    """
    Return the catalogue module of the ship's actuators, or None (the manoeuvres above).

    An actuator may declare what ``generate`` sails for a craft it drives (``TRIALS``: its
    catalogue, sensor noise, tables; ``core/actuators/__init__.py``); the first of the family's
    actuators that does wins.
    """
    from mmg_tuner.core.actuators import load_companion

    for name in ship.family.actuators:
        module = load_companion(name, 'TRIALS')
        if module is not None:
            return module
    return None


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
