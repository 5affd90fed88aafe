"""
ROS details of issue 28: each state published once, REP-105 frames, map -> odom optional.

And the replay's model odometry kept off /odom, where ``inspect`` reads the measurement. The
graph tests start the nodes as processes (ros_harness); the replay bag is checked without ROS.
"""
import math

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.bag import write_replay_bag
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import load_topic_map, topic_map_from_dict
import numpy as np
import pytest


@pytest.fixture(scope='module')
def replayed(tmp_path_factory):
    ship = load_ship('suzaku')
    _, tr = generate_trial(ship, 'zigzag', 20, None, 106.0, 3.086, 120.0, 1.0, SensorNoise(), 1,
                           'zz')
    sim = simulate(ship, tr.states[0], tr.controls, tr.dt, 'rk4', check=False)
    path = tmp_path_factory.mktemp('replay') / 'replay'
    write_replay_bag(tr, sim.states, path)
    return tr, sim, path


def test_the_replay_bag_holds_the_measurement_on_odom_and_the_model_elsewhere(replayed):
    tr, sim, path = replayed
    (read,) = load_trials(path)   # what inspect and tune read: the recording, not the model
    np.testing.assert_allclose(read.states, tr.states, atol=1e-6)
    (model,) = load_trials(path, topic_map_from_dict({'odom': {'topic': '/model/odom'}}))
    np.testing.assert_allclose(model.states, sim.states, atol=1e-6)


def test_the_topic_map_names_the_replay_topics():
    tm = load_topic_map(None)
    assert tm.replay_model_odom_topic == 'model/odom'
    assert tm.replay_recorded_odom_topic == 'recorded/odom'
    from pathlib import Path
    shipped = load_topic_map(Path(__file__).resolve().parents[2] / 'config' / 'topics.yaml')
    assert shipped.replay_model_odom_topic.strip('/') != shipped.odom_topic.strip('/')


def test_a_model_topic_on_odom_is_refused(replayed, tmp_path):
    from mmg_tuner.errors import OutputError
    tr, sim, _ = replayed
    with pytest.raises(OutputError, match='/odom holds the recorded odometry'):
        write_replay_bag(tr, sim.states, tmp_path / 'r', model_topic='/odom')


# ------------------------------------------------------------------------- on a ROS graph
@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    pytest.importorskip('rclpy')
    from ros_harness import ros_graph
    yield from ros_graph(tmp_path_factory, 'test_details', (101, 200), 3)


def test_sim_node_publishes_each_state_once_in_the_odom_frame(ros):
    from mmg_tuner.ros.conversions import seconds_from_stamp
    from nav_msgs.msg import Odometry
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from ros_harness import spin_until, start, stop
    from tf2_msgs.msg import TFMessage
    env, node, ex = ros
    got, tf, static = [], [], []
    node.create_subscription(Odometry, '/once/odom', got.append, 100)
    node.create_subscription(TFMessage, '/tf', tf.append, 100)
    node.create_subscription(TFMessage, '/tf_static', static.append, QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    # 50 Hz timer, a state every 0.1 s: 4 of 5 ticks hold no new state
    proc = start('sim_node', env, 'rate_hz:=50.0', 'dt:=0.1', 'real_time_factor:=1.0',
                 'odom_topic:=/once/odom', 'publish_map_to_odom:=false')
    try:
        ok = spin_until(ex, lambda: len(got) >= 20, 90.0)
        spin_until(ex, lambda: False, 1.0)   # a static transform, were there one, by now
    finally:
        log = stop(proc)
    assert ok, log
    stamps = [seconds_from_stamp(m.header.stamp) for m in got]
    assert len(set(stamps)) == len(stamps), 'repeated stamps'
    assert np.all(np.diff(stamps) > 0)
    assert np.median(np.diff(stamps)) == pytest.approx(0.1, abs=1e-6)
    assert all(m.header.frame_id == 'odom' and m.child_frame_id == 'base_link' for m in got)
    tf_stamps = [seconds_from_stamp(m.transforms[0].header.stamp) for m in tf
                 if m.transforms and m.transforms[0].child_frame_id == 'base_link']
    assert tf_stamps and len(set(tf_stamps)) == len(tf_stamps)
    assert not any(t.child_frame_id == 'odom' for m in static for t in m.transforms)


def test_sim_node_publishes_map_to_odom_by_default(ros):
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from ros_harness import spin_until, start, stop
    from tf2_msgs.msg import TFMessage
    env, node, ex = ros
    static = []
    node.create_subscription(TFMessage, '/tf_static', static.append, QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    proc = start('sim_node', env, 'odom_topic:=/dflt/odom')
    try:
        ok = spin_until(ex, lambda: any(t.child_frame_id == 'odom' for m in static
                                        for t in m.transforms), 90.0)
    finally:
        log = stop(proc)
    assert ok, log
    (t,) = [t for m in static for t in m.transforms if t.child_frame_id == 'odom']
    assert t.header.frame_id == 'map' and math.isclose(t.transform.rotation.w, 1.0)


def test_the_dt_parameter_says_a_change_restarts_the_run():
    pytest.importorskip('rclpy')
    from mmg_tuner.ros.sim_node import PARAMS, RESTART_PARAMS
    assert 'dt' in RESTART_PARAMS and 'restarts the run' in PARAMS['dt'].description
