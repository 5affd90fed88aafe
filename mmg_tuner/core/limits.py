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

Astern and thrusters follow the ship's model family (``core/models``): a family that covers
astern revolutions (``astern_rpm``) accepts rpm in [-rpm_max, rpm_max]; one with thruster
inputs accepts thruster revolutions up to the ship's ``steering.max_thruster_rps`` (clamped
beyond it, refused beyond twice it, like the rudder). Other families refuse both.

A family without a screw and rudder (the twin-azimuth tug) is commanded channel by channel:
:func:`command_limits` gives each command channel its clamp and plausibility cap by the
channel's unit -- a shaft speed [rev/s] the YAML's ``steering.max_thruster_rps``, an azimuth
angle [rad] its ``steering.max_azimuth_deg`` (0: a fixed thruster).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Callable, Iterable

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


@dataclass(frozen=True)
class InputLimits:
    """
    Plausibility ranges for one ship's inputs and simulated states (SI units, rpm).

    Attributes
    ----------
    rpm_max: largest plausible propeller speed [rev/min]; the model covers rpm > 0 only.
    rudder_max_rad: the steering gear's limit (``ShipConfig.max_rudder_rad``): commands
        beyond it are clamped to it.
    rudder_plausible_rad: hard cap for recorded rudder angles, min(2 x rudder_max_rad,
        90 deg): beyond it a sample is a unit error or corrupt, not a steering action.
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
    rpm_basis: how rpm_max was found (for messages).
    astern_rpm: the model family covers rpm <= 0 (then |rpm| <= rpm_max is plausible).
    thruster_max_rps: the thrusters' limit [rev/s]: commands beyond it are clamped to it;
        0 when the family has no thruster inputs (every thruster command is refused).
    thruster_basis: where thruster_max_rps comes from (for messages).
    model: the ship's model family (for messages).
    length_m: the ship's length between perpendiculars [m] (0: not known, generic limits);
        it scales the readers' consistency checks (data/consistency.py).

    """

    rpm_max: float
    rudder_max_rad: float
    rudder_plausible_rad: float
    top_speed_ms: float
    speed_max_ms: float
    yaw_rate_max_rad_s: float
    dt_min_s: float
    dt_max_s: float
    position_max_m: float = POSITION_MAX_M
    rpm_basis: str = ''
    astern_rpm: bool = False
    thruster_max_rps: float = 0.0
    thruster_basis: str = ''
    model: str = ''
    length_m: float = 0.0

    @property
    def thrusters(self) -> bool:
        """Whether the ship's model family has thruster inputs."""
        return self.thruster_max_rps > 0

    def check_rpm(self, rpm: float) -> str:
        """Say why rpm is not a plausible propeller speed for the family ('' if it is)."""
        if not math.isfinite(rpm):
            return f'rpm {rpm} is not finite'
        if rpm <= 0 and not self.astern_rpm:
            return f'rpm {rpm:g} <= 0 is outside the MMG model (forward revolutions only)'
        if abs(rpm) > self.rpm_max:
            return (f'rpm {rpm:g} exceeds the plausible {"+-" if self.astern_rpm else ""}'
                    f'{self.rpm_max:.0f} rpm ({self.rpm_basis})')
        return ''

    def check_thruster(self, rps: float, which: str = 'thruster') -> str:
        """
        Say why rps [rev/s] is not a plausible command for ``which`` thruster ('' if it is).

        The thrusters' own limit (``thruster_max_rps``) is a clamp, the caller's business, as
        for the rudder; refused here: no thrusters in the family, non-finite, or beyond
        THRUSTER_PLAUSIBLE_FACTOR x the limit (a unit error: rpm read as rev/s).
        """
        if not self.thrusters:
            model = f'{self.model} model' if self.model else 'model'
            return f"{which} command: the ship's {model} has no thrusters"
        if not math.isfinite(rps):
            return f'{which} {rps} rev/s is not finite'
        cap = THRUSTER_PLAUSIBLE_FACTOR * self.thruster_max_rps
        if abs(rps) > cap:
            return (f'{which} {rps:g} rev/s is beyond the plausible +-{cap:g} rev/s '
                    f'({THRUSTER_PLAUSIBLE_FACTOR:g} x the {self.thruster_max_rps:g} rev/s '
                    f'limit, {self.thruster_basis})')
        return ''

    def check_rudder(self, rudder_rad: float) -> str:
        """
        Return '' if rudder_rad is within the hard plausibility cap, else why not.

        '' if rudder_rad is within the hard plausibility cap, else why not (the steering gear's own
        limit, a clamp, is the caller's business).
        """
        return _finite_within('rudder', rudder_rad, self.rudder_plausible_rad, lambda: (
            f'rad ({math.degrees(rudder_rad):.0f} deg) is beyond the plausible '
            f'{math.degrees(self.rudder_plausible_rad):.0f} deg'))

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
    >>> round(lim.rpm_max)   # about 840

    """
    key = (ship.kind, ship.params.tobytes(), ship.max_rudder_rad)
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
    rudder = float(ship.max_rudder_rad)
    fam = ship.family
    thr, thr_basis = 0.0, ''
    if all(c in fam.inputs for c in THRUSTER_CHANNELS):
        thr, thr_basis = _thruster_limit(ship, RPM_FACTOR * rpm_top / 60.0)
    return InputLimits(
        rpm_max=RPM_FACTOR * rpm_top,
        rudder_max_rad=rudder,
        rudder_plausible_rad=min(2.0 * rudder, RUDDER_HARD_CAP_RAD),
        top_speed_ms=top,
        speed_max_ms=vmax,
        yaw_rate_max_rad_s=vmax / (0.5 * L),
        dt_min_s=DT_MIN_S,
        dt_max_s=L / top,
        rpm_basis=basis,
        astern_rpm=fam.astern_rpm,
        thruster_max_rps=thr,
        thruster_basis=thr_basis,
        model=ship.model,
        length_m=float(L))


def _thruster_limit(ship: ShipConfig, fallback_rps: float) -> tuple[float, str]:
    """
    Find the thrusters' limit [rev/s] and where it comes from.

    The YAML's ``steering.max_thruster_rps``, else the propeller's plausible maximum (a
    generous cap that still catches unit errors).
    """
    steering = ship.extra.get('steering') or {}
    value = steering.get('max_thruster_rps') if isinstance(steering, dict) else None
    if value is None:
        return fallback_rps, "no steering.max_thruster_rps: the propeller's plausible maximum"
    try:
        rps = float(value)
    except (TypeError, ValueError):
        rps = math.nan
    if isinstance(value, bool) or not (math.isfinite(rps) and rps > 0):
        raise ConfigError(f'{ship.source or ship.name}: steering.max_thruster_rps = {value!r} '
                          'must be a positive number of rev/s')
    return rps, f'steering.max_thruster_rps of {ship.name}'


@dataclass(frozen=True)
class CommandLimit:
    """
    The range of one command channel of a family commanded channel by channel.

    channel: its name (``core/channels.py``); unit: its unit; limit: |value| beyond it is
    clamped to it; plausible: |value| beyond it is refused (a unit error, not a command);
    basis: where the limit comes from (for messages).
    """

    channel: str
    unit: str
    limit: float
    plausible: float
    basis: str

    def check(self, value: Any) -> tuple[float | None, str]:
        """Return (the value to apply or None: refused, the problem or '')."""
        name = f'{self.channel} command'
        try:
            value = float(value)
        except (TypeError, ValueError):
            return None, f'{name} {value!r} is not a number: ignored'
        if not math.isfinite(value):
            return None, f'{name} {value} {self.unit} is not finite: ignored'
        if abs(value) > self.plausible:
            return None, (f'{name} {value:g} {self.unit} is beyond the plausible '
                          f'+-{self.plausible:g} {self.unit}: ignored')
        if abs(value) > self.limit:
            clamped = math.copysign(self.limit, value)
            deg = f' ({math.degrees(value):.1f} deg)' if self.unit == 'rad' else ''
            lim = f' ({math.degrees(self.limit):.1f} deg)' if self.unit == 'rad' else ''
            return clamped, (f'{name} {value:g} {self.unit}{deg} beyond the +-{self.limit:.6g} '
                             f'{self.unit}{lim} limit ({self.basis}): clamped to '
                             f'{clamped:.6g}')
        return value, ''


def command_limits(ship: ShipConfig, channels: Iterable[str]) -> dict[str, CommandLimit]:
    """
    Return the clamp and cap of each command channel, by its unit (module docstring).

    A shaft speed [rev/s] is clamped to ``steering.max_thruster_rps`` (refused beyond twice
    it), an angle [rad] to ``steering.max_azimuth_deg`` (refused beyond one turn); a channel
    in another unit gets no limit beyond finiteness. A bad YAML value is a ConfigError naming
    the file and field.
    """
    steering = ship.extra.get('steering') or {}
    if not isinstance(steering, dict):
        steering = {}
    out = {}
    for ch in channels:
        unit = TABLE[ch].unit
        if unit == 'rev/s':
            rps, basis = _thruster_limit(ship, 0.0)
            if rps == 0.0:
                raise ConfigError(f'{ship.source or ship.name}: steering.max_thruster_rps is '
                                  f'needed to command {ch} (the shaft speed limit, rev/s)')
            out[ch] = CommandLimit(ch, unit, rps, THRUSTER_PLAUSIBLE_FACTOR * rps, basis)
        elif unit == 'rad':
            value = steering.get('max_azimuth_deg', 180.0)
            deg = float(value) if isinstance(value, (int, float)) and \
                not isinstance(value, bool) else math.nan
            if not (math.isfinite(deg) and 0.0 <= deg <= 180.0):
                raise ConfigError(f'{ship.source or ship.name}: steering.max_azimuth_deg = '
                                  f'{value!r} must be a number of degrees in [0, 180]')
            basis = (f'steering.max_azimuth_deg of {ship.name}' if 'max_azimuth_deg' in steering
                     else 'no steering.max_azimuth_deg: a half turn')
            out[ch] = CommandLimit(ch, unit, math.radians(deg), ANGLE_PLAUSIBLE_RAD, basis)
        else:
            out[ch] = CommandLimit(ch, unit, math.inf, math.inf, 'no limit for this unit')
    return out
