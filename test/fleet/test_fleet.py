"""
The fleet: manifest validation, the drift fit and the proof on a real Dask cluster.

The fleet: manifest validation and input hashing (fast), the drift fit (seconds), and the proof on
a real Dask cluster (a `dask scheduler` and two `dask worker` processes on 127.0.0.1, about a
minute): three synthetic ships with different hidden effects, the named causes, a ship's results
equal to the sequential commands' to the bit, and resuming.
"""
from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import math
import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import sys
import time

from mmg_tuner.errors import ConfigError, OutputError
from mmg_tuner.fleet.manifest import load_manifest, manifest_from_dict
from mmg_tuner.fleet.resume import check_fleet_dir, input_digest, read_record, RECORD
import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
DASK = Path(sys.executable).parent / 'dask'


def ship(name='a', **kw):
    return {'name': name, 'ship': 'suzaku', 'tune': ['t1'], 'test': ['t2', 't3'], **kw}


# ------------------------------------------------------------------ manifest validation
@pytest.mark.parametrize('entry, words', [
    (ship(budjet='quick'), ['ships[0] (a)', "'budjet'", "did you mean 'budget'"]),
    (ship(budget='huge'), ['ships[0] (a)', 'budget', "'huge'"]),
    (ship(max_evals=0), ['ships[0] (a)', 'max_evals']),
    (ship(dt=-1), ['ships[0] (a)', 'dt']),
    (ship(name='../x'), ['name', "'../x'"]),
    ({'name': 'a', 'ship': 'suzaku'}, ['ships[0] (a)', '"tune" is required']),
    (ship(tune=[{'path': 't1', 'date': 'last week'}]), ['tune[0].date', "'last week'"]),
    (ship(tune_options={'integrator': 'leapfrog'}), ['ships[0] (a)', 'integrator']),
    (ship(steps=['tune', 'fly']), ['steps']),
])
def test_manifest_errors_name_ship_and_key(entry, words):
    with pytest.raises(ConfigError) as e:
        manifest_from_dict({'ships': [entry]}, 'fleet.yaml')
    msg = str(e.value)
    assert 'fleet.yaml' in msg
    for w in words:
        assert w in msg, msg


def test_manifest_rejects_duplicate_names_and_unknown_top_level_keys():
    with pytest.raises(ConfigError, match=r"ships\[1\].*'a' is already used by ships\[0\]"):
        manifest_from_dict({'ships': [ship('a'), ship('a')]})
    with pytest.raises(ConfigError, match='shipz'):
        manifest_from_dict({'shipz': [ship()]})
    with pytest.raises(ConfigError, match='non-empty list'):
        manifest_from_dict({'ships': []})


def test_manifest_defaults_paths_dates_and_step_options(tmp_path):
    (tmp_path / 'm.yaml').write_text(yaml.safe_dump({
        'defaults': {'budget': 'quick', 'seed': 7, 'tune_options': {'integrator': 'rk4'}},
        'ships': [ship('a', tune=[{'path': 'trials/t1', 'date': dt.date(2024, 3, 1)}, 't0'],
                       max_evals=900, effects=['current']),
                  ship('b', budget='full', ship='cfg/my.yaml')]}))
    m = load_manifest(tmp_path / 'm.yaml')
    a, b = m.ships
    assert a.tune[0].path == tmp_path / 'trials' / 't1' and a.tune[0].date == dt.date(2024, 3, 1)
    assert a.tune[1].date is None and a.test[0].path == tmp_path / 't2'
    # a field both steps have goes to both; one only tune has goes to tune
    assert a.tune_config.seed == a.diagnose_config.seed == 7
    assert a.tune_config.max_evals == 900 and a.diagnose_config.effects == ('current',)
    assert a.tune_config.integrator == 'rk4' and a.diagnose_config.integrator == 'rk4'
    assert a.diagnose_config.budget == 'quick' and b.diagnose_config.budget == 'full'
    assert b.tune_config.integrator == 'rk4' and b.ship == str(tmp_path / 'cfg' / 'my.yaml')
    assert not a.dated  # one date only: no trend
    with pytest.raises(ConfigError, match='cannot read|does not exist'):
        load_manifest(tmp_path / 'missing.yaml')


def test_input_digest_follows_content_and_options_only(tmp_path):
    for n in ('t1', 't2', 't3'):
        (tmp_path / n).mkdir()
        (tmp_path / n / 'data.csv').write_text(f'{n}\n1,2,3\n')
    m = manifest_from_dict({'ships': [ship()]}, tmp_path / 'm.yaml')
    d0 = input_digest(m.ships[0])
    assert input_digest(m.ships[0]) == d0
    os.utime(tmp_path / 't2' / 'data.csv', (1, 1))       # a touch is not a change
    assert input_digest(m.ships[0]) == d0
    (tmp_path / 't2' / 'data.csv').write_text('t2\n1,2,4\n')
    d1 = input_digest(m.ships[0])
    assert d1 != d0
    m2 = manifest_from_dict({'ships': [ship(max_evals=1000)]}, tmp_path / 'm.yaml')
    assert input_digest(m2.ships[0]) not in (d0, d1)
    (tmp_path / 't3' / 'extra.csv').write_text('x')          # a new file in a source folder
    assert input_digest(m.ships[0]) != d1


def test_fleet_out_refuses_a_users_folder(tmp_path):
    (tmp_path / 'mine.txt').write_text('keep')
    with pytest.raises(OutputError, match='not a fleet output'):
        check_fleet_dir(tmp_path)
    with pytest.raises(OutputError, match='existing file'):
        check_fleet_dir(tmp_path / 'mine.txt')
    assert check_fleet_dir(tmp_path / 'new') is False


def test_fleet_command_usage_errors(tmp_path, capsys):
    from mmg_tuner.cli.common import run_command
    from mmg_tuner.cli.fleet import command
    (tmp_path / 'm.yaml').write_text(yaml.safe_dump({'ships': [ship(budget='huge')]}))
    assert run_command(command, [str(tmp_path / 'm.yaml'), '--out', str(tmp_path / 'o')]) == 2
    assert 'ERROR: manifest' in capsys.readouterr().err
    assert run_command(command, [str(tmp_path / 'm.yaml'), '--out', 'o', '--workers', '0']) == 2
    assert '--workers' in capsys.readouterr().err


# ------------------------------------------------------------------ drift over dated trials
def test_trend_sees_a_rising_resistance(suzaku):
    """
    Trials of two dates, the later with R_0 30 % higher (fouling).

    The per-date fit follows it and the ship is flagged.
    """
    from mmg_tuner.data.generate import SensorNoise, generate_trial
    from mmg_tuner.fleet.jobs import Loaded, trend
    groups = [('2024-01-10', 1.0), ('2024-07-10', 1.3)]
    trials, dates = [], {}
    for d, f in groups:
        truth = suzaku.with_params({'R_0': suzaku['R_0'] * f})
        for k, (m, a) in enumerate((('turning', 35), ('zigzag', 20))):
            dates[len(trials)] = d
            trials.append(generate_trial(truth, m, a, None, 106.0, 3.086, 200.0, 1.0,
                                         SensorNoise(), 10 + k, f'{m}{a}_{d}')[1])
    m = manifest_from_dict({'ships': [ship(tune=[{'path': 'x', 'date': groups[0][0]}],
                                           test=[{'path': 'y', 'date': groups[1][0]}])]})
    r = trend(m.ships[0], Loaded(suzaku, trials, [], dates, {}), {})
    v = [g['value'] for g in r['groups']]
    assert v[0] == pytest.approx(suzaku['R_0'], rel=0.1)
    assert v[1] == pytest.approx(1.3 * suzaku['R_0'], rel=0.1)
    assert r['drifts'] and r['direction'] == 'rising' and r['slope_per_year'] > 0


# ------------------------------------------------------------------ the proof on a cluster
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def dask_cluster(n_workers: int = 2, timeout_s: float = 60.0):
    """Run a `dask scheduler` and n `dask worker` processes on 127.0.0.1; always shut down."""
    from distributed import Client
    port = _free_port()
    addr = f'tcp://127.0.0.1:{port}'
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]),
        'NUMBA_NUM_THREADS': '1'}
    procs = []
    try:
        procs.append(subprocess.Popen(
            [str(DASK), 'scheduler', '--host', '127.0.0.1', '--port', str(port),
             '--no-dashboard', '--no-show'], env=env, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        for _ in range(n_workers):
            procs.append(subprocess.Popen(
                [str(DASK), 'worker', addr, '--nthreads', '1', '--host', '127.0.0.1',
                 '--no-dashboard', '--death-timeout', str(int(timeout_s))], env=env,
                start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with Client(addr, timeout=timeout_s) as c:
            c.wait_for_workers(n_workers, timeout=timeout_s)
        yield addr
    finally:
        for p in reversed(procs):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGTERM)   # its own session: the worker's children too
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=15)


MANEUVERS = ['turning:35', 'zigzag:20', 'turning:-25', 'random:30', 'zigzag:-15', 'turning:-35']
HIDDEN = {'cur': ['--effect', 'current_speed=0.3', '--effect', 'current_dir=2.0'],
          'rud': ['--effect', 'rudder_offset=0.05'],
          'clean': []}
TUNE = ['turning_p35', 'turning_m25', 'zigzag_m15']
TEST = ['zigzag_p20', 'random_p30', 'turning_m35']
OPTIONS = {'budget': 'quick', 'max_effects': 1, 'max_evals': 1500,
           'effects': ['current', 'rudder_offset', 'yaw_moment_bias'], 'plots': False}


def _generate(out: Path, extra: list[str], seed: int = 0, maneuvers=MANEUVERS) -> None:
    from mmg_tuner.cli.generate import command as generate
    with contextlib.redirect_stdout(io.StringIO()):
        assert generate(['--out', str(out), '--duration', '240', '--rate-hz', '1',
                         '--seed', str(seed), '--maneuvers', *maneuvers, *extra]) == 0


def _sequential(trials: Path, out: Path) -> None:
    """
    Run the same ship with the sequential commands, as a user would run them.

    Each command a fresh process (as the dask workers are), not this test process, whose numba and
    BLAS state earlier tests may have changed.
    """
    t = [str(trials / n) for n in TUNE]
    s = [str(trials / n) for n in TEST]
    for cmd in (['tune', *t, '--test', *s, '--ship', 'suzaku', '--out', str(out / 'tune'),
                 '--max-evals', '1500', '--dt', '1.0', '--no-plots', '--quiet'],
                ['diagnose', *t, '--test', *s, '--ship', 'suzaku', '--out',
                 str(out / 'diagnose'), '--budget', 'quick', '--max-effects', '1', '--effects',
                 'current', 'rudder_offset', 'yaw_moment_bias', '--dt', '1.0', '--no-plots',
                 '--quiet']):
        run = subprocess.run([sys.executable, '-m', f'mmg_tuner.cli.{cmd[0]}', *cmd[1:]],
                             capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]


def _results(folder: Path) -> dict:
    """Return what must be equal to the bit: params and every J (wall times excluded)."""
    rep = json.loads((folder / 'tune' / 'report.json').read_text())
    dx = json.loads((folder / 'diagnose' / 'diagnosis.json').read_text())
    return {'tune_params.yaml': (folder / 'tune' / 'params.yaml').read_text(),
            'diagnose_params.yaml': (folder / 'diagnose' / 'params.yaml').read_text(),
            'J': rep['J'], 'per_trial': rep['per_trial'], 'params': rep['params'],
            'causes': dx['causes'], 'baseline': dx['baseline'], 'final': dx['final'],
            'dx_params': dx['params'], 'candidates': dx['candidates']}


@pytest.mark.skipif(not DASK.is_file(), reason='the dask command is not installed')
def test_fleet_on_a_real_dask_cluster(tmp_path, capsys):
    from mmg_tuner.cli.fleet import command as fleet
    for name, extra in HIDDEN.items():
        _generate(tmp_path / 'trials' / name, extra)
    manifest = tmp_path / 'fleet.yaml'
    manifest.write_text(yaml.safe_dump({'defaults': OPTIONS, 'ships': [
        {'name': n, 'ship': 'suzaku', 'tune': [f'trials/{n}/{t}' for t in TUNE],
         'test': [f'trials/{n}/{t}' for t in TEST]} for n in HIDDEN]}))
    out = tmp_path / 'out'
    with dask_cluster(2) as addr:
        t0 = time.perf_counter()
        assert fleet([str(manifest), '--out', str(out), '--scheduler', addr, '--quiet']) == 0
        first_s = time.perf_counter() - t0
        doc = json.loads((out / 'fleet.json').read_text())
        assert doc['causes'] == {'current': ['cur'], 'rudder_offset': ['rud']}
        assert doc['ships']['clean']['causes'] == [] and doc['counts']['done'] == 3
        assert (out / 'fleet.md').is_file() and (out / 'fleet.png').stat().st_size > 1000

        # a ship run with the sequential commands, as a user would: equal to the bit. One
        # ship (the one with a named cause) proves the worker runs the commands' code path;
        # each further ship would cost two fresh processes and a tune and diagnosis more.
        _sequential(tmp_path / 'trials' / 'rud', tmp_path / 'seq' / 'rud')
        assert _results(out / 'rud') == _results(tmp_path / 'seq' / 'rud')
        first = {name: _results(out / name) for name in HIDDEN}

        # a second run skips every ship and rewrites none of their files
        stamp = {p: p.stat().st_mtime_ns for p in out.rglob('*') if p.parent != out}
        assert fleet([str(manifest), '--out', str(out), '--scheduler', addr, '--quiet']) == 0
        again = json.loads((out / 'fleet.json').read_text())
        assert again['counts'] == {'done': 0, 'skipped': 3, 'failed': 0}
        assert {p: p.stat().st_mtime_ns for p in stamp} == stamp
        assert again['causes'] == doc['causes']

        # one ship's trial changes, another's run was killed before its record: those two
        # are redone, the third is skipped; a missing bag fails its ship alone
        _generate(tmp_path / 'regen', [], seed=5, maneuvers=['zigzag:20'])
        shutil.rmtree(tmp_path / 'trials' / 'clean' / 'zigzag_p20')
        shutil.copytree(tmp_path / 'regen' / 'zigzag_p20',
                        tmp_path / 'trials' / 'clean' / 'zigzag_p20')
        (out / 'rud' / 'fleet_ship.json').unlink()
        ships = yaml.safe_load(manifest.read_text())
        ships['ships'].append({'name': 'broken', 'ship': 'suzaku', 'tune': ['trials/none'],
                               'test': [f'trials/cur/{t}' for t in TEST]})
        manifest.write_text(yaml.safe_dump(ships))
        assert fleet([str(manifest), '--out', str(out), '--scheduler', addr, '--quiet']) == 1
        third = json.loads((out / 'fleet.json').read_text())
        status = {n: e['status'] for n, e in third['ships'].items()}
        assert status == {'cur': 'skipped', 'rud': 'done', 'clean': 'done', 'broken': 'failed'}
        assert 'trials/none' in third['failed']['broken'] and 'load' in third['failed']['broken']
        assert _results(out / 'rud') == _results(tmp_path / 'seq' / 'rud') == first['rud']
        assert _results(out / 'clean') != first['clean']
        assert _results(out / 'cur') == first['cur']
    print(f'fleet of 3 ships on 2 dask workers: {first_s:.0f} s', file=sys.stderr)
    assert math.isfinite(first_s)


@pytest.mark.parametrize('files', [['../outside.txt'], ['/etc/hosts'], ['tune/../../x'], [3]])
def test_a_record_naming_files_outside_its_ship_folder_is_no_record(tmp_path, files):
    """A rerun deletes the files the last record lists: one naming others' files is refused."""
    ship_dir = tmp_path / 'out' / 'a'
    ship_dir.mkdir(parents=True)
    rec = {'name': 'a', 'digest': 'd', 'status': 'ok', 'files': ['tune/params.yaml']}
    (ship_dir / RECORD).write_text(json.dumps(rec))
    assert read_record(ship_dir).files == ['tune/params.yaml']
    (ship_dir / RECORD).write_text(json.dumps({**rec, 'files': files}))
    assert read_record(ship_dir) is None
