"""
``sim_node``: the tuned ship as a ROS 2 simulator.

Subscribes rudder, propeller and (for a model with them) bow and stern thruster commands
(last value holds; astern rpm where the model covers it) -- or, for a craft commanded channel
by channel (the twin-azimuth tug, the Otter, a plugin's actuator), one topic per command
channel, the topic its actuator declares (a tug: VRX-style ``thrusters/<name>/thrust`` and
``thrusters/<name>/pos``; ``command_topics`` overrides any), publishing the joints its
actuator declares (``JOINTS``: a tug's azimuth angles) as sensor_msgs/JointState --
publishes nav_msgs/Odometry in the
``odom`` frame (REP-105: header ``odom``, child ``base_link``; for an ensemble model its
covariance from the members' spread, zeros otherwise: ``ros/uncertainty.py``) and TF
``odom -> base_link`` whenever the state has advanced (checked at ``rate_hz``, so at most
once per step ``dt``: never a repeated stamp), the static ``map -> odom`` unless
``publish_map_to_odom`` is false (another localisation source owns it), optional
simulated GNSS (sensor_msgs/NavSatFix) and IMU (sensor_msgs/Imu) on simulated time, and its
health on ``/diagnostics`` at 1 Hz; ``~/reset`` (std_srvs/Trigger) returns to the initial
state. Topic names are relative and the ship's frames carry ``frame_prefix`` (default: the
namespace), so ``-r __ns:=/ship2`` runs a second ship. All model work is
:class:`~mmg_tuner.core.stepper.ShipSimulator`; this file only wires ROS.

    ros2 run mmg_tuner sim_node --ros-args --params-file config/sim_node.yaml
"""
from __future__ import annotations

from dataclasses import replace
import math
import re
import time
from typing import Any, Callable, cast, Iterable, Mapping, Sequence, TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticArray
from mmg_tuner.core.actuators import actuator
from mmg_tuner.core.channels import TABLE as CHANNEL_TABLE
from mmg_tuner.core.frames import enu_yaw_to_psi
from mmg_tuner.core.limits import DT_MIN_S, POSITION_MAX_M, THRUSTER_CHANNELS
from mmg_tuner.core.plausibility import checked
from mmg_tuner.core.stepper import ShipSimulator, THRUSTERS
from mmg_tuner.errors import ConfigError, MmgTunerError
from mmg_tuner.learn.model import load_model
from mmg_tuner.learn.plausibility import network_checked
from mmg_tuner.ros.command_watch import channel_state, zeroed_on_timeout
from mmg_tuner.ros.conversions import (identity_transform, odometry_from_state, seconds_from_stamp,
                                       stamp_from_seconds, transform_from_state)
from mmg_tuner.ros.health import CommandHealth, Health, plausibility_status
from mmg_tuner.ros.run import declare_parameters, Param, spin_node, unknown_overrides
from mmg_tuner.ros.sensors import datum_from_params, SimulatedSensors
from mmg_tuner.ros.uncertainty import EnsembleSpread, fill_covariance
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
# (ClockType is rclpy.clock_type's in this rclpy, imported by rclpy.clock without re-export;
# an older rclpy defines it in rclpy.clock)
from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Imu, JointState, NavSatFix
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

if TYPE_CHECKING:   # annotations only
    from rclpy.parameter import Parameter
    from rclpy.publisher import Publisher

try:  # no wheel on PyPI: scripts/build_tf2_msgs.py builds it; a ROS install has it
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

# Static ranges; the ship-dependent ones (rpm, speed, rudder and dt limits of
# mmg_tuner.core.limits.input_limits) are checked when the simulator is built.
PARAMS = {
    'ship': Param('suzaku', 'ship config name or YAML path (a change restarts the simulation)'),
    'params_file': Param('', 'tuned params.yaml from tune/diagnose, empty: none (a change '
                         'restarts the simulation)'),
    'rate_hz': Param(50.0, 'timer rate [Hz, wall clock]: the simulation is stepped to the '
                     'clock and odometry/TF published when the state has advanced (at most '
                     'once per step dt of simulated time: no stamp repeats)', (1.0, 1000.0),
                     read_only=True),
    'dt': Param(0.1, 'integration step [s of simulated time]; at most the time to sail one '
                'ship length at its top speed. A change restarts the run from the initial '
                "state (the step is the simulated clock, the sensors' sampling grid and a "
                "residual network's window: see doc/conventions.md)", (DT_MIN_S, 10.0)),
    'integrator': Param('rk4', 'integration method', constraints='euler or rk4'),
    'real_time_factor': Param(1.0, 'simulated seconds per wall second; 0: as fast as possible',
                              (0.0, 1e4)),
    'initial_x': Param(0.0, 'initial position x in frame_id (ENU, east) [m]',
                       (-POSITION_MAX_M, POSITION_MAX_M)),
    'initial_y': Param(0.0, 'initial position y in frame_id (ENU, north) [m]',
                       (-POSITION_MAX_M, POSITION_MAX_M)),
    'initial_yaw': Param(math.pi / 2, 'initial yaw in frame_id (ENU, from east) [rad]',
                         (-2 * math.pi, 2 * math.pi)),
    'initial_speed': Param(3.0, 'initial surge speed [m/s]; > 0 (>= 0 for a model covering '
                           "u <= 0), at most the ship's top speed (Froude number 0.5)",
                           (0.0, 1000.0)),
    'initial_rpm': Param(106.0, 'propeller rpm until a command arrives; > 0 (>= 0 for a model '
                         "covering astern), at most the ship's plausible maximum", (0.0, 1e5)),
    'initial_rudder': Param(0.0, 'rudder angle until a command arrives [rad, + starboard]; '
                            "within the steering gear's limit", (-math.pi / 2, math.pi / 2)),
    # relative names: /odom etc. in the root namespace, /ship2/odom under -r __ns:=/ship2
    'odom_topic': Param('odom', "published odometry (relative: in the node's namespace)",
                        read_only=True),
    'rudder_topic': Param('rudder_angle', 'std_msgs/Float64 rudder command [rad, + starboard]',
                          read_only=True),
    'rpm_topic': Param('propeller_rpm', 'std_msgs/Float64 propeller command [rpm]; < 0 '
                       '(astern) only for a model covering astern', read_only=True),
    # thruster topics as config/topics.yaml names them for recordings: one per thruster
    # (bow_thruster_topic, stern_thruster_topic), described alike
    **{f'{side}_thruster_topic': Param(f'{side}_thruster', f'std_msgs/Float64 {side} thruster '
                                       f'command [rev/s, + pushes the {side} to starboard]; '
                                       'only for a model with thrusters', read_only=True)
       for side in THRUSTERS},
    # one std_msgs/Float64 topic per command channel of any model, in the channel's unit and
    # sign, clamped to the ship's limit; the topic the actuator declares for it
    # (core/channels.py), relative, unless a parameter names another
    'command_topics': Param('', 'CHANNEL=TOPIC,... overriding the topic a command channel '
                            'is read from (default: its parameter above, else the topic its '
                            'actuator declares, relative)', read_only=True),
    'joint_states_topic': Param('joint_states', 'sensor_msgs/JointState of the joints the '
                                "model's actuators declare (position, velocity in their "
                                "states' units and signs) with the odometry", read_only=True),
    'frame_id': Param('map', 'world frame (ENU), shared by all ships: not prefixed; the '
                      'parent of the static map -> odom'),
    'odom_frame_id': Param('odom', "the ship's odometry frame (ENU): Odometry.header.frame_id "
                           '(REP-105) and the parent of base_link in TF; prefixed with '
                           'frame_prefix'),
    'child_frame_id': Param('base_link', 'body frame (FLU); prefixed with frame_prefix'),
    'frame_prefix': Param('', 'prefix of the ship\'s own frames, joined with "/" (default: the '
                          "node's namespace, e.g. ship2 -> ship2/base_link)"),
    'publish_tf': Param(True, 'publish odom -> base_link on /tf and map -> odom on /tf_static '
                        '(needs tf2_msgs)', read_only=True),
    'publish_map_to_odom': Param(True, 'publish the static identity map -> odom; false when '
                                 'another localisation source (a localisation node, a GNSS '
                                 'fusion) owns map -> odom: two parents would clash',
                                 read_only=True),
    'gnss_topic': Param('fix', 'simulated sensor_msgs/NavSatFix (relative)', read_only=True),
    'gnss_rate_hz': Param(0.0, 'simulated GNSS rate [Hz of simulated time]; 0: off',
                          (0.0, 100.0), read_only=True),
    'gnss_noise_m': Param(0.5, 'GNSS horizontal noise, 1 sigma per axis [m]', (0.0, 100.0)),
    'gnss_alt_noise_m': Param(1.0, 'GNSS altitude noise, 1 sigma [m]', (0.0, 100.0)),
    # ASSUMPTION: a datum in Tokyo Bay, SUZAKU's waters; any other place works the same
    'datum_lat_deg': Param(35.5, 'WGS84 latitude of the map origin [deg]', (-90.0, 90.0)),
    'datum_lon_deg': Param(139.8, 'WGS84 longitude of the map origin [deg]', (-180.0, 180.0)),
    'datum_alt_m': Param(0.0, 'WGS84 ellipsoidal height of the map origin [m]',
                         (-1e4, 1e4)),
    'imu_topic': Param('imu/data', 'simulated sensor_msgs/Imu (relative)', read_only=True),
    'imu_rate_hz': Param(0.0, 'simulated IMU rate [Hz of simulated time]; 0: off',
                         (0.0, 1000.0), read_only=True),
    'imu_yaw_noise_rad': Param(0.005, 'IMU heading noise, 1 sigma [rad]', (0.0, 1.0)),
    'imu_gyro_noise_rad_s': Param(0.001, 'IMU yaw-rate noise, 1 sigma [rad/s]', (0.0, 1.0)),
    'imu_accel_noise_m_s2': Param(0.02, 'IMU acceleration noise, 1 sigma [m/s^2]',
                                  (0.0, 10.0)),
    'noise_seed': Param(0, 'seed of the sensor noise (a change reseeds)', (0, 2 ** 31 - 1)),
    'publish_clock': Param(False, 'publish /clock with the simulated time (stamps start at 0)',
                           read_only=True),
    'wait_for_commands': Param(False, 'hold the simulation until both commands have arrived',
                               read_only=True),
    'command_stale_s': Param(1.0, 'a command channel whose last message is older than this, '
                             'or that has received none this long after the start, is stale '
                             '(diagnostics WARN: the node is not being driven) [s, wall clock]',
                             (0.1, 86400.0)),
    'command_timeout_s': Param(0.0, 'after this long without a message on a channel, its '
                               'shaft speed (rpm, thrusters) is set to zero and every angle '
                               'held, with a WARN (rpm only where the model '
                               'covers rpm 0); checked once a second [s, wall clock]; 0: off',
                               (0.0, 86400.0)),
}
RETIRED = dict.fromkeys(('thrust_topic', 'azimuth_topic'),
                        'no longer read: each command channel is on the topic its actuator '
                        'declares; move any with command_topics (CHANNEL=TOPIC,...)')
"""Parameters of earlier versions a params file may still set, and what replaces them."""
FRAME_PARAMS = {'frame_id', 'odom_frame_id', 'child_frame_id', 'frame_prefix'}
DATUM_PARAMS = {'datum_lat_deg', 'datum_lon_deg', 'datum_alt_m'}
DIAGNOSTICS_PERIOD_S = 1.0
RESTART_PARAMS = {'ship', 'params_file', 'dt', 'integrator', 'initial_x', 'initial_y',
                  'initial_yaw', 'initial_speed', 'initial_rpm', 'initial_rudder'}
BUSY_FRACTION = 0.8  # of each timer period spent stepping at most: the executor stays served
CHUNK_STEPS = 50     # steps per compiled call between deadline checks (~0.2 ms with RK4)
SHOWN_UNIT = {'rev/min': 'rpm'}   # a channel unit as /diagnostics and the log show it
_NUMBER = re.compile(r'[-+]?\d[\d.e+-]*')
FAILURE_LOG_S = 5.0  # [s] at most one divergence ERROR per this wall time


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__('sim_node')
        specs = dict(PARAMS)  # the frame prefix defaults to the namespace: /ship2 -> ship2/
        specs['frame_prefix'] = replace(PARAMS['frame_prefix'],
                                        default=self.get_namespace().strip('/'))
        self.p = declare_parameters(self, specs)
        retired = [n for n in RETIRED if n in unknown_overrides(self)]
        if retired:   # else the node would listen on the declared topics without a word
            raise ConfigError('; '.join(f'parameter {n}: {RETIRED[n]}' for n in retired))
        self._check_frames(self.p)
        datum_from_params(self.p)  # a bad datum is refused at start (ConfigError)
        self.sim = self._build(self.p)
        self._spread = EnsembleSpread.of(self.sim, self.p['integrator'])
        self._pending: ShipSimulator | None = None  # built by _validate, taken by _apply
        self.frames = self._frames(self.p)
        world, odom, body = self.frames
        self.odom_pub = self.create_publisher(Odometry, self.p['odom_topic'], 10)
        self.clock_pub = self.create_publisher(ClockMsg, '/clock', 10) \
            if self.p['publish_clock'] else None
        self.tf_pub = self.tf_static_pub = None
        if self.p['publish_tf'] and TFMessage is None:
            self.get_logger().warn('tf2_msgs is not installed: no TF (run scripts/install.sh, '
                                   'or install ros-jazzy-tf2-msgs)')
        elif self.p['publish_tf']:
            self.tf_pub = self.create_publisher(TFMessage, '/tf', 10)
            self.tf_static_pub = self.create_publisher(
                TFMessage, '/tf_static',
                QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        pubs = {}
        if self.p['gnss_rate_hz'] > 0:
            pubs['gnss'] = self.create_publisher(NavSatFix, self.p['gnss_topic'], 10).publish
        if self.p['imu_rate_hz'] > 0:
            pubs['imu'] = self.create_publisher(Imu, self.p['imu_topic'], 10).publish
        self.sensors = SimulatedSensors(self.p, self.sim.dt, pubs, body)
        # channel -> topic: one subscription per command channel, whatever the actuator
        self.channel_topics = command_topics(self._subscribed(self.sim),
                                             self.p['command_topics'], self._screw_topics(self.p))
        for ch, topic in self.channel_topics.items():
            self.create_subscription(Float64, topic, self._taker(ch), 10)
        self.joint_pub = self._joint_msg = None
        self._joints = declared_joints(self.sim.ship.family.actuators)
        if self._joints:
            self.joint_pub = self.create_publisher(JointState, self.p['joint_states_topic'], 10)
            self._joint_msg = JointState(name=list(self._joints))
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        # a channel with a default value (a tunnel thruster) need not be commanded to start
        # (the propeller's speed shown in rpm, as ships and their crews give it)
        commands = {ch: CommandHealth(SHOWN_UNIT.get(CHANNEL_TABLE[ch].unit,
                                                     CHANNEL_TABLE[ch].unit),
                                      self.sim.commands.get(ch, 0.0),
                                      required=CHANNEL_TABLE[ch].default is None,
                                      supported=ch in self.sim.command_channels)
                    for ch in self.channel_topics}
        self.health = Health(self.get_fully_qualified_name(), self.sim.ship.name,
                             commands=commands, since=self._steady_s())
        self._unsupported_logged: set[str] = set()
        self.health.rtf_requested = self.p['real_time_factor']
        self._warned: dict[str, float] = {}
        self._failure_logged, self._unlogged_failures = -math.inf, 0
        self._restart_clock()
        self._odom = odometry_from_state(self.sim.observed(), 0.0, odom, body)   # REP-105
        self._published: tuple[int, int] | None = None   # (run, step) last published
        self._tf = None if self.tf_pub is None else \
            TFMessage(transforms=[transform_from_state(self.sim.observed(), 0.0, odom, body)])
        self._publish_static_tf()
        self._clock_msg = ClockMsg()
        self._period = 1.0 / self.p['rate_hz']
        # real-time shortfall bookkeeping: simulated and wall seconds over the last window
        self._window = (self._steady_s(), 0)
        self._steps_done = 0  # steps since start, across resets (achieved real-time factor)
        self._report_at = (self._steady_s(), 0)
        # on system time the default clock's timer is the cheapest; with use_sim_time a timer on
        # ROS time would wait for /clock, which this node may be the one to publish
        sim_time = self.get_parameter('use_sim_time').value
        self.create_timer(self._period, self._tick, clock=self.steady if sim_time else None)
        self.get_logger().info(
            f"{self.sim.ship.name} ({self.sim.ship.model} model) at {self.p['rate_hz']:g} Hz, "
            f"dt {self.p['dt']:g} s, real-time factor {self.p['real_time_factor']:g}; "
            f'commands accepted: {self._accepted()}; frames {world} -> {odom} -> {body}')
        for key in ('gnss_rate_hz', 'imu_rate_hz'):
            if self.p[key] * self.sim.dt > 1.0:
                self.get_logger().warn(f'{key} {self.p[key]:g} exceeds the step rate 1/dt = '
                                       f'{1 / self.sim.dt:g} Hz: one sample per step')

    # ---- set-up -------------------------------------------------------------------------
    @staticmethod
    def _build(p: Mapping[str, Any]) -> ShipSimulator:
        """
        Build the simulator for parameters p.

        A SimulationError/ConfigError says what is wrong.
        """
        model = load_model(p['ship'], p['params_file'] or None)   # the network it names too
        psi = enu_yaw_to_psi(p['initial_yaw'])
        x0 = [p['initial_y'], p['initial_x'], psi, p['initial_speed'], 0.0, 0.0]
        return ShipSimulator(model.ship, p['dt'], x0, p['initial_rpm'], p['initial_rudder'],
                             p['integrator'], residual=model.residual)

    def _accepted(self) -> str:
        """Describe the command ranges of the current ship, for the log."""
        out = []
        for ch, topic in self.channel_topics.items():
            c = self.sim.command_limits.get(ch)
            if c is not None:
                c = replace(c, unit=SHOWN_UNIT.get(c.unit, c.unit))
            if c is None:
                out.append(f'{ch} on {topic}: none (the model has no such input)')
            elif c.forward_only:
                out.append(f'{ch} on {topic} in (0, {c.limit:.6g}] {c.unit}')
            elif c.limit == c.plausible:
                out.append(f'{ch} on {topic} in [-{c.limit:.6g}, {c.limit:.6g}] {c.unit}')
            else:
                deg = f' ({math.degrees(c.limit):.1f} deg)' if c.unit == 'rad' else ''
                out.append(f'{ch} on {topic} clamped to +-{c.limit:.4g} {c.unit}{deg}')
        return ', '.join(out)

    @staticmethod
    def _subscribed(sim: ShipSimulator) -> tuple[str, ...]:
        """
        Return the command channels subscribed for ``sim``'s ship.

        Its own; a screw-and-rudder ship also both tunnel thrusters (a ship without them says
        so, once: a ship swapped in by the ``ship`` parameter may have them).
        """
        extra = THRUSTER_CHANNELS if sim.rpm_rudder else ()
        return tuple(dict.fromkeys(sim.command_channels + extra))

    @staticmethod
    def _screw_topics(p: Mapping[str, Any]) -> dict[str, str]:
        """Return the screw-and-rudder channels' topics their own parameters name."""
        return {'rudder': p['rudder_topic'], 'rpm': p['rpm_topic'],
                **{f'{w}_thruster': p[f'{w}_thruster_topic'] for w in THRUSTERS}}

    @staticmethod
    def _frames(p: Mapping[str, Any]) -> tuple[str, str, str]:
        """(world, odom, body) frame names: the ship's own two carry the prefix."""
        pre = p['frame_prefix'].strip('/')
        return (p['frame_id'],) + tuple(f'{pre}/{p[k]}' if pre else p[k]
                                        for k in ('odom_frame_id', 'child_frame_id'))

    @staticmethod
    def _check_frames(p: Mapping[str, Any]) -> None:
        for name in ('frame_id', 'odom_frame_id', 'child_frame_id', 'frame_prefix'):
            v = p[name]
            if name != 'frame_prefix' and not v.strip():
                raise MmgTunerError(f'parameter {name} is empty: give a frame name')
            if v != v.strip() or any(c.isspace() for c in v) or \
                    (name != 'frame_prefix' and v.startswith('/')):
                raise MmgTunerError(f'parameter {name} = {v!r}: a TF frame name has no spaces '
                                    'and no leading "/"')
        world, odom, body = SimNode._frames(p)
        if body in (world, odom):
            raise MmgTunerError(f'parameter child_frame_id: the body frame {body!r} must differ '
                                f'from the world frame {world!r} and the odometry frame '
                                f'{odom!r}')

    def _restart_clock(self) -> None:
        self._runs = getattr(self, '_runs', 0) + 1   # a new run: its first state is new
        self.wall0 = self._steady_s()
        self.stamp0 = 0.0 if self.p['publish_clock'] else \
            seconds_from_stamp(self.get_clock().now().to_msg())
        # wait_for_commands gates only the first start: after a reset the last commands hold
        self.started = not self.p['wait_for_commands'] or self.health.ready()
        self.health.waiting = not self.started
        self.sensors.restart(self.sim.steps, self.sim.dt)

    @staticmethod
    def _steady_s() -> float:
        return time.monotonic()  # cheaper than rclpy's Clock.now() in a 50 Hz loop

    def _publish_static_tf(self) -> None:
        """Map -> odom, identity (the simulator knows its pose exactly: no drift to correct)."""
        world, odom, _ = self.frames
        if self.tf_static_pub is not None and world != odom and self.p['publish_map_to_odom']:
            self.tf_static_pub.publish(TFMessage(transforms=[identity_transform(
                self.stamp0, world, odom)]))

    # ---- commands -----------------------------------------------------------------------
    def _taker(self, channel: str) -> Callable[[Float64], None]:
        """Return the subscription callback of ``channel``'s commands."""
        return lambda msg: self._on_command(channel, msg)

    def _on_command(self, channel: str, msg: Float64) -> None:
        """Take one command of a channel (checked against its limit, clamped, or refused)."""
        if channel not in self.sim.command_channels:   # one state, logged once per ship
            c = self.sim.check_thruster(channel.removesuffix('_thruster'), msg.data)
            self.health.command(channel, None, c.problem, self._steady_s())
            if channel not in self._unsupported_logged:
                self._unsupported_logged.add(channel)
                self.get_logger().warn(f'{c.problem} ({self.sim.ship.name}); further {channel} '
                                       'commands are ignored silently (see /diagnostics)')
            return
        c = self.sim.check_command(channel, msg.data)
        if c.value is not None:
            self.sim.set_command(channel, c.value)
        self._command_received(channel, c.value, c.problem)

    def _command_received(self, which: str, value: float | None, problem: str) -> None:
        now = self._steady_s()
        cmd = self.health.commands[which]
        if cmd.stale:  # one line per transition, not one per message
            self.get_logger().info(
                f'{which} commands resumed after {now - cmd.last_rx:.0f} s' if cmd.last_rx
                is not None else f'first {which} command received')
            cmd.stale = False
        self.health.command(which, value, problem, now)
        if problem:
            # throttle per kind of problem: the message without its numbers
            self._warn(problem, key=which + _NUMBER.sub('#', problem))
        if not self.started and self.health.ready():
            self.started = True
            self.health.waiting = False
            self.wall0 = self._steady_s()

    def _warn(self, msg: str, key: str, period_s: float = 2.0) -> None:
        """Warn at most once per period for each kind of problem (not per call site)."""
        now = self._steady_s()
        if now - self._warned.get(key, -math.inf) >= period_s:
            self._warned[key] = now
            self.get_logger().warn(msg)

    # ---- simulation ---------------------------------------------------------------------
    def _tick(self) -> None:
        """
        Step the simulation to the wall clock (or as far as the time budget allows).

        Then publish odometry and TF; diagnostics once a second.
        """
        now = self._steady_s()
        if self.started:
            self._step(now)
        if now - self._report_at[0] >= DIAGNOSTICS_PERIOD_S:
            self._report(now)
        if not self.started:
            return
        # only a state that has advanced (or a new run's first): at rate_hz > 1/dt the same
        # state would go out several times with the same stamp
        key = (self._runs, self.sim.steps)
        if key == self._published:
            return
        self._published = key
        t = self.stamp0 + self.sim.t
        state = self.sim.observed()
        msg = odometry_from_state(state, t, msg=self._odom)
        fill_covariance(msg, self._spread, self.sim, self._runs, state)
        self.odom_pub.publish(msg)
        if self._tf is not None:
            transform_from_state(state, t, msg=self._tf.transforms[0])
            cast('Publisher', self.tf_pub).publish(self._tf)   # (made with _tf)
        if self.joint_pub is not None:
            act = self.sim.actuator_states()
            js = cast(JointState, self._joint_msg)   # (made with joint_pub)
            js.header.stamp = msg.header.stamp
            js.position = [act[pos] for pos, _ in self._joints.values()]
            js.velocity = [act[vel] if vel else math.nan for _, vel in self._joints.values()]
            self.joint_pub.publish(js)
        if self.clock_pub is not None:
            self._clock_msg.clock = msg.header.stamp
            self.clock_pub.publish(self._clock_msg)

    def _step(self, now: float) -> None:
        """
        Step the simulation for one timer tick, within a bounded share of the period.

        The stepping per tick is bounded by BUSY_FRACTION of the period whatever dt and
        real_time_factor ask for, so services and subscriptions are always served; a demand beyond
        that is reported as a real-time-factor shortfall. With sensors on, the steps stop exactly
        at each sample's simulated time.
        """
        rtf = self.p['real_time_factor']
        deadline = time.perf_counter() + BUSY_FRACTION * self._period
        if rtf > 0:
            n = int((now - self.wall0) * rtf / self.sim.dt + 1e-9) - self.sim.steps
        else:  # free running: as many steps as the budget allows
            n = 1 << 62
        sensors = self.sensors if self.sensors.active else None
        if sensors is not None:
            sensors.sample_due(self.sim, self.stamp0)
        while n > 0:
            k = min(n, CHUNK_STEPS)
            if sensors is not None:
                k = min(k, sensors.steps_to_next(self.sim.steps))
            if not self._advance(k):
                return
            n -= k
            if sensors is not None:
                sensors.sample_due(self.sim, self.stamp0)
            if time.perf_counter() >= deadline:
                break
        if rtf > 0 and n > 0:
            self._behind(now, n, rtf)

    def _behind(self, now: float, n_left: int, rtf: float) -> None:
        """
        Step are still owed after this tick's budget.

        Report the achieved real-time factor and, when more than a second behind, drop the backlog
        (never catch up in a burst).
        """
        behind_s = n_left * self.sim.dt / rtf  # wall time worth of steps still to do
        if behind_s <= 1.0:
            return
        w0, steps0 = self._window
        if now - w0 > 0:
            achieved = (self.sim.steps - steps0) * self.sim.dt / (now - w0)
            self._warn(f'real-time factor shortfall: achieving {achieved:.3g} of the requested '
                       f'{rtf:g} (dt {self.sim.dt:g} s: {rtf / self.sim.dt:.3g} steps/s asked); '
                       'simulated time runs slower than requested', key='behind', period_s=10.0)
        self.wall0 = now - self.sim.steps * self.sim.dt / rtf
        self._window = (now, self.sim.steps)

    def _advance(self, n: int) -> bool:
        if self.sim.step(n):
            self._steps_done += n
            return True
        # an ERROR per failure, at most one per FAILURE_LOG_S (a configuration that diverges
        # from its initial state would otherwise flood the log), with the count in between
        now = self._steady_s()
        self.health.reset(str(self.sim.failure), now)
        self._unlogged_failures += 1
        if now - self._failure_logged >= FAILURE_LOG_S:
            more = f' ({self._unlogged_failures} failures since the last report)' \
                if self._unlogged_failures > 1 else ''
            self.get_logger().error(f'simulation failed {self.sim.failure}; reset to the '
                                    f'initial state and commands{more}')
            self._failure_logged, self._unlogged_failures = now, 0
        self._restart_clock()
        self._window = (self._steady_s(), 0)
        return False

    def _report(self, now: float) -> None:
        """Once a second: staleness transitions (logged once) and /diagnostics."""
        t0, steps0 = self._report_at
        self._report_at = (now, self._steps_done)
        if self.started:
            self.health.rtf_achieved = (self._steps_done - steps0) * self.sim.dt / (now - t0)
        limit = self.p['command_stale_s']
        self._timeouts(now)
        for which, cmd in self.health.commands.items():
            if self.health.update_stale(which, now, limit) != 'stale':
                continue
            if cmd.last_rx is None:
                self.get_logger().warn(
                    f'no {which} command received in the {limit:g} s since the start (topic '
                    f'{self._command_topic(which)}): the ship is not being driven (holding '
                    f'{cmd.value:.6g} {cmd.unit}; see /diagnostics)')
            else:
                self.get_logger().warn(
                    f'no {which} command for {limit:g} s: holding the last value '
                    f'{cmd.value:.6g} {cmd.unit} (stale until the next one; see /diagnostics)')
        msg = self.health.array(now, stamp_from_seconds(self.stamp0 + self.sim.t), self.sim.t,
                                limit)
        msg.status.append(plausibility_status(   # implausible model: WARN with the figure
            self.health.node_name, self.health.hardware_id, checked(self.sim.ship)
            + network_checked(self.sim.ship, self.sim.residual)))   # its network's full helm
        self.diag_pub.publish(msg)

    def _command_topic(self, which: str) -> str:
        """Return the topic a command channel is subscribed on (for the log)."""
        return self.channel_topics.get(which, which)

    def _timeouts(self, now: float) -> None:
        """Zero the shaft speed of each channel silent beyond command_timeout_s (once each)."""
        timeout = self.p['command_timeout_s']
        if timeout <= 0:
            return
        for which, cmd in self.health.commands.items():
            if cmd.timed_out or not cmd.supported or not zeroed_on_timeout(which) or \
                    not channel_state(cmd.last_rx, now, self.health.since, timeout, timeout,
                                      cmd.required).timed_out or cmd.value == 0.0:
                continue
            problem = self.sim.set_command(which, 0.0)
            if problem:   # rpm 0 is outside a model of ahead revolutions only: held
                self._warn(f'no {which} command for {timeout:g} s (command_timeout_s): cannot '
                           f'zero it ({problem}); holding {cmd.value:.6g} {cmd.unit}',
                           key=f'timeout {which}', period_s=60.0)
                continue
            cmd.timed_out, cmd.value = True, 0.0
            self.get_logger().warn(f'no {which} command for {timeout:g} s '
                                   '(command_timeout_s): set to 0 until the next one')

    # ---- services and parameters --------------------------------------------------------
    def _on_reset(self, request: Any, response: Any) -> Any:   # Trigger's (messages are Any)
        self.sim.reset()
        self._restart_clock()
        self._window = (self._steady_s(), 0)
        response.success, response.message = True, 'reset to the initial state'
        return response

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        """
        Refuse, with the reason, any parameter change that cannot be applied.

        Refuse, with the reason, any change that cannot be applied (descriptor ranges and read-only
        flags are checked by rclpy before this).
        """
        trial = dict(self.p)
        trial.update({p.name: p.value for p in params})
        names = {p.name for p in params}
        try:
            self._check_frames(trial)
            if names & DATUM_PARAMS:
                datum_from_params(trial)
            if names & RESTART_PARAMS:
                self._pending = self._build(trial)
                old, new = self.sim.command_channels, self._pending.command_channels
                # the subscriptions are made for the commands at start (a screw-and-rudder
                # ship's take every ship of that kind, thrusters or not)
                if new != old and not (self.sim.rpm_rudder and self._pending.rpm_rudder):
                    self._pending = None
                    raise MmgTunerError(
                        f'{trial["ship"]} is commanded by {", ".join(new)}, the running ship '
                        f'by {", ".join(old)}: start a new node for it')
        except MmgTunerError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        """
        Apply an accepted change.

        A new simulator (restart), a new real-time anchor, new frame names, datum or noise seed;
        nothing accepted is ignored.
        """
        names = {p.name for p in params}
        self.p.update({p.name: p.value for p in params})
        if names & RESTART_PARAMS:
            self.sim = self._pending or self._build(self.p)
            self._spread = EnsembleSpread.of(self.sim, self.p['integrator'])
            self._pending = None
            self.health.hardware_id = self.sim.ship.name
            for ch, cmd in self.health.commands.items():   # the new ship may have thrusters
                if CHANNEL_TABLE[ch].default is not None:
                    cmd.supported, cmd.value = ch in self.sim.command_channels, 0.0
            self._unsupported_logged.clear()
            self._restart_clock()
            self._window = (self._steady_s(), 0)
        elif 'real_time_factor' in names:  # keep the simulated time, re-anchor the wall clock
            rtf = self.p['real_time_factor']
            now = self._steady_s()
            self.wall0 = now - (self.sim.steps * self.sim.dt / rtf if rtf > 0 else 0.0)
            self._window = (now, self.sim.steps)
        self.health.rtf_requested = self.p['real_time_factor']
        if names & FRAME_PARAMS:
            self.frames = self._frames(self.p)
            world, odom, body = self.frames
            self._odom.header.frame_id, self._odom.child_frame_id = odom, body
            if self._tf is not None:
                tf = self._tf.transforms[0]
                tf.header.frame_id, tf.child_frame_id = odom, body
            self.sensors.frame_id = body
            self._publish_static_tf()
        if names & DATUM_PARAMS:
            self.sensors.datum = datum_from_params(self.p)
        if 'noise_seed' in names:
            self.sensors.reseed(self.p['noise_seed'])
        self.get_logger().info(f'applied {sorted(names)}'
                               + (f': restarted {self.sim.ship.name}'
                                  if names & RESTART_PARAMS else ''))


def command_topics(channels: Sequence[str], overrides: str,
                   params: Mapping[str, str] | None = None) -> dict[str, str]:
    """
    Return channel -> command topic, one per command channel.

    Each channel on the topic ``overrides`` (``CHANNEL=TOPIC,...``, the ``command_topics``
    parameter) names, else its own parameter's (``params``: ``rudder_topic``, ``rpm_topic``,
    the thrusters'; as given), else the topic its actuator declares (``CHANNELS``' 4th element,
    core/channels.py), made relative (in the node's namespace).
    """
    given: dict[str, str] = {}
    for item in overrides.split(','):
        if not item.strip():
            continue
        ch, sep, topic = (x.strip() for x in item.partition('='))
        if not sep or not topic or ch not in channels:
            raise MmgTunerError(f'parameter command_topics: {item.strip()!r} is not '
                                f'CHANNEL=TOPIC with CHANNEL one of {", ".join(channels)}')
        given[ch] = topic.lstrip('/')
    out = {}
    for ch in channels:
        if ch in given:
            out[ch] = given[ch]
        elif params and ch in params:
            out[ch] = params[ch]
        elif ch in CHANNEL_TABLE and CHANNEL_TABLE[ch].topic:
            out[ch] = CHANNEL_TABLE[ch].topic.lstrip('/')
    missing = [c for c in channels if c not in out]
    if missing:
        raise MmgTunerError(f'no topic for the command(s) {", ".join(missing)}: give it in the '
                            'parameter command_topics (CHANNEL=TOPIC), or declare it in the '
                            "actuator's CHANNELS (4th element)")
    return out


def declared_joints(actuators: Iterable[str]) -> dict[str, tuple[str, str]]:
    """Return joint -> (position state, velocity state) the actuators declare (``JOINTS``)."""
    return {joint: states for a in actuators for joint, states in actuator(a).joints.items()}


def main(args: list[str] | None = None) -> None:
    spin_node(SimNode, args)


if __name__ == '__main__':
    main()
