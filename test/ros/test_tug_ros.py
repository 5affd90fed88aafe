"""
The twin-azimuth tug everywhere else: the stepper, bags of its thruster topics and the nodes.

The stepper and bag tests need no ROS; the node tests run sim_node and replay_node as
processes on a private graph (test/ros/ros_harness.py) and are skipped without rclpy.
"""
import math

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate
from mmg_tuner.core.stepper import ShipSimulator
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import topic_map_from_dict, TopicMap
from mmg_tuner.errors import TrialDataError
import numpy as np
import pytest

DT = 0.2   # the paper's 5 Hz
AZ = math.radians(20.0)


def _commands(T: int, n: float, az_cmd: float, az0: float = 0.0) -> dict[str, np.ndarray]:
    """Held commands as simulate takes them: the thrusters start at az0 and turn to az_cmd."""
    return {'n_port': np.full(T, n), 'n_stbd': np.full(T, n),
            'azimuth_port': np.full(T, az0), 'azimuth_stbd': np.full(T, az0),
            'azimuth_cmd_port': np.full(T, az_cmd), 'azimuth_cmd_stbd': np.full(T, az_cmd)}


def _azimuth_step(t: np.ndarray, target: float, k1: float, k2: float):
    """
    Return (angle, rate) of alpha'' = k1 (target - alpha) - k2 alpha' from rest at 0.

    The textbook underdamped step response (wn = sqrt(k1), zeta = k2 / (2 wn)): an
    independent reference for the actuator's exact per-step integration.
    """
    wn = math.sqrt(k1)
    zeta = k2 / (2 * wn)
    wd = wn * math.sqrt(1 - zeta ** 2)
    e = np.exp(-zeta * wn * t)
    angle = target * (1 - e * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t)))
    rate = target * wn / math.sqrt(1 - zeta ** 2) * e * np.sin(wd * t)
    return angle, rate


def _assert_same_state(got, want, atol: float = 1e-6) -> None:
    """Compare model states, the heading modulo a turn (odometry carries a wrapped yaw)."""
    d = np.asarray(got, dtype=float) - np.asarray(want, dtype=float)
    d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
    np.testing.assert_allclose(d, np.zeros(6), rtol=0, atol=atol)


@pytest.fixture(scope='module')
def tug():
    return load_ship('qiuxin_tug')


def test_stepper_drives_the_tug_as_simulate(tug):
    """
    Per-channel commands, changed mid-run, reproduce simulate with the same history.

    The azimuth angles carry over between steps (a second-order drive), so a stepper that
    restarted them per call, or applied the command at once, would drift from simulate.
    """
    sim = ShipSimulator(tug, dt=DT, x0=[0, 0, 0, 0.0, 0, 0])
    assert sim.command_channels == ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
    T1, T2 = 76, 75   # 15 s straight ahead, then 15 s with the azimuths at 20 deg
    for ch in ('n_port', 'n_stbd'):
        assert sim.set_command(ch, 7.0) == ''
    for _ in range(T1 - 1):   # one step per call: the states must carry over
        assert sim.step(1)
    for ch in ('azimuth_port', 'azimuth_stbd'):
        assert sim.set_command(ch, AZ) == ''
    assert sim.step(T2)
    cmd = _commands(T1 + T2, 7.0, 0.0)
    for side in ('port', 'stbd'):
        cmd[f'azimuth_cmd_{side}'][T1 - 1:] = AZ   # sample k's command acts over k -> k + 1
    offline = simulate(tug, [0, 0, 0, 0.0, 0, 0], cmd, DT, 'rk4')
    np.testing.assert_allclose(sim.observed(), offline.states[-1], rtol=0, atol=1e-9)
    assert offline.states[-1, 5] < -0.05   # azimuths + 20 deg turn the tug to port
    t = DT * np.arange(T2 + 1)
    angle, rate = _azimuth_step(t, AZ, tug['azimuth_k1'], tug['azimuth_k2'])
    act = sim.actuator_states()
    assert act['alpha_port'] == pytest.approx(angle[-1], abs=1e-9)
    assert act['alpha_rate_stbd'] == pytest.approx(rate[-1], abs=1e-9)


def test_tug_commands_are_clipped_to_the_yaml_limits_with_a_diagnostic(tug):
    sim = ShipSimulator(tug, dt=DT, x0=[0, 0, 0, 0.0, 0, 0])
    problem = sim.set_command('azimuth_port', math.radians(60))   # steering: +-45 deg
    assert 'clamped' in problem and 'max_azimuth_deg' in problem and '60.0 deg' in problem
    assert sim.commands['azimuth_port'] == pytest.approx(math.radians(45))
    problem = sim.set_command('n_stbd', -15.0)   # steering.max_thruster_rps: 12
    assert 'clamped' in problem and 'max_thruster_rps' in problem
    assert sim.commands['n_stbd'] == -12.0
    problem = sim.set_command('n_stbd', 200.0)   # rpm read as rev/s: ignored, value held
    assert 'ignored' in problem and sim.commands['n_stbd'] == -12.0
    assert 'not finite' in sim.set_command('azimuth_stbd', math.nan)
    with pytest.raises(ValueError, match='rudder.*n_port, n_stbd'):
        sim.set_command('rudder', 0.1)
    # the clamped command is what acts: the angle settles at 45 deg, not 60
    sim.step(150)
    assert sim.actuator_states()['alpha_port'] == pytest.approx(math.radians(45), abs=1e-4)


@pytest.fixture(scope='module')
def tug_csv(tmp_path_factory):
    """Return a tug trial CSV from generate (a +-20 deg azimuth zigzag at 7 rev/s, 40 s)."""
    from mmg_tuner.cli.generate import command as generate
    out = tmp_path_factory.mktemp('tug_twin')
    assert generate(['--ship', 'qiuxin_tug', '--out', str(out), '--only',
                     'zigzag_p20deg_7rps', '--duration', '40']) == 0
    return out / 'csv' / 'zigzag_p20deg_7rps.csv'


def test_tug_bag_round_trip(tug_csv, tmp_path):
    """A bag of odometry and the four VRX-style thruster topics reads back as the trial."""
    (trial,) = load_trials(tug_csv)
    write_trial_bag(trial, tmp_path / 'bag')
    from rosbags.highlevel import AnyReader
    with AnyReader([tmp_path / 'bag']) as r:
        topics = {c.topic: c.msgtype for c in r.connections}
    assert topics == {'/odom': 'nav_msgs/msg/Odometry',
                      **{f'/thrusters/{s}/{k}': 'std_msgs/msg/Float64'
                         for s in ('port', 'stbd') for k in ('thrust', 'pos')}}
    (back,) = load_trials(tmp_path / 'bag', TopicMap(dt=trial.dt))
    assert set(back.inputs) == {'n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd'}
    assert len(back) == len(trial)
    for ch in back.inputs:
        np.testing.assert_allclose(back[ch], trial[ch], rtol=0, atol=1e-9, err_msg=ch)
    np.testing.assert_allclose(back.states, trial.states, rtol=0, atol=1e-9)
    # the tug's model sails it from the bag as from the CSV (azimuths measured: no command)
    ship = load_ship('qiuxin_tug')
    a = simulate(ship, back.states[0], back, back.dt, 'rk4', check=False)
    b = simulate(ship, trial.states[0], {c: trial[c] for c in back.inputs}, trial.dt, 'rk4',
                 check=False)
    np.testing.assert_allclose(a.states, b.states, rtol=0, atol=1e-6)


def test_tug_bag_without_a_thruster_topic_names_it(tug_csv, tmp_path):
    (trial,) = load_trials(tug_csv)
    write_trial_bag(trial, tmp_path / 'bag',
                    tm=topic_map_from_dict({'azimuth_stbd': {'topic': ''}}))
    with pytest.raises(TrialDataError) as exc:
        load_trials(tmp_path / 'bag', TopicMap(dt=trial.dt))
    msg = str(exc.value)
    assert '/thrusters/stbd/pos' in msg and "channel 'azimuth_stbd'" in msg, msg


# ---- the nodes (ROS) ---------------------------------------------------------------------

@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    pytest.importorskip('rclpy')
    from ros_harness import ros_graph
    yield from ros_graph(tmp_path_factory, 'tug_driver', (101, 160), 24)


def test_sim_node_drives_the_tug_from_thruster_commands(ros, tug):
    """
    VRX-style thruster topics drive the tug as simulate predicts; JointState the azimuths.

    Both thrusters at 7 rev/s and 20 deg from rest: the odometry matches the offline run of
    the same commands, and the published azimuth angle and rate follow the second-order
    step response of the YAML's drive (k1 = 4, k2 = 3.6), not the command at once.
    """
    from mmg_tuner.ros.conversions import seconds_from_stamp, state_from_odometry
    from nav_msgs.msg import Odometry
    from ros_harness import spin_until, start, stop
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    env, node, ex = ros
    odom, joints = [], []
    subs = [node.create_subscription(Odometry, '/tug/odom', odom.append, 100),
            node.create_subscription(JointState, '/tug/joint_states', joints.append, 100)]
    cmd = {f'/tug/thrusters/{s}/thrust': 7.0 for s in ('port', 'stbd')}
    cmd.update({f'/tug/thrusters/{s}/pos': AZ for s in ('port', 'stbd')})
    pubs = {t: node.create_publisher(Float64, t, 10) for t in cmd}

    def commanding():
        for t, v in cmd.items():
            pubs[t].publish(Float64(data=v))
        return bool(odom) and seconds_from_stamp(odom[-1].header.stamp) >= 30.0

    proc = start('sim_node', env, 'ship:=qiuxin_tug', 'initial_speed:=0.0', 'dt:=0.2',
                 'publish_clock:=true', 'wait_for_commands:=true', 'real_time_factor:=5.0',
                 ros_args=('-r', '__ns:=/tug'))
    try:
        assert spin_until(ex, commanding, 240.0), f'no odometry; node said:\n{stop(proc)}'
    finally:
        for s in subs:
            node.destroy_subscription(s)
        out = stop(proc)
    assert 'Traceback' not in out, out
    assert 'n_port on thrusters/port/thrust clamped to +-12 rev/s' in out, out
    T = 151
    offline = simulate(tug, [0, 0, 0, 0.0, 0, 0], _commands(T, 7.0, AZ), DT, 'rk4')
    checked = 0
    for m in odom:
        k = int(round(seconds_from_stamp(m.header.stamp) / DT))
        if 0 < k < T:
            _assert_same_state(state_from_odometry(m), offline.states[k])
            checked += 1
    assert checked > 30   # of 150: one message per timer tick, fewer on a loaded machine
    assert offline.states[-1, 5] < -0.05 and odom[-1].twist.twist.angular.z > 0.05  # to port
    # JointState: both azimuths, the second-order step response at the odometry's stamps
    assert joints and list(joints[-1].name) == ['port_azimuth_joint', 'stbd_azimuth_joint']
    t = np.array([seconds_from_stamp(m.header.stamp) for m in joints])
    pos = np.array([list(m.position) for m in joints])
    vel = np.array([list(m.velocity) for m in joints])
    angle, rate = _azimuth_step(t, AZ, tug['azimuth_k1'], tug['azimuth_k2'])
    np.testing.assert_allclose(pos, np.column_stack([angle, angle]), atol=1e-9)
    np.testing.assert_allclose(vel, np.column_stack([rate, rate]), atol=1e-9)
    early = (t > 0) & (t < 2.0)   # 95 % of the way at 2 s: moving there, not jumped
    assert early.any() and np.all(pos[early] < 0.96 * AZ)
    assert abs(pos[-1, 0] - AZ) < 1e-3


@pytest.mark.parametrize('kind', ['csv', 'bag'])
def test_replay_node_plays_a_tug_recording(ros, tug_csv, tmp_path, kind):
    """The replay node plays a tug CSV and bag: the model's odometry on model/odom."""
    from mmg_tuner.ros.conversions import seconds_from_stamp, state_from_odometry
    from nav_msgs.msg import Odometry
    from ros_harness import spin_until, start, stop
    from std_msgs.msg import Float64
    env, node, ex = ros
    (trial,) = load_trials(tug_csv)
    path = tug_csv
    if kind == 'bag':
        path = tmp_path / 'bag'
        write_trial_bag(trial, path)
        (trial,) = load_trials(path, TopicMap(dt=trial.dt))
    sim = []
    topics = {'n_port': '/thrusters/port/thrust', 'n_stbd': '/thrusters/stbd/thrust',
              'azimuth_port': '/thrusters/port/pos', 'azimuth_stbd': '/thrusters/stbd/pos'}
    cmd = {ch: [] for ch in topics}   # wait_for_subscribers: every command topic is heard
    subs = [node.create_subscription(Odometry, '/model/odom', sim.append, 300)] + [
        node.create_subscription(Float64, t, cmd[ch].append, 300) for ch, t in topics.items()]
    proc = start('replay_node', env, f'trial:={path}', 'ship:=qiuxin_tug', 'dt:=0.2',
                 'speed:=20.0', 'wait_for_subscribers:=true')

    def last_heard() -> bool:   # every channel's last recorded sample has arrived
        return all(v and abs(v[-1].data - trial[ch][-1]) <= 1e-12 for ch, v in cmd.items())
    try:
        spin_until(ex, lambda: proc.poll() is not None, 240.0)
        # the node's last messages may still be in flight when it exits (a loaded machine
        # once had the last thrust of the bag's run missing): take them, within a few seconds
        spin_until(ex, last_heard, 5.0)
    finally:
        for s in subs:
            node.destroy_subscription(s)
        log = stop(proc)
    assert proc.returncode == 0, log
    assert 'replay finished: position error rms' in log, log
    offline = simulate(load_ship('qiuxin_tug'), trial.states[0], trial, trial.dt, 'rk4',
                       check=False)
    assert len(sim) > 100 and all(len(v) > 100 for v in cmd.values())
    for m in sim:
        k = int(round(seconds_from_stamp(m.header.stamp) / trial.dt))
        _assert_same_state(state_from_odometry(m), offline.states[k])
    for ch, msgs in cmd.items():   # the recorded channels, in the map's units (rev/s, rad)
        np.testing.assert_allclose(msgs[-1].data, trial[ch][-1], atol=1e-12, err_msg=ch)


def test_command_topics_come_from_the_actuator_and_the_parameter_overrides_them():
    pytest.importorskip('rclpy')
    from mmg_tuner.errors import MmgTunerError
    from mmg_tuner.ros.sim_node import command_topics, declared_joints
    chans = ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
    assert command_topics(chans, '') == {
        'n_port': 'thrusters/port/thrust', 'n_stbd': 'thrusters/stbd/thrust',
        'azimuth_port': 'thrusters/port/pos', 'azimuth_stbd': 'thrusters/stbd/pos'}
    moved = command_topics(chans, 'n_port=/port/rps, azimuth_stbd=stbd/angle')
    assert moved['n_port'] == 'port/rps' and moved['azimuth_stbd'] == 'stbd/angle'
    assert moved['n_stbd'] == 'thrusters/stbd/thrust'
    for bad in ('rudder=x', 'n_port', 'n_port='):
        with pytest.raises(MmgTunerError, match='command_topics'):
            command_topics(chans, bad)
    assert declared_joints(('twin_azimuth',)) == {
        'port_azimuth_joint': ('alpha_port', 'alpha_rate_port'),
        'stbd_azimuth_joint': ('alpha_stbd', 'alpha_rate_stbd')}
    assert declared_joints(('screw_rudder',)) == {}
