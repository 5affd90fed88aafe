"""
What ``generate`` sails for a craft driven by ``twin_azimuth``: its catalogue, sensors, tables.

The actuator declares this module (``TRIALS`` in ``twin_azimuth.py``); ``data/generate.py`` and
the ``generate`` command use it through that declaration (the protocol is in
``core/actuators/__init__.py``), so nothing above the core names the craft.

- :func:`catalogue`: the MBPE-LOGO paper's 12 identification manoeuvres and a validation set.
- :class:`Noise`: RTK-class sensors (ASSUMPTION, doc/reference/mbpe_logo_tug.md).
- :func:`generate`: (truth, measured) of one manoeuvre.
- :func:`tables`: the bollard-pull table written beside the trials.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import TYPE_CHECKING

from mmg_tuner.core.actuators.twin_azimuth import thrust
from mmg_tuner.core.noise import Sigmas
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import SimulationError
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.core.models import Family

RATE_HZ = 5.0
"""Default recording rate [Hz] (the paper's)."""
ASSUMPTIONS = ('thrust curve, azimuth constants and sensor noise are stand-ins (see {source} and '
               'core/actuators/twin_azimuth_trials.py Noise)')
"""What trials.yaml says of the generated data ({source}: the ship file)."""


@dataclass(frozen=True)
class Noise(Sigmas):
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
        notes = trial.notes + ['sensor noise added: ' + self.describe()]
        return Trial(trial.t, st, name=trial.name, source=trial.source, notes=notes,
                     inputs=inputs)


@dataclass(frozen=True)
class Maneuver:
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


def max_azimuth_rad(ship: ShipConfig) -> float:
    """Return the azimuth command limit of the YAML (``steering.max_azimuth_deg``; 0: fixed)."""
    return math.radians(float((ship.extra.get('steering') or {}).get('max_azimuth_deg', 45.0)))


def max_thruster_rps(ship: ShipConfig) -> float:
    """Return the shaft speed limit of the YAML (``steering.max_thruster_rps``) [rev/s]."""
    return float((ship.extra.get('steering') or {}).get('max_thruster_rps', 10.0))


def catalogue(ship: ShipConfig) -> list[Maneuver]:
    """
    Return the manoeuvres ``generate`` sails (identification first).

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
    out = [Maneuver(f'straight_{n:g}rps', 'straight', n, approach_s=0.0, duration_s=60.0,
                    role='identification') for n in speeds]
    out += [Maneuver(f'zigzag_p{zz:g}{unit}_{n:g}rps'.replace('.', '_'), 'zigzag', n, zz,
                     role='identification') for n in speeds]
    out += [Maneuver(f'turning_p{a:g}{unit}_{n_turn:g}rps'.replace('.', '_'), 'turning',
                     n_turn, a, role='identification') for a in turns]
    out += [Maneuver(f'zigzag_m{zz:g}{unit}_{n:g}rps'.replace('.', '_'), 'zigzag', n, -zz)
            for n in speeds]
    out += [Maneuver(f'turning_m{a:g}{unit}_{n_turn:g}rps'.replace('.', '_'), 'turning',
                     n_turn, -a) for a in turns[::2]]
    out += [Maneuver(f'random_{k}', 'random', speeds[-1], zz, duration_s=180.0, seed=k)
            for k in range(1, 5)]
    out += [Maneuver(f'differential_{k}', 'differential', speeds[min(k, len(speeds) - 1)],
                     0.3 * (-1) ** k, seed=k) for k in range(1, 3)]
    return out


def _commands(ship: ShipConfig, m: Maneuver, t: np.ndarray
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


def _inputs(ship: ShipConfig, n_p: np.ndarray, n_s: np.ndarray, order: np.ndarray
            ) -> dict[str, np.ndarray]:
    """Channel arrays for the truth run: orders as commands, the first angle as measured."""
    return {'n_port': n_p, 'n_stbd': n_s,
            'azimuth_port': np.full(n_p.size, order[0, 0]),
            'azimuth_stbd': np.full(n_p.size, order[0, 1]),
            'azimuth_cmd_port': order[:, 0], 'azimuth_cmd_stbd': order[:, 1]}


def mirror(ship: ShipConfig, m: Maneuver) -> Maneuver | None:
    """
    Return ``m`` sailed to the other side: its steer negated (None: it has no other side).

    The diagnosis's advice sails an advised manoeuvre twice, once to each side. A straight
    run has no side, and a random sequence's sign is drawn (its steer is an amplitude).
    """
    if m.kind in ('straight', 'random') or m.steer == 0.0:
        return None
    return replace(m, name=f'{m.name}_mirrored', steer=-m.steer)


def generate(ship: ShipConfig, m: Maneuver, rate_hz: float, noise: Noise,
             seed: int) -> tuple[Trial, Trial]:
    """
    Return (truth, measured) of one manoeuvre, sampled at rate_hz (the paper's 5 Hz).

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
    n_p, n_s, order = _commands(ship, m, t)
    top, az_max = max_thruster_rps(ship), max_azimuth_rad(ship)
    n_p, n_s = np.clip(n_p, -top, top), np.clip(n_s, -top, top)
    order = np.clip(order, -az_max, az_max)
    x0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def run() -> tuple[Trial, Family]:
        fam = ship.family
        trial = simulate(ship, x0, _inputs(ship, n_p, n_s, order), dt, 'rk4')
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


def bollard_pull_table(ship: ShipConfig, noise: Noise, seed: int,
                       step_rps: float = 0.5) -> np.ndarray:
    """
    (n [rev/s], thrust [N per thruster]) of a bollard-pull test, 0 to the shaft speed limit.

    The thrust is the ship's curve (``thrust_p0..p5``: for qiuxin_tug the ASSUMPTION stand-in
    F = 0.4 n|n|) plus the load cell's noise; ahead only, as the paper's test.
    """
    n = np.arange(0.0, max_thruster_rps(ship) + 1e-9, step_rps)
    f = np.array([thrust(ship.params, float(x)) for x in n])
    rng = np.random.default_rng(seed + 7)
    return np.column_stack([n, f + rng.normal(0, noise.bollard_n, n.size)])


def tables(ship: ShipConfig, noise: Noise, seed: int) -> dict[str, tuple[str, np.ndarray, str]]:
    """Return the tables written beside the trials: name -> (CSV header, rows, description)."""
    return {'bollard_pull': ('n,thrust', bollard_pull_table(ship, noise, seed),
                             'n [rev/s], thrust [N per thruster]')}
