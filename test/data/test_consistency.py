"""
Cross-channel consistency of recordings (issue 28): faults named once, clean data silent.

Each synthetic fault (a 180 deg heading flip for five samples, a 5 m jump, a single sample
5 km off, one surge speed sample 64 m/s off, a clock reset, a run astern with the propeller
ahead) gives exactly one WARNING line
naming trial, check, time and size, and is cut out or leaves the recording unused; the real
Esso Osaka runs in the repository and clean generated trials give none.
"""
import logging
import math

import mmg_tuner as mt
from mmg_tuner.cli import diagnose as cli_diagnose
from mmg_tuner.cli import evaluate as cli_evaluate
from mmg_tuner.cli import inspect as cli_inspect
from mmg_tuner.cli import tune as cli_tune
from mmg_tuner.cli.generate import approach
from mmg_tuner.data.csv_io import csv_text, write_trial_csv
from mmg_tuner.data.esso import esso_data_dir
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.errors import TrialDataError
import numpy as np
import pytest

FAULT_AT = 2000          # sample index of the fault (t = 200 s at 10 Hz)
CHECKS = ('velocity spike', 'clock reset', 'heading vs yaw rate', 'position outlier',
          'position jump',
          'track vs velocities', 'astern with propeller ahead')


def _warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records
            if r.levelno >= logging.WARNING and r.getMessage().startswith('WARNING:')]


def _findings(caplog) -> list[str]:
    return [w for w in _warnings(caplog) if any(f': {c} at t = ' in w for c in CHECKS)]


@pytest.fixture(scope='module')
def zigzag(suzaku):
    """Generate a clean 400 s SUZAKU zigzag at 10 Hz with the default sensor noise."""
    rpm, speed, _ = approach(suzaku, None, None)
    return generate_trial(suzaku, 'zigzag', 20, None, rpm, speed, 400.0, 10.0, SensorNoise(), 3,
                          'zz')[1]


def _write(tmp_path, name, t, states, controls):
    p = tmp_path / f'{name}.csv'
    p.write_text(csv_text(t, states, controls))
    return p


# ------------------------------------------------------------------------- clean: silent
def test_the_esso_osaka_runs_in_the_repository_give_no_warning(caplog):
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        plain = mt.load_trials(esso_data_dir())
        with_ship = mt.load_trials(esso_data_dir(), ship=mt.load_ship('esso_osaka_3m'))
    assert plain and with_ship
    assert _warnings(caplog) == []
    assert not any('cut out' in n for tr in plain + with_ship for n in tr.notes)


CLEAN = [('suzaku', 'turning', 35, 10.0, True), ('suzaku', 'zigzag', 20, 10.0, True),
         ('suzaku', 'pullout', 20, 1.0, True), ('suzaku', 'random', 30, 10.0, False),
         ('suzaku', 'zigzag', 10, 1.0, False), ('esso_osaka_3m', 'berthing', 20, 10.0, True),
         ('esso_osaka_3m', 'random_astern', 30, 10.0, True),
         ('esso_osaka_3m', 'turning', 35, 1.0, False)]


@pytest.mark.parametrize('ship_name, maneuver, rudder, rate, noisy', CLEAN)
def test_clean_generated_trials_give_no_warning(ship_name, maneuver, rudder, rate, noisy,
                                                tmp_path, caplog):
    ship = mt.load_ship(ship_name)
    rpm, speed, _ = approach(ship, None, None)
    noise = SensorNoise() if noisy else SensorNoise.none()
    # two different manoeuvres (noise-free, the same one twice is one trial under two names,
    # which load_trials rightly reads once with a warning)
    for seed, extra in ((0, 0), (11, 2)):
        _, tr = generate_trial(ship, maneuver, rudder - extra, None, rpm, speed, 300.0, rate,
                               noise, seed, maneuver)
        write_trial_csv(tr, tmp_path / f'{maneuver}_{seed}.csv')
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        plain = mt.load_trials(tmp_path)
        with_ship = mt.load_trials(tmp_path, ship=ship)
    assert plain and with_ship
    assert _warnings(caplog) == []


# ------------------------------------------------------------------------- faults: one each
def _flip(t, st, c):
    st = st.copy()
    st[FAULT_AT:FAULT_AT + 5, 2] += math.pi
    return t, st, c


def _jump(t, st, c):
    st = st.copy()
    st[FAULT_AT:, 0] += 5.0
    return t, st, c


def _outlier(t, st, c):
    st = st.copy()
    st[FAULT_AT, 1] += 5000.0
    return t, st, c


def _spike(t, st, c):   # a byte flipped in one message of a bag: u 64 m/s off for a sample
    st = st.copy()
    st[FAULT_AT, 3] += 64.0
    return t, st, c


def _reset(t, st, c):   # the clock restarts 580 s back: sorting would splice the two stretches
    t = t.copy()
    t[FAULT_AT:] -= 580.0
    return t, st, c


FAULTS = [(_flip, 'heading vs yaw rate', 180.0, 'deg'),
          (_jump, 'position jump', 5.0, 'm'),
          (_outlier, 'position outlier', 5000.0, 'm'),
          (_spike, 'velocity spike', 64.0, 'm/s'),
          (_reset, 'clock reset', 580.0, 's')]


@pytest.mark.parametrize('fault, check, size, unit', FAULTS, ids=[f[1] for f in FAULTS])
def test_each_short_fault_gives_one_warning_and_is_cut_out(fault, check, size, unit, zigzag,
                                                           tmp_path, caplog):
    p = _write(tmp_path, 'run', *fault(zigzag.t, zigzag.states, zigzag.controls))
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        trials = mt.load_trials(p, dt=0.1)
    (line,) = _findings(caplog)
    assert line.startswith(f'WARNING: run: {check} at t = 199.') or \
        line.startswith(f'WARNING: run: {check} at t = 200.'), line
    shown = float(line.split(': ')[3].split(' ')[0])
    assert shown == pytest.approx(size, rel=0.1), line
    assert unit in line.split(': ')[3]
    # split around it: two trials, little lost, the faulty samples in neither
    assert len(trials) == 2
    assert sum(tr.duration_s for tr in trials) > 395.0
    for tr in trials:
        assert any(check in n for n in tr.notes)
        assert np.hypot(np.diff(tr['x']), np.diff(tr['y'])).max() < 50.0   # no 5 km, no splice
        assert np.abs(np.diff(tr['psi'])).max() < 1.0                        # no flip
        assert np.abs(tr['u']).max() < 10.0                                   # no spike
    if fault is _jump:   # cut between the two samples, each side kept whole
        first, second = sorted(trials, key=lambda tr: tr.start_s)
        assert first.start_s + first.duration_s == pytest.approx(199.9, abs=1e-6)
        assert second.start_s == pytest.approx(200.0, abs=1e-6)


def test_a_run_astern_with_the_propeller_ahead_is_not_used(zigzag, tmp_path, caplog):
    st = zigzag.states.copy()   # a heading 180 deg off, velocities derived from it
    st[:, 2] += math.pi
    st[:, 3:5] *= -1
    bad = _write(tmp_path, 'astern', zigzag.t, st, zigzag.controls)
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        with pytest.raises(TrialDataError, match='astern with propeller ahead'):
            mt.load_trials(bad, keep_astern=True)
    (line,) = _findings(caplog)
    assert 'astern: astern with propeller ahead at t = 0.00-400.00 s' in line
    assert 'not used' in line
    # in a folder the others are still read (the unusable one skipped with its reason)
    write_trial_csv(zigzag, tmp_path / 'good.csv')
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        (tr,) = mt.load_trials(tmp_path, ship=mt.load_ship('suzaku'))
    assert tr.name == 'good'
    assert any('astern.csv' in w and 'skipped' in w for w in _warnings(caplog))


def test_the_esso_reader_splits_at_a_clock_reset_and_cuts_a_flip(tmp_path, caplog):
    src = sorted((esso_data_dir() / 'zigzag').glob('*.csv'))[0]
    lines = src.read_text().splitlines()
    head, rows = lines[0], [r.split(',') for r in lines[1:]]
    cols = [c.strip() for c in head.split(',')]
    it, ipsi = cols.index('t [s]'), cols.index('psi_hat [rad]')
    mid = len(rows) // 2
    for r in rows[mid:mid + 5]:
        r[ipsi] = repr(float(r[ipsi]) + math.pi)
    for r in rows[mid + 300:]:
        r[it] = repr(float(r[it]) - 100.0)
    f = tmp_path / src.name
    f.write_text('\n'.join([head] + [','.join(r) for r in rows]) + '\n')
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        trials = mt.load_trials(f)
    found = _findings(caplog)
    assert sum('heading vs yaw rate' in w for w in found) == 1, found
    assert sum('clock reset' in w for w in found) == 1, found
    assert len(found) == 2
    for tr in trials:
        assert np.abs(np.diff(tr['psi'])).max() < 1.0


# ------------------------------------------------------------------------- the commands
@pytest.fixture
def jumped(zigzag, tmp_path):
    return _write(tmp_path, 'jumped', *_jump(zigzag.t, zigzag.states, zigzag.controls))


def test_inspect_shows_the_warning_and_strict_makes_it_an_error(jumped, capsys, caplog):
    with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
        assert cli_inspect.command([str(jumped)]) == 0
    assert any(w.startswith('WARNING: jumped: position jump at t = ') for w in _findings(caplog))
    with pytest.raises(SystemExit) as stop:
        cli_inspect.main([str(jumped), '--strict'])
    err = capsys.readouterr().err
    assert stop.value.code == 2
    (line,) = [ln for ln in err.splitlines() if ln.startswith('ERROR:')]
    assert '--strict: 1 WARNING(s)' in line and 'position jump' in line, err


def test_inspect_prints_the_warning_on_stderr_when_run_as_a_program(jumped):
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, '-m', 'mmg_tuner.cli.inspect', str(jumped)], cwd=root,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert 'WARNING: jumped: position jump at t = 199.90-200.00 s' in run.stderr, run.stderr


@pytest.mark.parametrize('main', [cli_tune.main, cli_evaluate.main, cli_diagnose.main])
def test_tune_evaluate_diagnose_refuse_the_warning_under_strict(main, jumped, tmp_path,
                                                                capsys):
    argv = [str(jumped), '--out', str(tmp_path / 'o'), '--strict']
    if main is cli_diagnose.main:
        argv += ['--test', str(jumped)]
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and 'Traceback' not in err
    assert 'WARNING: jumped: position jump' in err
    assert 'ERROR: --strict: 1 WARNING(s)' in err, err
    assert not (tmp_path / 'o' / 'params.yaml').exists()


def test_evaluate_without_strict_shows_the_warning_and_runs(jumped, tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        cli_evaluate.main([str(jumped), '--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert stop.value.code == 0, err
    assert 'WARNING: jumped: position jump at t = ' in err


# ------------------------------------------------------------------------- one readable line
def test_time_in_milliseconds_is_refused_in_one_short_line(zigzag, tmp_path):
    p = _write(tmp_path, 'ms', zigzag.t * 1000.0, zigzag.states, zigzag.controls)
    with pytest.raises(TrialDataError) as err:
        mt.load_trials(p)
    text = str(err.value)
    assert '\n' not in text
    assert len(text) < 1500, len(text)
    assert 'more like it' in text, text


def test_brief_counts_repeated_notes_and_caps_the_line():
    from mmg_tuner.data.files import brief
    notes = [f'/rpm: gap of {k}.0 s at t = {3 * k}.0 s: trial split there' for k in range(5000)]
    notes += [f'note {c} of its own kind' * 3 for c in 'abcdefghijklmnopqrstuvwxyz']
    text = brief(notes)
    assert text.startswith('/rpm: gap of 0.0 s at t = 0.0 s: trial split there (and 4999 more '
                           'like it)')
    assert len(text) <= 700 and 'more kind(s) of note' in text
    assert brief(['a', 'b']) == 'a; b'
