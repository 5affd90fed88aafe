"""
Bad input never crashes simulate, generate, inspect or the trial readers.

And no file is lost (issue 10, sections 4 and 5): every bad value is refused at the edge with one
``ERROR: ...`` line naming the option, file or key; the readers repair what they can, with a note,
and refuse the rest; nothing is overwritten that the run did not create.
"""
import contextlib
import dataclasses
import errno
import io
import os
from pathlib import Path
import shutil
import threading

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
from mmg_tuner.cli import generate as gen_cli
from mmg_tuner.cli import inspect as inspect_cli
from mmg_tuner.cli import simulate as sim_cli
from mmg_tuner.cli.common import run_command
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.data import csv_io
from mmg_tuner.data.bag import read_series, write_trial_bag
from mmg_tuner.data.csv_io import write_trial_csv
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np
import pytest

FUZZ = settings(max_examples=40, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


def call(command, argv):
    """(exit status, stdout, stderr) of a command run in-process as its executable runs it."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = run_command(command, argv)
    return rc, out.getvalue(), err.getvalue()


def assert_refused(rc, err, *names):
    """Exit 2 and exactly one line, 'ERROR: ...', naming every one of names."""
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and lines[0].startswith('ERROR: '), err
    for name in names:
        assert name in lines[0], (name, lines[0])


# ---------------------------------------------------------------- options, fuzzed at the edge

NOT_NUMBERS = st.sampled_from(['nan', 'NaN', 'inf', '-inf', '1e999', 'abc', '', ' ', '1,5',
                               '0x10', 'None'])
NOT_POSITIVE = st.floats(max_value=0.0, allow_nan=False, allow_infinity=False).map(repr)
HUGE = st.floats(min_value=1e12, max_value=1e308).map(repr)
NEGATIVE = st.floats(max_value=-1e-6, min_value=-1e308).map(repr)
NOT_WHOLE = st.sampled_from(['1.5', '1e3', 'nan', 'ten', '', '-1', '2147483648'])

SIMULATE_BAD = {
    '--dt': st.one_of(NOT_NUMBERS, NOT_POSITIVE, HUGE,
                      st.floats(min_value=1e-300, max_value=9e-4).map(repr)),
    '--duration': st.one_of(NOT_NUMBERS, NOT_POSITIVE, HUGE),
    '--substeps': st.one_of(NOT_WHOLE, st.integers(max_value=0).map(str),
                            st.integers(min_value=1001).map(str)),
    '--seed': st.one_of(NOT_WHOLE, st.integers(max_value=-1).map(str)),
    '--rpm': st.one_of(NOT_NUMBERS, NOT_POSITIVE, st.floats(min_value=1e4, max_value=1e308)
                       .map(repr)),
    '--speed-kn': st.one_of(NOT_NUMBERS, NOT_POSITIVE, st.floats(min_value=100, max_value=1e308)
                            .map(repr)),
    '--speed-ms': st.one_of(NOT_NUMBERS, NOT_POSITIVE, st.floats(min_value=50, max_value=1e308)
                            .map(repr)),
    '--rudder-deg': st.one_of(NOT_NUMBERS, st.floats(min_value=46, max_value=1e308).map(repr),
                              st.floats(max_value=-46, min_value=-1e308).map(repr)),
    '--check-deg': st.one_of(NOT_NUMBERS, st.just('0'), st.floats(min_value=90.01).map(repr)),
    '--approach': st.one_of(NOT_NUMBERS, NEGATIVE, st.floats(min_value=900, max_value=1e300)
                            .map(repr)),
    '--pullout-after': st.one_of(NOT_NUMBERS, NOT_POSITIVE),
    '--rudder-rate': st.one_of(NOT_NUMBERS, NEGATIVE),
}


@FUZZ
@given(data=st.data())
def test_simulate_refuses_every_bad_number(data, tmp_path):
    opt = data.draw(st.sampled_from(sorted(SIMULATE_BAD)), label='option')
    value = data.draw(SIMULATE_BAD[opt], label='value')
    out = tmp_path / f'run_{abs(hash(value))}.csv'
    rc, _, err = call(sim_cli.command, [opt, value, '--out', str(out)])
    assert_refused(rc, err, opt)
    assert not out.exists()


GENERATE_BAD = {
    '--rpm': SIMULATE_BAD['--rpm'],
    '--speed-kn': SIMULATE_BAD['--speed-kn'],
    '--duration': st.one_of(NOT_NUMBERS, NOT_POSITIVE, HUGE, st.just('1')),
    '--rate-hz': st.one_of(NOT_NUMBERS, NOT_POSITIVE, st.floats(min_value=1001).map(repr)),
    '--seed': SIMULATE_BAD['--seed'],
    '--effect': st.sampled_from(['current_speed=nan', 'current_speed=inf', 'current_speed',
                                 '=0.3', 'no_such_effect=1', 'current_speed=abc']),
    '--maneuvers': st.sampled_from(['turning:nan', 'turning:inf', 'zigzag:0', 'turning:1e308',
                                    'spin:10', 'turning:35/10', 'zigzag:20/0', 'zigzag:20/nan',
                                    'random:-1e3', 'turning:60']),
}


@FUZZ
@given(data=st.data())
def test_generate_refuses_every_bad_value_before_writing(data, tmp_path):
    opt = data.draw(st.sampled_from(sorted(GENERATE_BAD)), label='option')
    value = data.draw(GENERATE_BAD[opt], label='value')
    out = tmp_path / f'trials_{abs(hash(value))}'
    rc, _, err = call(gen_cli.command, ['--out', str(out), '--duration', '30', '--rate-hz',
                                        '1', '--maneuvers', 'turning:20', opt, value])
    assert_refused(rc, err, opt)
    assert not out.exists()  # checked before any work: nothing created


BAD_TOPIC_MAPS = [b'odom: [1, 2]', b'- a\n- b', b'resample: {dt: .nan}', b'resample: {dt: abc}',
                  b'resample: {dt: 1.0e-9}', b'resample: {max_gap_s: -1}', b'rudder: {sign: 2}',
                  b'rudder: {unit: furlong}', b'odom: {topic: 5}', b'odom: {type: null}',
                  b'\xff\xfe\x00binary', b'odom: {topic: [/a]}', b'42', b'odom: {topik: /x}',
                  b'extra: {a: 1}', b'rpm: {unit: rps, sign: 2}', b'resample: {dt: true}',
                  b'{{{']


@FUZZ
@given(data=st.data())
def test_inspect_refuses_bad_options_and_topic_maps(data, tmp_path):
    which = data.draw(st.sampled_from(['--dt', '--topics']), label='option')
    if which == '--dt':
        value = data.draw(st.one_of(NOT_NUMBERS, NOT_POSITIVE, HUGE,
                                    st.floats(min_value=1e-300, max_value=9e-4).map(repr)))
        argv, name = ['--dt', value], '--dt'
    else:
        f = tmp_path / 'map.yaml'
        f.write_bytes(data.draw(st.sampled_from(BAD_TOPIC_MAPS)))
        argv, name = ['--topics', str(f)], str(f)
    rc, _, err = call(inspect_cli.command, [str(tmp_path)] + argv)
    assert_refused(rc, err, name)


def test_inspect_dt_zero_is_refused_not_replaced_by_one_second(tmp_path):
    rc, _, err = call(inspect_cli.command, [str(tmp_path), '--dt', '0'])
    assert_refused(rc, err, '--dt')


def test_implausible_rpm_and_rudder_named_with_the_ship(suzaku):
    rc, _, err = call(sim_cli.command, ['--rpm', '1e308'])
    assert_refused(rc, err, '--rpm', 'plausible')
    rc, _, err = call(gen_cli.command, ['--out', '/nonexistent/x', '--rpm', '5000'])
    assert_refused(rc, err, '--rpm')


# ------------------------------------------------------------------------ outputs: nothing lost

def test_simulate_never_overwrites_and_checks_before_work(tmp_path, monkeypatch):
    out = tmp_path / 'run.csv'
    out.write_text('my own file\n')
    rc, _, err = call(sim_cli.command, ['--duration', '50', '--out', str(out)])
    assert_refused(rc, err, '--out', str(out))
    assert out.read_text() == 'my own file\n'
    rc, _, err = call(sim_cli.command, ['--duration', '50', '--out', str(tmp_path)])
    assert_refused(rc, err, '--out')
    # a write that fails (disk full) says so and leaves nothing behind
    import mmg_tuner.cli.common as common

    def full(*a, **k):
        raise OSError(errno.ENOSPC, 'No space left on device')
    monkeypatch.setattr(common.os, 'link', full)
    new = tmp_path / 'new.csv'
    rc, _, err = call(sim_cli.command, ['--duration', '50', '--out', str(new)])
    assert_refused(rc, err, str(new), 'No space left', 'nothing was written')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['run.csv']


@pytest.mark.skipif(os.geteuid() == 0, reason='root writes into read-only folders')
def test_read_only_folders_are_refused_before_work(tmp_path):
    ro = tmp_path / 'ro'
    ro.mkdir()
    ro.chmod(0o555)
    try:
        for command, argv in ((sim_cli.command, ['--out', str(ro / 'a.csv')]),
                              (gen_cli.command, ['--out', str(ro / 'g')]),
                              (inspect_cli.command, [str(tmp_path), '--csv', str(ro / 'c')])):
            rc, _, err = call(command, argv)
            assert_refused(rc, err, str(ro))
    finally:
        ro.chmod(0o755)


def _gen(out, *more):
    return call(gen_cli.command, ['--out', str(out), '--duration', '30', '--rate-hz', '1',
                                  '--maneuvers', *more])


def test_generate_writes_beside_never_over(tmp_path, monkeypatch):
    out = tmp_path / 'trials'
    rc, text, err = _gen(out, 'turning:35', 'turning:35')  # the same name twice in one call
    assert rc == 0, err
    assert {p.name for p in out.iterdir() if p.is_dir()} == {'turning_p35', 'turning_p35_2',
                                                             'csv'}
    first = {p: p.read_bytes() for p in out.rglob('*') if p.is_file() and 'lock' not in p.name}
    rc, text, err = _gen(out, 'turning:35')  # again into the same folder
    assert rc == 0, err
    assert 'turning_p35_3' in text and 'written beside' in text
    for p, data in first.items():
        assert p.read_bytes() == data  # untouched
    # (three runs of one noise-free manoeuvre hold the same data: read once, with a note)
    assert len([p for p in out.iterdir() if p.is_dir() and p.name != 'csv']) == 3
    # --out is an existing file
    f = tmp_path / 'file'
    f.write_text('x')
    rc, _, err = _gen(f, 'turning:35')
    assert_refused(rc, err, '--out', str(f))
    assert f.read_text() == 'x'
    # the disk fills while the second trial is written: the first stays, the error says so
    real = gen_cli.write_trial_bag
    calls = []

    def fill_up(trial, path, storage):
        calls.append(path)
        if len(calls) == 2:
            Path(path).mkdir()
            (Path(path) / 'half.mcap').write_bytes(b'\x89MCAP0\r\n')
            raise OSError(errno.ENOSPC, 'No space left on device')
        real(trial, path, storage)
    monkeypatch.setattr(gen_cli, 'write_trial_bag', fill_up)
    fresh = tmp_path / 'fresh'
    rc, _, err = _gen(fresh, 'turning:20', 'zigzag:20')
    assert_refused(rc, err, 'No space left', 'written so far', 'turning_p20')
    assert (fresh / 'turning_p20').is_dir() and not (fresh / 'zigzag_p20').exists()


def test_inspect_csv_refuses_a_folder_with_files(tmp_path):
    src = tmp_path / 'src'
    assert _gen(src, 'turning:35')[0] == 0
    dest = tmp_path / 'dest'
    dest.mkdir()
    (dest / 'turning_p35.csv').write_text('mine')
    rc, _, err = call(inspect_cli.command, [str(src), '--csv', str(dest)])
    assert_refused(rc, err, '--csv', str(dest))
    assert (dest / 'turning_p35.csv').read_text() == 'mine'


# ------------------------------------------------------------------------------- the readers

@pytest.fixture(scope='module')
def short_trial(suzaku):
    tr = mv.run(suzaku, mv.ManeuverSpec('zigzag', rudder_deg=20, duration_s=60, dt=1.0))
    return Trial(tr.t, tr.states, tr.controls, name='zz')


def test_csv_with_a_byte_order_mark_is_read(tmp_path, short_trial):
    f = tmp_path / 'bom.csv'
    write_trial_csv(short_trial, f)
    f.write_bytes(b'\xef\xbb\xbf' + f.read_bytes())
    (back,) = load_trials(f)
    np.testing.assert_allclose(back.states, short_trial.states, atol=1e-6)


def test_rows_with_nan_time_are_trimmed_with_a_note(tmp_path, short_trial):
    f = tmp_path / 'nan_t.csv'
    write_trial_csv(short_trial, f)
    lines = f.read_text().splitlines()
    ncol = lines[1].count(',')
    lines[10] = 'nan' + lines[10][lines[10].index(','):]            # an isolated row
    lines += ['nan' + ',0' * ncol, ',' * ncol, 'nan' + ',1' * ncol]  # a trailing, cut-off log
    f.write_text('\n'.join(lines) + '\n')
    (back,) = load_trials(f)
    assert any('time t is not a number' in n and 'nan_t.csv' in n for n in back.notes)
    assert back.duration_s == pytest.approx(60.0)


def _run_with_timeout(fn, seconds=20.0):
    box = {}

    def target():
        try:
            box['value'] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the test thread
            box['error'] = exc
    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(seconds)
    return th.is_alive(), box


def test_fifos_devices_and_huge_files_are_refused(tmp_path, short_trial, monkeypatch):
    fifo = tmp_path / 'pipe.csv'
    os.mkfifo(fifo)
    try:
        hung, box = _run_with_timeout(lambda: load_trials(fifo))
    finally:  # unblock a reader stuck in open() so that the thread can end
        try:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
    assert not hung, 'reading a FIFO blocked'
    assert isinstance(box.get('error'), TrialDataError) and 'not a regular file' in \
        str(box['error'])
    zero = tmp_path / 'zero.csv'
    zero.symlink_to('/dev/zero')
    with pytest.raises(TrialDataError, match='not a regular file'):
        load_trials(zero)
    with pytest.raises(TrialDataError, match='not a regular file'):
        load_trials(tmp_path)  # the folder holds nothing else readable... and says why
    big = tmp_path / 'big' / 'big.csv'
    big.parent.mkdir()
    write_trial_csv(short_trial, big)
    monkeypatch.setattr(csv_io, 'MAX_CSV_BYTES', 1000)
    with pytest.raises(TrialDataError, match='MB'):
        load_trials(big)


def test_non_utf8_names_never_break_reports(tmp_path, short_trial):
    name = os.fsdecode(b'turn\xff\xfe')
    write_trial_csv(short_trial, tmp_path / f'{name}.csv')
    (tr,) = load_trials(tmp_path)
    tr.name.encode('utf-8')
    tr.source.encode('utf-8')
    (tmp_path / 'report.md').write_text(f'# {tr.name}\n{tr.source}\n', encoding='utf-8')
    rc, text, err = call(inspect_cli.command, [str(tmp_path), '--csv', str(tmp_path / 'o')])
    assert rc == 0, err
    assert '1 usable trial(s)' in text


def test_implausible_samples_are_dropped_with_a_note(tmp_path, short_trial, suzaku):
    from mmg_tuner.core.limits import input_limits
    tr = Trial(short_trial.t, short_trial.states, short_trial.controls.copy(), name='x')
    rudder, rpm = tr.inputs['rudder'], tr.inputs['rpm']   # the trial's channels, by name
    rudder[[5, 30]] = 1e308
    f = tmp_path / 'x.csv'
    write_trial_csv(tr, f)
    (back,) = load_trials(f)
    assert np.abs(back['rudder']).max() < np.radians(46)
    assert any('column rudder' in n and 'implausible' in n and 't = 5.000 s' in n
               for n in back.notes)
    # a dropped position is not a time base: a CSV has one time column, no header stamps
    states = short_trial.states.copy()
    states[12, 0] = 1e12
    write_trial_csv(Trial(short_trial.t, states, short_trial.controls, name='x'), f)
    (back,) = load_trials(f)
    assert any('columns x, y, psi, u, v, r: dropped 1 implausible' in n for n in back.notes)
    assert not any('header stamps' in n for n in back.notes), back.notes
    # with the ship, its own limits: 5000 rpm is a unit error for SUZAKU (not for a model)
    rudder[:] = short_trial.controls[:, 1]
    rpm[40:] = 5000.0
    write_trial_csv(tr, f)
    (back,) = load_trials(f)
    assert back['rpm'].max() == 5000.0
    (back,) = load_trials(f, limits=input_limits(suzaku))
    assert back['rpm'].max() < 200 and any('column rpm' in n for n in back.notes)
    # nothing plausible left: refused, naming file and column
    rudder[:] = 1e308
    write_trial_csv(tr, f)
    with pytest.raises(TrialDataError, match=r'x\.csv.*column rudder.*implausible'):
        load_trials(f)


def test_same_names_from_different_folders_stay_apart(tmp_path, short_trial):
    from mmg_tuner.data.load import load_many
    for d, dx in (('a', 0.0), ('b', 1.0)):   # two recordings (the same data twice is one)
        moved = dataclasses.replace(short_trial, states=short_trial.states + [dx, 0, 0, 0, 0, 0])
        write_trial_csv(moved, tmp_path / d / 'turn.csv')
    trials = load_many([tmp_path / 'a', tmp_path / 'b'])
    assert [t.name for t in trials] == ['a/turn', 'b/turn']
    rc, text, err = call(inspect_cli.command, [str(tmp_path / 'a'), str(tmp_path / 'b'),
                                               '--csv', str(tmp_path / 'out')])
    assert rc == 0, err
    assert sorted(str(p.relative_to(tmp_path / 'out')) for p in (tmp_path / 'out').rglob(
        '*.csv')) == ['a/turn.csv', 'b/turn.csv']


def _footerless(src: Path, dest: Path) -> Path:
    """dest: the MCAP file src cut where its summary starts, as a killed recorder leaves it."""
    import struct
    with open(src, 'rb') as f:  # the footer: summary_start, summary_offset_start, crc, magic
        f.seek(-(8 + 8 + 4 + 8), os.SEEK_END)
        summary_start = struct.unpack('<Q', f.read(8))[0]
    dest.write_bytes(src.read_bytes()[:summary_start])
    return dest


def test_mcap_without_footer_is_recovered_with_a_note(tmp_path, short_trial):
    write_trial_bag(short_trial, tmp_path / 'bag', 'mcap')
    (mcap_file,) = (tmp_path / 'bag').glob('*.mcap')
    killed = _footerless(mcap_file, tmp_path / 'killed.mcap')
    (back,) = load_trials(killed)
    np.testing.assert_allclose(back.states, short_trial.states, atol=1e-9)
    note = next(n for n in back.notes if 'recovered' in n)
    assert 'footer' in note and f'{3 * len(short_trial)} intact message' in note
    # a rosbag2 folder whose MCAP lost its footer (metadata.yaml present) too
    shutil.copytree(tmp_path / 'bag', tmp_path / 'bag2')
    (cp,) = (tmp_path / 'bag2').glob('*.mcap')
    _footerless(mcap_file, cp)
    (back,) = load_trials(tmp_path / 'bag2')
    assert len(back) == len(short_trial) and any('recovered' in n for n in back.notes)


def test_our_own_bugs_are_not_relabelled_as_corrupt_data(tmp_path, short_trial, monkeypatch):
    from rosbags.rosbag2 import Reader
    write_trial_bag(short_trial, tmp_path / 'bag', 'mcap')

    def bug(self, *a, **k):
        raise ZeroDivisionError('a bug, not a corrupt file')
        yield  # pragma: no cover
    monkeypatch.setattr(Reader, 'messages', bug)
    with pytest.raises(ZeroDivisionError):
        read_series(tmp_path / 'bag', TopicMap())
