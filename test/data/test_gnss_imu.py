"""
Recordings as a real ship makes them.

NavSatFix + Imu (+ TwistStamped, heading topics), frames checked, time bases (header/receive,
/clock, GPS-time offsets), topics found by type, and a command/state time offset detected (issue
13, "Recordings in").
"""
from dataclasses import replace
import math

from mmg_tuner.core.geodesy import Datum
from mmg_tuner.data.assemble import command_lag_s, local_poly_fit
from mmg_tuner.data.bag import write_sensor_bag, write_trial_bag
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import topic_map_from_dict, TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, TrialDataError
import numpy as np
import pytest

DATUM = Datum(34.6, 135.4, 40.0)
LEVER = (12.0, -1.5)  # antenna forward of midship, to starboard [m] (FLU)
GIVEN = {'gnss': {'datum_lat_deg': DATUM.lat_deg, 'datum_lon_deg': DATUM.lon_deg,
                  'datum_alt_m': DATUM.alt_m, 'lever_x_m': LEVER[0], 'lever_y_m': LEVER[1]}}


@pytest.fixture(scope='module')
def noisy(suzaku):
    """(truth, measured) 10 Hz noisy zigzag: the case central differences split."""
    return generate_trial(suzaku, 'zigzag', 20, None, 106, 3.086, 300, 10.0, SensorNoise(), 7,
                          'zz')


def _map(**sections):
    doc = {k: dict(v) for k, v in GIVEN.items()}
    for k, v in sections.items():
        doc.setdefault(k, {}).update(v)
    return topic_map_from_dict(doc)


def _states_at(truth: Trial, t):
    return np.column_stack([np.interp(t, truth.t, truth.states[:, i]) for i in range(6)])


def test_navsatfix_imu_bag_gives_the_odometry_trial(tmp_path, noisy):
    truth, meas = noisy
    write_trial_bag(meas, tmp_path / 'odom')
    write_sensor_bag(meas, tmp_path / 'gnss', DATUM, lever_arm_m=LEVER)
    (a,) = load_trials(tmp_path / 'odom')
    (b,) = load_trials(tmp_path / 'gnss', _map())  # one trial: not split by noisy velocities
    np.testing.assert_allclose(b.t, a.t)
    # pose and yaw rate are the same samples: equal to well within the noise
    np.testing.assert_allclose(b.states[:, :3], a.states[:, :3], atol=1e-3)
    np.testing.assert_allclose(b['r'], a['r'], atol=1e-9)
    # u, v derived from 0.5 m GNSS noise by the smoother: as close to the truth as the
    # recorded 0.02 m/s velocities are (within a factor 2), bias-free
    ref = _states_at(truth, a.t)
    for col in (3, 4):
        err_a = np.std(a.states[:, col] - ref[:, col])
        err_b = b.states[:, col] - ref[:, col]
        assert np.std(err_b) < 2.0 * err_a + 0.01 and abs(np.mean(err_b)) < 0.01
    assert any('local linear least-squares fit over 10 s' in n for n in b.notes)
    # without the lever arm the track is the antenna's: off by up to the lever arm
    (c,) = load_trials(tmp_path / 'gnss', topic_map_from_dict({'gnss': {
        k: v for k, v in GIVEN['gnss'].items() if 'datum' in k}}))
    off = np.hypot(c['x'] - a['x'], c['y'] - a['y'])
    assert np.allclose(off, math.hypot(*LEVER), atol=0.01)


def test_no_topic_map_reads_one_navsatfix_and_one_imu(tmp_path, noisy):
    _, meas = noisy
    write_sensor_bag(meas, tmp_path / 'gnss', DATUM)
    (a,) = load_trials(tmp_path / 'gnss')  # no map: found by type, datum = the first fix
    text = ' '.join(a.notes)
    assert 'pose source: /fix (NavSatFix)' in text and 'first fix' in text
    assert '/imu/data' in text and 'r = -omega_z' in text
    # a first-fix datum moves the origin only: the same track as the configured datum
    (b,) = load_trials(tmp_path / 'gnss', _map(gnss={'lever_x_m': 0.0, 'lever_y_m': 0.0}))
    d = a.states[:, :2] - b.states[:, :2]
    assert np.ptp(d[:, 0]) < 1e-3 and np.ptp(d[:, 1]) < 1e-3
    np.testing.assert_allclose(a.states[0, :2], 0.0, atol=1e-3)  # origin: the first fix


def test_ambiguous_topics_list_the_candidates(tmp_path, noisy):
    from mmg_tuner.data.bag import TYPESTORE, NAVSATFIX
    from rosbags.rosbag2 import Writer
    _, meas = noisy
    short = meas.slice(0, 30)
    write_sensor_bag(short, tmp_path / 'one', DATUM)
    (f,) = (tmp_path / 'one').glob('*.mcap')
    # a second GNSS receiver: which one is the pose? An error naming both, never a guess
    from rosbags.rosbag2 import Reader
    with Reader(tmp_path / 'one') as r, Writer(tmp_path / 'two', version=9) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=TYPESTORE)
                 for c in r.connections}
        extra = w.add_connection('/gnss2/fix', NAVSATFIX, typestore=TYPESTORE)
        for c, ts, raw in r.messages():
            w.write(conns[c.id], ts, raw)
            if c.topic == '/fix':
                w.write(extra, ts, raw)
    with pytest.raises(TrialDataError, match=r'pose source is ambiguous.*/fix .*NavSatFix.*'
                                             r'/gnss2/fix .*odom\.topic'):
        load_trials(tmp_path / 'two')
    # naming one in the map settles it
    (tr,) = load_trials(tmp_path / 'two', topic_map_from_dict(
        {'odom': {'topic': '/gnss2/fix', 'type': 'sensor_msgs/msg/NavSatFix'}}))
    assert any('/gnss2/fix' in n for n in tr.notes)


@pytest.mark.parametrize('frame', ['map', 'base_link', 'ship2/base_link'])
def test_twist_is_read_in_its_frame(tmp_path, noisy, frame):
    """
    nmea_navsat_driver's /vel is the antenna's ENU velocity.

    Taken as body surge it read u 0.0-2.0 m/s where the truth was 0.8-3.2. Its frame_id decides how
    it is read.
    """
    truth, meas = noisy
    write_sensor_bag(truth.slice(0, 200), tmp_path / 'b', DATUM, lever_arm_m=LEVER,
                     twist_frame=frame)
    (tr,) = load_trials(tmp_path / 'b', _map())
    ref = _states_at(truth, tr.t)
    np.testing.assert_allclose(tr['u'], ref[:, 3], atol=1e-6)
    np.testing.assert_allclose(tr['v'], ref[:, 4], atol=1e-6)
    kind = 'earth' if frame == 'map' else 'body'
    assert any(f'/vel (TwistStamped in {kind} frame' in n for n in tr.notes)


def test_unknown_or_contradictory_frames_are_errors(tmp_path, noisy):
    _, meas = noisy
    short = meas.slice(0, 30)
    write_sensor_bag(short, tmp_path / 'unknown', DATUM, twist_frame='gps_vel')
    with pytest.raises(TrialDataError, match=r"topic /vel: frame_id 'gps_vel' is not a known "
                                             r'frame.*frames.earth or frames.body'):
        load_trials(tmp_path / 'unknown')
    # ... unless the map says what it is
    (tr,) = load_trials(tmp_path / 'unknown', topic_map_from_dict(
        {'frames': {'earth': ['map', 'gps_vel']}}))
    assert any('earth frame gps_vel' in n for n in tr.notes)
    write_sensor_bag(short, tmp_path / 'imu_in_map', DATUM, imu_frame='map')
    with pytest.raises(TrialDataError, match=r"topic /imu/data: frame_id 'map' is an earth.*"
                                             r'must be a body frame'):
        load_trials(tmp_path / 'imu_in_map')
    write_sensor_bag(short, tmp_path / 'fix_in_odom', DATUM, gnss_frame='odom')
    with pytest.raises(TrialDataError, match=r"topic /fix: frame_id 'odom' is an earth"):
        load_trials(tmp_path / 'fix_in_odom')


def test_odometry_child_frame_is_checked(tmp_path, noisy, monkeypatch):
    import mmg_tuner.data.bag as bag
    real = bag.odometry_msg

    def in_map(state, stamp):
        m = real(state, stamp)
        m.child_frame_id = 'map'
        return m
    monkeypatch.setattr(bag, 'odometry_msg', in_map)
    write_trial_bag(noisy[1].slice(0, 30), tmp_path / 'b')
    with pytest.raises(TrialDataError, match=r"topic /odom: child_frame_id 'map' is an earth"):
        load_trials(tmp_path / 'b')


def test_heading_from_quaternion_or_compass_number(tmp_path, noisy):
    truth, _ = noisy
    tr0 = truth.slice(0, 120)
    write_sensor_bag(tr0, tmp_path / 'q', DATUM, heading='quaternion')
    (q,) = load_trials(tmp_path / 'q')  # Imu without orientation: the one QuaternionStamped
    np.testing.assert_allclose(q['psi'], tr0.states[::10, 2], atol=1e-9)
    write_sensor_bag(tr0, tmp_path / 'deg', DATUM, heading='north_deg')
    # a plain number needs its unit and convention stated; the Imu has no orientation
    with pytest.raises(TrialDataError, match=r'/imu/data: orientation is not given.*'
                                             r'heading.topic'):
        load_trials(tmp_path / 'deg')
    tm = topic_map_from_dict({'heading': {'topic': '/heading', 'type': 'std_msgs/msg/Float64',
                                          'unit': 'deg', 'convention': 'north_cw'}})
    (d,) = load_trials(tmp_path / 'deg', tm)
    np.testing.assert_allclose(np.unwrap(d['psi']), tr0.states[::10, 2], atol=1e-9)
    assert any('[deg, north_cw]' in n for n in d.notes)


def test_simulated_time_reads_like_wall_time(tmp_path, noisy):
    """
    A simulation's stamps count from 0 on /clock while rosbag2 records wall-clock receive times.

    The header-less commands are mapped onto the simulated clock.
    """
    _, meas = noisy
    tr0 = meas.slice(0, 120)
    write_sensor_bag(tr0, tmp_path / 'wall', DATUM)
    write_sensor_bag(tr0, tmp_path / 'sim', DATUM, sim_time=True)
    (a,) = load_trials(tmp_path / 'wall', _map())
    (b,) = load_trials(tmp_path / 'sim', _map())
    np.testing.assert_allclose(b.states, a.states, atol=1e-6)
    np.testing.assert_allclose(b.controls, a.controls, atol=1e-9)
    assert any('through /clock' in n for n in b.notes)
    # without /clock: mapped by a linear fit of the pose's stamps to its receive times
    write_sensor_bag(tr0, tmp_path / 'noclock', DATUM, sim_time=True, write_clock=False)
    (c,) = load_trials(tmp_path / 'noclock', _map())
    np.testing.assert_allclose(c.states, a.states, atol=1e-6)
    np.testing.assert_allclose(c.controls, a.controls, atol=1e-9)
    assert any('no /clock' in n and 'linear fit' in n for n in c.notes)


def test_gps_time_offset_is_refused_and_correctable(tmp_path, noisy):
    _, meas = noisy
    tr0 = meas.slice(0, 120)
    write_sensor_bag(tr0, tmp_path / 'ok', DATUM)
    write_sensor_bag(tr0, tmp_path / 'gps', DATUM, state_stamp_offset_s=18.0)
    with pytest.raises(TrialDataError, match=r'topic /(fix|imu/data) header.stamp runs '
                                             r'\+18.000 s.*two clocks.*offset_s: -18.000'):
        load_trials(tmp_path / 'gps')
    (a,) = load_trials(tmp_path / 'ok', _map())
    (b,) = load_trials(tmp_path / 'gps', _map(odom={'offset_s': -18.0},
                                              imu={'offset_s': -18.0}))
    np.testing.assert_allclose(b.states, a.states, atol=1e-6)
    # or time everything by receive time
    (c,) = load_trials(tmp_path / 'gps', _map(odom={'stamp': 'receive'},
                                              imu={'stamp': 'receive'}))
    np.testing.assert_allclose(c.states, a.states, atol=1e-6)


def test_command_offset_is_detected_and_inspect_shows_the_reading(tmp_path, suzaku, capsys):
    from mmg_tuner.cli.inspect import command as inspect
    truth, meas = generate_trial(suzaku, 'zigzag', 10, None, 106, 3.086, 400, 2.0,
                                 SensorNoise(), 3, 'zz')
    good = command_lag_s(meas)
    assert good is not None and abs(good[0]) < 2.5 and good[1] > 0.8
    shifted = Trial(meas.t, meas.states, np.column_stack(
        [np.interp(meas.t + 20.0, meas.t, meas.controls[:, i]) for i in range(2)]), 'late')
    lag, fit = command_lag_s(shifted)  # commands stamped 20 s early: the motion follows late
    assert abs(lag - 20.0) < 3.0 and fit > 0.8
    write_sensor_bag(shifted, tmp_path / 'late', DATUM)
    assert inspect([str(tmp_path / 'late')]) == 0
    out = capsys.readouterr().out
    for what in ('read as:', 'pose source: /fix (NavSatFix)', 'datum', 'first fix',
                 'frames: /fix gps, /imu/data imu_link', 'time bases: /fix header.stamp',
                 '/rudder_angle receive time', 'beyond time.max_lag_s'):
        assert what in out, what
    write_sensor_bag(meas, tmp_path / 'ok', DATUM)
    assert inspect([str(tmp_path / 'ok')]) == 0
    out = capsys.readouterr().out
    # a lag within max_lag_s is no finding (it used to read 'follows the rudder by ...')
    assert 'beyond time.max_lag_s' not in out and 'follows the rudder' not in out
    assert 'commands and motion agree within time.max_lag_s' in out


@pytest.mark.parametrize('seed', [0, 2])
def test_a_turn_put_over_at_the_start_claims_no_command_offset(tmp_path, suzaku, seed):
    """
    A clean 200 s turn with the helm put over at t = 0 has no lag to find.

    The fit window moved with the lag, dropping the yaw transient at large lags, so such a trial
    "followed the rudder by +18.1 s" and was reported as a suspected clock offset.
    """
    from mmg_tuner.data.csv_io import write_trial_csv
    _, meas = generate_trial(suzaku, 'turning', 35, None, 106.0, 3.086, 200.0, 2.0,
                             SensorNoise(), seed, 'tp')
    write_trial_csv(meas, tmp_path / 'tp.csv')
    (tr,) = load_trials(tmp_path / 'tp.csv')
    assert command_lag_s(tr) is None
    assert not any('max_lag_s' in n for n in tr.notes), tr.notes


def test_local_poly_fit_is_exact_for_quadratics_and_smooths_noise():
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 100, 800))  # irregular stamps
    y = 3.0 + 0.5 * t - 0.01 * t ** 2
    val, der = local_poly_fit(t, y, 10.0)
    np.testing.assert_allclose(val, y, atol=1e-8)
    np.testing.assert_allclose(der, 0.5 - 0.02 * t, atol=1e-8)
    noisy = y + rng.normal(0, 0.5, t.size)
    _, d = local_poly_fit(t, noisy, 10.0)
    assert np.std(d - (0.5 - 0.02 * t)) < 0.1  # central differences: ~ 0.5 * sqrt(2) / 0.125


def test_topic_map_refuses_what_it_cannot_read():
    for doc, what in (({'heading': {'unit': 'grad'}}, 'heading.unit'),
                      ({'heading': {'convention': 'south'}}, 'heading.convention'),
                      ({'imu': {'type': 'sensor_msgs/msg/NavSatFix'}}, 'imu.type'),
                      ({'odom': {'stamp': 'gps'}}, 'odom.stamp'),
                      ({'gnss': {'datum_lat_deg': 35.0}}, 'go together'),
                      ({'gnss': {'datum_lat_deg': 95.0, 'datum_lon_deg': 0.0,
                                 'datum_alt_m': 0.0}}, 'lat_deg'),
                      ({'frames': {'earth': 'map'}}, 'list of frame_id'),
                      ({'frames': {'body': ['map']}}, 'both earth and body')):
        with pytest.raises(ConfigError, match=what):
            topic_map_from_dict(doc)
    tm = topic_map_from_dict({'odom': {'type': 'sensor_msgs/msg/NavSatFix'}})
    assert 'odom_type' in tm.given and 'odom_topic' not in tm.given
    assert replace(TopicMap(), dt=2.0).given == frozenset()


def test_tuning_on_either_recording_gives_the_same_parameters(tmp_path, suzaku):
    """
    Odometry and NavSatFix + Imu bags of the same trials tune to the same parameters.

    Must hold: a bag with Odometry and one with NavSatFix + Imu of the same trials tune to the same
    parameters within noise (small budget: a smoke-size run, both sides alike).
    """
    import mmg_tuner.api as mt
    pairs = [generate_trial(suzaku, m, d, None, 106, 3.086, 200, 5.0, SensorNoise(), s, n)[1]
             for m, d, s, n in (('zigzag', 20, 1, 'z20'), ('turning', 35, 2, 't35'))]
    for tr in pairs:
        write_trial_bag(tr, tmp_path / 'odom' / tr.name)
        write_sensor_bag(tr, tmp_path / 'gnss' / tr.name, DATUM)
    a = load_trials(tmp_path / 'odom')
    b = load_trials(tmp_path / 'gnss')
    targets = ('N_r', 'Y_v')
    fa = mt.tune(suzaku, a, targets=targets, max_evals=600, seed=1)
    fb = mt.tune(suzaku, b, targets=targets, max_evals=600, seed=1)
    # measured over 4 noise seeds (Odometry bags alone): N_r -0.0549..-0.0566, Y_v
    # -0.29..-0.40 (sway hardly identifiable from x, y, psi); GNSS - Odometry differences were
    # <= 0.0007 and <= 0.047. Tolerances: 4x and 2x those.
    assert fb.params['N_r'] == pytest.approx(fa.params['N_r'], abs=0.003)
    assert fb.params['Y_v'] == pytest.approx(fa.params['Y_v'], abs=0.1)
    assert fa.params['N_r'] == pytest.approx(suzaku['N_r'], rel=0.1)  # both near the truth
