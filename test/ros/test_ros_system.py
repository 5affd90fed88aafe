"""
The simulator as a citizen of a ROS system (issue 13).

Namespaces and frames, TF, simulated GNSS and IMU, /diagnostics, the replay node's topic-map units;
plus the pure pieces (message builders, health levels) without ROS processes. Geodesy:
test_geodesy.py.

Every node process is started by ``running`` and always stopped (SIGINT, then kill) however
the test ends, so a failure never leaves a node burning CPU.
"""
import math
from pathlib import Path

from mmg_tuner.core.geodesy import Datum, geodetic_to_enu
import numpy as np
import pytest


# ---- message builders and health (rclpy messages, no processes) ---------------------------
rclpy = pytest.importorskip('rclpy')
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402, I100
from mmg_tuner.core.ship import load_ship  # noqa: E402
from mmg_tuner.core.simulate import simulate  # noqa: E402
from mmg_tuner.ros.conversions import (imu_from_state, odometry_from_state,  # noqa: E402
                                       seconds_from_stamp, transform_from_state,
                                       yaw_from_quaternion)
from mmg_tuner.ros.health import CommandHealth, Health  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from ros_harness import ros_graph, running, spin_until  # noqa: E402
from sensor_msgs.msg import Imu, JointState, NavSatFix  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

try:
    from tf2_msgs.msg import TFMessage
except ImportError:  # built by scripts/install.sh; a ROS install has it
    TFMessage = None


def test_transform_is_the_odometry_pose():
    """TF odom -> base_link carries the same pose as the odometry (ENU position, yaw)."""
    state = np.array([120.0, -40.0, math.radians(30.0), 3.0, 0.2, 0.01])  # model frame
    tf = transform_from_state(state, 12.5, 'ship2/odom', 'ship2/base_link')
    odom = odometry_from_state(state, 12.5, 'map', 'ship2/base_link')
    assert (tf.header.frame_id, tf.child_frame_id) == ('ship2/odom', 'ship2/base_link')
    assert seconds_from_stamp(tf.header.stamp) == pytest.approx(12.5)
    # north 120 m, east -40 m -> ENU (x east, y north); heading 30 deg from north -> yaw 60 deg
    assert (tf.transform.translation.x, tf.transform.translation.y) == (-40.0, 120.0)
    assert math.degrees(yaw_from_quaternion(tf.transform.rotation)) == pytest.approx(60.0)
    assert tf.transform.translation.x == odom.pose.pose.position.x
    assert tf.transform.rotation.z == odom.pose.pose.orientation.z


def test_imu_message_signs_and_missing_acceleration():
    state = np.array([0.0, 0.0, 0.0, 3.0, 0.0, 0.02])  # heading north, turning to starboard
    m = imu_from_state(state, None, 1.0, 'base_link')
    assert math.degrees(yaw_from_quaternion(m.orientation)) == pytest.approx(90.0)
    assert m.angular_velocity.z == pytest.approx(-0.02)  # starboard turn: clockwise in ENU
    assert m.linear_acceleration_covariance[0] == -1.0  # "not available" (first sample)
    m = imu_from_state(state, (0.1, -0.06), 1.1, 'base_link', msg=m)
    assert m.linear_acceleration_covariance[0] > 0 and m.linear_acceleration.y == -0.06
    assert m.linear_acceleration.z == pytest.approx(9.80665)


def test_health_levels():
    h = Health('/ship2/sim_node', 'suzaku', commands={'rudder': CommandHealth('rad', 0.0),
                                                      'rpm': CommandHealth('rpm', 106.0)})

    def status(now):
        arr = h.array(now, Odometry().header.stamp, 10.0, 1.0)
        return {s.name.split(': ')[1]: s for s in arr.status}

    assert all(s.level == DiagnosticStatus.OK for s in status(0.0).values())
    h.command('rudder', 0.7854, 'rudder command 60 deg beyond the 45 deg limit: clamped', 1.0)
    s = status(1.5)['commands']
    assert s.level == DiagnosticStatus.WARN and 'rudder clamped' in s.message
    h.command('rudder', None, 'rudder command: rudder nan is not finite: ignored', 2.0)
    s = status(2.5)['commands']
    assert s.level == DiagnosticStatus.ERROR and 'rudder rejected' in s.message
    kv = {v.key: v.value for v in s.values}
    assert kv['rudder rejected (total)'] == '1' and kv['rudder clamped (total)'] == '1'
    assert kv['rudder [rad]'] == '0.7854' and kv['rpm age [s]'] == 'never received'
    # staleness is a state: one transition each way, then nothing more to log
    assert h.update_stale('rudder', 3.5, 1.0) == 'stale'
    assert h.update_stale('rudder', 9.0, 1.0) == ''
    s = status(9.0)['commands']
    assert s.level == DiagnosticStatus.WARN and s.message == 'rudder stale'
    h.reset('at t = 3.00 s: diverged', 9.0)
    assert status(9.5)['model'].level == DiagnosticStatus.ERROR
    assert status(20.0)['model'].level == DiagnosticStatus.OK  # held HOLD_S, then clear
    h.rtf_requested, h.rtf_achieved = 10.0, 4.0
    assert status(20.0)['real time'].level == DiagnosticStatus.WARN


def test_health_of_thruster_commands():
    """
    Report thrusters as optional commands.

    Not waited for; on a ship without them a refused command is one WARN state 'unsupported'
    with a count (never stale, never an ERROR).
    """
    def status(h, now):
        arr = h.array(now, Odometry().header.stamp, 10.0, 1.0)
        return {s.name.split(': ')[1]: s for s in arr.status}['commands']

    for supported in (True, False):
        h = Health('/sim_node', 'ship', commands={
            'rudder': CommandHealth('rad', 0.0), 'rpm': CommandHealth('rpm', 106.0),
            'bow_thruster': CommandHealth('rev/s', 0.0, required=False, supported=supported)})
        h.command('rudder', 0.1, '', 0.0)
        h.command('rpm', 100.0, '', 0.0)
        assert h.ready()  # the thruster is not required to start
        kv = {v.key: v.value for v in status(h, 0.5).values}
        assert ('bow_thruster [rev/s]' in kv) == supported
    for k in range(30):  # a stream of refused thruster commands on a ship without them
        h.command('bow_thruster', None, 'bow_thruster command: no thrusters: ignored', 1.0 + k)
    s = status(h, 31.0)
    kv = {v.key: v.value for v in s.values}
    assert s.level == DiagnosticStatus.WARN and s.message == 'bow_thruster unsupported'
    assert kv['bow_thruster ignored (total)'] == '30'
    assert h.update_stale('bow_thruster', 100.0, 1.0) == ''
    assert 'bow_thruster' not in status(h, 100.0).message  # it stopped coming: no state


def test_misspelt_parameter_is_named_not_dropped_and_ranges_read_in_full():
    """
    A -p value no declared parameter takes is logged with the likely intended name.

    rclpy drops it silently, so ``-p intial_speed:=5.0`` ran the node at the default speed.
    """
    from mmg_tuner.errors import ConfigError
    from mmg_tuner.ros.run import declare_parameters, Param, unknown_overrides
    specs = {'initial_speed': Param(3.0, 'initial surge speed [m/s]', (0.0, 10.0)),
             'noise_seed': Param(0, 'seed', (0, 2 ** 31 - 1))}
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, args=[])
    try:
        node = rclpy.create_node('typo_node', context=ctx, cli_args=[
            '--ros-args', '-p', 'intial_speed:=5.0', '-p', 'use_sim_time:=false'])
        logged = []
        node.get_logger().warn = logged.append
        p = declare_parameters(node, specs)
        assert p['initial_speed'] == 3.0
        assert unknown_overrides(node) == ['intial_speed']  # use_sim_time is the node's own
        assert len(logged) == 1 and 'intial_speed' in logged[0], logged
        assert 'did you mean initial_speed?' in logged[0]
        node.destroy_node()
        node = rclpy.create_node('seed_node', context=ctx,
                                 cli_args=['--ros-args', '-p', 'noise_seed:=-3'])
        with pytest.raises(ConfigError, match=r'outside \[0, 2147483647\]'):
            declare_parameters(node, specs)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


def test_replay_publishes_recorded_thrusters_in_the_maps_units():
    """Publish a recording's thrusters as its topic map describes them (topic, unit, sign)."""
    from mmg_tuner.data.topics import topic_map_from_dict
    from mmg_tuner.ros.replay_node import CommandPublisher

    class Node:  # stands in for rclpy's: collects what each topic's publisher sends
        sent: dict = {}

        def create_publisher(self, msgtype, topic, depth):
            box = self.sent.setdefault(topic, [])
            return type('Pub', (), {'publish': staticmethod(box.append)})()

    tm = topic_map_from_dict({'bow_thruster': {'topic': '/bt', 'unit': 'rpm', 'sign': -1},
                              'stern_thruster': {'topic': '/st'}})
    node = Node()
    pub = CommandPublisher(node, tm, thrusters=True)
    pub.publish({'rpm': 100.0, 'rudder': 0.1, 'bow_thruster': 5.0, 'stern_thruster': -3.0},
                None)
    assert node.sent['/bt'][0].data == pytest.approx(-300.0)  # 5 rev/s, as rpm to port
    assert node.sent['/st'][0].data == pytest.approx(-3.0)
    assert node.sent['/propeller_rpm'][0].data == pytest.approx(100.0)
    node.sent.clear()
    CommandPublisher(node, tm).publish({'rpm': 100.0, 'rudder': 0.1}, None)  # without them
    assert set(node.sent) == {'/rudder_angle', '/propeller_rpm'}


# ---- node processes -----------------------------------------------------------------------
@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    yield from ros_graph(tmp_path_factory, 'test_system_driver', (101, 200), 13)


def collect(node, msgtype, topic, qos=50):
    got = []
    sub = node.create_subscription(msgtype, topic, got.append, qos)
    return got, sub


TF_STATIC_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_two_ships_in_two_namespaces_follow_their_own_commands(ros, tmp_path):
    """
    -r __ns:=/shipN.

    Own topics, own frames (shipN/odom, shipN/base_link), own commands; config/sim_node.yaml
    applies in a namespace too (its node key used to match only /sim_node, so sim.launch.py
    namespace:=ship2 silently ran on defaults).
    """
    env, node, ex = ros
    cfg = Path(__file__).resolve().parents[2] / 'config' / 'sim_node.yaml'
    ship2_cfg = tmp_path / 'sim_node.yaml'
    ship2_cfg.write_text(cfg.read_text().replace('frame_id: map ', 'frame_id: world '))
    common = ('wait_for_commands:=true', 'real_time_factor:=40.0', 'initial_speed:=3.0',
              'imu_rate_hz:=2.0')
    rudder = {'ship1': 0.35, 'ship2': -0.35}  # + starboard (MMG sign), - port
    odom, imu, subs, pubs = {}, {}, [], []
    for ns in rudder:
        odom[ns], s1 = collect(node, Odometry, f'/{ns}/odom')
        imu[ns], s2 = collect(node, Imu, f'/{ns}/imu/data')
        subs += [s1, s2]
        pubs.append((node.create_publisher(Float64, f'/{ns}/rudder_angle', 10),
                     node.create_publisher(Float64, f'/{ns}/propeller_rpm', 10), rudder[ns]))
    tf, s3 = collect(node, TFMessage, '/tf') if TFMessage else ([], None)
    tf_static, s4 = collect(node, TFMessage, '/tf_static', TF_STATIC_QOS) if TFMessage \
        else ([], None)

    def command():
        for rud, rpm, value in pubs:
            rud.publish(Float64(data=value))
            rpm.publish(Float64(data=106.0))

    def far_enough():  # 120 s simulated: well into the steady turn
        return all(o and seconds_from_stamp(o[-1].header.stamp) - seconds_from_stamp(
            o[0].header.stamp) > 120.0 for o in odom.values())

    with running('sim_node', env, '-r', '__ns:=/ship1', params=common) as p1, \
            running('sim_node', env, '-r', '__ns:=/ship2', '--params-file', str(ship2_cfg),
                    params=common) as p2:
        assert spin_until(ex, far_enough, 40.0, every=command), p1.output + p2.output
    for s in subs + [s3, s4]:
        if s is not None:
            node.destroy_subscription(s)
    for ns, sign in (('ship1', -1), ('ship2', 1)):
        last = odom[ns][-1]
        # REP-105: odometry in the ship's odom frame; the world frame is map -> odom's parent
        assert last.header.frame_id == f'{ns}/odom' and last.child_frame_id == f'{ns}/base_link'
        # starboard turn: clockwise in ENU, angular.z < 0; port: > 0
        assert sign * last.twist.twist.angular.z > 0, ns
        yaw = np.unwrap([yaw_from_quaternion(m.pose.pose.orientation) for m in odom[ns]])
        assert sign * (yaw[-1] - yaw[0]) > math.radians(30), ns
        # the IMU feels the centripetal acceleration towards the turn: -y (starboard) for a
        # starboard turn in FLU; its first sample has no acceleration yet (covariance -1)
        assert imu[ns][0].linear_acceleration_covariance[0] == -1.0
        ay = [m.linear_acceleration.y for m in imu[ns][len(imu[ns]) // 2:]]
        assert ay and sign * np.mean(ay) > 0.005, (ns, ay)
        assert all(m.header.frame_id == f'{ns}/base_link' for m in imu[ns])
    if TFMessage is None:
        pytest.skip('tf2_msgs not installed (scripts/install.sh builds it): TF not checked')
    pairs = {(t.header.frame_id, t.child_frame_id) for m in tf for t in m.transforms}
    assert {('ship1/odom', 'ship1/base_link'), ('ship2/odom', 'ship2/base_link')} <= pairs
    static = {(t.header.frame_id, t.child_frame_id): t for m in tf_static for t in m.transforms}
    assert {('map', 'ship1/odom'), ('world', 'ship2/odom')} <= set(static)
    assert all(t.transform.rotation.w == 1.0 and t.transform.translation.x == 0.0
               for t in static.values())
    # TF carries the odometry's pose (published in the same tick, with the same stamp)
    pose = {(o.header.stamp.sec, o.header.stamp.nanosec): o.pose.pose for o in odom['ship1']}
    matched = 0
    for t in (t for m in tf for t in m.transforms if t.child_frame_id == 'ship1/base_link'):
        p = pose.get((t.header.stamp.sec, t.header.stamp.nanosec))
        if p is not None:
            matched += 1
            assert (p.position.x, p.position.y, p.orientation.z) == (
                t.transform.translation.x, t.transform.translation.y, t.transform.rotation.z)
    assert matched > 10


def test_navsat_fix_maps_back_to_the_simulated_track(ros):
    """
    GNSS about a datum while the ship sails north-east.

    Each fix, mapped back to the local plane with core.geodesy, lies on the offline simulation of
    the same commands within the noise; the IMU heading and yaw rate agree too.
    """
    env, node, ex = ros
    datum = Datum(-33.85, 151.25, 20.0)  # southern and eastern hemisphere: signs matter
    sigma = 0.8
    params = ('publish_clock:=true', 'wait_for_commands:=true', 'real_time_factor:=40.0',
              'initial_yaw:=0.7853981634', 'initial_speed:=3.0', 'gnss_rate_hz:=2.0',
              f'gnss_noise_m:={sigma}', 'gnss_alt_noise_m:=0.5', 'imu_rate_hz:=1.0',
              f'datum_lat_deg:={datum.lat_deg}', f'datum_lon_deg:={datum.lon_deg}',
              f'datum_alt_m:={datum.alt_m}', 'noise_seed:=7', 'odom_topic:=/nav/odom',
              'gnss_topic:=/nav/fix', 'imu_topic:=/nav/imu', 'rudder_topic:=/nav/rudder',
              'rpm_topic:=/nav/rpm')
    fixes, s1 = collect(node, NavSatFix, '/nav/fix')
    imus, s2 = collect(node, Imu, '/nav/imu')
    rud = node.create_publisher(Float64, '/nav/rudder', 10)
    rpm = node.create_publisher(Float64, '/nav/rpm', 10)

    def command():
        rud.publish(Float64(data=0.0))
        rpm.publish(Float64(data=106.0))

    with running('sim_node', env, params=params) as proc:
        assert spin_until(ex, lambda: fixes and seconds_from_stamp(
            fixes[-1].header.stamp) >= 150.0, 40.0, every=command), proc.output
    node.destroy_subscription(s1)
    node.destroy_subscription(s2)
    T = 1501
    sim = simulate(load_ship('suzaku'), [0, 0, math.pi / 4, 3.0, 0, 0],
                   np.tile([106.0, 0.0], (T, 1)), 0.1, 'rk4')
    t = np.array([seconds_from_stamp(f.header.stamp) for f in fixes])
    k = np.round(t / 0.1).astype(int)
    keep = k < T
    assert keep.sum() > 250 and np.allclose(t[keep], k[keep] * 0.1, atol=1e-6)  # on steps
    lat = np.array([f.latitude for f in fixes])[keep]
    lon = np.array([f.longitude for f in fixes])[keep]
    alt = np.array([f.altitude for f in fixes])[keep]
    e, n, u = geodetic_to_enu(lat, lon, alt, datum)
    de, dn = e - sim.states[k[keep], 1], n - sim.states[k[keep], 0]
    # within noise: 5 sigma per sample, and the mean error far below one sigma
    assert np.max(np.abs(de)) < 5 * sigma and np.max(np.abs(dn)) < 5 * sigma
    assert abs(de.mean()) < 0.3 * sigma and abs(dn.mean()) < 0.3 * sigma
    assert 0.5 * sigma < de.std() < 1.5 * sigma  # the noise is there, at its size
    assert np.max(np.abs(u)) < 5 * 0.5  # at the datum's height, within the altitude noise
    # the track really went north-east, hundreds of metres: no trivial agreement
    assert e[-1] > 200 and n[-1] > 200
    assert fixes[0].position_covariance[0] == pytest.approx(sigma ** 2)
    assert fixes[0].status.status == 0  # STATUS_FIX
    for m in imus[1:]:
        kk = int(round(seconds_from_stamp(m.header.stamp) / 0.1))
        if kk < T:
            psi = sim.states[kk, 2]
            dyaw = yaw_from_quaternion(m.orientation) - (math.pi / 2 - psi)
            assert abs((dyaw + math.pi) % (2 * math.pi) - math.pi) < 5 * 0.005
            assert abs(m.angular_velocity.z + sim.states[kk, 5]) < 5 * 0.001


def set_param(node, ex, client, name, value):
    if isinstance(value, str):
        pv = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    elif isinstance(value, bool):
        pv = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    elif isinstance(value, int):
        pv = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    else:
        pv = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    fut = client.call_async(SetParameters.Request(parameters=[Parameter(name=name, value=pv)]))
    assert spin_until(ex, fut.done, 20), f'no answer setting {name}'
    return fut.result().results[0]


def commands_status(arrays, node_name):
    for arr in reversed(arrays):
        for s in arr.status:
            if s.name == f'{node_name}: commands':
                return s, {v.key: v.value for v in s.values}
    return None, {}


def test_diagnostics_stale_and_rejected_commands_and_new_parameters(ros):
    """
    /diagnostics reports stale and rejected commands; new parameters apply or refuse.

    /diagnostics: a stale command is one WARN state (logged once, however long it lasts), a
    rejected one an ERROR with its count; every new parameter is applied or refused.
    """
    env, node, ex = ros
    diags, s1 = collect(node, DiagnosticArray, '/diagnostics')
    odom, s2 = collect(node, Odometry, '/diag/odom')
    rud = node.create_publisher(Float64, '/diag/rudder_angle', 10)
    rpm = node.create_publisher(Float64, '/diag/propeller_rpm', 10)
    name = '/diag/sim_node'
    with running('sim_node', env, '-r', '__ns:=/diag',
                 params=('command_stale_s:=1.0', 'real_time_factor:=5.0')) as proc:
        # one command each, then silence: stale after 1 s, and it stays one state
        assert spin_until(ex, lambda: rud.get_subscription_count() > 0 and
                          rpm.get_subscription_count() > 0, 20), proc.output
        rud.publish(Float64(data=0.1))
        rpm.publish(Float64(data=100.0))

        def stale_reports():
            n = 0
            for arr in diags:
                for s in arr.status:
                    kv = {v.key: v.value for v in s.values}
                    if s.name == f'{name}: commands' and kv.get('rudder stale') == 'True':
                        n += 1
            return n

        assert spin_until(ex, lambda: stale_reports() >= 4, 120), proc.output  # cold cache
        s, kv = commands_status(diags, name)
        assert s.level == DiagnosticStatus.WARN and 'rudder stale' in s.message
        assert kv['rudder [rad]'] == '0.1' and kv['rpm [rpm]'] == '100'
        # a rejected command: ERROR with the count; the rudder is no longer stale
        assert spin_until(ex, lambda: commands_status(diags, name)[1].get(
            'rudder rejected (total)', '0') != '0', 10,
            every=lambda: rud.publish(Float64(data=math.nan))), proc.output
        s, kv = commands_status(diags, name)
        assert s.level == DiagnosticStatus.ERROR and 'rudder rejected' in s.message
        assert kv['rudder stale'] == 'False' and kv['rudder [rad]'] == '0.1'
        assert 'not finite' in kv['rudder last problem']
        real_time = [st for st in diags[-1].status if st.name == f'{name}: real time'][0]
        assert float({v.key: v.value for v in real_time.values}[
            'achieved real-time factor']) > 0
        # new parameters: applied (and visible) or refused with a reason
        pcli = node.create_client(SetParameters, f'{name}/set_parameters')
        assert pcli.wait_for_service(timeout_sec=20)
        # (a long timeout from here on: no new stale transition while parameters are set)
        assert set_param(node, ex, pcli, 'command_stale_s', 60.0).successful
        assert set_param(node, ex, pcli, 'frame_prefix', 'red/ship').successful
        odom.clear()
        assert spin_until(ex, lambda: len(odom) > 3, 10, every=lambda: rud.publish(
            Float64(data=math.nan)))
        assert odom[-1].child_frame_id == 'red/ship/base_link'
        for bad, words in ((('frame_prefix', 'red ship'), 'spaces'),
                           (('child_frame_id', 'odom'), 'must differ'),
                           (('odom_frame_id', '/odom'), 'leading'),
                           (('datum_lat_deg', 91.0), ''), (('gnss_noise_m', -1.0), ''),
                           (('gnss_rate_hz', 5.0), 'read-only'),
                           (('publish_tf', False), 'read-only'),
                           (('imu_topic', 'x'), 'read-only')):
            res = set_param(node, ex, pcli, *bad)
            assert not res.successful and res.reason and words in res.reason, (bad, res.reason)
        for ok in (('noise_seed', 3), ('datum_lat_deg', -10.0), ('imu_yaw_noise_rad', 0.01)):
            assert set_param(node, ex, pcli, *ok).successful, ok
    node.destroy_subscription(s1)
    node.destroy_subscription(s2)
    out = proc.output
    # one line per transition, not one every 10 s for as long as it lasts
    assert out.count('no rudder command for') == 1, out
    assert out.count('no rpm command for') == 1, out
    assert 'rudder commands resumed' in out and 'Traceback' not in out
    assert "applied ['frame_prefix']" in out and "applied ['noise_seed']" in out


def test_replay_publishes_commands_in_the_topic_maps_units_and_sign(ros, tmp_path):
    """
    The replay publishes commands in the topic map's units and sign.

    Topic map: rudder in deg with the REP-103 sign on a Float64 topic, rpm as rev/s in a
    JointState: the replay publishes exactly that (it used to publish rad whatever the map).
    """
    from mmg_tuner.data.csv_io import csv_text
    env, node, ex = ros
    dt, T = 1.0, 40
    rudder = np.radians(np.where(np.arange(T) % 20 < 10, 15.0, -10.0))
    controls = np.column_stack([np.full(T, 100.0), rudder])
    sim = simulate(load_ship('suzaku'), [0, 0, 0, 3.0, 0, 0], controls, dt, 'rk4')
    (tmp_path / 'trial.csv').write_text(csv_text(np.arange(T) * dt, sim.states, controls))
    (tmp_path / 'topics.yaml').write_text(
        'rudder: {topic: /replay_test/rudder_deg, unit: deg, sign: -1}\n'
        'rpm: {topic: /replay_test/shaft, type: sensor_msgs/msg/JointState, joint: prop, '
        'unit: rps}\n')
    rud, s1 = collect(node, Float64, '/replay_test/rudder_deg', 100)
    shaft, s2 = collect(node, JointState, '/replay_test/shaft', 100)
    # wait_for_subscribers: at 20x the replay lasts 2 s, less than discovery can take under load
    with running('replay_node', env, params=(f"trial:={tmp_path / 'trial.csv'}",
                                             f"topics:={tmp_path / 'topics.yaml'}",
                                             'speed:=20.0', 'exit_at_end:=false',
                                             'wait_for_subscribers:=true')) as proc:
        # 120 s: a node's first start on a cold numba cache compiles its kernels (~16 s alone)
        assert spin_until(ex, lambda: len(rud) >= T - 5 and len(shaft) >= T - 5, 120), \
            proc.output
    node.destroy_subscription(s1)
    node.destroy_subscription(s2)
    got = np.array([m.data for m in rud])
    # the recording's own unit and sign: deg, positive to port
    assert set(np.round(got, 6)) == {-15.0, 10.0}
    assert all(m.name == ['prop'] and m.velocity[0] == pytest.approx(100.0 / 60.0)
               for m in shaft)
