"""
A stateful ship for interactive simulation (the ROS node's engine; no ROS here).

It steps the same compiled :func:`~mmg_tuner.core.integrate.advance` as the offline simulation,
for every model family, so a command history held per step reproduces
:func:`~mmg_tuner.core.simulate.simulate` exactly. Commands are held per channel
(``core/channels.py``): rpm and rudder (and thrusters) for a screw-and-rudder ship, the
shaft speeds and azimuth angles of a twin-azimuth tug; the actuators' internal states (the
actual rudder angle, the azimuth angles and rates) carry over from step to step.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, TYPE_CHECKING

from mmg_tuner.core.actuators import actuator
from mmg_tuner.core.correction import FEATURES, features_fit, N_COMMAND_SLOTS, reads_physics
from mmg_tuner.core.dynamics import apparent_wind, family_tag, N_ACT_STATES
from mmg_tuner.core.integrate import (advance, observe, physics_accelerations, start_actuators,
                                      start_state)
from mmg_tuner.core.layout import DIVERGED, OK, PARAM_INDEX, STATE_NAMES, STATUS_TEXT
from mmg_tuner.core.limits import CommandLimit, input_limits, InputLimits
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.errors import ConfigError, SimulationError
from numba import njit
import numpy as np

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray
    import numpy.typing as npt

IMPLAUSIBLE = -1  # status of a finite state beyond the ship's plausible speed or yaw rate
ARITHMETIC = -2   # the compiled model raised ZeroDivisionError
MAX_SUBSTEPS = 1000
THRUSTERS = ('bow', 'stern')  # thruster commands, in the order of the input channels
RPM_RUDDER = ('rpm', 'rudder')  # the first inputs of a family commanded by rpm and rudder


@dataclass
class CommandCheck:
    """The outcome of validating a command: the value to apply (or None) and why."""

    value: float | None
    problem: str = ''


@dataclass(frozen=True)
class StepFailure:
    """
    Why and when a step failed; the simulator was then reset to its initial state.

    time_s: simulated time of the step that failed [s]; reason: what was wrong;
    last_state / bad_state: the model state (x, y, psi, u, v, r; SI, rad) before and after it;
    rpm, rudder_rad, delta_act_rad: the commands held and the actual rudder angle;
    bow_rps, stern_rps: the thruster commands held [rev/s]; commands: every command held,
    (channel, value) in the channel's unit, for a family commanded channel by channel (its
    rpm, rudder_rad and delta_act_rad are NaN).
    """

    time_s: float
    reason: str
    last_state: tuple[float, ...]
    bad_state: tuple[float, ...]
    rpm: float
    rudder_rad: float
    delta_act_rad: float
    bow_rps: float = 0.0
    stern_rps: float = 0.0
    commands: tuple[tuple[str, float], ...] = ()

    def __str__(self) -> str:
        def fmt(state: tuple[float, ...]) -> str:
            return ', '.join(f'{n} {v:.4g}' for n, v in zip(STATE_NAMES, state))
        if self.commands:
            held = ', '.join(f'{n} {v:.6g}' for n, v in self.commands)
            return (f'at t = {self.time_s:.2f} s: {self.reason}; commands {held}; last good '
                    f'state [{fmt(self.last_state)}]; failed state [{fmt(self.bad_state)}]')
        thrusters = f', thrusters bow {self.bow_rps:.4g} stern {self.stern_rps:.4g} rev/s' \
            if self.bow_rps or self.stern_rps else ''
        return (f'at t = {self.time_s:.2f} s: {self.reason}; commands rpm {self.rpm:.6g}, '
                f'rudder {math.degrees(self.rudder_rad):.2f} deg (actual '
                f'{math.degrees(self.delta_act_rad):.2f} deg){thrusters}; last good state '
                f'[{fmt(self.last_state)}]; failed state [{fmt(self.bad_state)}]')


@njit(cache=True)
def _advance_checked(kind: tuple[int, ...], p: FloatArray, s: FloatArray, a: FloatArray,
                     row: FloatArray, dt: float, substeps: int, method: int, n: int,
                     speed_max: float, yaw_rate_max: float, last: FloatArray, r0: float,
                     r1: float, r2: float, physics: float) -> tuple[int, int]:
    """
    N calls of advance, each followed by a per-element finiteness and plausibility check.

    Compiled without fastmath on purpose: under 'nsz' + 'reassoc' LLVM folds
    isfinite(a + b + ...) to True, so advance's own check cannot be relied on. The commands
    ``row`` (1, the family's channels) are held; ``a`` holds the actuator states; (r0, r1,
    r2) a residual network's accelerations (zeros and physics 1.0 without one). Returns
    (status, steps done); on failure ``last`` holds the state before the failed step and
    ``s`` the failed one.
    """
    vmax2 = speed_max * speed_max
    for i in range(n):
        for j in range(6):
            last[j] = s[j]
        status = advance(kind, p, s, a, row, 0, 0.0, 1, dt, substeps, method, r0, r1, r2,
                         physics)
        if status != OK:
            return status, i
        for j in range(6):
            if not math.isfinite(s[j]):
                return DIVERGED, i
        if s[3] * s[3] + s[4] * s[4] > vmax2 or abs(s[5]) > yaw_rate_max:
            return IMPLAUSIBLE, i
    return OK, n


def apparent_wind_body(ship: ShipConfig, state: npt.ArrayLike, wind_n: float = math.nan,
                       wind_e: float = math.nan) -> tuple[float, float]:
    """
    Return the apparent wind in body axes [m/s] for a model state (for the node).

    From the measured true wind (air velocity north/east [m/s]) or, when NaN, the ship's wind
    parameters.
    """
    p = np.array(ship.params, dtype=float)
    if wind_n == wind_n and wind_e == wind_e:
        p[PARAM_INDEX['wind_speed']] = math.hypot(wind_n, wind_e)
        p[PARAM_INDEX['wind_dir']] = math.atan2(-wind_e, -wind_n)
    s = np.asarray(state, dtype=float)
    wu, wv = apparent_wind(p, float(s[2]), float(s[3]), float(s[4]))
    return float(wu), float(wv)


class ShipSimulator:
    """
    Fixed-step simulation of one ship of any model family driven by held commands.

    Everything is validated against the ship's plausibility ranges
    (:func:`~mmg_tuner.core.limits.input_limits`): construction refuses bad settings with a
    SimulationError; a bad command is ignored or clamped and the problem returned; every step
    checks the state, and a non-finite or implausible one resets the simulator (``failure``
    says what happened), so the state is never NaN. What the ship's model family covers
    decides the rest: astern rpm (rpm <= 0) and u <= 0 only where the family has them, thruster
    commands (``set_thruster``) only for a family with thruster inputs.

    Any family is commanded by channel name (``command_channels``; ``set_command``): a
    screw-and-rudder ship by rpm, rudder and its thrusters (``rpm``/``rudder_rad`` give
    their initial values), a twin-azimuth tug by ``n_port``, ``n_stbd`` [rev/s] and
    ``azimuth_port``, ``azimuth_stbd`` [rad], each clamped to the ship YAML's limits
    (``steering.max_thruster_rps``, ``steering.max_azimuth_deg``; ``command_limits``) with
    the problem returned. An azimuth command is the angle the thruster turns to: the
    actuator's dynamics (``azimuth_k1``, ``azimuth_k2`` and the rate limit
    ``azimuth_rate_max`` of the YAML) move it there over the following steps
    (``actuator_states``).

    Examples
    --------
    >>> sim = ShipSimulator(load_ship('suzaku'), dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106)
    >>> sim.set_rudder(math.radians(10)); sim.step(100)
    >>> sim.observed()  # x, y, psi, u, v, r in the model frame
    >>> tug = ShipSimulator(load_ship('qiuxin_tug'), dt=0.2, x0=[0, 0, 0, 0.0, 0, 0])
    >>> tug.set_command('n_port', 7.0); tug.set_command('azimuth_port', math.radians(20))
    >>> tug.step(50); tug.actuator_states()['alpha_port']   # approaching 0.349 rad

    """

    def __init__(self, ship: ShipConfig, dt: float = 0.1, x0: npt.ArrayLike | None = None,
                 rpm: float = 100.0, rudder_rad: float = 0.0, integrator: str = 'rk4',
                 substeps: int = 1, residual: Any = None,
                 commands: Mapping[str, float] | None = None) -> None:
        self.ship = ship
        # a learned residual network (``learn.ResidualNet``, or anything with dt_s, physics and
        # stepper() -> .accelerations(state, commands, wind_body[, physics]), .reset(); the
        # physics' accelerations when its features end with them) or None
        self.residual = residual
        self._tag = family_tag(ship.kind)
        fam = ship.family
        self.rpm_rudder = fam.inputs[:2] == RPM_RUDDER
        acts = [actuator(a) for a in fam.actuators]
        # measured channel -> the channel its command goes to (the actuator moves the former)
        self._commanded = {m: c for a in acts for m, c in a.commanded.items()}
        self.command_channels: tuple[str, ...] = tuple(
            c for c in fam.inputs if c not in self._commanded.values())
        self._col = {c: j for j, c in enumerate(fam.channels)}
        # the actuators' internal states, by name, at their place in the state array
        names = [n for a in acts for n in a.states]
        self._state_index = {n: i for i, n in enumerate(names)}
        self._inp = np.full((1, len(fam.channels)), np.nan)   # the held commands; wind: none
        self._inp[0, :len(fam.inputs)] = 0.0
        self._a = np.zeros(N_ACT_STATES)
        self.limits: InputLimits = input_limits(ship)
        # each command channel's clamp and plausibility cap (one table for every family)
        self.command_limits: dict[str, CommandLimit] = {
            c: self.limits.channels[c] for c in self.command_channels}
        for c, lim_c in self.command_limits.items():
            if lim_c.unit == 'rev/s' and not math.isfinite(lim_c.limit):
                raise ConfigError(f'{ship.source or ship.name}: steering.max_thruster_rps is '
                                  f'needed to command {c} (the shaft speed limit, rev/s)')
        if residual is not None and not features_fit(
                getattr(residual, 'features', FEATURES), fam):
            raise SimulationError(f'{ship.name}: the residual network reads '
                                  f'{", ".join(getattr(residual, "features", FEATURES))}, '
                                  f'not the {fam.name!r} family\'s {", ".join(fam.inputs)}')
        lim = self.limits
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise SimulationError(f'dt must be a number, got {dt!r}') from None
        if problem := lim.check_dt(dt):
            raise SimulationError(f'{ship.name}: {problem}')
        self.dt = dt
        if not isinstance(integrator, str):
            raise SimulationError(f'integrator must be a name, got {integrator!r}')
        self.method = integrator_code(integrator)
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) \
                or not 1 <= substeps <= MAX_SUBSTEPS:
            raise SimulationError(f'substeps must be an integer in [1, {MAX_SUBSTEPS}], '
                                  f'got {substeps!r}')
        self.substeps = int(substeps)
        self.x0 = self._check_x0(x0)
        self._cmd: dict[str, float] = dict.fromkeys(self.command_channels, 0.0)
        if self.rpm_rudder:
            rpm, rudder_rad = float(rpm), float(rudder_rad)
            for name, value in (('rpm', rpm), ('rudder', rudder_rad)):
                if problem := self._initial_problem(name, value):
                    raise SimulationError(f'{ship.name}: initial {problem}')
        else:   # rpm and rudder mean nothing here: the initial commands come from ``commands``
            rpm = rudder_rad = math.nan
        self.rpm0 = rpm
        self.rudder0 = rudder_rad
        self._cmd0 = dict(self._cmd)
        for name, value in (commands or {}).items():
            if problem := self._initial_problem(name, value):
                raise SimulationError(f'{ship.name}: initial {problem}')
            self._cmd0[name] = float(value)
        self._last = np.empty(6)
        self._obs = np.empty(6)
        self.failure: StepFailure | None = None
        self.failures = 0
        self.reset()
        self.step(1)  # compile (or load from cache) now, not in the middle of a real-time loop
        self.reset()
        if self.failures:  # the very first step failed: refuse the settings
            raise SimulationError(f'{ship.name}: the first step fails ({self.failure})')

    def _initial_problem(self, channel: str, value: Any) -> str:
        """
        Say why ``value`` cannot be ``channel``'s initial command ('' if it can).

        An initial command is a setting: beyond the channel's limit it is refused, not
        clamped (ValueError for a channel the family is not commanded by).
        """
        if channel not in self.command_limits:
            self.check_command(channel, 0.0)   # the ValueError naming the family's commands
        c = self.command_limits[channel]
        try:
            v = float(value)
        except (TypeError, ValueError):
            return f'{channel} command {value!r} is not a number'
        if problem := c.problem(v):
            return problem
        if abs(v) > c.limit:
            return (f'{channel} command {c.show(v)} is outside the +-{c.show(c.limit)} '
                    f'limit ({c.basis})')
        return ''

    def _check_x0(self, x0: npt.ArrayLike | None) -> np.ndarray:
        lim = self.limits
        try:
            x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0] if x0 is None else x0, dtype=float)
        except (TypeError, ValueError):
            raise SimulationError(f'initial state must be 6 numbers, got {x0!r}') from None
        if x.shape != (6,):
            raise SimulationError(f'initial state must be 6 numbers (x, y, psi, u, v, r), '
                                  f'got shape {x.shape}')
        bad = [f'{n} = {v}' for n, v in zip(STATE_NAMES, x) if not math.isfinite(v)]
        if bad:
            raise SimulationError(f'initial state not finite: {", ".join(bad)}')
        if max(abs(x[0]), abs(x[1])) > lim.position_max_m:
            raise SimulationError(f'initial position ({x[0]:g}, {x[1]:g}) m is beyond '
                                  f'{lim.position_max_m:g} m from the frame origin')
        if self.ship.family.astern_surge:
            if not abs(x[3]) <= lim.top_speed_ms:
                raise SimulationError(
                    f'{self.ship.name}: initial surge speed u = {x[3]:g} m/s is outside '
                    f'[-{lim.top_speed_ms:.2f}, {lim.top_speed_ms:.2f}] m/s (a generous top '
                    'speed, Froude number 0.5)')
        elif not 0 < x[3] <= lim.top_speed_ms:
            raise SimulationError(
                f'{self.ship.name}: initial surge speed u = {x[3]:g} m/s is outside (0, '
                f'{lim.top_speed_ms:.2f}] m/s (the MMG model covers u > 0; the upper bound is '
                f'a generous top speed, Froude number 0.5)')
        if abs(x[4]) > lim.top_speed_ms or abs(x[5]) > lim.yaw_rate_max_rad_s:
            raise SimulationError(f'{self.ship.name}: initial sway {x[4]:g} m/s or yaw rate '
                                  f'{x[5]:g} rad/s is implausible')
        return x

    def reset(self) -> None:
        """Back to the initial state and the initial commands."""
        self.t = 0.0
        self.steps = 0
        self._cmd.update(self._cmd0)
        if self.rpm_rudder:
            self.rpm = self.rpm0
            self.rudder = self.rudder0
        for measured in self._commanded:   # an actuator starts at rest at its command
            self._inp[0, self._col[measured]] = self._cmd[measured]
        self.s = np.empty(6)
        start_state(self.ship.params, self.x0, self.s)
        start_actuators(self._tag, self.ship.params, self._row(), 0.0, 1, self._a)
        self.status = 'ok'
        if getattr(self, '_residual', None) is not None:
            self._residual.reset()   # the network's window starts afresh

    def _row(self) -> np.ndarray:
        """Return the held commands as one sample of the family's input array."""
        for name, value in self._cmd.items():
            self._inp[0, self._col[self._commanded.get(name, name)]] = value
        return self._inp

    def _get(self, channel: str) -> float:
        return self._cmd.get(channel, 0.0)

    def _set(self, channel: str, value: float) -> None:
        if channel in self._cmd:   # a channel the family lacks holds nothing
            self._cmd[channel] = float(value)

    rpm = property(lambda self: self._get('rpm'), lambda self, v: self._set('rpm', v),
                   doc='the propeller command held [rev/min] (screw and rudder)')
    rudder = property(lambda self: self._get('rudder'), lambda self, v: self._set('rudder', v),
                      doc='the rudder command held [rad] (screw and rudder)')
    bow = property(lambda self: self._get('bow_thruster'),
                   lambda self, v: self._set('bow_thruster', v),
                   doc='the bow thruster command held [rev/s]; 0 without one')
    stern = property(lambda self: self._get('stern_thruster'),
                     lambda self, v: self._set('stern_thruster', v),
                     doc='the stern thruster command held [rev/s]; 0 without one')

    @property
    def commands(self) -> dict[str, float]:
        """Return the commands held, channel -> value in the channel's unit."""
        return dict(self._cmd)

    def actuator_states(self) -> dict[str, float]:
        """
        Return the actuators' internal states by name, as they stand after the last step.

        delta_actual [rad] for a screw and rudder; alpha_port, alpha_rate_port, alpha_stbd,
        alpha_rate_stbd [rad, rad/s; + toward starboard] for twin azimuths.
        """
        return {n: float(self._a[i]) for n, i in self._state_index.items()}

    @property
    def delta_act(self) -> float:
        """Return the actual rudder angle [rad] (the screw-and-rudder actuator's state)."""
        return float(self._a[0]) if self.rpm_rudder else math.nan

    def check_command(self, channel: str, value: float) -> CommandCheck:
        """
        Check a command of any channel in ``command_channels`` (ValueError for another).

        Against the channel's :class:`~mmg_tuner.core.limits.CommandLimit`: clamped beyond its
        limit (the steering gear's, the YAML's), ignored when not a plausible value (not a
        number, not finite, beyond the cap, rpm <= 0 for a family without astern), the
        problem said.
        """
        if channel not in self.command_channels:
            raise ValueError(f'{self.ship.name}: {channel!r} is no command of the '
                             f'{self.ship.family.name} family; its commands: '
                             f'{", ".join(self.command_channels)}')
        return CommandCheck(*self.command_limits[channel].check(value))

    def set_command(self, channel: str, value: float) -> str:
        """Apply a command of any channel (validated); a problem description or ''."""
        c = self.check_command(channel, value)
        if c.value is not None:
            self._cmd[channel] = c.value
        return c.problem

    def check_rudder(self, rudder_rad: float) -> CommandCheck:
        """Check a rudder command [rad] (:meth:`check_command` of ``rudder``)."""
        return self.check_command('rudder', rudder_rad)

    def check_rpm(self, rpm: float) -> CommandCheck:
        """Check an rpm command (:meth:`check_command` of ``rpm``)."""
        return self.check_command('rpm', rpm)

    def check_thruster(self, which: str, rps: float) -> CommandCheck:
        """
        Check a bow or stern thruster command [rev/s] (:meth:`check_command`).

        Ignored, said so, when the family has no thrusters.
        """
        if which not in THRUSTERS:
            raise ValueError(f'which must be one of {THRUSTERS}, got {which!r}')
        channel = f'{which}_thruster'
        if channel not in self.command_limits:
            model = f'{self.ship.model} model' if self.ship.model else 'model'
            return CommandCheck(None, f"{which} thruster command: the ship's {model} has no "
                                'thrusters')
        return self.check_command(channel, rps)

    def set_thruster(self, which: str, rps: float) -> str:
        """Apply a thruster command ('bow' or 'stern', validated); a problem or ''."""
        c = self.check_thruster(which, rps)
        if c.value is not None:
            setattr(self, which, c.value)
        return c.problem

    def set_rudder(self, rudder_rad: float) -> str:
        """Apply a rudder command (validated); returns a problem description or ''."""
        c = self.check_rudder(rudder_rad)
        if c.value is not None:
            self.rudder = c.value
        return c.problem

    def set_rpm(self, rpm: float) -> str:
        """Apply an rpm command (validated); returns a problem description or ''."""
        c = self.check_rpm(rpm)
        if c.value is not None:
            self.rpm = c.value
        return c.problem

    def step(self, n: int = 1) -> bool:
        """
        Advance n steps of dt with the held commands.

        False if a step left the model's range, diverged or reached an implausible state:
        ``failure`` then says when, why, with which commands and from which state, and the
        simulator is back at its initial state and commands (``status`` keeps the reason).
        """
        try:
            status, done = self._steps(int(n))
        except ZeroDivisionError:  # compiled code raises it (x / 0.0): a failure, not a crash
            status, done = ARITHMETIC, 0
        self.steps += done
        self.t = self.steps * self.dt
        delta = self.delta_act
        lim = self.limits
        if status == OK:
            return True
        if status == IMPLAUSIBLE:
            u, v, r = self.s[3:]
            reason = 'implausible state: ' + lim.state_problem(u, v, r)
        elif status == ARITHMETIC:
            reason = f'division by zero in the model within the next {int(n)} step(s)'
        else:
            reason = STATUS_TEXT[status]
        self.failure = StepFailure(
            time_s=self.t + self.dt, reason=reason,
            last_state=tuple(float(a) for a in self._last),
            bad_state=tuple(float(a) for a in self.s), rpm=self.rpm, rudder_rad=self.rudder,
            delta_act_rad=float(delta), bow_rps=self.bow, stern_rps=self.stern,
            commands=() if self.rpm_rudder else tuple(self._cmd.items()))
        self.failures += 1
        self.reset()
        self.status = reason
        return False

    def _steps(self, n: int) -> tuple[int, int]:
        """
        Return (status, steps done) of n checked steps with the held commands.

        With a residual network (learn/residual.py) it is evaluated every net.dt_s of simulated
        time (dt must divide it) from the window of its past samples and held in between, as
        the offline hybrid does; the same checks follow every step.
        """
        lim = self.limits
        p, s, inp = self.ship.params, self.s, self._row()
        net = self.residual
        if net is None:
            return _advance_checked(self._tag, p, s, self._a, inp, self.dt, self.substeps,
                                    self.method, n, lim.speed_max_ms,
                                    lim.yaw_rate_max_rad_s, self._last, 0.0, 0.0, 0.0, 1.0)
        if getattr(self, '_residual', None) is None:
            every = int(round(net.dt_s / self.dt))
            if every < 1 or abs(every * self.dt - net.dt_s) > 1e-9 * net.dt_s:
                raise SimulationError(f'{self.ship.name}: dt = {self.dt:g} s must divide the '
                                      f"residual network's sample interval {net.dt_s:g} s")
            self._residual, self._every, self._acc = net.stepper(), every, (0.0,) * 3
        done = 0
        while done < n:
            if (self.steps + done) % self._every == 0:
                seen: tuple[Any, ...] = (s, self._feature_commands,
                                         apparent_wind_body(self.ship, s))
                if reads_physics(getattr(net, 'features', FEATURES)):   # over a sample, as
                    # offline (physics_accelerations), not over this simulator's step
                    seen += (physics_accelerations(self._tag, p, s, self._a, inp, 0, 0.0, 1,
                                                   float(net.dt_s)),)
                self._acc = self._residual.accelerations(*seen)
            chunk = min(n - done, self._every - (self.steps + done) % self._every)
            status, k = _advance_checked(self._tag, p, s, self._a, inp, self.dt, self.substeps,
                                         self.method, chunk,
                                         lim.speed_max_ms, lim.yaw_rate_max_rad_s, self._last,
                                         *self._acc, float(net.physics))
            done += k
            if status != OK:
                return status, done
        return OK, n

    @property
    def _feature_commands(self) -> tuple[float, ...]:
        """
        Return the network's command slots: the family's first channels, as held.

        In kernel order (``core.correction.feature_names``); a measured angle's slot holds
        the angle commanded (offline, the recorded one: they differ by the drive's lag).
        """
        names = self.ship.family.inputs[:N_COMMAND_SLOTS]
        return tuple(self._cmd.get(c, 0.0) for c in names) + \
            (0.0,) * (N_COMMAND_SLOTS - len(names))

    def observed(self) -> np.ndarray:
        """x, y, psi, u, v, r as measured (antenna position, velocities over ground)."""
        observe(self.ship.params, self.s, self._obs)
        return self._obs.copy()
