"""The ``inspect`` command: topics, detected manoeuvres, problems, CSV export, exit status."""
import subprocess

from conftest import installed_executable
from mmg_tuner.cli.generate import command as generate
from mmg_tuner.cli.inspect import command as inspect
from mmg_tuner.data.csv_io import read_trial_csv
import pytest


@pytest.fixture(scope='module')
def trials_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp('gen')
    assert generate(['--out', str(d), '--maneuvers', 'turning:35', 'zigzag:20', 'random:30',
                     'pullout:20', '--duration', '400', '--rate-hz', '5']) == 0
    return d


def test_detects_manoeuvres_and_topics(trials_dir, tmp_path, capsys):
    assert inspect([str(trials_dir), '--csv', str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert '/odom' in out and 'nav_msgs/msg/Odometry' in out and '5.00 Hz' in out
    for name, kind in (('turning_p35', 'turning'), ('zigzag_p20', 'zigzag'),
                       ('random_p30', 'mixed'), ('pullout_p20', 'pull-out')):
        assert f'trial {name}: {kind},' in out
        assert len(read_trial_csv(tmp_path / f'{name}.csv')) == 401
    assert '4 usable trial(s)' in out


def test_marin_data_through_the_same_door(capsys):
    from mmg_tuner.data.marin import marin_data_dir
    assert inspect([str(marin_data_dir())]) == 0
    out = capsys.readouterr().out
    assert out.count(': zigzag,') == 4 and out.count(': pull-out,') == 2


@pytest.mark.parametrize('amp', [10.0, 35.0])
def test_a_short_zigzag_is_a_zigzag(amp):
    # 100 s holds one rudder reversal; at 35 deg the gear slews a third of the time. Both were
    # called 'mixed' before the slewing samples were set aside and one reversal was enough
    from mmg_tuner.core.ship import load_ship
    from mmg_tuner.data.generate import generate_trial, SensorNoise
    from mmg_tuner.data.summary import detect_maneuver
    _, measured = generate_trial(load_ship('suzaku'), 'zigzag', amp, amp, 100.0, 3.0, 100.0,
                                 10.0, SensorNoise(), 0, 'short')
    assert detect_maneuver(measured) == 'zigzag'


def test_slewing_is_found_when_the_record_starts_with_the_rudder_over():
    # held at +20 deg, slewing at 2.3 deg/s to -20, held: the edges of the record must not
    # read as a jump (a zero-padded smoothing made them the fastest rate and hid the slewing)
    import numpy as np
    from mmg_tuner.data.summary import _slewing
    t = np.arange(0.0, 60.0, 0.1)
    rud = np.clip(20.0 - 2.3 * (t - 20.0), -20.0, 20.0)
    moving = (t > 20.5) & (t < 20.0 + 40.0 / 2.3 - 0.5)
    flagged = _slewing(t, rud)
    assert flagged[moving].mean() > 0.9 and flagged[~moving].mean() < 0.05


def test_pond_runs_are_told_apart():
    # one reversal is a zigzag only at one rpm: the berthing runs (ahead and astern) stay mixed
    from mmg_tuner.data.esso import esso_data_dir, read_esso
    from mmg_tuner.data.summary import detect_maneuver
    root = esso_data_dir()
    kinds = {f.parent.name: [] for f in root.glob('*/*.csv')}
    for f in sorted(root.glob('*/*.csv')):
        kinds[f.parent.name].append(detect_maneuver(read_esso(f, keep_astern=True)[0]))
    assert set(kinds['zigzag']) == {'zigzag'}
    assert 'zigzag' not in kinds['berthing'] + kinds['random'] + kinds['turning']


def test_nothing_usable_exits_nonzero(tmp_path, capsys):
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(b'not an mcap file at all')
    assert inspect([str(bad), str(tmp_path / 'missing')]) == 1
    out = capsys.readouterr().out
    assert 'PROBLEM' in out and 'bad.mcap' in out and '0 usable trial(s)' in out


def test_installed_executables_answer_help():
    for exe in ('inspect', 'generate'):
        path = installed_executable(exe)
        if path is None:
            pytest.skip('package not installed with colcon (run through scripts/test.sh)')
        res = subprocess.run([path, '--help'], capture_output=True, text=True, timeout=120)
        assert res.returncode == 0 and 'usage' in res.stdout


@pytest.mark.parametrize('name', ['simulate', 'generate', 'inspect', 'tune', 'diagnose',
                                  'evaluate', 'fleet', 'precompile'])
def test_help_states_each_default_once_and_never_none(name):
    import importlib
    import re
    text = importlib.import_module(f'mmg_tuner.cli.{name}').build_parser().format_help()
    assert 'usage' in text and '(default: None)' not in text and '(default: False)' not in text
    # one option's help, from its flag to the next option: at most one default stated
    for help_of_option in re.split(r'\n  -', text):
        assert len(re.findall(r'\(default', ' '.join(help_of_option.split()))) <= 1, \
            help_of_option
