"""Trials in and out: rosbag2 (sqlite3, MCAP), bare MCAP, CSV; framing, repairs and errors."""
import dataclasses
import math
import shutil

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.data.assemble import assemble_trials, body_velocities_from_poses
from mmg_tuner.data.bag import RawRecording, read_series, Series, write_trial_bag
from mmg_tuner.data.csv_io import read_trial_csv, write_trial_csv
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import topic_map_from_dict, TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, TrialDataError
import numpy as np
import pytest


@pytest.fixture(scope='module')
def zigzag_trial(suzaku):
    tr = mv.run(suzaku, mv.ManeuverSpec('zigzag', rudder_deg=20, duration_s=400, dt=1.0))
    return Trial(tr.t, tr.states, tr.controls, name='zz')


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_round_trip_rosbag2(tmp_path, zigzag_trial, storage):
    bag = tmp_path / 'bag'
    write_trial_bag(zigzag_trial, bag, storage)
    (back,) = load_trials(bag)
    np.testing.assert_allclose(back.t, zigzag_trial.t)
    np.testing.assert_allclose(back.states, zigzag_trial.states, atol=1e-9)
    np.testing.assert_allclose(back.controls, zigzag_trial.controls, atol=1e-12)


def test_bare_mcap_and_csv(tmp_path, zigzag_trial):
    write_trial_bag(zigzag_trial, tmp_path / 'bag', 'mcap')
    (mcap_file,) = (tmp_path / 'bag').glob('*.mcap')
    (back,) = load_trials(mcap_file)
    np.testing.assert_allclose(back.states, zigzag_trial.states, atol=1e-9)
    write_trial_csv(zigzag_trial, tmp_path / 'zz.csv')
    back = read_trial_csv(tmp_path / 'zz.csv')
    np.testing.assert_allclose(back.states, zigzag_trial.states, rtol=1e-9, atol=1e-9)


def test_frames_starboard_turn_is_clockwise_in_enu(tmp_path, suzaku):
    """A starboard turn (MMG r > 0) is a clockwise track in ENU with negative angular.z."""
    tr = mv.run(suzaku, mv.ManeuverSpec('turning', rudder_deg=35, duration_s=120, dt=1.0))
    write_trial_bag(Trial(tr.t, tr.states, tr.controls), tmp_path / 'b', 'mcap')
    rec = read_series(tmp_path / 'b', TopicMap())
    odom = rec.series['odom'].values
    assert odom[-1, 5] < 0                          # angular.z (FLU) negative
    assert np.all(np.diff(np.unwrap(odom[:, 2]))[5:] < 0)  # ENU yaw decreasing = clockwise
    assert odom[-1, 0] > 0                          # moved east (x_map) when heading north-east


def _rec(t_odom, odom_vals, t_cmd, rud, rpm):
    ns = lambda t: (np.asarray(t) * 1e9).astype(np.int64)  # noqa: E731
    series = {
        'odom': Series('/odom', 'nav_msgs/msg/Odometry', ns(t_odom), np.asarray(odom_vals, float),
                       ns(t_odom)),
        'rudder': Series('/rudder_angle', 'std_msgs/msg/Float64', ns(t_cmd),
                         np.asarray(rud, float)[:, None], ns(t_cmd)),
        'rpm': Series('/propeller_rpm', 'std_msgs/msg/Float64', ns(t_cmd),
                      np.asarray(rpm, float)[:, None], ns(t_cmd)),
    }
    return RawRecording('fake.mcap', series, {s.topic: (s.msgtype, len(s.stamps_ns))
                                              for s in series.values()})


def _straight(t):
    t = np.asarray(t, float)
    # heading north in MMG = yaw pi/2 in ENU; moving along y_map at 3 m/s
    return np.column_stack([np.zeros_like(t), 3 * t, np.full_like(t, np.pi / 2),
                            np.full_like(t, 3.0), np.zeros_like(t), np.zeros_like(t)])


def test_repairs_are_documented():
    t = np.arange(0, 100, 0.1)
    odom = _straight(t)
    odom[50, 3] = np.nan
    t_cmd = np.arange(0, 100, 0.5)
    t_cmd_shuffled = t_cmd.copy()
    t_cmd_shuffled[[10, 11]] = t_cmd_shuffled[[11, 10]]
    rec = _rec(t, odom, t_cmd_shuffled, np.zeros_like(t_cmd), np.full_like(t_cmd, 100.0))
    (trial,) = assemble_trials(rec, TopicMap())
    text = ' '.join(trial.notes)
    assert 'dropped 1 non-finite sample(s), first at t = 5.000 s' in text
    assert 'not sorted' in text
    assert trial['x'][-1] == pytest.approx(3 * trial.t[-1], rel=1e-6)  # north in MMG
    assert np.allclose(trial['psi'], 0) and np.allclose(trial['u'], 3.0)


def test_gap_and_reverse_propeller_split_the_trial():
    t = np.arange(0, 200, 0.1)
    t = t[(t < 60) | (t > 80)]  # a 20 s gap in odometry
    t_cmd = np.arange(0, 200, 0.5)
    rpm = np.where((t_cmd > 140) & (t_cmd < 150), -30.0, 100.0)  # astern for 10 s
    trials = assemble_trials(_rec(t, _straight(t), t_cmd, np.zeros_like(t_cmd), rpm),
                             TopicMap(), name='fake')
    assert len(trials) == 3
    notes = ' '.join(trials[0].notes)
    assert 'gap of 20.2 s at t = 59.9 s' in notes
    assert any('rpm <= 0' in n and 'from t = 141.1' in n for n in trials[-1].notes)
    assert [t.name for t in trials] == ['fake_1', 'fake_2', 'fake_3']


def test_missing_topic_names_what_was_found():
    t = np.arange(0, 50, 0.1)
    rec = _rec(t, _straight(t), t, np.zeros_like(t), np.full_like(t, 100.0))
    del rec.series['rpm']
    del rec.topics_found['/propeller_rpm']
    with pytest.raises(TrialDataError, match=r'fake.mcap: topic /propeller_rpm missing.*'
                                             r'/odom \(nav_msgs/msg/Odometry'):
        assemble_trials(rec, TopicMap())


def test_wrong_type_and_corrupt_files(tmp_path, zigzag_trial):
    write_trial_bag(zigzag_trial, tmp_path / 'bag', 'mcap')
    tm = topic_map_from_dict({'odom': {'topic': '/rudder_angle'}, 'rudder': {'topic': '/x'}})
    with pytest.raises(TrialDataError, match='topic /rudder_angle has type std_msgs/msg/Float64,'
                                             ' the topic map expects nav_msgs/msg/Odometry'):
        read_series(tmp_path / 'bag', tm)
    (mcap_file,) = (tmp_path / 'bag').glob('*.mcap')
    data = mcap_file.read_bytes()
    truncated = tmp_path / 'trunc.mcap'
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(TrialDataError, match='trunc.mcap'):
        load_trials(truncated)
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    with pytest.raises(TrialDataError, match='empty.mcap'):
        load_trials(empty)
    garbage = tmp_path / 'garbage.mcap'
    garbage.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(TrialDataError, match='garbage.mcap'):
        load_trials(garbage)
    shutil.copytree(tmp_path / 'bag', tmp_path / 'nometa')
    (tmp_path / 'nometa' / 'metadata.yaml').unlink()
    # without metadata.yaml the folder is a directory of inputs: its .mcap reads as bare MCAP
    (back,) = load_trials(tmp_path / 'nometa')
    np.testing.assert_allclose(back.states, zigzag_trial.states, atol=1e-9)


def test_corrupted_bytes_are_refused_by_name_or_read_as_recorded(tmp_path, zigzag_trial):
    """
    Fuzz: flip random bytes of a real MCAP; what reads back is the recording, or an error.

    Either TrialDataError naming the file, or trials whose every sample sits on the recording's
    time grid and equals the recorded one, except at most one sample per flipped byte (a byte
    lies in one message). Both outcomes occur over the 40 cases.
    """
    rec = zigzag_trial.slice(0, 60)
    write_trial_bag(rec, tmp_path / 'bag', 'mcap')
    (mcap_file,) = (tmp_path / 'bag').glob('*.mcap')
    data = bytearray(mcap_file.read_bytes())
    rng = np.random.default_rng(42)
    refused = read = 0
    for i in range(40):
        bad = bytearray(data)
        flipped = rng.integers(0, len(bad), size=int(rng.integers(1, 20)))
        for k in flipped:
            bad[k] = int(rng.integers(0, 256))
        f = tmp_path / f'fuzz{i}.mcap'
        f.write_bytes(bytes(bad))
        try:
            trials = load_trials(f)
        except TrialDataError as exc:
            assert f.name in str(exc)
            refused += 1
            continue
        read += 1
        changed = 0
        for tr in trials:
            k = np.searchsorted(rec.t, tr.t + tr.start_s)
            assert np.all(k < rec.t.size), (f.name, tr.t)
            np.testing.assert_allclose(rec.t[k], tr.t + tr.start_s, atol=1e-9)
            changed += int(np.sum(np.any(np.abs(tr.states - rec.states[k]) > 1e-9, axis=1)
                                  | np.any(np.abs(tr.controls - rec.controls[k]) > 1e-9,
                                           axis=1)))
        assert changed <= len(flipped), (f.name, changed, len(flipped))
    assert refused and read, (refused, read)


def test_topic_map_options():
    tm = topic_map_from_dict({'rudder': {'unit': 'deg', 'sign': -1}, 'rpm': {'unit': 'rps'}})
    assert tm.factor('rudder') == pytest.approx(-math.pi / 180) and tm.factor('rpm') == 60.0
    with pytest.raises(ConfigError, match='unknown key rudder.units'):
        topic_map_from_dict({'rudder': {'units': 'deg'}})
    # every channel of the table has its section, in its own units (a thruster in rpm)
    tm = topic_map_from_dict({'n_port': {'unit': 'rpm', 'topic': '/tug/port'}})
    assert tm.factor('n_port') == pytest.approx(1 / 60) and tm.topic('n_port') == '/tug/port'
    assert 'n_port_topic' in tm.given and tm.topic('n_stbd') == '/thrusters/stbd/thrust'
    with pytest.raises(ConfigError, match=r"azimuth_port.unit 'rpm' not one of \['rad', 'deg'\]"):
        topic_map_from_dict({'azimuth_port': {'unit': 'rpm'}})


def test_velocities_derived_from_poses():
    t = np.arange(0, 100, 0.5)
    psi = 0.01 * t
    R = 3.0 / 0.01  # a circle at 3 m/s, r = 0.01 rad/s
    x, y = R * np.sin(psi), R * (1 - np.cos(psi))
    u, v, r = body_velocities_from_poses(t, x, y, psi)
    assert np.allclose(u[1:-1], 3.0, rtol=1e-3) and np.allclose(v[1:-1], 0, atol=1e-2)
    assert np.allclose(r, 0.01)


def test_generate_command(tmp_path, capsys):
    from mmg_tuner.cli.generate import command
    assert command(['--out', str(tmp_path), '--maneuvers', 'turning:35', 'zigzag:20/10',
                    '--duration', '120', '--rate-hz', '5', '--seed', '3']) == 0
    trials = load_trials(tmp_path)
    assert sorted(t.name for t in trials) == ['turning_p35', 'zigzag_p20_10']
    csv = read_trial_csv(tmp_path / 'csv' / 'turning_p35.csv')
    assert csv.dt == pytest.approx(0.2) and len(csv) == 601
    # the bag, resampled at 1 s, agrees with the 5 Hz CSV at the common samples (noise kept)
    bag = next(t for t in trials if t.name == 'turning_p35')
    np.testing.assert_allclose(bag.states, csv.states[::5], atol=1e-6)
    assert np.std(np.diff(csv['x'], 2)) > 0.1  # sensor noise present


def _write_custom_bag(path, t, trial_states, rudder_deg, rpm_rps, pose_only=True):
    """
    Write a bag as another ship's logger might write it.

    PoseStamped (no twist), JointState actuators in degrees and rev/s.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    from mmg_tuner.data.bag import TYPESTORE as ts
    PS, JS = ts.types['geometry_msgs/msg/PoseStamped'], ts.types['sensor_msgs/msg/JointState']
    H, Tm = ts.types['std_msgs/msg/Header'], ts.types['builtin_interfaces/msg/Time']
    P, Q, Pose = (ts.types['geometry_msgs/msg/Point'], ts.types['geometry_msgs/msg/Quaternion'],
                  ts.types['geometry_msgs/msg/Pose'])
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        cp = w.add_connection('/gnss/pose', PS.__msgtype__, typestore=ts)
        ca = w.add_connection('/actuators', JS.__msgtype__, typestore=ts)
        for k, tk in enumerate(t):
            ns = int(tk * 1e9) + 10**18
            hdr = H(stamp=Tm(sec=ns // 10**9, nanosec=ns % 10**9), frame_id='map')
            x, y, psi = trial_states[k, :3]
            yaw = np.pi / 2 - psi
            msg = PS(header=hdr, pose=Pose(position=P(x=y, y=x, z=0.0),
                                           orientation=Q(x=0.0, y=0.0, z=np.sin(yaw / 2),
                                                         w=np.cos(yaw / 2))))
            w.write(cp, ns + 5_000_000, ts.serialize_cdr(msg, PS.__msgtype__))  # late receipt
            js = JS(header=hdr, name=['rudder', 'propeller'],
                    position=np.array([rudder_deg[k], 0.0]),
                    velocity=np.array([0.0, rpm_rps[k]]), effort=np.array([], dtype=float))
            w.write(ca, ns, ts.serialize_cdr(js, JS.__msgtype__))


def test_posestamped_and_jointstate_with_units(tmp_path, suzaku):
    tr = mv.run(suzaku, mv.ManeuverSpec('turning', rudder_deg=20, duration_s=200, dt=0.2))
    _write_custom_bag(tmp_path / 'custom', tr.t, tr.states, np.degrees(tr['rudder']),
                      tr['rpm'] / 60.0)
    tm = topic_map_from_dict({
        'odom': {'topic': '/gnss/pose', 'type': 'geometry_msgs/msg/PoseStamped'},
        'rudder': {'topic': '/actuators', 'type': 'sensor_msgs/msg/JointState',
                   'joint': 'rudder', 'unit': 'deg'},
        'rpm': {'topic': '/actuators', 'type': 'sensor_msgs/msg/JointState',
                'joint': 'propeller', 'unit': 'rps'}})
    (back,) = load_trials(tmp_path / 'custom', tm)
    truth = tr.states[::5]
    np.testing.assert_allclose(back.controls[:, 1], tr['rudder'][::5], atol=1e-9)
    np.testing.assert_allclose(back.controls[:, 0], tr['rpm'][::5], rtol=1e-9)
    np.testing.assert_allclose(back.states[:, :3], truth[:, :3], atol=1e-6)
    # no twist: velocities derived from the poses, close to the truth
    np.testing.assert_allclose(back.states[5:-5, 3:], truth[5:-5, 3:], atol=0.02)
    assert any('derived from positions' in n for n in back.notes)
    assert any('header stamps used' in n for n in back.notes)


def test_time_ranges_cut_one_recording(tmp_path, zigzag_trial):
    write_trial_bag(zigzag_trial, tmp_path / 'bag', 'mcap')
    parts = load_trials(tmp_path / 'bag', time_ranges=[(10, 100), (200, 300)])
    assert [p.name for p in parts] == ['bag_r1', 'bag_r2']
    assert parts[1].start_s == 200 and len(parts[1]) == 101
    np.testing.assert_allclose(parts[1].states, zigzag_trial.states[200:301], atol=1e-9)


def test_csv_passes_the_same_checks(tmp_path, zigzag_trial):
    f = tmp_path / 'zz.csv'
    write_trial_csv(zigzag_trial, f)
    lines = f.read_text().splitlines()
    lines[20] = ','.join(['nan' if i == 4 else v for i, v in enumerate(lines[20].split(','))])
    f.write_text('\n'.join(lines) + '\n')
    (back,) = load_trials(f)
    assert any('non-finite' in n for n in back.notes)
    np.testing.assert_allclose(back.states, zigzag_trial.states, atol=0.05)


def test_measured_wind_round_trips_and_apparent_wind_becomes_true(tmp_path, suzaku):
    from mmg_tuner.data.assemble import _true_wind
    from mmg_tuner.data.generate import SensorNoise, generate_trial
    ship = suzaku.with_params({'wind_speed': 9.0, 'wind_dir': -2.0})
    _, meas = generate_trial(ship, 'turning', 25, None, 106, 3.086, 120, 1.0, SensorNoise(), 4,
                             'w', record_wind=True)
    assert meas.wind is not None and meas.wind.shape == (len(meas), 2)
    write_trial_bag(meas, tmp_path / 'bag')
    (back,) = load_trials(tmp_path / 'bag')
    np.testing.assert_allclose(back.wind, meas.wind, atol=1e-9)
    write_trial_csv(meas, tmp_path / 'w.csv')
    np.testing.assert_allclose(read_trial_csv(tmp_path / 'w.csv').wind, meas.wind, atol=1e-7)
    (from_csv,) = load_trials(tmp_path / 'w.csv')
    np.testing.assert_allclose(from_csv.wind, meas.wind, atol=1e-7)
    # an anemometer on board sees the air relative to the ship in FLU; turned back to true
    # wind with the recorded heading and velocity it must give the true wind again
    tr = meas
    psi, u, v = tr['psi'], tr['u'], tr['v']
    n, e = tr.wind[:, 0], tr.wind[:, 1]
    ub = n * np.cos(psi) + e * np.sin(psi) - u        # air minus ship, MMG body axes
    vb = -n * np.sin(psi) + e * np.cos(psi) - v
    ns = np.round(tr.t * 1e9).astype(np.int64)
    s = Series('/wind', 'geometry_msgs/msg/Vector3Stamped', ns, np.column_stack([ub, -vb]), ns,
               frame='apparent_flu')
    np.testing.assert_allclose(_true_wind(s, 0, tr.t, psi, u, v), tr.wind, atol=1e-9)
    assert topic_map_from_dict({'wind': {'topic': ''}}).wind_topic == ''
    with pytest.raises(ConfigError, match='wind.frame'):
        topic_map_from_dict({'wind': {'frame': 'from_north'}})


def test_folders_are_searched_recursively(tmp_path, zigzag_trial):
    root = tmp_path / 'set'
    (root / 'a' / 'deep').mkdir(parents=True)
    (root / 'b' / 'csv').mkdir(parents=True)
    (root / '.cache').mkdir()
    write_trial_csv(zigzag_trial, root / 'a' / 'deep' / 'one.csv')
    other = dataclasses.replace(zigzag_trial, states=zigzag_trial.states + [1.0, 0, 0, 0, 0, 0])
    write_trial_bag(other, root / 'b' / 'two')          # (the same data twice is one trial)
    write_trial_csv(other, root / 'b' / 'csv' / 'two.csv')   # generate's copy of 'two'
    write_trial_csv(zigzag_trial, root / '.cache' / 'three.csv')    # hidden: skipped
    (root / 'README.md').write_text('# runs\n')
    (root / 'LICENSE').write_text('CC BY 4.0\n')
    trials = load_trials(root)
    assert [t.name for t in trials] == ['one', 'two']                # sorted walk, each once
    assert [t.name for t in load_trials(root / 'b' / 'csv')] == ['two']  # asked for directly
    (root / 'b' / 'notes.csv').write_text('hello,world\n1,2\n')      # not a trial: an error
    with pytest.raises(TrialDataError, match='notes.csv'):
        load_trials(root)
    (tmp_path / 'empty' / 'sub').mkdir(parents=True)
    with pytest.raises(TrialDataError, match='subfolders'):
        load_trials(tmp_path / 'empty')


def test_paper_turning_trials_are_the_papers_turns_with_seeded_noise(suzaku):
    from mmg_tuner.data.generate import (paper_turning_trials, PAPER_TEST_DEG, PAPER_TUNE_DEG,
                                         SensorNoise)
    assert sorted(PAPER_TUNE_DEG) == sorted(-a for a in PAPER_TEST_DEG)   # mirrored sets
    tune = paper_turning_trials(suzaku, PAPER_TUNE_DEG[:2], duration_s=60.0, seed=3)
    assert [t.name for t in tune] == ['turn+10', 'turn-20']
    for tr, a in zip(tune, PAPER_TUNE_DEG):
        assert tr.dt == 1.0 and len(tr) == 61
        assert np.median(tr.controls[-20:, 0]) == pytest.approx(106.0, abs=1.0)
        assert np.degrees(np.median(tr.controls[-20:, 1])) == pytest.approx(a, abs=0.5)
        assert np.sign(np.median(tr.states[-20:, 5])) == np.sign(a)   # r follows the rudder
        assert tr.states[0, 3] == pytest.approx(6 * mv.KNOT, abs=0.1)
    again = paper_turning_trials(suzaku, PAPER_TUNE_DEG[:2], duration_s=60.0, seed=3)
    assert all(np.array_equal(a.states, b.states) for a, b in zip(tune, again))
    clean = paper_turning_trials(suzaku, PAPER_TUNE_DEG[:1], duration_s=60.0,
                                 noise=SensorNoise.none())[0]
    assert not np.array_equal(clean.states, tune[0].states)
