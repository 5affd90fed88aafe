"""
Units and faults the SUZAKU path already caught, now everywhere (issues 43.4, 43.6, 45).

- rpm logged as rev/s, recognised from the ship's own resistance/propeller balance
  (data/consistency.rpm_unit_warning); a clean log stays silent; ``inspect --strict`` fails.
- ``inspect`` on a tug (channel) CSV: no traceback, its channels reported; a 5 km GNSS spike
  flagged and cut out as on the SUZAKU path; ``--strict`` fails on it.
- sim_node's staleness rule (ros/command_watch.py), pure: never received, stale, timed out.
"""
import csv
import logging
import math

from mmg_tuner.cli.common import run_command
from mmg_tuner.cli.generate import approach
from mmg_tuner.cli.inspect import command as inspect_command
from mmg_tuner.core.actuators import twin_azimuth_trials as twin
from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.trial import Trial
from mmg_tuner.data.consistency import rpm_unit_warning
from mmg_tuner.data.csv_io import csv_text, trial_csv_text
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.ros.command_watch import channel_state, zeroed_on_timeout
import numpy as np
import pytest


def inspect(argv, capsys):
    code = run_command(inspect_command, [str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out + out.err


# ---------------------------------------------------------------------- rpm or rev/s
@pytest.fixture(scope='module')
def zigzag(suzaku):
    """Return a clean 200 s SUZAKU zigzag at 10 Hz, default sensor noise (20 s approach)."""
    rpm, speed, _ = approach(suzaku, None, None)
    return generate_trial(suzaku, 'zigzag', 20, None, rpm, speed, 200.0, 10.0, SensorNoise(), 5,
                          'zz', approach_s=20.0)[1]


def _write(path, tr, rpm_factor=1.0):
    path.write_text(csv_text(tr.t, tr.states, tr.controls * [rpm_factor, 1.0]))
    return path


def test_rpm_logged_as_rev_per_s_is_named_and_strict_fails(suzaku, zigzag, tmp_path, capsys):
    assert rpm_unit_warning(zigzag, suzaku) == ''    # the clean log: silent
    rps = zigzag.slice(0.0)
    rps.inputs['rpm'] = zigzag.inputs['rpm'] / 60.0
    w = rpm_unit_warning(rps, suzaku)
    assert "channel 'rpm'" in w and 'looks like rev/s' in w and 'multiply by 60' in w, w
    q = float(w.split(' times the logged')[0].split()[-1])   # ~60: the balance needs 60 x
    assert 40 < q < 80, w
    # through inspect: a WARNING, and --strict turns it into an error (exit 2)
    clean = _write(tmp_path / 'clean.csv', zigzag)
    bad = _write(tmp_path / 'rps.csv', zigzag, 1 / 60)
    code, out = inspect([clean, '--ship', 'suzaku', '--strict'], capsys)
    assert code == 0 and 'rev/s' not in out, out
    code, out = inspect([bad, '--ship', 'suzaku', '--strict'], capsys)
    assert code == 2 and 'ERROR: --strict' in out and 'looks like rev/s' in out, out


# ------------------------------------------------------------------- the tug's CSV
@pytest.fixture(scope='module')
def tug_csv(tmp_path_factory):
    ship = load_ship('qiuxin_tug')
    m = twin.Maneuver('zz', 'zigzag', 7.0, 20.0, approach_s=10.0, duration_s=60.0)
    _, tr = twin.generate(ship, m, 5.0, twin.Noise(), 7)
    p = tmp_path_factory.mktemp('tug') / 'zz.csv'
    p.write_text(trial_csv_text(tr))
    return p


def test_inspect_reads_a_tug_csv_and_flags_a_gnss_spike(tug_csv, tmp_path, capsys, caplog):
    code, out = inspect([tug_csv, '--ship', 'qiuxin_tug', '--strict'], capsys)
    assert code == 0 and 'Traceback' not in out, out
    assert 'trial zz: zigzag' in out and 'n_port +' in out and 'azimuth_port' in out, out
    assert 'WARNING' not in out, out   # a clean tug record: silent
    rows = list(csv.reader(tug_csv.open()))
    i = rows[0].index('x')
    rows[150][i] = str(float(rows[150][i]) + 5000.0)   # one fix 5 km off, at t = 29.8 s
    spiked = tmp_path / 'spiked.csv'
    with spiked.open('w', newline='') as f:
        csv.writer(f).writerows(rows)
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        code, out = inspect([spiked, '--ship', 'qiuxin_tug'], capsys)
    assert code == 0, out
    lines = [r.getMessage() for r in caplog.records if 'position outlier' in r.getMessage()]
    assert len(lines) == 1 and 't = 29.80 s' in lines[0] and '5e+03 m' in lines[0], lines
    assert 'trial spiked_1' in out and 'trial spiked_2' in out, out   # cut out: split there
    code, out = inspect([spiked, '--strict'], capsys)
    assert code == 2 and 'position outlier' in out, out


# -------------------------------------------------------------- sim_node: being driven?
def test_staleness_never_received_stale_and_timed_out():
    # never received: judged from the watch's start, stale once stale_s has passed
    s = channel_state(None, now=10.5, since=10.0, stale_s=1.0)
    assert not s.received and not s.stale and s.age_s == pytest.approx(0.5)
    s = channel_state(None, now=12.0, since=10.0, stale_s=1.0, timeout_s=5.0)
    assert s.stale and not s.timed_out
    assert channel_state(None, 16.0, 10.0, 1.0, 5.0).timed_out
    # an optional channel (bow thruster) never sent, or no start known: not stale
    assert not channel_state(None, 100.0, 0.0, 1.0, 5.0, required=False).stale
    assert not channel_state(None, 100.0, None, 1.0, 5.0).stale
    # received: the age of the last message
    s = channel_state(20.0, now=20.8, since=0.0, stale_s=1.0, timeout_s=2.0)
    assert s.received and not s.stale and not s.timed_out
    s = channel_state(20.0, now=22.5, since=0.0, stale_s=1.0, timeout_s=2.0)
    assert s.stale and s.timed_out and s.age_s == pytest.approx(2.5)
    assert not channel_state(20.0, 1e6, 0.0, 1.0, 0.0).timed_out   # timeout 0: off
    assert math.isinf(channel_state(None, 5.0, None, 1.0).age_s)


def test_a_timeout_zeroes_shaft_speeds_and_holds_angles():
    for ch in ('rpm', 'bow_thruster', 'stern_thruster', 'n_port', 'n_stbd'):
        assert zeroed_on_timeout(ch), ch
    for ch in ('rudder', 'azimuth_port', 'azimuth_stbd'):
        assert not zeroed_on_timeout(ch), ch


def test_a_tug_trial_without_recorded_orders_is_summarised_from_its_measured_angles():
    # the order columns present but never recorded (NaN): the steering is the measured angles
    # (this crashed detect_maneuver with an IndexError before)
    from mmg_tuner.data.summary import detect_maneuver
    ship = load_ship('qiuxin_tug')
    m = twin.Maneuver('zz', 'zigzag', 7.0, 20.0, approach_s=10.0, duration_s=60.0)
    _, tr = twin.generate(ship, m, 5.0, twin.Noise(), 7)
    blind = Trial(tr.t, tr.states, name='blind', inputs={
        **tr.inputs, 'azimuth_cmd_port': np.full(len(tr), np.nan),
        'azimuth_cmd_stbd': np.full(len(tr), np.nan)})
    assert detect_maneuver(blind) == detect_maneuver(tr) == 'zigzag'
