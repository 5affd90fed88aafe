"""Thrusters and low-speed trials through the data layer: bags, CSV, generate, the API."""
import math

from mmg_tuner import api as mt
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.bag import read_series, write_trial_bag
from mmg_tuner.data.csv_io import read_trial_csv, write_trial_csv
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import topic_map_from_dict
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, SimulationError
import numpy as np
import pytest

ESSO_RPM = 572.0   # holds about 0.38 m/s (Froude number 0.07) with the Esso Osaka 3 m model
ESSO_U = 0.38


@pytest.fixture(scope='module')
def esso():
    return mt.load_ship('esso_osaka_3m')


@pytest.fixture(scope='module')
def berthing(esso):
    """(truth, measured) of a noise-free generated berthing trial, 10 Hz."""
    return generate_trial(esso, 'berthing', 20, None, ESSO_RPM, ESSO_U, 240.0, 10.0,
                          SensorNoise.none(), 1, 'berth')


def _trial_with_thrusters(T=60, astern=False):
    t = np.arange(T, dtype=float)
    st = np.zeros((T, 6))
    st[:, 0], st[:, 3] = 0.3 * t, 0.3
    rpm = np.where(t > 20, -300.0, 300.0) if astern else np.full(T, 300.0)
    ctrl = np.column_stack([rpm, np.full(T, 0.05)])
    thr = np.column_stack([np.linspace(-12.0, 12.0, T), 5.0 * np.sin(t / 7.0)])
    return Trial(t, st, ctrl, name='thr', thrusters=thr)


def test_thrusters_round_trip_through_bag_and_csv(tmp_path):
    tr = _trial_with_thrusters()
    write_trial_bag(tr, tmp_path / 'bag')
    (back,) = load_trials(tmp_path / 'bag')
    assert back.thrusters is not None
    np.testing.assert_allclose(back.thrusters, tr.thrusters, atol=1e-12)   # rev/s in, rev/s out
    write_trial_csv(tr, tmp_path / 'thr.csv')
    header = (tmp_path / 'thr.csv').read_text().splitlines()[0]
    assert header.endswith('rudder,bow_thruster,stern_thruster')
    np.testing.assert_allclose(read_trial_csv(tmp_path / 'thr.csv').thrusters, tr.thrusters,
                               atol=1e-8)
    (via_load,) = load_trials(tmp_path / 'thr.csv')   # the bag's checks and resampling
    np.testing.assert_allclose(via_load.thrusters, tr.thrusters, atol=1e-8)
    # a trial without thrusters writes and reads none
    plain = Trial(tr.t, tr.states, tr.controls, name='plain')
    write_trial_bag(plain, tmp_path / 'plain')
    assert load_trials(tmp_path / 'plain')[0].thrusters is None


def test_thruster_units_and_sign_from_the_topic_map(tmp_path):
    tr = _trial_with_thrusters()
    tm = topic_map_from_dict({'bow_thruster': {'unit': 'rpm', 'sign': -1},
                              'stern_thruster': {'topic': '/thr/stern', 'unit': 'rad_s'}})
    write_trial_bag(tr, tmp_path / 'bag', tm=tm)
    rec = read_series(tmp_path / 'bag', tm)
    # on the wire: the map's unit and sign
    np.testing.assert_allclose(rec.series['bow_thruster'].values[:, 0], -60.0 * tr.thrusters[:, 0])
    np.testing.assert_allclose(rec.series['stern_thruster'].values[:, 0],
                               2 * math.pi * tr.thrusters[:, 1])
    (back,) = load_trials(tmp_path / 'bag', tm)
    np.testing.assert_allclose(back.thrusters, tr.thrusters, atol=1e-9)
    # read with the default map (rps) the rpm values are mostly beyond any thruster: dropped
    (default,) = load_trials(tmp_path / 'bag')
    assert any('/bow_thruster: dropped' in n and 'implausible' in n for n in default.notes)
    assert np.abs(default.thrusters[:, 0]).max() <= 200.0
    assert np.all(default.thrusters[:, 1] == 0)   # /stern_thruster not recorded: 0, with a note
    assert any('/stern_thruster: not recorded' in n for n in default.notes)
    for bad in ({'bow_thruster': {'unit': 'knots'}}, {'stern_thruster': {'sign': 2}},
                {'bow_thruster': {'type': 'std_msgs/msg/String'}}):
        with pytest.raises(ConfigError, match='thruster'):
            topic_map_from_dict(bad)


def test_thrusters_from_a_jointstate(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer

    from mmg_tuner.data.bag import TYPESTORE as ts
    from mmg_tuner.data.bag import odometry_msg
    tr = _trial_with_thrusters()
    JS = ts.types['sensor_msgs/msg/JointState']
    H, Tm = ts.types['std_msgs/msg/Header'], ts.types['builtin_interfaces/msg/Time']
    Od = 'nav_msgs/msg/Odometry'
    with Writer(tmp_path / 'js', version=9, storage_plugin=StoragePlugin.MCAP) as w:
        co = w.add_connection('/odom', Od, typestore=ts)
        ca = w.add_connection('/actuators', JS.__msgtype__, typestore=ts)
        for k in range(len(tr)):
            ns = int(tr.t[k] * 1e9) + 10**18
            w.write(co, ns, ts.serialize_cdr(odometry_msg(tr.states[k], ns), Od))
            js = JS(header=H(stamp=Tm(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=''),
                    name=['rudder', 'propeller', 'bow', 'stern'],
                    position=np.array([tr.controls[k, 1], 0.0, 0.0, 0.0]),
                    velocity=np.array([0.0, tr.controls[k, 0] / 60.0, tr.thrusters[k, 0],
                                       tr.thrusters[k, 1]]),
                    effort=np.array([], dtype=float))
            w.write(ca, ns, ts.serialize_cdr(js, JS.__msgtype__))
    act = {'topic': '/actuators', 'type': 'sensor_msgs/msg/JointState'}
    tm = topic_map_from_dict({'rudder': {**act, 'joint': 'rudder'},
                              'rpm': {**act, 'joint': 'propeller', 'unit': 'rps'},
                              'bow_thruster': {**act, 'joint': 'bow'},
                              'stern_thruster': {**act, 'joint': 'stern'}})
    (back,) = load_trials(tmp_path / 'js', tm)
    np.testing.assert_allclose(back.thrusters, tr.thrusters, atol=1e-9)
    np.testing.assert_allclose(back.controls, tr.controls, atol=1e-9)


def test_damaged_thruster_columns_never_traceback(tmp_path):
    tr = _trial_with_thrusters()
    write_trial_csv(tr, tmp_path / 'ok.csv')
    lines = (tmp_path / 'ok.csv').read_text().splitlines(keepends=True)

    def bad_field(line, value):
        return ','.join(line.split(',')[:-1] + [value]) + '\n'
    cases = {
        'nan_thruster.csv': lines[:10] + [bad_field(lines[10], 'nan')] + lines[11:],
        'text_thruster.csv': lines[:10] + [bad_field(lines[10], 'fast')] + lines[11:],
        'cut.csv': lines[:40] + [lines[40][:30]],
        'huge.csv': lines[:10] + [bad_field(lines[10], '1e9')] + lines[11:],
    }
    for name, body in cases.items():
        p = tmp_path / name
        p.write_text(''.join(body))
        (back,) = load_trials(p)
        assert np.all(np.isfinite(back.thrusters)), name
        assert np.abs(back.thrusters).max() <= 12.0 + 1e-9, name
    notes = ' '.join(load_trials(tmp_path / 'nan_thruster.csv')[0].notes)
    assert 'column stern_thruster: dropped 1 non-finite sample' in notes
    notes = ' '.join(load_trials(tmp_path / 'huge.csv')[0].notes)
    assert 'implausible' in notes and 'stern_thruster' in notes


def test_generated_berthing_goes_astern_and_uses_thrusters(esso, berthing):
    truth, measured = berthing
    assert truth.ok and truth.thrusters is not None
    assert truth['rpm'].min() < 0 and truth['u'].min() < 0          # astern, sternway
    assert np.abs(truth.thrusters).max(axis=0).min() > 10.0          # both thrusters used
    np.testing.assert_array_equal(measured.states, truth.states)     # SensorNoise.none()
    # replayed with the same ship from its first state: the same trial
    again = simulate(esso, truth.states[0], truth, truth.dt, 'rk4', 1)
    np.testing.assert_allclose(again.states, truth.states, rtol=0, atol=1e-9)
    # through the API (start state fitted over the first 10 s of the steady approach)
    run = mt.simulate(esso, truth, integrator='rk4')
    assert run.ok and np.max(np.abs(run.states - truth.states)) < 1e-3
    np.testing.assert_array_equal(run.thrusters, truth.thrusters)


def test_simulate_is_driven_by_the_thrusters(esso, berthing):
    truth, _ = berthing
    without = Trial(truth.t, truth.states, truth.controls, name='no thrusters')
    a = mt.simulate(esso, truth, integrator='rk4')
    b = mt.simulate(esso, without, integrator='rk4')
    assert b.thrusters is None
    # the thrusters push for 50 s and then check the swing: tens of degrees
    assert np.max(np.abs(a['psi'] - b['psi'])) > math.radians(10)


def test_random_astern_is_seeded(esso):
    def gen(seed):
        return generate_trial(esso, 'random_astern', 30, None, ESSO_RPM, ESSO_U, 150.0, 5.0,
                              SensorNoise.none(), seed, 'ra')[0]
    a, b, c = gen(3), gen(3), gen(4)
    ch = esso.family.channels
    np.testing.assert_array_equal(a.input_array(ch), b.input_array(ch))
    assert not np.array_equal(a.input_array(ch), c.input_array(ch))
    assert a['rpm'].min() < 0 and np.any(a.thrusters != 0)


def test_lowspeed_manoeuvres_refused_for_families_without_astern(suzaku, tmp_path, capsys):
    with pytest.raises(SimulationError, match="'container' family.*astern"):
        mv.run(suzaku, mv.ManeuverSpec('berthing', rudder_deg=20, duration_s=100))
    from mmg_tuner.cli.generate import main
    with pytest.raises(SystemExit) as ex:
        main(['--ship', 'kvlcc2', '--out', str(tmp_path / 'g'), '--maneuvers',
              'random_astern:30'])
    assert ex.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('ERROR: --maneuvers random_astern:30') and 'lowspeed' in err
    assert not (tmp_path / 'g').exists()      # refused before any work


def test_generate_command_writes_lowspeed_trials_that_load_back(esso, tmp_path, capsys):
    from mmg_tuner.cli.generate import command
    out = tmp_path / 'gen'
    assert command(['--ship', 'esso_osaka_3m', '--out', str(out), '--maneuvers', 'berthing:20',
                    '--duration', '240', '--rate-hz', '5', '--no-noise']) == 0
    text = capsys.readouterr().out
    assert 'cannot plausibly make 6 kn' in text       # a pond model's own approach speed
    csv = read_trial_csv(out / 'csv' / 'berthing_p20.csv')
    assert csv.thrusters is not None and csv['rpm'].min() < 0
    # the folder holds the bag and generate's CSV copy: read once, astern kept for lowspeed
    (tr,) = mt.load_trials([out], ship=esso, dt=0.2)
    assert tr.thrusters is not None and tr['rpm'].min() < 0 and tr['u'].min() < 0
    np.testing.assert_allclose(tr.thrusters, csv.thrusters, atol=1e-9)
    # a standard-family ship leaves the astern part out, with the note
    parts = mt.load_trials([out], ship=mt.load_ship('kvlcc2'), dt=0.2)
    assert all(p['rpm'].min() > 0 and p['u'].min() > 0 for p in parts)
    assert any('left out' in n for p in parts for n in p.notes)
