"""The ``simulate`` command, called as a function and as the installed executable."""
import subprocess

from conftest import installed_executable
from mmg_tuner.cli.simulate import command
from mmg_tuner.data.csv_io import read_trial_csv
import numpy as np
import pytest
import yaml


def test_turning_writes_csv_and_prints_indices(tmp_path, capsys):
    out = tmp_path / 'run.csv'
    rc = command(['--ship', 'suzaku', '--maneuver', 'turning', '--rudder-deg', '35', '--rpm',
                  '106', '--speed-kn', '6', '--duration', '900', '--dt', '1.0', '--integrator',
                  'euler', '--rudder-rate', '0', '--out', str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert 'tactical diameter' in text and 'advance' in text
    trial = read_trial_csv(out)
    assert len(trial) == 901 and trial.t[-1] == 900.0
    assert out.read_text().splitlines()[0] == 't,x,y,psi,u,v,r,rpm,rudder'
    assert trial['r'][-1] > 0 and trial['rudder'][5] == pytest.approx(np.radians(35))


def test_zigzag_and_params_overlay(tmp_path, capsys):
    out1, out2 = tmp_path / 'a.csv', tmp_path / 'b.csv'
    args = ['--maneuver', 'zigzag', '--rudder-deg', '20', '--check-deg', '20', '--duration',
            '400']
    assert command(args + ['--out', str(out1)]) == 0
    assert 'first overshoot' in capsys.readouterr().out
    params = tmp_path / 'params.yaml'
    params.write_text(yaml.safe_dump({'params': {'gamma_Rn': 0.3, 'N_r': -0.08}}))
    assert command(args + ['--out', str(out2), '--params', str(params)]) == 0
    assert not np.allclose(read_trial_csv(out1).states, read_trial_csv(out2).states)


def test_bad_input_gives_error_not_traceback(capsys):
    from mmg_tuner.cli.simulate import main
    with pytest.raises(SystemExit) as exc:
        main(['--rpm', '-5'])
    assert exc.value.code == 2
    assert "ERROR: simulate: argument --rpm: '-5' must be > 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(['--ship', 'nonexistent'])
    assert exc.value.code == 2


def test_installed_executable_help():
    exe = installed_executable('simulate')
    if exe is None:
        pytest.skip('package not installed with colcon (run through scripts/test.sh)')
    res = subprocess.run([exe, '--help'], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and '--maneuver' in res.stdout
