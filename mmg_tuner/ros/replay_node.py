"""
``replay_node``: plays a recorded trial through the model beside the recording.

Publishes /clock (trial time), the recorded commands (rudder, rpm and any thrusters; a
twin-azimuth craft's shaft speeds and azimuth angles on ``/thrusters/<name>/thrust`` and
``.../pos``) on the topic map's topics in its message types, units and signs (as the
recording had them), the recorded odometry on ``recorded/odom`` and the model's odometry
on ``model/odom`` (relative names; the topic map's ``replay`` section renames them), at
``speed`` x real time; logs the error summary at the end; optionally writes everything to an
MCAP that Foxglove opens, with the recorded odometry on the map's odometry topic (``/odom``:
``inspect`` reads the measurement from it) and the model's on ``/model/odom``.

    ros2 run mmg_tuner replay_node --ros-args -p trial:=trials/zigzag_p20 -p speed:=10.0
"""
from __future__ import annotations

from dataclasses import replace
import os
from pathlib import Path
import shutil
import tempfile
from typing import Any, Mapping

from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.bag import write_replay_bag
from mmg_tuner.data.consistency import rpm_unit_warning
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import (load_topic_map, per_channel_actuators, THRUSTER_ROLES,
                                   TopicMap)
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import MmgTunerError, OutputError
from mmg_tuner.learn.model import load_model
from mmg_tuner.learn.residual import simulate_hybrid
from mmg_tuner.ros.conversions import odometry_from_state, stamp_from_seconds
from mmg_tuner.ros.run import declare_parameters, Param, spin_node
from nav_msgs.msg import Odometry
import numpy as np
# (ClockType is rclpy.clock_type's in this rclpy, imported by rclpy.clock without re-export;
# an older rclpy defines it in rclpy.clock)
from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float32, Float64

ACK_TIMEOUT_S = 2.0   # at most this long per publisher for its last samples to be delivered

# All read once at start-up: none can change while the node runs.
PARAMS = {
    'trial': Param('', 'recorded trial: rosbag2 dir, .mcap, .csv or .dat', read_only=True),
    'trial_index': Param(0, 'which trial when the recording holds several', (0, 1_000_000),
                         read_only=True),
    'topics': Param('', 'topic map YAML for the recording', read_only=True),
    'dt': Param(1.0, 'resampling step of the recording [s]', (1e-3, 60.0), read_only=True),
    'ship': Param('suzaku', 'ship config name or YAML path', read_only=True),
    'params_file': Param('', 'tuned params.yaml', read_only=True),
    'integrator': Param('rk4', 'integration method', read_only=True,
                        constraints='euler or rk4'),
    'speed': Param(1.0, 'replay speed factor', (0.01, 1000.0), read_only=True),
    'output_mcap': Param('', 'write recorded + simulated odometry and commands to this new '
                         'rosbag2 MCAP directory (empty: none); an existing path is refused, '
                         'never overwritten', read_only=True),
    'exit_at_end': Param(True, 'shut down after the last sample', read_only=True),
    'wait_for_subscribers': Param(False, 'hold the first sample until every command topic has '
                                  'a subscriber (nothing is lost to a late viewer or logger)',
                                  read_only=True),
}


def error_summary(recorded: np.ndarray, simulated: np.ndarray) -> dict[str, float]:
    d = np.hypot(simulated[:, 0] - recorded[:, 0], simulated[:, 1] - recorded[:, 1])
    dpsi = (simulated[:, 2] - recorded[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return {'position_rms_m': float(np.sqrt(np.nanmean(d ** 2))),
            'position_final_m': float(d[-1]),
            'heading_rms_deg': float(np.degrees(np.sqrt(np.nanmean(dpsi ** 2)))),
            'speed_rms_ms': float(np.sqrt(np.nanmean((simulated[:, 3] - recorded[:, 3]) ** 2)))}


def check_new_output(path: str) -> Path:
    """
    Return the output_mcap path, refused if anything exists there.

    The output_mcap path, refused (like ``ros2 bag record -o``) if anything exists there and
    checked writable before any work starts.
    """
    out = Path(path).expanduser()
    if os.path.lexists(out):
        kind = 'folder' if out.is_dir() else 'file'
        raise OutputError(f'output_mcap {out} is an existing {kind}; nothing is overwritten: '
                          'choose a new path')
    parent = out.parent
    if not parent.is_dir():
        raise OutputError(f'output_mcap {out}: folder {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f'output_mcap {out}: cannot write in {parent}')
    return out


def write_new_bag(trial: Trial, sim_states: np.ndarray, out: Path, tm: TopicMap | None = None
                  ) -> None:
    """
    Write the replay bag beside ``out`` and move it into place when complete.

    Write the replay bag into a private temporary folder beside ``out`` and move it into place only
    when complete (the path is checked again just before the move).
    """
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f'.{out.name}.'))
    try:
        staged = tmp / out.name  # rosbag2 names its file after the folder
        write_replay_bag(trial, sim_states, staged, model_topic=(
            tm or TopicMap()).replay_model_odom_topic)
        if os.path.lexists(out):
            raise OutputError(f'output_mcap {out} appeared while writing; nothing is '
                              f'overwritten: choose a new path')
        os.rename(staged, out)
    except OSError as exc:
        raise OutputError(f'output_mcap {out}: writing failed ({exc.strerror or exc}); '
                          'nothing was written') from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # our own temporary folder, created above


class CommandPublisher:
    """
    Publish the recorded commands as the topic map describes the recording.

    Rudder [rad, MMG sign], rpm and, when the trial has them, the bow and stern thrusters
    [rev/s, + to starboard], each on its topic, in its message type (Float64, Float32 or
    JointState with its joint: rudder as position, shaft speeds as velocity, one message per
    shared topic), unit and sign. A trial of a craft commanded per thruster (``channels``:
    those of the map's n_port, n_stbd, azimuth_port, ... it has) publishes those instead of
    rudder and rpm (angles as a JointState's position).
    """

    SCALARS = {'std_msgs/msg/Float64': Float64, 'std_msgs/msg/Float32': Float32}
    JOINT = 'sensor_msgs/msg/JointState'

    def __init__(self, node: Node, tm: TopicMap, thrusters: bool = False,
                 channels: tuple[str, ...] = ()) -> None:
        # role -> (topic, type, joint, scale from the model's unit to the map's unit and sign)
        def role(name: str, topic: str) -> tuple[str, str, str, float]:
            c = tm.channel(name)
            return topic, c.msgtype, c.joint, 1.0 / tm.factor(name)

        self.roles = {r: role(r, tm.topic(r)) for r in ('rudder', 'rpm')} if not channels else {}
        for r in channels:   # a channel with no topic in the map ('') is not published
            if tm.topic(r):
                self.roles[r] = role(r, tm.topic(r))
        if thrusters:
            for r in THRUSTER_ROLES:
                self.roles[r] = role(r, tm.topic(r) or TABLE[r].topic)
        types: dict[str, tuple[str, str]] = {}  # topic -> (type, the first role on it)
        for which, (topic, typ, _, _) in self.roles.items():
            if topic in types and types[topic][0] != typ:
                other, first = types[topic]
                raise MmgTunerError(f'topic map: {first} and {which} share topic {topic} with '
                                    f'different types {other} and {typ}')
            types.setdefault(topic, (typ, which))
        self.pubs = {topic: node.create_publisher(
            JointState if typ == self.JOINT else self.SCALARS[typ], topic, 10)
            for topic, (typ, _) in types.items()}

    def subscribed(self) -> bool:
        """Whether every command topic has at least one matched subscription."""
        return all(pub.get_subscription_count() > 0 for pub in self.pubs.values())

    def publish(self, inputs: Mapping[str, float], stamp: Any) -> None:   # stamp: a Time
        """
        Publish one sample.

        inputs: the trial's input channels at this sample, by name (rpm, rudder [rad], bow and
        stern thrusters [rev/s], ...); a role whose channel the trial lacks publishes 0.
        """
        values = inputs
        joints: dict[str, JointState] = {}
        for role, (topic, typ, joint, scale) in self.roles.items():
            v = float(values.get(role, 0.0) * scale)
            if typ != self.JOINT:
                self.pubs[topic].publish(self.SCALARS[typ](data=v))
                continue
            msg = joints.setdefault(topic, JointState())
            msg.header.stamp = stamp
            msg.name.append(joint)
            # an angle (rudder, azimuth) is the joint position, a shaft's speed its velocity
            angle = role in TABLE and TABLE[role].unit == 'rad'
            msg.position.append(v if angle else float('nan'))
            msg.velocity.append(float('nan') if angle else v)
        for topic, msg in joints.items():
            self.pubs[topic].publish(msg)


class ReplayNode(Node):
    def __init__(self) -> None:
        super().__init__('replay_node')
        p = declare_parameters(self, PARAMS)
        if not p['trial']:
            raise MmgTunerError('parameter "trial" is empty: give a recording to replay')
        out = check_new_output(p['output_mcap']) if p['output_mcap'] else None
        tm = replace(load_topic_map(p['topics'] or None), dt=float(p['dt']))
        trials = load_trials(p['trial'], tm)
        if not 0 <= p['trial_index'] < len(trials):
            raise MmgTunerError(f"{p['trial']}: trial_index {p['trial_index']} out of range "
                                f'(it holds {len(trials)} trial(s))')
        self.trial = trials[p['trial_index']]
        model = load_model(p['ship'], p['params_file'] or None)
        ship = model.ship
        unit = rpm_unit_warning(self.trial, ship)   # rpm logged as rev/s: the ship's balance
        if unit:
            self.get_logger().warn(f'{self.trial.name}: {unit}')
        if model.residual is not None:   # the params file names a network: run the hybrid
            sim = simulate_hybrid(ship, model.residual, self.trial, integrator=p['integrator'],
                                  restart_every_s=0.0)   # from the recorded first state
        else:
            sim = simulate(ship, self.trial.states[0], self.trial, self.trial.dt,
                           p['integrator'], check=False)
        if not sim.ok:
            self.get_logger().warn(f'the model stopped at t = {sim.fail_time_s:.1f} s: '
                                   f'{sim.status}')
        self.sim_states = sim.states
        self.summary = error_summary(self.trial.states, self.sim_states)
        if out is not None:
            write_new_bag(self.trial, self.sim_states, out, tm)
            self.get_logger().info(f'wrote {out} (open it in Foxglove)')
        self.speed = float(p['speed'])
        self.exit_at_end = bool(p['exit_at_end'])
        self.pub_odom = self.create_publisher(Odometry, tm.replay_model_odom_topic, 10)
        self.pub_rec = self.create_publisher(Odometry, tm.replay_recorded_odom_topic, 10)
        self.pub_cmd = CommandPublisher(self, tm, self.trial.thrusters is not None, tuple(
            r for ins in per_channel_actuators(self.trial.inputs).values() for r in ins
            if r in self.trial.inputs))
        self.inputs = self.trial.inputs   # channel name -> values
        self.pub_clock = self.create_publisher(ClockMsg, '/clock', 10)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.wall0: float | None = None  # steady time of the first sample [s]; None: not started
        self.wait_for_subscribers = bool(p['wait_for_subscribers'])
        self.k = 0
        self.done = False
        period = max(0.005, min(0.1, self.trial.dt / self.speed))
        self.create_timer(period, self._tick, clock=self.steady)
        wait = ', once every command topic has a subscriber' if self.wait_for_subscribers else ''
        self.get_logger().info(f'replaying {self.trial.name} ({len(self.trial)} samples, '
                               f'{self.trial.duration_s:.0f} s) at {self.speed:g}x{wait}')

    def _tick(self) -> None:
        now = self.steady.now().nanoseconds * 1e-9
        if self.wall0 is None:
            if self.wait_for_subscribers and not self.pub_cmd.subscribed():
                return
            self.wall0 = now
        elapsed = (now - self.wall0) * self.speed
        tr = self.trial
        while self.k < len(tr) and tr.t[self.k] - tr.t[0] <= elapsed:
            t = float(tr.t[self.k] - tr.t[0])
            stamp = stamp_from_seconds(t)
            self.pub_clock.publish(ClockMsg(clock=stamp))
            self.pub_cmd.publish({n: v[self.k] for n, v in self.inputs.items()}, stamp)
            self.pub_rec.publish(odometry_from_state(tr.states[self.k], t))
            if np.all(np.isfinite(self.sim_states[self.k])):
                self.pub_odom.publish(odometry_from_state(self.sim_states[self.k], t))
            self.k += 1
        if self.k >= len(tr) and not self.done:
            self.done = True
            s = self.summary
            self.get_logger().info(
                f"replay finished: position error rms {s['position_rms_m']:.2f} m, final "
                f"{s['position_final_m']:.2f} m; heading rms {s['heading_rms_deg']:.2f} deg; "
                f"speed rms {s['speed_rms_ms']:.3f} m/s")
            if self.exit_at_end:
                # the last samples may still sit in the publishers' queues: deliver them to
                # the reliable subscribers before exiting (a loaded machine once lost the
                # last thrust command of a bag's replay when the process left first)
                for pub in [*self.pub_cmd.pubs.values(), self.pub_clock, self.pub_rec,
                            self.pub_odom]:
                    pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
                raise SystemExit(0)


def main(args: list[str] | None = None) -> None:
    spin_node(ReplayNode, args)


if __name__ == '__main__':
    main()
