"""
sim_node serves a vessel that is new files only: the toy water-jet plugin (test/core/toy_plugin).

The plugin's actuator declares its channels' topics (jet/thrust, jet/angle) and its nozzle as a
joint; the node subscribes one topic per channel in its namespace and publishes the joint, with
no edit under mmg_tuner/. The node's odometry follows the offline simulation of the same
commands.
"""
from pathlib import Path
import sys

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'core'))
from ros_harness import ros_graph, spin_until, start, stop  # noqa: E402, I100
from toy_plugin import toy_plugin_env, TOY_SHIP_YAML  # noqa: E402


@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    yield from ros_graph(tmp_path_factory, 'toy_driver', (231, 232), 46)


def test_sim_node_serves_the_toy_water_jet_on_its_declared_topics(ros, tmp_path):
    from mmg_tuner.ros.conversions import seconds_from_stamp
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    env, node, ex = ros
    plugin = toy_plugin_env(tmp_path)
    env = {**env, **plugin,
           'PYTHONPATH': plugin['PYTHONPATH'] + ':' + env.get('PYTHONPATH', '')}
    ship = tmp_path / 'toy.yaml'
    ship.write_text(TOY_SHIP_YAML)
    odom = []
    sub = node.create_subscription(Odometry, '/toy/odom', odom.append, 100)
    joints = []
    jsub = node.create_subscription(JointState, '/toy/joint_states', joints.append, 100)
    pubs = {t: node.create_publisher(Float64, f'/toy/jet/{t}', 10) for t in ('thrust', 'angle')}

    def commanding():
        pubs['thrust'].publish(Float64(data=4000.0))
        pubs['angle'].publish(Float64(data=0.0))
        return bool(odom) and seconds_from_stamp(odom[-1].header.stamp) >= 20.0

    proc = start('sim_node', env, f'ship:={ship}', 'initial_speed:=0.0', 'dt:=0.1',
                 'publish_clock:=true', 'wait_for_commands:=true', 'real_time_factor:=10.0',
                 ros_args=('-r', '__ns:=/toy'))
    try:
        assert spin_until(ex, commanding, 240.0), f'no odometry; node said:\n{stop(proc)}'
    finally:
        node.destroy_subscription(sub)
        node.destroy_subscription(jsub)
        out = stop(proc)
    assert 'Traceback' not in out, out
    # the nozzle the toy declares as a joint (JOINTS), its angle with the odometry
    assert joints and list(joints[-1].name) == ['nozzle_joint'], (joints[-1:], out)
    assert joints[-1].position[0] == pytest.approx(0.0, abs=1e-9)
    assert np.isnan(joints[-1].velocity[0])
    # thrust 4000 N against X_u = 2000 N s/m: u -> 2 (1 - exp(-t m / X_u)), m / X_u = 10 s
    t = seconds_from_stamp(odom[-1].header.stamp)
    u = odom[-1].twist.twist.linear.x
    assert u == pytest.approx(2.0 * (1.0 - np.exp(-t / 10.0)), abs=0.02), (t, u, out)
