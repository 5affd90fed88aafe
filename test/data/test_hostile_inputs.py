"""
Hostile and faulty inputs cost no more than their size and end in one clean line (issue 45).

Every reader of a file a user can hand over (ship configs, params overlays, topic maps, fleet
manifests, measurement files, network ``.npz`` files, checkpoints, a resumed run's
``args.json``, CSV tables) refuses what crosses a limit of ``mmg_tuner/_limits.py`` with one
``ERROR``-able line naming the file and the limit, in bounded time and memory (the issue's
must-hold: an input under 10 MB costs at most 5 s and 300 MB before its refusal); and the
other items of the issue that exist as behaviour: the same data under two names read once,
options that cancel each other refused up front, file modes from the umask, the lock file
removed, no matplotlib glyph warning on stderr.
"""
import contextlib
import io
import json
import logging
import os
from pathlib import Path
import time
import tracemalloc
import warnings
import zipfile

from mmg_tuner import _limits
from mmg_tuner._atomic import write_atomic
from mmg_tuner._outdir import LOCK_NAME, OutputDir
from mmg_tuner.cli import simulate as cli_simulate
from mmg_tuner.cli import tune as cli_tune
from mmg_tuner.cli.common import run_command, write_new_file
from mmg_tuner.core.ship import load_params_file, load_ship
from mmg_tuner.data.csv_io import read_csv_table, trial_csv_text
from mmg_tuner.data.esso import read_esso_table
from mmg_tuner.data.topics import load_topic_map
from mmg_tuner.errors import (ConfigError, DiagnosisError, MmgTunerError, TrialDataError,
                              TuningError)
import mmg_tuner.learn.residual  # noqa: F401  (imported here: its import is no reader's cost)
import numpy as np
import pytest

MB = 1 << 20
WALL_S = 5.0
PEAK_BYTES = 300 * MB
REPO = Path(__file__).resolve().parents[2]


def bounded(fn, *args, **kw):
    """Call fn, returning (result or exception); assert the issue's time and memory bound."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        try:
            out = fn(*args, **kw)
        except MmgTunerError as exc:
            out = exc
        wall = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert wall < WALL_S, f'{wall:.1f} s'
    assert peak < PEAK_BYTES, f'{peak / MB:.0f} MB'
    return out


def refused(fn, *args, error=MmgTunerError, names=None, says=None, **kw):
    """Assert a clean refusal: the error class, one line, at most a screen, naming the file."""
    exc = bounded(fn, *args, **kw)
    assert isinstance(exc, error), f'not refused: {exc!r}'
    msg = str(exc)
    assert '\n' not in msg and len(msg) <= 1000, msg[:2000]
    if names is not None:
        assert str(names) in msg, msg
    for word in ([says] if isinstance(says, str) else says or []):
        assert any(w in msg for w in word.split('|')), msg
    assert 'allow_pickle' not in msg and 'Traceback' not in msg
    return msg


def one_error_line(capsys, code, status=2):
    """Return the single ERROR line a command printed (exit status checked, no traceback)."""
    err = capsys.readouterr().err
    assert code == status, err
    assert 'Traceback' not in err
    lines = [ln for ln in err.splitlines() if ln.startswith('ERROR:')]
    assert len(lines) == 1, err
    assert len(lines[0]) <= 1010
    return lines[0]


def run_main(main, argv):
    """
    Run a command's main in-process (within the bounds); return its exit status.

    Run once unbounded first: the bound is on what the input costs, not on the first import of
    the command's modules or a cold compile cache on a loaded machine (45 s seen in CI).
    """
    def call():
        with pytest.raises(SystemExit) as stop:
            main(argv)
        return stop.value.code
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        call()
    return bounded(call)


# ------------------------------------------------------------------------------- hostile YAML
def _bomb() -> str:
    lines = ['a0: &a0 [' + ', '.join(['"lol"'] * 9) + ']']
    for i in range(1, 10):
        lines.append(f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']')
    return 'params:\n  R_0: 0.02\n' + '\n'.join(lines) + '\n'


YAML_CASES = {
    'alias_bomb': (_bomb(), 'alias'),
    'deep_flow': ('x: ' + '[' * 200_000 + ']' * 200_000 + '\n', 'nested deeper than'),
    'deep_block': ('- ' * 100_000 + '1\n', 'nested deeper than'),
    'too_large': ('# padding\n' * 150_000 + 'params: {R_0: 0.02}\n', 'the limit|at most 1 MB'),
    'not_utf8': (b'params: {R_0: \xff\xfe}\n', 'not UTF-8'),
    'invalid_long_line': ('params: [' + 'x' * 400_000 + '\n', 'not valid YAML'),
}
"""A YAML file of each hostile kind (text, a word its refusal says)."""


def _write(path: Path, content) -> Path:
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return path


def _read_measured(p):
    from mmg_tuner.diagnosis import measured
    return measured.load(p)


def _read_manifest(p):
    from mmg_tuner.fleet.manifest import load_manifest
    return load_manifest(p)


def _read_residual(p):
    from mmg_tuner.learn.residual import load_residual
    return load_residual(p)


YAML_READERS = {
    'ship_config': lambda p: load_ship(p),
    'params_overlay': lambda p: load_ship('suzaku', p),
    'topic_map': load_topic_map,
    'fleet_manifest': _read_manifest,
    'measurements': _read_measured,
    'residual_params': _read_residual,
}


@pytest.mark.parametrize('kind', sorted(YAML_CASES))
@pytest.mark.parametrize('reader', sorted(YAML_READERS))
def test_hostile_yaml_is_refused_in_bounded_time_and_memory(reader, kind, tmp_path):
    text, word = YAML_CASES[kind]
    path = _write(tmp_path / f'{kind}.yaml', text)
    refused(YAML_READERS[reader], path, names=path, says=word)


def test_alias_bomb_as_simulate_params_is_one_short_error_line(tmp_path, capsys):
    path = _write(tmp_path / 'bomb.yaml', _bomb())
    code = run_main(cli_simulate.main, ['--params', str(path), '--duration', '10',
                                        '--out', str(tmp_path / 'run.csv')])
    line = one_error_line(capsys, code)
    assert str(path) in line and 'alias' in line
    assert not (tmp_path / 'run.csv').exists()


def test_a_few_aliases_are_still_yaml(tmp_path):
    path = _write(tmp_path / 'p.yaml', 'note: &n hello\nship_config: *n\nparams: {R_0: 0.02}\n')
    assert load_params_file(path) == {'R_0': 0.02}


# ----------------------------------------------------------------- unknown keys in an overlay
def test_params_overlay_with_many_unknown_keys_names_the_first_few(tmp_path):
    body = ''.join(f'junk_{i}: {i}\n' for i in range(5000))
    path = _write(tmp_path / 'p.yaml', 'params: {R_0: 0.02}\n' + body)
    msg = refused(load_ship, 'suzaku', path, error=ConfigError, names=path,
                  says=["'junk_0'", "'junk_2'", '4997 more', 'params'])
    assert 'junk_3' not in msg


def test_params_overlay_with_a_typo_key_is_refused(tmp_path):
    path = _write(tmp_path / 'p.yaml', 'params: {R_0: 0.02}\nresidul: net.npz\n')
    refused(load_ship, 'suzaku', path, error=ConfigError, names=path, says="'residul'")


def test_params_overlay_with_the_written_keys_is_read(tmp_path):
    path = _write(tmp_path / 'p.yaml', 'ship: suzaku\nship_config: x.yaml\nnote: n\n'
                  'provenance: {a: 1}\nparams: {R_0: 0.021}\n')
    assert load_ship('suzaku', path)['R_0'] == 0.021


def test_a_huge_key_in_a_ship_config_is_quoted_short(tmp_path):
    path = _write(tmp_path / 's.yaml', '? ' + 'k' * 500_000 + '\n: 1\nmodel: container\n')
    refused(load_ship, path, error=ConfigError, names=path, says='unknown top-level key')


# -------------------------------------------------------------------------------- hostile JSON
def test_json_nested_deep_is_refused_before_parsing():
    refused(_limits.json_loads, '[' * 5_000_000 + ']' * 5_000_000, 'x.json', says='nested')


def test_json_brackets_inside_strings_do_not_count():
    doc = {'a': '[' * 10_000, 'b': ['{"x"]', {'c': '\\"[['}]}
    assert _limits.json_loads(json.dumps(doc), 'x.json') == doc


def test_json_larger_than_its_limit_is_refused(tmp_path):
    path = _write(tmp_path / 'big.json', '[' + '1,' * (600_000) + '1]')
    refused(_limits.load_json, path, 'record', limit=1 * MB, names=path, says='limit')


def test_resume_args_json_nested_deep_is_one_error_line(tmp_path, capsys):
    out = tmp_path / 'handed_over'
    out.mkdir()
    _write(out / 'args.json', '[' * 100_000 + ']' * 100_000)
    code = run_main(cli_tune.main, ['--resume', str(out)])
    line = one_error_line(capsys, code)
    assert 'args.json' in line and 'nested' in line


def test_diagnosis_checkpoint_json_nested_deep_is_refused(tmp_path):
    from mmg_tuner.diagnosis.checkpoint import SearchCheckpoint
    path = _write(tmp_path / 'checkpoint.json', '{"a": ' + '[' * 100_000 + ']' * 100_000 + '}')
    refused(SearchCheckpoint, path, 'fp', resume=True, error=DiagnosisError, names=path,
            says=['nested', 'without --resume'])


def test_diagnosis_json_for_advice_nested_deep_is_refused(tmp_path):
    from mmg_tuner.diagnosis.advice import load_advice
    path = _write(tmp_path / 'diagnosis.json', '[' * 100_000 + ']' * 100_000)
    refused(load_advice, path, error=DiagnosisError, names=path, says='nested')


def test_fleet_record_nested_deep_is_no_record(tmp_path):
    from mmg_tuner.fleet.resume import RECORD, read_record
    _write(tmp_path / RECORD, '[' * 100_000 + ']' * 100_000)
    assert bounded(read_record, tmp_path) is None


# --------------------------------------------------------------------------------- hostile npz
def _npy(arr) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.asanyarray(arr), allow_pickle=True)
    return buf.getvalue()


def _npy_header_only(shape, dtype='<f8') -> bytes:
    """Return an .npy member whose header declares ``shape`` but which holds no data."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {'descr': dtype, 'fortran_order': False,
                                               'shape': shape})
    return buf.getvalue()


def _zip(path: Path, members: dict) -> Path:
    with zipfile.ZipFile(path, 'w', zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def _net_members(meta='{}', **extra) -> dict:
    """Return the members of a small, valid residual network file (learn/residual.py)."""
    from mmg_tuner.learn.residual import FEATURES, FORMAT
    n_in = 2 * len(FEATURES)   # window 2
    arrays = {'format': np.array(FORMAT), 'window': np.array(2, np.int64),
              'dt_s': np.array(1.0), 'physics': np.array(True), 'seed': np.array(0, np.int64),
              'n_layers': np.array(2), 'x_mean': np.zeros(len(FEATURES)),
              'x_std': np.ones(len(FEATURES)),
              'y_scale': np.ones(3), 'features': np.array(FEATURES), 'meta': np.array(meta),
              'W0': np.zeros((4, n_in)), 'b0': np.zeros(4), 'W1': np.zeros((3, 4)),
              'b1': np.zeros(3)}
    out = {f'{k}.npy': _npy(v) for k, v in arrays.items()}
    out.update(extra)
    return out


def _load_net(path):
    from mmg_tuner.learn.residual import ResidualNet
    return ResidualNet.load(path)


def test_a_valid_network_file_is_read(tmp_path):
    net = _load_net(_zip(tmp_path / 'net.npz', _net_members(meta='{"a": [1, 2]}')))
    assert net.meta == {'a': [1, 2]} and len(net.weights) == 2


def test_etc_passwd_as_network_is_not_an_npz_archive():
    msg = refused(_load_net, '/etc/passwd', error=ConfigError, names='/etc/passwd',
                  says='not an .npz archive')
    assert 'pickle' not in msg


NPZ_CASES = {
    # an extra member of 200 MB of zeros, compressed to ~200 kB: refused unread
    'unknown_zero_member': (
        lambda: {'zeros.npy': _npy_header_only((25 * MB,)) + bytes(200 * MB)}, 'refused unread'),
    'huge_declared_shape': ({'W0.npy': _npy_header_only((400_000, 400_000))},
                            'more than the limit'),
    'shape_beyond_data': ({'W0.npy': _npy_header_only((1000, 1000))}, 'truncated'),
    'object_dtype': ({'W0.npy': _npy(np.array([{'a': 1}, None], dtype=object))},
                     'Python objects'),
    'not_npy_member': ({'W0': b'\x00' * 64}, 'refused unread'),
    'npy_name_not_npy': ({'W0.npy': b'just bytes, no npy header'}, 'not an .npy'),
    'deep_meta': ({'meta.npy': _npy(np.array('[' * 50_000 + ']' * 50_000))}, 'nested'),
}
"""Per kind: the hostile members of a network file (replacing or added), a word refused with."""


@pytest.mark.parametrize('kind', sorted(NPZ_CASES))
def test_hostile_network_npz_is_refused(kind, tmp_path):
    extra, word = NPZ_CASES[kind]
    path = _zip(tmp_path / f'{kind}.npz', _net_members(**(extra() if callable(extra) else extra)))
    assert path.stat().st_size < 10 * MB
    refused(_load_net, path, error=ConfigError, names=path, says=word)


def test_network_named_by_a_params_file_as_simulate_is_one_error_line(tmp_path, capsys):
    _write(tmp_path / 'net.npz', Path('/etc/passwd').read_bytes())
    params = _write(tmp_path / 'p.yaml', 'ship: suzaku\nparams: {R_0: 0.02}\nresidual: net.npz\n')
    code = run_main(cli_simulate.main, ['--params', str(params), '--duration', '10',
                                        '--out', str(tmp_path / 'run.csv')])
    line = one_error_line(capsys, code)
    assert 'net.npz' in line and 'not an .npz archive' in line


def _checkpoint_members(**extra) -> dict:
    meta = json.dumps({'format': 'x', 'version': 0})
    members = {'meta.npy': _npy(np.array(meta)), 'best_z.npy': _npy(np.zeros(2))}
    members.update(extra)
    return members


CHECKPOINT_CASES = {
    'not_npy_member': ({'best_z': b'raw bytes'}, 'refused unread'),
    'npy_name_not_npy': ({'best_z.npy': b'raw bytes'}, 'not an .npy'),
    'unknown_member': ({'evil.npy': _npy(np.zeros(3))}, 'refused unread'),
    'object_dtype': ({'best_z.npy': _npy(np.array([None], dtype=object))}, 'Python objects'),
    'huge_shape': ({'cma._C.npy': _npy_header_only((1 << 20, 1 << 20))}, 'limit'),
    'deep_meta': ({'meta.npy': _npy(np.array('{"a":' + '[' * 50_000 + ']' * 50_000 + '}'))},
                  'nested'),
    'not_a_zip': (None, 'not a tuning checkpoint'),
}
"""Per kind: a tuning checkpoint's hostile members and a word its refusal says."""


@pytest.mark.parametrize('kind', sorted(CHECKPOINT_CASES))
def test_hostile_tuning_checkpoint_is_refused(kind, tmp_path):
    from mmg_tuner.tuning.tuner import Tuner
    extra, word = CHECKPOINT_CASES[kind]
    path = tmp_path / 'checkpoint.npz'
    if extra is None:
        _write(path, b'PK\x01\x02' + b'x' * 100)   # no zip's local header
    else:
        _zip(path, _checkpoint_members(**extra))
    tuner = Tuner.__new__(Tuner)   # _decode reads the file before it needs the problem
    refused(tuner._decode, path.read_bytes(), path, error=TuningError, names=path,
            says=[word, 'without --resume'] if extra is not None else [word])


# --------------------------------------------------------------------------------- CSV limits
def test_csv_with_a_10_mb_line_is_refused_quickly(tmp_path):
    path = _write(tmp_path / 'one_line.csv', 't,' * (5 * MB - 1) + 't\n0\n')
    refused(read_csv_table, path, error=TrialDataError, names=path, says='characters')


def test_csv_with_a_long_data_line_is_refused(tmp_path):
    path = _write(tmp_path / 'rows.csv', 't,x,y,psi,u,v,r,rpm,rudder\n' + '0,' * 100_000 + '0\n')
    refused(read_csv_table, path, error=TrialDataError, names=path, says='line 2')


def test_esso_csv_with_a_long_line_is_refused(tmp_path):
    path = _write(tmp_path / 'esso.csv', 'time,' + 'x' * 200_000 + '\n1\n')
    refused(read_esso_table, path, error=TrialDataError, names=path, says='characters')


def test_bollard_table_with_a_long_line_is_refused(tmp_path):
    from mmg_tuner.tuning.lo_go import read_bollard_table
    path = _write(tmp_path / 'bollard.csv', 'n,thrust\n' + '1' * 100_000 + ',2\n')
    refused(read_bollard_table, path, error=TuningError, names=path, says='characters')


def test_bollard_table_larger_than_its_limit_is_refused(tmp_path):
    from mmg_tuner.tuning.lo_go import read_bollard_table
    path = _write(tmp_path / 'bollard.csv', 'n,thrust\n' + '1,2\n' * 400_000)
    refused(read_bollard_table, path, error=TuningError, names=path, says='limit')


# ---------------------------------------------------------------------------- error lines
def test_an_error_line_is_never_longer_than_a_screen(capsys):
    def command(argv):
        raise ConfigError('x.yaml: value ' + 'v' * 2_000_000 + '\nsecond line')
    code = run_command(command, [])
    line = one_error_line(capsys, code)
    assert 'characters cut' in line


def test_clip_says_how_long_the_quoted_text_was():
    assert _limits.clip('a' * 500, 10) == 'aaaaaaaaaa... (500 characters)'
    assert _limits.clip('short') == 'short'


# ------------------------------------------------------------------ same data under two names
@pytest.fixture(scope='module')
def trial(suzaku):
    from mmg_tuner.data.generate import generate_trial, SensorNoise
    return generate_trial(suzaku, 'turning', 35, None, 106.0, 3.086, 30.0, 1.0, SensorNoise(), 5,
                          'turn')[1]


def test_the_same_trial_under_two_names_is_read_once(trial, tmp_path, caplog):
    import mmg_tuner as mt
    (tmp_path / 'a').mkdir()
    (tmp_path / 'b').mkdir()
    _write(tmp_path / 'a' / 'turn.csv', trial_csv_text(trial))
    _write(tmp_path / 'b' / 'copy_of_turn.csv', trial_csv_text(trial))
    with caplog.at_level(logging.WARNING):
        trials = bounded(mt.load_trials, [tmp_path / 'a', tmp_path / 'b'])
    assert [t.name for t in trials] == ['turn']
    warned = [r.getMessage() for r in caplog.records if 'same data' in r.getMessage()]
    assert len(warned) == 1 and 'turn.csv' in warned[0] and 'copy_of_turn.csv' in warned[0]


def test_different_trials_are_all_kept(trial, tmp_path):
    import mmg_tuner as mt
    other = trial.resampled(trial.dt)
    other.states = other.states.copy()
    other.states[:, 0] += 1.0
    _write(tmp_path / 'one.csv', trial_csv_text(trial))
    _write(tmp_path / 'two.csv', trial_csv_text(other))
    assert sorted(t.name for t in mt.load_trials(tmp_path)) == ['one', 'two']


# -------------------------------------------------------------- options that cancel each other
def test_recipe_polish_with_shoot_every_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / 'out'
    code = run_main(cli_tune.main, [str(REPO / 'data' / 'esso_osaka_frt'), '--ship',
                                    'esso_osaka_3m', '--shoot-every', '100', '--out', str(out)])
    line = one_error_line(capsys, code)
    assert '--shoot-every 100' in line and '--max-evals 0' in line and 'recipe' in line
    assert not out.exists()


def test_max_evals_0_with_shoot_every_on_the_command_line_is_refused(tmp_path, capsys):
    code = run_main(cli_tune.main, ['x.csv', '--max-evals', '0', '--polish', '50',
                                    '--shoot-every', '20', '--out', str(tmp_path / 'o')])
    line = one_error_line(capsys, code)
    assert '--shoot-every 20' in line and '--max-evals 0' in line and 'recipe' not in line


def test_api_refuses_max_evals_0_with_shoot_every():
    import mmg_tuner as mt
    with pytest.raises(TuningError, match='shoot_every_s.*cancel each other'):
        mt.TuneConfig(max_evals=0, polish=10, shoot_every_s=100.0)


def test_a_tune_that_changed_nothing_says_so_last_and_exits_3(suzaku, trial, tmp_path,
                                                              capsys, monkeypatch):
    from types import SimpleNamespace
    csv = _write(tmp_path / 'turn.csv', trial_csv_text(trial))

    def fake_tune(ship, tune_trials, test_trials, config, **kw):
        names = ship.tuning_targets
        J = SimpleNamespace(tune=1.0, test=None, failed_at_s={})
        return SimpleNamespace(params={n: float(ship[n]) for n in names}, J=J, J_pre=J,
                               choice=None, residual=None, prior_choice=None,
                               bounds_hit=[], evaluations=0,
                               wall_s=0.0, interrupted=False, write=lambda out, **kw: None)

    monkeypatch.setattr(cli_tune.api, 'tune', fake_tune)
    with pytest.raises(SystemExit) as stop:
        cli_tune.main([str(csv), '--max-evals', '10', '--quiet', '--out', str(tmp_path / 'o')])
    code = stop.value.code
    captured = capsys.readouterr()
    assert code == cli_tune.NOTHING_CHANGED == 3, captured.err
    assert captured.out.splitlines()[-1].startswith('nothing changed')


# ------------------------------------------------------------------- modes, lock, glyphs
@pytest.mark.parametrize('mask, mode', [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_get_the_mode_of_the_umask(mask, mode, tmp_path):
    old = os.umask(mask)
    try:
        write_atomic(tmp_path / 'a.txt', 'x')
        write_new_file(tmp_path / 'b.csv', 'x', '--out')
        with OutputDir.open(tmp_path / 'o') as od:
            od.write_bytes('c.bin', b'x')
    finally:
        os.umask(old)
    for p in (tmp_path / 'a.txt', tmp_path / 'b.csv', tmp_path / 'o' / 'c.bin'):
        assert p.stat().st_mode & 0o777 == mode, p


def test_lock_file_removed_on_close_and_on_error(tmp_path):
    with OutputDir.open(tmp_path / 'o') as od:
        assert (od.path / LOCK_NAME).exists()
    assert not (tmp_path / 'o' / LOCK_NAME).exists()
    with pytest.raises(RuntimeError):
        with OutputDir.open(tmp_path / 'p'):
            raise RuntimeError('a failure inside the run')
    assert not (tmp_path / 'p' / LOCK_NAME).exists()


def test_lock_file_removed_when_a_folder_is_never_closed(tmp_path):
    import gc
    od = OutputDir.open(tmp_path / 'o')
    del od
    gc.collect()
    assert not (tmp_path / 'o' / LOCK_NAME).exists()


def test_a_held_folder_is_still_refused_and_free_again_after(tmp_path):
    from mmg_tuner.errors import OutputError
    with OutputDir.open(tmp_path / 'o'):
        with pytest.raises(OutputError, match='in use'):
            OutputDir.open(tmp_path / 'o', resume=True)
    with OutputDir.open(tmp_path / 'o', resume=True):
        pass
    assert os.listdir(tmp_path / 'o') == []


def test_lock_file_removed_after_a_refused_command(tmp_path, capsys):
    out = tmp_path / 'o'
    code = run_main(cli_tune.main, [str(tmp_path / 'missing.csv'), '--max-evals', '5',
                                    '--out', str(out)])
    one_error_line(capsys, code)
    assert not (out / LOCK_NAME).exists()


def test_missing_glyphs_are_said_once_in_our_words(caplog, capsys):
    from matplotlib.figure import Figure
    from mmg_tuner.tuning import plots
    plots._SAID_MISSING.discard('\u8a66')
    with warnings.catch_warnings():
        warnings.simplefilter('error')   # any warning reaching the caller fails the test
        with caplog.at_level(logging.WARNING, logger='mmg_tuner'):
            for _ in range(2):
                fig = Figure()
                fig.add_subplot().set_title('\u8a66\u9a13 trial')
                assert plots.png_bytes(fig)[:4] == b'\x89PNG'
    said = [r.getMessage() for r in caplog.records if 'no glyph' in r.getMessage()]
    assert len(said) == 1 and '\u8a66' in said[0]
    assert 'Glyph' not in capsys.readouterr().err
