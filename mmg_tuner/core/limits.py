"""
Physical plausibility ranges of a ship's inputs and states.

One place says what a command, a recorded sample or a simulated state of *this* ship can
physically be, so that the node, the CLIs and the trial readers refuse the same nonsense (a
rudder of 1e308 rad, 1e6 rpm, a state moving at Mach 3) with the same numbers. The ranges are
deliberately generous: they catch unit errors, corrupt data and divergence, not unusual trials.

Scale: a displacement hull cannot be driven much beyond its "hull speed" (Froude number
Fn = U / sqrt(g L_pp) about 0.4, where wave resistance walls it off); merchant ships serve at
Fn 0.15-0.25. So

- ``top_speed_ms`` (Fn 0.5) is a generous top speed,
- ``speed_max_ms`` (Fn 1.5) is a speed no simulated or recorded state of the ship can reach:
  beyond it the state has diverged. The MMG model has no wave wall, so ``rpm_max`` held in a
  straight run drives it to about Fn 1.0; Fn 1.5 leaves a margin above that,
- ``rpm_max`` is ``RPM_FACTOR`` x the rpm that holds ``top_speed_ms`` in a straight run
  (:func:`~mmg_tuner.core.simulate.self_propulsion_rpm`): the factor covers transient overload
  (a propeller accelerating the ship from rest turns faster than its self-propulsion rpm at
  the same power only by some 10-20 %), rpm_scale effects and a resistance the config
  underestimates, and still excludes unit errors (rad/s or rev/s read as rpm differ by 6.28
  and 60). For SUZAKU (service 106 rpm at 6 kn) this gives about 840 rpm; for the 7 m KVLCC2
  model (about 710 rpm at 1.18 m/s) about 5000 rpm.

Every input channel has one :class:`CommandLimit` (``InputLimits.channels``), by its name or
unit: a command beyond ``limit`` is clamped to it, beyond ``plausible`` refused; a recorded sample
beyond ``recorded`` is dropped by the readers. The rpm is refused beyond ``rpm_max`` and, unless
the family covers astern revolutions (``astern_rpm``), at or below 0; the rudder is clamped to
the steering gear's ``max_rudder_deg`` and refused beyond twice it (90 deg at most); a shaft
speed [rev/s] (a tunnel thruster, an azimuth drive) is clamped to the YAML's
``steering.max_thruster_rps`` and refused beyond twice it; another angle [rad] (an azimuth) is
clamped to ``steering.max_azimuth_deg`` (0: a fixed thruster) and refused beyond one turn. The
simulator, the node, the readers and the units checks all read this one table.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Iterable, Mapping

from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import self_propulsion_rpm
from mmg_tuner.errors import ConfigError, SimulationError

G = 9.80665  # m/s^2, standard gravity
FN_TOP = 0.5  # Froude number of a generous top speed for a displacement hull
FN_MAX = 1.5  # Froude number beyond which a state is taken as diverged
RPM_FACTOR = 2.0  # rpm_max / rpm that holds the top speed (see the module docstring)
RUDDER_HARD_CAP_RAD = math.pi / 2  # beyond 90 deg a rudder angle has no physical meaning
DT_MIN_S = 1e-3  # finer than any manoeuvring dynamics; real time then costs 1000 steps/s
POSITION_MAX_M = 2.0e7  # half the Earth's circumference: no local frame reaches farther
THRUSTER_PLAUSIBLE_FACTOR = 2.0  # beyond 2 x the thruster limit: a unit error, not a command
THRUSTER_CHANNELS = ('bow_thruster', 'stern_thruster')
ANGLE_PLAUSIBLE_RAD = 2 * math.pi  # beyond one turn: degrees read as radians, not a command
# no recorded shaft turns faster: a model's thruster reaches ~30 rev/s, a ship's a few; beyond it
# a sample is corrupt (within it a wrong unit is named by data/channel_units.py, data kept)
RECORDED_RPS_MAX = 200.0


@dataclass(frozen=True)
class CommandLimit:
    """
    The range of one input channel: what a command may be and what a recording may show.

    channel: its name (``core/channels.py``); unit: its unit; limit: |value| beyond it is
    clamped to it (a steering gear's or a thruster's limit); plausible: |value| beyond it is
    refused as a command (a unit error, not a command); recorded: |value| beyond it is no
    sample of a recording (the readers drop it; looser than ``plausible`` where the readers
    keep the data and the units checks name a wrong unit instead); basis: where the limit
    comes from (for messages); forward_only: values <= 0 are outside the model (the rpm of a
    family without astern revolutions).
    """

    channel: str
    unit: str
    limit: float
    plausible: float
    basis: str
    recorded: float = math.inf
    forward_only: bool = False

    def show(self, value: float) -> str:
        """Return ``value unit``, with degrees beside radians."""
        deg = f' ({math.degrees(value):.1f} deg)' if self.unit == 'rad' else ''
        return f'{value:.6g} {self.unit}{deg}'

    def problem(self, value: float) -> str:
        """Say why ``value`` is no plausible command of the channel ('' if it is)."""
        name = f'{self.channel} command'
        if not math.isfinite(value):
            return f'{name} {value} is not finite'
        if value <= 0 and self.forward_only:
            return (f'{name} {value:g} {self.unit} <= 0 is outside the model (forward '
                    'revolutions only)')
        if abs(value) > self.plausible:
            span = f'(0, {self.show(self.plausible)}]' if self.forward_only else \
                f'+-{self.show(self.plausible)}'
            return (f'{name} {self.show(value)} is beyond the plausible {span}'
                    + (f' ({self.basis})' if self.plausible == self.limit else ''))
        return ''

    def check(self, value: Any) -> tuple[float | None, str]:
        """Return (the value to apply or None: refused, the problem or '')."""
        try:
            value = float(value)
        except (TypeError, ValueError):
            return None, f'{self.channel} command {value!r} is not a number: ignored'
        if problem := self.problem(value):
            return None, f'{problem}: ignored'
        if abs(value) > self.limit:
            clamped = math.copysign(self.limit, value)
            return clamped, (f'{self.channel} command {self.show(value)} beyond the '
                             f'+-{self.show(self.limit)} limit ({self.basis}): clamped to '
                             f'{clamped:.6g}')
        return value, ''


@dataclass(frozen=True)
class InputLimits:
    """
    Plausibility ranges for one ship's inputs and simulated states (SI units, rpm).

    Attributes
    ----------
    channels: each input channel's clamp and caps (:class:`CommandLimit`), by name: the rpm,
        rudder and thrusters of a screw-and-rudder ship, an azimuth tug's shaft speeds and
        angles (:func:`command_limits`); the one table the simulator, the node and the
        readers judge commands and recorded samples by.
    top_speed_ms: generous top speed (Fn 0.5) [m/s]; e.g. the largest initial speed.
    speed_max_ms: no state of the ship moves faster (Fn 1.5) [m/s]; beyond it the
        simulation has diverged or a recording is corrupt.
    yaw_rate_max_rad_s: |r| beyond speed_max_ms / (L_pp / 2) (turning on a circle of one
        ship length at speed_max_ms) is a diverged state [rad/s].
    dt_min_s, dt_max_s: the integration step range [s]; dt_max_s is the time to sail one
        ship length at the top speed: a coarser step cannot resolve a turn. (Within the
        range an explicit integrator may still diverge at high speed; the simulation
        detects that at run time.)
    position_max_m: |x|, |y| beyond it [m] is no position in a local frame.
    model: the ship's model family (for messages).
    length_m: the ship's length between perpendiculars [m] (0: not known, generic limits);
        it scales the readers' consistency checks (data/consistency.py).

    """

    channels: Mapping[str, CommandLimit]
    top_speed_ms: float
    speed_max_ms: float
    yaw_rate_max_rad_s: float
    dt_min_s: float
    dt_max_s: float
    position_max_m: float = POSITION_MAX_M
    model: str = ''
    length_m: float = 0.0

    @property
    def thrusters(self) -> bool:
        """Whether the ship's model family has tunnel-thruster inputs."""
        return all(c in self.channels for c in THRUSTER_CHANNELS)

    def channel(self, name: str) -> CommandLimit:
        """
        Return the limit of channel ``name``: the ship's own, else the generic one by unit.

        A channel the ship lacks still has a recording cap (a bag may carry a thruster topic
        the model ignores): :func:`generic_limit`.
        """
        return self.channels.get(name) or generic_limit(name)

    def check_speed(self, speed_ms: float) -> str:
        """'' if speed_ms is a plausible (initial or recorded) forward speed, else why not."""
        return _finite_within('speed', speed_ms, self.speed_max_ms, lambda: (
            f'm/s exceeds the plausible {self.speed_max_ms:.1f} m/s (Froude number {FN_MAX:g})'))

    def check_dt(self, dt: float) -> str:
        """'' if dt [s] is a usable integration step, else why not."""
        if not (math.isfinite(dt) and self.dt_min_s <= dt <= self.dt_max_s):
            return (f'dt {dt} s is outside [{self.dt_min_s:g}, {self.dt_max_s:.3g}] s '
                    f'(1 ms to one ship length at the top speed)')
        return ''

    def state_problem(self, u: float, v: float, r: float) -> str:
        """'' if velocities (u, v [m/s], r [rad/s]) are finite and plausible, else why not."""
        if not (math.isfinite(u) and math.isfinite(v) and math.isfinite(r)):
            return f'non-finite velocity (u {u}, v {v}, r {r})'
        speed = math.hypot(u, v)
        if speed > self.speed_max_ms:
            return (f'speed {speed:.3g} m/s beyond the plausible {self.speed_max_ms:.1f} m/s '
                    f'(Froude number {FN_MAX:g})')
        if abs(r) > self.yaw_rate_max_rad_s:
            return (f'yaw rate {math.degrees(r):.3g} deg/s beyond the plausible '
                    f'{math.degrees(self.yaw_rate_max_rad_s):.1f} deg/s')
        return ''


def _finite_within(name: str, value: float, cap: float, beyond: Callable[[], str]) -> str:
    """
    Return '' if value is finite and within +-cap, else why not.

    The reason starts with ``name value``; past the cap, beyond() says the rest (built only
    then: every command the node receives is checked).
    """
    if not math.isfinite(value):
        return f'{name} {value} is not finite'
    if abs(value) > cap:
        return f'{name} {value:g} {beyond()}'
    return ''


def input_limits(ship: ShipConfig) -> InputLimits:
    """
    Return the plausibility ranges of ``ship`` (cached per model, parameters, rudder limit).

    Examples
    --------
    >>> lim = input_limits(load_ship('suzaku'))
    >>> round(lim.channels['rpm'].limit)   # about 840

    """
    steering = ship.extra.get('steering')
    key = (ship.kind, ship.params.tobytes(), ship.max_rudder_rad, ship.name, ship.source,
           repr(sorted(steering.items())) if isinstance(steering, dict) else repr(steering))
    lim = _CACHE.get(key)
    if lim is None:
        if len(_CACHE) >= 64:
            _CACHE.clear()
        lim = _CACHE[key] = _compute(ship)
    return lim


_CACHE: dict[tuple[object, ...], InputLimits] = {}


def _compute(ship: ShipConfig) -> InputLimits:
    L = ship.L_pp
    top = FN_TOP * math.sqrt(G * L)
    vmax = FN_MAX * math.sqrt(G * L)
    try:
        rpm_top = self_propulsion_rpm(ship, top)
        basis = (f'{RPM_FACTOR:g} x the {rpm_top:.0f} rpm that holds a top speed of '
                 f'{top:.1f} m/s, Froude number {FN_TOP:g}')
    except SimulationError:  # no rpm holds it (an odd tuned resistance): the search bracket
        rpm_top = 1e5 / RPM_FACTOR
        basis = f'no rpm holds {top:.1f} m/s; the search bracket'
    rpm_max = RPM_FACTOR * rpm_top
    return InputLimits(
        channels=_channel_limits(ship, ship.family.inputs, rpm_max, basis),
        top_speed_ms=top,
        speed_max_ms=vmax,
        yaw_rate_max_rad_s=vmax / (0.5 * L),
        dt_min_s=DT_MIN_S,
        dt_max_s=L / top,
        model=ship.model,
        length_m=float(L))


def _channel_limits(ship: ShipConfig, channels: Iterable[str], rpm_max: float,
                    rpm_basis: str) -> dict[str, CommandLimit]:
    """
    Return each channel's limits, by its name or unit (the module docstring).

    rpm: refused beyond ``rpm_max`` (and at or below 0 without astern revolutions); rudder:
    clamped to the steering gear's ``max_rudder_rad``, refused beyond min(2 x it, 90 deg); a
    shaft speed [rev/s]: clamped to ``steering.max_thruster_rps`` (the propeller's plausible
    maximum without one), refused beyond twice it; another angle [rad]: clamped to
    ``steering.max_azimuth_deg`` (a half turn without one), refused beyond one turn; another
    unit: finiteness only. A bad YAML value is a ConfigError naming the file and field.
    """
    out = {}
    for ch in channels:
        unit = TABLE[ch].unit
        if ch == 'rpm':
            out[ch] = CommandLimit(ch, unit, rpm_max, rpm_max, rpm_basis, recorded=rpm_max,
                                   forward_only=not ship.family.astern_rpm)
        elif ch == 'rudder':
            rudder = float(ship.max_rudder_rad)
            cap = min(2.0 * rudder, RUDDER_HARD_CAP_RAD)
            out[ch] = CommandLimit(ch, unit, rudder, cap, f'the steering gear of {ship.name}',
                                   recorded=cap)
        elif unit == 'rev/s':   # a tunnel thruster may go without a YAML limit, a drive not
            rps, basis = _thruster_limit(ship, rpm_max / 60.0 if ch in THRUSTER_CHANNELS
                                         else math.inf)
            # (a drive without one: no limit to clamp to; the simulator refuses to command it)
            out[ch] = CommandLimit(ch, unit, rps, THRUSTER_PLAUSIBLE_FACTOR * rps, basis,
                                   recorded=RECORDED_RPS_MAX)
        elif unit == 'rad':
            out[ch] = _angle_limit(ship, ch)
        else:
            out[ch] = CommandLimit(ch, unit, math.inf, math.inf, 'no limit for this unit')
    return out


def _angle_limit(ship: ShipConfig, channel: str) -> CommandLimit:
    """Return an azimuth angle's limit: ``steering.max_azimuth_deg`` (0: a fixed thruster)."""
    steering = ship.extra.get('steering') or {}
    if not isinstance(steering, dict):
        steering = {}
    value = steering.get('max_azimuth_deg', 180.0)
    deg = float(value) if isinstance(value, (int, float)) and \
        not isinstance(value, bool) else math.nan
    if not (math.isfinite(deg) and 0.0 <= deg <= 180.0):
        raise ConfigError(f'{ship.source or ship.name}: steering.max_azimuth_deg = '
                          f'{value!r} must be a number of degrees in [0, 180]')
    basis = (f'steering.max_azimuth_deg of {ship.name}' if 'max_azimuth_deg' in steering
             else 'no steering.max_azimuth_deg: a half turn')
    return CommandLimit(channel, 'rad', math.radians(deg), ANGLE_PLAUSIBLE_RAD, basis,
                        recorded=ANGLE_PLAUSIBLE_RAD)


def _thruster_limit(ship: ShipConfig, fallback_rps: float) -> tuple[float, str]:
    """
    Find the thrusters' limit [rev/s] and where it comes from.

    The YAML's ``steering.max_thruster_rps``, else ``fallback_rps`` (for a tunnel thruster the
    propeller's plausible maximum, a generous cap that still catches unit errors; for a drive
    none: inf).
    """
    steering = ship.extra.get('steering') or {}
    value = steering.get('max_thruster_rps') if isinstance(steering, dict) else None
    if value is None:
        return fallback_rps, ('no steering.max_thruster_rps' if fallback_rps == math.inf else
                              "no steering.max_thruster_rps: the propeller's plausible maximum")
    try:
        rps = float(value)
    except (TypeError, ValueError):
        rps = math.nan
    if isinstance(value, bool) or not (math.isfinite(rps) and rps > 0):
        raise ConfigError(f'{ship.source or ship.name}: steering.max_thruster_rps = {value!r} '
                          'must be a positive number of rev/s')
    return rps, f'steering.max_thruster_rps of {ship.name}'


def command_limits(ship: ShipConfig, channels: Iterable[str]) -> dict[str, CommandLimit]:
    """Return the limits of the ship's input channels ``channels`` (``input_limits``'s)."""
    table = input_limits(ship).channels
    return {ch: table[ch] for ch in channels}


# Without a ship the readers still refuse what no ship can do (a unit error, corrupt data).
GENERIC_BASIS = 'no ship given: the generic cap'
_GENERIC = {'rpm': 1e5, 'rudder': RUDDER_HARD_CAP_RAD}
_GENERIC_BY_UNIT = {'rev/s': RECORDED_RPS_MAX, 'rad': ANGLE_PLAUSIBLE_RAD}


def generic_limit(channel: str) -> CommandLimit:
    """
    Return the generic limit of ``channel``: what no ship's recording of it can show.

    1e5 rpm, a 90-deg rudder, a shaft speed of RECORDED_RPS_MAX, an angle of one turn; no
    limit for another unit or a name outside the channel table.
    """
    ch = TABLE.get(channel)
    unit = ch.unit if ch is not None else ''
    cap = _GENERIC.get(channel, _GENERIC_BY_UNIT.get(unit, math.inf))
    return CommandLimit(channel, unit, cap, cap, GENERIC_BASIS, recorded=cap)


GENERIC_LIMITS = InputLimits(
    channels={c: generic_limit(c) for c in ('rpm', 'rudder') + THRUSTER_CHANNELS},
    top_speed_ms=50.0, speed_max_ms=100.0, yaw_rate_max_rad_s=2 * math.pi, dt_min_s=DT_MIN_S,
    dt_max_s=60.0)
