"""``sim_node``: the tuned ship as a ROS 2 simulator.

Subscribes rudder and propeller commands (last value holds), publishes nav_msgs/Odometry
(REP-103/105) at ``rate_hz``; ``~/reset`` (std_srvs/Trigger) returns to the initial state.
All model work is :class:`~mmg_tuner.core.stepper.ShipSimulator`; this file only wires ROS.

    ros2 run mmg_tuner sim_node --ros-args --params-file config/sim_node.yaml
"""
from __future__ import annotations

import math
import time

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64
from std_srvs.srv import Trigger
from nav_msgs.msg import Odometry

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.stepper import ShipSimulator
from mmg_tuner.errors import MmgTunerError
from mmg_tuner.ros.run import spin_node
from mmg_tuner.ros.conversions import odometry_from_state, seconds_from_stamp

PARAMS = {  # name: (default, description)
    'ship': ('suzaku', 'ship config name or YAML path'),
    'params_file': ('', 'tuned params.yaml from tune/diagnose (empty: none)'),
    'rate_hz': (50.0, 'odometry publication rate [Hz, wall clock]'),
    'dt': (0.1, 'integration step [s of simulated time]'),
    'integrator': ('rk4', 'euler or rk4'),
    'real_time_factor': (1.0, 'simulated seconds per wall second; <= 0: as fast as possible'),
    'initial_x': (0.0, 'initial position x in frame_id (ENU, east) [m]'),
    'initial_y': (0.0, 'initial position y in frame_id (ENU, north) [m]'),
    'initial_yaw': (math.pi / 2, 'initial yaw in frame_id (ENU, from east) [rad]'),
    'initial_speed': (3.0, 'initial surge speed [m/s]'),
    'initial_rpm': (106.0, 'propeller rpm until a command arrives'),
    'initial_rudder': (0.0, 'rudder angle until a command arrives [rad, + starboard]'),
    'odom_topic': ('/odom', 'published odometry'),
    'rudder_topic': ('/rudder_angle', 'std_msgs/Float64 rudder command [rad, + starboard]'),
    'rpm_topic': ('/propeller_rpm', 'std_msgs/Float64 propeller command [rpm]'),
    'frame_id': ('map', 'odometry frame (ENU)'),
    'child_frame_id': ('base_link', 'body frame (FLU)'),
    'publish_clock': (False, 'publish /clock with the simulated time (stamps start at 0)'),
    'wait_for_commands': (False, 'hold the simulation until both commands have arrived'),
    'command_timeout_s': (5.0, 'warn when a command is older than this [s, wall clock]'),
}
RESTART_PARAMS = {'ship', 'params_file', 'dt', 'integrator', 'initial_x', 'initial_y',
                  'initial_yaw', 'initial_speed', 'initial_rpm', 'initial_rudder'}


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__('sim_node')
        for name, (default, desc) in PARAMS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=desc))
        self.p = {n: self.get_parameter(n).value for n in PARAMS}
        self.sim = self._build(self.p)
        self.odom_pub = self.create_publisher(Odometry, self.p['odom_topic'], 10)
        self.clock_pub = self.create_publisher(ClockMsg, '/clock', 10) \
            if self.p['publish_clock'] else None
        self.create_subscription(Float64, self.p['rudder_topic'], self._on_rudder, 10)
        self.create_subscription(Float64, self.p['rpm_topic'], self._on_rpm, 10)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.last_cmd = {'rudder': None, 'rpm': None}
        self._warned: dict[str, float] = {}
        self._stale_checked = 0.0
        self._restart_clock()
        self._odom = odometry_from_state(self.sim.observed(), 0.0, self.p['frame_id'],
                                         self.p['child_frame_id'])
        self._clock_msg = ClockMsg()
        # on system time the default clock's timer is the cheapest; with use_sim_time a timer on
        # ROS time would wait for /clock, which this node may be the one to publish
        sim_time = self.get_parameter('use_sim_time').value
        self.create_timer(1.0 / self.p['rate_hz'], self._tick,
                          clock=self.steady if sim_time else None)
        self.get_logger().info(
            f"{self.sim.ship.name} ({self.sim.ship.model} model) at {self.p['rate_hz']:g} Hz, "
            f"dt {self.p['dt']:g} s, real-time factor {self.p['real_time_factor']:g}")

    # ---- set-up -------------------------------------------------------------------------
    @staticmethod
    def _build(p: dict) -> ShipSimulator:
        ship = load_ship(p['ship'], p['params_file'] or None)
        psi = math.pi / 2 - p['initial_yaw']
        x0 = [p['initial_y'], p['initial_x'], psi, p['initial_speed'], 0.0, 0.0]
        return ShipSimulator(ship, p['dt'], x0, p['initial_rpm'], p['initial_rudder'],
                             p['integrator'])

    def _restart_clock(self) -> None:
        self.wall0 = self._steady_s()
        self.stamp0 = 0.0 if self.p['publish_clock'] else \
            seconds_from_stamp(self.get_clock().now().to_msg())
        # wait_for_commands gates only the first start: after a reset the last commands hold
        self.started = not self.p['wait_for_commands'] or \
            all(v is not None for v in getattr(self, 'last_cmd', {'x': None}).values())

    @staticmethod
    def _steady_s() -> float:
        return time.monotonic()  # cheaper than rclpy's Clock.now() in a 50 Hz loop

    # ---- commands -----------------------------------------------------------------------
    def _on_rudder(self, msg: Float64) -> None:
        problem = self.sim.set_rudder(msg.data)
        self._command_received('rudder', problem)

    def _on_rpm(self, msg: Float64) -> None:
        problem = self.sim.set_rpm(msg.data)
        self._command_received('rpm', problem)

    def _command_received(self, which: str, problem: str) -> None:
        self.last_cmd[which] = self._steady_s()
        if problem:
            self._warn(problem, key=which + problem.split(':')[-1])
        if not self.started and all(v is not None for v in self.last_cmd.values()):
            self.started = True
            self.wall0 = self._steady_s()

    def _warn(self, msg: str, key: str, period_s: float = 2.0) -> None:
        """Warn at most once per period for each kind of problem (not per call site)."""
        now = self._steady_s()
        if now - self._warned.get(key, -math.inf) >= period_s:
            self._warned[key] = now
            self.get_logger().warn(msg)

    # ---- simulation ---------------------------------------------------------------------
    def _tick(self) -> None:
        now = self._steady_s()
        if not self.started:
            return
        rtf = self.p['real_time_factor']
        if rtf > 0:
            n = int((now - self.wall0) * rtf / self.sim.dt + 1e-9) - self.sim.steps
            behind_s = n * self.sim.dt / rtf  # wall time worth of steps still to do
            if behind_s > 1.0:  # stalled (e.g. the machine paused us): resynchronise
                self._warn(f'fell {behind_s:.1f} s behind real time: resynchronising',
                           key='behind', period_s=10.0)
                self.wall0 += behind_s - 1.0 / self.p['rate_hz']
                n = int((now - self.wall0) * rtf / self.sim.dt + 1e-9) - self.sim.steps
        else:  # free running: spend most of each tick stepping
            n = 0
            deadline = time.perf_counter() + 0.8 / self.p['rate_hz']
            while time.perf_counter() < deadline and self._advance(50):
                pass
        if n > 0 and not self._advance(n):
            return
        if now - self._stale_checked > 1.0:
            self._stale_checked = now
            self._check_stale(now)
        t = self.stamp0 + self.sim.t
        msg = odometry_from_state(self.sim.observed(), t, msg=self._odom)
        self.odom_pub.publish(msg)
        if self.clock_pub is not None:
            self._clock_msg.clock = msg.header.stamp
            self.clock_pub.publish(self._clock_msg)

    def _advance(self, n: int) -> bool:
        if self.sim.step(n):
            return True
        self.get_logger().error(f'simulation stopped at t = {self.sim.t:.1f} s: '
                                f'{self.sim.status}; reset to the initial state')
        self.sim.reset()
        self._restart_clock()
        return False

    def _check_stale(self, now: float) -> None:
        limit = self.p['command_timeout_s']
        for which, t in self.last_cmd.items():
            if t is not None and now - t > limit:
                self._warn(f'no {which} command for {now - t:.0f} s: holding the last value',
                           key='stale ' + which, period_s=10.0)

    # ---- services and parameters --------------------------------------------------------
    def _on_reset(self, request, response):
        self.sim.reset()
        self._restart_clock()
        response.success, response.message = True, 'reset to the initial state'
        return response

    def _validate(self, params) -> SetParametersResult:
        trial = dict(self.p)
        trial.update({p.name: p.value for p in params})
        if {p.name for p in params} & {'odom_topic', 'rudder_topic', 'rpm_topic',
                                       'publish_clock', 'rate_hz'}:
            return SetParametersResult(successful=False,
                                       reason='topics, clock and rate are fixed at start-up')
        if {p.name for p in params} & RESTART_PARAMS:
            try:
                self._build(trial)
            except (MmgTunerError, KeyError, TypeError, ValueError) as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply(self, params) -> None:
        self.p.update({p.name: p.value for p in params})
        if {p.name for p in params} & RESTART_PARAMS:
            self.sim = self._build(self.p)
            self._restart_clock()
            self.get_logger().info(f'applied {[p.name for p in params]}: restarted '
                                   f'{self.sim.ship.name}')


def main(args=None) -> None:
    spin_node(SimNode, args)


if __name__ == '__main__':
    main()
