"""
sim_node says when it is not being driven (issue 43.6): no command ever arrives -> WARN.

One node process on a private graph (ros_harness); nothing is published to it. The staleness
rule itself: test/data/test_units_and_spikes.py (pure, no ROS).
"""
import pytest

rclpy = pytest.importorskip('rclpy')
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402, I100
from ros_harness import ros_graph, running, spin_until  # noqa: E402


@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    yield from ros_graph(tmp_path_factory, 'idle_driver', (201, 230), 43)


def test_commands_never_received_is_a_warn(ros):
    env, node, ex = ros
    got = []
    sub = node.create_subscription(DiagnosticArray, '/diagnostics', got.append, 50)
    name = '/idle/sim_node'

    def status():
        for arr in reversed(got):
            for s in arr.status:
                if s.name == f'{name}: commands':
                    return s
        return None

    # a wrong topic name: the node listens, nobody publishes there
    with running('sim_node', env, '-r', '__ns:=/idle',
                 params=('rudder_topic:=rudder_typo', 'command_stale_s:=1.0',
                         'command_timeout_s:=2.0')) as proc:
        assert spin_until(ex, lambda: status() is not None and status().level ==
                          DiagnosticStatus.WARN and 'never received' in status().message
                          and 'cannot zero' in proc.output, 120), proc.output
    node.destroy_subscription(sub)
    s = status()
    kv = {v.key: v.value for v in s.values}
    assert 'rudder never received' in s.message and 'rpm never received' in s.message
    assert kv['rudder age [s]'] == 'never received' and kv['rudder stale'] == 'True'
    out = proc.output
    # logged once per channel, naming the topic listened on; SUZAKU's rpm cannot be zeroed
    assert out.count('no rudder command received') == 1 and 'rudder_typo' in out, out
    assert 'holding 106 rpm' in out and 'Traceback' not in out, out
