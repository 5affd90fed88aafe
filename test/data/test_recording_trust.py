"""
Recordings you can trust (issue 28 items 2 to 5): incomplete files, clashing names, foreign params.

Every bad input is the package's own error naming the file (and field), or a WARNING line naming
it, never a traceback from a library and never a silent choice.
"""
import logging

import mmg_tuner as mt
from mmg_tuner.cli import diagnose as cli_diagnose
from mmg_tuner.cli import evaluate as cli_evaluate
from mmg_tuner.cli import inspect as cli_inspect
from mmg_tuner.cli import tune as cli_tune
from mmg_tuner.data.csv_io import write_trial_csv
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.data.load import load_trials
from mmg_tuner.errors import TrialDataError
import pytest

MCAP_MAGIC = b'\x89MCAP0\r\n'


@pytest.fixture(scope='module')
def short_trial(suzaku):
    return generate_trial(suzaku, 'zigzag', 20, None, 106.0, 3.086, 40.0, 1.0, SensorNoise(), 3,
                          'zz')[1]


# ------------------------------------------------------------------ 2. an 8-byte MCAP
def test_an_mcap_holding_only_its_magic_is_a_data_error_naming_it(tmp_path):
    f = tmp_path / 'stub.mcap'
    f.write_bytes(MCAP_MAGIC)
    with pytest.raises(TrialDataError, match=r'stub\.mcap: not a complete MCAP file'):
        load_trials(f)
    # inside a rosbag2 folder too
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    (bag / 'bag_0.mcap').write_bytes(MCAP_MAGIC)
    with pytest.raises(TrialDataError, match=r'bag_0\.mcap: not a complete MCAP file'):
        load_trials(bag)


@pytest.mark.parametrize('main', [cli_tune.main, cli_evaluate.main, cli_diagnose.main,
                                  cli_inspect.main])
def test_every_command_reports_the_stub_mcap_in_one_line(main, tmp_path, capsys):
    f = tmp_path / 'stub.mcap'
    f.write_bytes(MCAP_MAGIC)
    argv = [str(f)] if main is cli_inspect.main else [str(f), '--out', str(tmp_path / 'o')]
    if main is cli_diagnose.main:
        argv += ['--test', str(f), str(f)]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr()
    text = err.out + err.err
    assert 'Traceback' not in text and 'TypeError' not in text
    assert 'stub.mcap: not a complete MCAP file' in text, text
    assert stop.value.code != 0


def test_a_folder_skips_the_stub_mcap_with_a_warning_and_reads_the_rest(tmp_path, short_trial,
                                                                        caplog):
    (tmp_path / 'a_stub.mcap').write_bytes(MCAP_MAGIC)
    write_trial_csv(short_trial, tmp_path / 'b_good.csv')
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        (tr,) = load_trials(tmp_path)
    assert tr.name == 'b_good'
    lines = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any(ln.startswith('WARNING:') and 'a_stub.mcap' in ln and 'skipped' in ln
               for ln in lines), lines
    # the API and a folder holding nothing else: the error, not an empty list
    assert len(mt.load_trials([tmp_path], ship=mt.load_ship('suzaku'))) == 1
    (tmp_path / 'b_good.csv').unlink()
    with pytest.raises(TrialDataError, match='a_stub.mcap'):
        load_trials(tmp_path)


# ------------------------------------------------------------------ 3. figure file names
CLASHING = ['run 1', 'run_1', '旋回試験', '停止試験', 'Zig', 'zig']


def test_file_stems_are_distinct_where_names_are():
    from mmg_tuner.tuning.report import file_stems
    stems = file_stems(CLASHING)
    assert len({s.casefold() for s in stems}) == len(CLASHING), stems
    assert all(s.isascii() and '/' not in s and not s.startswith('.') for s in stems)
    assert file_stems(['run 1', 'zigzag_p20']) == ['run_1', 'zigzag_p20']   # no clash: as before
    assert file_stems(CLASHING) == stems   # deterministic


def test_trials_whose_names_clash_as_file_names_get_a_figure_each(suzaku, short_trial):
    from mmg_tuner.data.trial import Trial
    from mmg_tuner.tuning.report import plot_trials
    trials = [Trial(short_trial.t, short_trial.states, short_trial.controls, name=n)
              for n in CLASHING[:4]]
    images = plot_trials(suzaku, trials, {'tuned': suzaku.params}, 'plot_')
    assert len(images) == 4, sorted(images)
    ev = mt.evaluate(suzaku, trials)
    assert len(ev.plots()) == 4


# ------------------------------------------------------------------ 4. another ship's params
@pytest.fixture
def kvlcc2_params(tmp_path):
    f = tmp_path / 'tuned_kvlcc2' / 'params.yaml'
    f.parent.mkdir()
    f.write_text('ship: kvlcc2\nparams:\n  R_0: 0.022\n')
    return f


def test_a_params_file_of_another_ship_is_refused_by_the_api(kvlcc2_params, tmp_path):
    with pytest.raises(mt.ConfigError, match=r"params\.yaml.*'kvlcc2'.*'suzaku'"):
        mt.load_ship('suzaku', kvlcc2_params)
    assert mt.load_ship('kvlcc2', kvlcc2_params)['R_0'] == 0.022   # its own ship: applied
    plain = tmp_path / 'hand_written.yaml'   # no ship key: the user vouches for it
    plain.write_text('params:\n  R_0: 0.02\n')
    assert mt.load_ship('suzaku', plain)['R_0'] == 0.02


@pytest.mark.parametrize('command', ['simulate', 'generate', 'tune', 'evaluate'])
def test_every_command_refuses_another_ships_params(command, kvlcc2_params, tmp_path, capsys):
    import importlib
    main = importlib.import_module(f'mmg_tuner.cli.{command}').main
    out = str(tmp_path / 'o')
    argv = {'simulate': ['--maneuver', 'turning', '--out', out + '.csv'],
            'generate': ['--out', out, '--maneuvers', 'turning:35'],
            'tune': [str(kvlcc2_params), '--out', out],      # (refused before any trial is read)
            'evaluate': [str(kvlcc2_params), '--out', out]}[command]
    with pytest.raises(SystemExit) as stop:
        main(argv + ['--ship', 'suzaku', '--params', str(kvlcc2_params)])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and 'Traceback' not in err
    assert 'kvlcc2' in err and 'suzaku' in err and 'params.yaml' in err, err


def test_sim_node_refuses_another_ships_params(kvlcc2_params):
    pytest.importorskip('rclpy')
    from mmg_tuner.ros.sim_node import SimNode
    p = {'ship': 'suzaku', 'params_file': str(kvlcc2_params), 'initial_yaw': 0.0,
         'initial_x': 0.0, 'initial_y': 0.0, 'initial_speed': 0.5, 'dt': 0.1,
         'initial_rpm': 10.0, 'initial_rudder': 0.0, 'integrator': 'rk4'}
    with pytest.raises(mt.ConfigError, match=r"params\.yaml.*'kvlcc2'.*'suzaku'"):
        SimNode._build(p)


# ------------------------------------------------------------------ 5. implausible ship files
def _ship_doc(name='suzaku'):
    import yaml
    from mmg_tuner.core.ship import resolve_config_path
    return yaml.safe_load(resolve_config_path(name).read_text())


@pytest.mark.parametrize('edit,words', [
    (lambda d: d['particulars'].update(x_G=1e6), ['x_G = 1e+06', 'L_pp / 2 = 41.5']),
    (lambda d: d['particulars'].update(x_G=-42.0), ['x_G = -42', 'L_pp / 2 = 41.5']),
    (lambda d: d['hull'].update(R_0=-0.01), ['R_0 = -0.01', 'negative']),
    (lambda d: d.update(particuliers={'B': 1.0}),
     ["'particuliers'", 'particulars', 'known']),
    (lambda d: d.update(tunning={'a_r': 0.5}), ["'tunning'", 'tuning']),
])
def test_implausible_ship_files_are_refused_naming_file_and_key(tmp_path, edit, words):
    import yaml
    doc = _ship_doc()
    edit(doc)
    f = tmp_path / 'odd.yaml'
    f.write_text(yaml.safe_dump(doc, allow_unicode=True))
    with pytest.raises(mt.ConfigError) as e:
        mt.load_ship(f)
    assert str(f) in str(e.value) and all(w in str(e.value) for w in words), str(e.value)


def test_every_shipped_config_still_loads_and_x_G_is_checked_in_overlays(tmp_path):
    for name in ('suzaku', 'kvlcc2', 'esso_osaka_3m'):
        s = mt.load_ship(name)
        assert abs(s['x_G']) <= s['L_pp'] / 2 and s['R_0'] >= 0
    f = tmp_path / 'params.yaml'
    f.write_text('ship: suzaku\nparams:\n  x_G: 100.0\n')
    with pytest.raises(mt.ConfigError, match=r'params\.yaml.*x_G = 100'):
        mt.load_ship('suzaku', f)


def test_a_csv_with_a_duplicated_column_is_refused_naming_file_and_column(tmp_path, short_trial):
    f = tmp_path / 'dup.csv'
    write_trial_csv(short_trial, f)
    head, *rows = f.read_text().splitlines()
    assert head.split(',')[4] == 'u'
    # a second 'u' (e.g. a logger's speed through water beside speed over ground): which one?
    f.write_text('\n'.join([head + ',U'] + [r + ',0.0' for r in rows]) + '\n')
    with pytest.raises(TrialDataError, match=r"dup\.csv: column 'u' appears twice.*5 and 10"):
        load_trials(f)


# ------------------------------------------------------------------ 7. unit sanity of a CSV
DEG = 57.29577951308232


def _unit_warnings(caplog, path) -> list[str]:
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        try:
            load_trials(path)
        except TrialDataError:   # t in ms: 1000 s gaps leave no trial; the warning says why
            pass
    return [r.getMessage() for r in caplog.records
            if r.levelno == logging.WARNING and 'looks like' in r.getMessage()]


@pytest.fixture(scope='module')
def unit_trials(suzaku, kvlcc2):
    """Clean synthetic trials: a long turn (heading over many radians), a zigzag, a random run."""
    return [generate_trial(ship, m, a, None, rpm, speed, 300.0, hz, SensorNoise(), 7,
                           f'{ship.name}_{m}')[1]
            for ship, rpm, speed in ((suzaku, 106.0, 3.086), (kvlcc2, 600.0, 1.18))
            for m, a, hz in (('turning', 35, 1.0), ('zigzag', 20, 10.0), ('random', 30, 2.0))]


@pytest.mark.parametrize('column,convert,words', [
    ('t', lambda c: c * 1000, 'milliseconds'),
    ('rudder', lambda c: c * DEG, 'degrees'),
    ('psi', lambda c: (c * DEG) % 360, 'degrees'),     # a compass heading, 0..360
    ('psi', lambda c: c * DEG, 'degrees'),
    ('r', lambda c: c * DEG, 'deg/s'),
])
def test_a_csv_column_in_another_unit_gives_a_warning_with_the_fix(
        unit_trials, tmp_path, caplog, column, convert, words):
    from mmg_tuner.data.trial import CSV_COLUMNS
    import numpy as np
    for tr in unit_trials:
        f = tmp_path / f'{tr.name}.csv'
        write_trial_csv(tr, f)
        head, *rows = f.read_text().splitlines()
        data = np.array([[float(x) for x in r.split(',')] for r in rows])
        k = list(CSV_COLUMNS).index(column)
        data[:, k] = convert(data[:, k])
        np.savetxt(f, data, delimiter=',', header=head, comments='', fmt='%.10g')
        lines = _unit_warnings(caplog, f)
        assert len(lines) == 1, (tr.name, lines)
        line = lines[0]
        assert line.startswith('WARNING:') and str(f) in line and f"column '{column}'" in line
        assert words in line and ('divide' in line or 'multiply' in line), line


def test_no_unit_warning_on_clean_trials_or_the_repositorys_recordings(
        unit_trials, tmp_path, caplog):
    from pathlib import Path
    for tr in unit_trials:
        write_trial_csv(tr, tmp_path / f'{tr.name}.csv')
        assert _unit_warnings(caplog, tmp_path / f'{tr.name}.csv') == []
    data = Path(__file__).resolve().parents[2] / 'data'
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        assert _unit_warnings(caplog, folder) == [], folder
