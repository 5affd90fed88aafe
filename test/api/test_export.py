"""
``export``: the tug model for MPC, loaded without mmg_tuner, against the package's simulator.

(a) dynamics.casadi, loaded in an isolated interpreter with casadi and numpy only, steps like
ShipSimulator (RK4 and Euler) from the simulator's own states, azimuth rate limit and astern
thrust included: equal to 1e-9. (b) doc/examples/tug_heading_lqr.py designs an LQR on the
exported (A, B) and holds a 20 deg heading change on the simulator within the limits.
"""
import json
from pathlib import Path
import subprocess
import sys

from mmg_tuner.api.exporting import export_model
from mmg_tuner.cli.export import command
from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.stepper import ShipSimulator
import numpy as np
import pytest

pytest.importorskip('casadi')

ROOT = Path(__file__).resolve().parents[2]
DT = 0.2
# (steps, n_port, n_stbd, azimuth command port, stbd [rad]): ahead, a 40 deg order (rate
# limit active), astern thrust on one side, full ahead with opposite azimuths
SCHEDULE = [(10, 8.0, 8.0, 0.0, 0.0), (30, 10.0, 6.0, 0.7, 0.7), (30, -4.0, 7.0, -0.5, 0.3),
            (30, 12.0, 12.0, 0.2, -0.2)]

ISOLATED = r"""
import json, sys
import casadi as ca
import numpy as np
d = np.load(sys.argv[1])
dyn = ca.Function.load(sys.argv[2])
X, U, XN, dt = d['X'], d['U'], d['XN'], float(d['dt'])
step = np.vstack([np.array(dyn(X[k], U[k], dt)[0]).ravel() for k in range(len(X))])
x = X[0].copy()
free = []
for k in range(len(X)):
    x = np.array(dyn(x, U[k], dt)[0]).ravel()
    free.append(x)
print(json.dumps({'step': float(np.max(np.abs(step - XN))),
                  'free': float(np.max(np.abs(np.vstack(free) - XN))),
                  'mmg_tuner_loaded': any(m.split('.')[0] == 'mmg_tuner' for m in sys.modules),
                  'path': sys.path}))
"""


@pytest.fixture(scope='module')
def exports(tmp_path_factory):
    base = tmp_path_factory.mktemp('export')
    return {integ: export_model('qiuxin_tug', base / integ, dt=DT, integrator=integ)
            for integ in ('rk4', 'euler')}


def _simulator_run(integrator):
    sim = ShipSimulator(load_ship('qiuxin_tug'), dt=DT, x0=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
                        integrator=integrator, commands={'n_port': 8.0, 'n_stbd': 8.0})
    X, U, XN = [], [], []

    def state():
        a = sim.actuator_states()
        return np.concatenate([sim.observed(), [a['alpha_port'], a['alpha_rate_port'],
                                                a['alpha_stbd'], a['alpha_rate_stbd']]])
    for steps, n_p, n_s, a_p, a_s in SCHEDULE:
        for name, v in (('n_port', n_p), ('n_stbd', n_s), ('azimuth_port', a_p),
                        ('azimuth_stbd', a_s)):
            assert sim.set_command(name, v) == ''
        for _ in range(steps):
            X.append(state())
            U.append([n_p, n_s, a_p, a_s])
            assert sim.step(), sim.failure
            XN.append(state())
    return np.array(X), np.array(U), np.array(XN)


@pytest.mark.parametrize('integrator', ['rk4', 'euler'])
def test_exported_step_matches_the_simulator_without_mmg_tuner(exports, integrator, tmp_path):
    X, U, XN = _simulator_run(integrator)
    # the drive slews at its limit: the rate approaches 0.8 rad/s with the motor's lag
    assert np.ptp(X[:, 7]) > 0.5 and 0.7 < np.max(np.abs(X[:, 7])) <= 0.8 + 1e-12
    np.savez(tmp_path / 'run.npz', X=X, U=U, XN=XN, dt=DT)
    (tmp_path / 'check.py').write_text(ISOLATED)
    run = subprocess.run([sys.executable, '-I', str(tmp_path / 'check.py'),
                          str(tmp_path / 'run.npz'),
                          str(exports[integrator].out / 'dynamics.casadi')],
                         cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    res = json.loads(run.stdout)
    assert not res['mmg_tuner_loaded']
    assert str(ROOT) not in res['path']
    assert res['step'] <= 1e-9, res
    assert res['free'] <= 1e-9, res
    print(f'{integrator}: max |F - simulator| per step {res["step"]:.2e}, free run '
          f'{res["free"]:.2e}')


def test_model_json_holds_the_ship_and_a_stable_linearisation(exports):
    res = exports['rk4']
    ship = load_ship('qiuxin_tug')
    model = json.loads((res.out / 'model.json').read_text())
    assert model['hull']['M'] == [[ship['m11'], 0.0, 0.0], [0.0, ship['m22'], ship['m23']],
                                  [0.0, ship['m32'], ship['m33']]]
    assert model['thrusters']['thrust_curve']['p'][2] == ship['thrust_p2']
    assert model['thrusters']['limits']['n_max_rev_s'] == 12.0
    lin = json.loads((res.out / 'linear.json').read_text())
    assert lin['operating_point']['nu_dot_residual'] < 1e-9
    assert lin['x_op'][3] == pytest.approx(1.249, abs=0.01)   # the service speed
    A = np.array(lin['discrete']['A'])[2:, 2:]
    eig = np.sort(np.abs(np.linalg.eigvals(A)))
    assert eig[-1] == pytest.approx(1.0) and eig[-2] < 1.0   # heading integrates, rest decays
    for name in ('dynamics.casadi', 'nu_dot.casadi', 'README.md'):
        assert (res.out / name).is_file()


def test_lqr_example_holds_a_heading_change_on_the_simulator(exports):
    env = {'PYTHONPATH': str(ROOT), 'PATH': '/usr/bin:/bin', 'NUMBA_NUM_THREADS': '1'}
    run = subprocess.run([sys.executable, str(ROOT / 'doc' / 'examples' / 'tug_heading_lqr.py'),
                          str(exports['rk4'].out), '--heading-deg', '20', '--duration', '40'],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    res = json.loads(run.stdout.strip().splitlines()[-1])
    print(res)
    assert res['settling_time_s'] is not None and res['settling_time_s'] < 20.0
    assert res['final_error_deg'] < 0.1
    assert res['within_limits'] and not res['problems']
    assert res['max_n_rev_s'] <= 12.0 and res['max_azimuth_deg'] <= 45.0
    assert abs(res['speed_end_ms'] - 1.249) < 0.05


def test_command_errors_are_one_line(tmp_path, capsys):
    from mmg_tuner.cli.common import run_command
    assert run_command(command, ['--ship', 'suzaku', '--out', str(tmp_path / 'a')]) == 2
    err = capsys.readouterr().err.strip()
    assert '\n' not in err and 'supported families: surge_decoupled' in err
    assert run_command(command, ['--ship', 'qiuxin_tug', '--out', str(tmp_path / 'b'),
                                 '--at', 'u=fast']) == 2
    assert "--at: u = 'fast'" in capsys.readouterr().err
    assert not (tmp_path / 'a').exists() and not (tmp_path / 'b').exists()
    with pytest.raises(SystemExit):
        command(['--help'])
    assert '--integrator' in capsys.readouterr().out


def test_command_exports_a_params_overlay(tmp_path, capsys):
    # what `tune --method lo-go` writes: the ship's name and the identified values
    params = tmp_path / 'params.yaml'
    params.write_text('ship: qiuxin_tug\nparams: {m22: 120.0, m23: -2.0, X_u: -12.0, '
                      'N_r: -30.0, thrust_p2: 0.45}\n')
    out = tmp_path / 'mpc'
    assert command(['--ship', 'qiuxin_tug', '--params', str(params), '--out', str(out),
                    '--at', 'u=0.8,v=0,r=0', '--dt', '0.1']) == 0
    assert 'n_port' in capsys.readouterr().out
    model = json.loads((out / 'model.json').read_text())
    assert model['hull']['M'][1][1:] == [120.0, -2.0]
    assert model['hull']['D']['coefficients']['X_u'] == -12.0
    lin = json.loads((out / 'linear.json').read_text())
    assert lin['x_op'][3] == 0.8 and lin['discrete']['dt'] == 0.1
    # one step of the simulator with the overlay, from the operating point with a turn ordered
    ship = load_ship('qiuxin_tug', params)
    n = lin['u_op'][0]
    sim = ShipSimulator(ship, dt=0.1, x0=[0, 0, 0, 0.8, 0, 0], integrator='rk4',
                        commands={'n_port': n, 'n_stbd': n})
    sim.set_command('azimuth_port', 0.3)
    assert sim.step()
    import casadi
    dyn = casadi.Function.load(str(out / 'dynamics.casadi'))
    x_next = np.array(dyn([0, 0, 0, 0.8, 0, 0, 0, 0, 0, 0], [n, n, 0.3, 0.0], 0.1)[0]).ravel()
    a = sim.actuator_states()
    assert np.max(np.abs(x_next - np.concatenate([sim.observed(), [
        a['alpha_port'], a['alpha_rate_port'], a['alpha_stbd'], a['alpha_rate_stbd']]]))) < 1e-12


def test_a_craft_with_fixed_thrusters_exports_with_its_angles_held_at_zero(tmp_path):
    # the Otter's steering.max_azimuth_deg is 0: the trim leaves its angles out (a zero box
    # is no box to SciPy) and solves the shaft speeds alone
    res = export_model('otter_usv', tmp_path / 'otter')
    op = res.operating_point
    assert op.inputs['azimuth_port'] == 0.0 and op.inputs['azimuth_stbd'] == 0.0
    assert op.residual < 1e-6 and op.state['u'] > 0
    assert op.trimmed == ['n_port', 'n_stbd']   # the angles are not trimmed: they are fixed
