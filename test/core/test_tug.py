"""
The twin-azimuth tug (issue 24, part A): its families, its actuator, its configs and its twin.

Physics checked against numbers the test derives on its own from the published coefficients
(doc/reference/mbpe_logo_tug.md): the steady speed where thrust meets the surge damping,
the turning direction the thruster geometry implies, the Coriolis and tau_v switches, the
azimuth drive's lag and rate limit, a differential-thrust craft's turn.
"""
import math

import mmg_tuner as mt
from mmg_tuner.core.simulate import kernel_inputs, simulate
from mmg_tuner.errors import SimulationError
import numpy as np
import pytest

DT = 0.2   # s, the paper's 5 Hz
T = 501    # 100 s


def commands(n=(8.0, 8.0), az=(0.0, 0.0), cmd=None, T=T):
    """Held commands: shaft speeds [rev/s], measured azimuths [rad], optional commands [rad]."""
    out = {'n_port': np.full(T, n[0]), 'n_stbd': np.full(T, n[1]),
           'azimuth_port': np.full(T, az[0]), 'azimuth_stbd': np.full(T, az[1])}
    if cmd is not None:
        out['azimuth_cmd_port'] = np.full(T, cmd[0])
        out['azimuth_cmd_stbd'] = np.full(T, cmd[1])
    return out


@pytest.fixture(scope='module')
def tug():
    return mt.load_ship('qiuxin_tug')


def test_qiuxin_config_holds_the_published_values(tug):
    assert tug.model == 'surge_decoupled'
    assert tug['m'] == pytest.approx(187.6)            # rho * 0.1876 m^3 (Table 1)
    assert tug['m11'] == 138.0574 and tug['N_absv_r'] == -2.3474   # Table 3, first and last
    assert tug['thruster_x_port'] == -0.8 and tug['thruster_y_port'] == -0.163
    assert tug['thruster_y_stbd'] == 0.163
    assert len(tug.tuning_targets) == 22
    assert tug['thrust_scale_port'] == 1.0 and tug['azimuth_offset_stbd'] == 0.0   # neutral


def test_straight_run_settles_where_thrust_meets_the_surge_damping(tug):
    n = 8.0
    run = simulate(tug, [0, 0, 0, 0.0, 0, 0], commands((n, n)), DT, 'rk4')
    assert run.ok
    # independent: 2 k n^2 = -(X_u + X_|u|u u + X_uuu u^2) u with Table 3 and k = 0.4
    roots = np.roots([6.8953, 31.4285, 8.9859, -2 * 0.4 * n * n])
    u_ss = float(max(r.real for r in roots if abs(r.imag) < 1e-12))
    assert u_ss == pytest.approx(1.041, abs=0.001)
    assert run.states[-1, 3] == pytest.approx(u_ss, rel=1e-4)
    assert np.abs(run.states[:, 4:]).max() < 1e-9   # symmetric: no sway, no yaw
    # astern: the same curve (thrust_astern_ratio 1), the same speed backwards
    back = simulate(tug, [0, 0, 0, 0.0, 0, 0], commands((-n, -n)), DT, 'rk4')
    assert back.states[-1, 3] == pytest.approx(-u_ss, rel=1e-4)


def test_azimuth_toward_starboard_turns_the_tug_to_port_and_mirrors(tug):
    a = math.radians(20)
    port = simulate(tug, [0, 0, 0, 1.0, 0, 0], commands(az=(a, a)), DT, 'rk4')
    stbd = simulate(tug, [0, 0, 0, 1.0, 0, 0], commands(az=(-a, -a)), DT, 'rk4')
    assert port.ok and stbd.ok
    # thrusters aft push the stern to starboard: r < 0 (to port), heading decreasing
    r = port.states[-1, 5]
    assert -0.5 < r < -0.1, r
    assert port.states[-1, 2] < -5.0
    np.testing.assert_allclose(stbd.states[:, 3:], port.states[:, 3:] * [1, -1, -1], atol=1e-9)
    # the steady turn is steady: the last 10 s change r by < 0.1 %
    assert abs(port.states[-1, 5] - port.states[-51, 5]) < 1e-3 * abs(r)


def test_more_thrust_on_the_port_thruster_turns_the_tug_to_starboard(tug):
    run = simulate(tug, [0, 0, 0, 1.0, 0, 0], commands((10.0, 4.0)), DT, 'rk4')
    assert run.ok and run.states[-1, 5] > 0.02


def test_the_coriolis_form_switch_matters(tug):
    a = math.radians(20)
    runs = [simulate(tug.with_params({'coriolis_form': form}), [0, 0, 0, 1.0, 0, 0],
                     commands(az=(a, a)), DT, 'rk4') for form in (0, 1)]
    r_ped, r_fos = (run.states[-1, 5] for run in runs)
    # (m23 + m32) / 2 = -7.47 kg m instead of m23 = 1.13 kg m: a 27 % faster steady turn
    assert r_fos < r_ped < 0
    assert 0.15 < r_fos / r_ped - 1 < 0.4, (r_ped, r_fos)
    # a straight run has v = r = 0: there the forms agree
    straight = [simulate(tug.with_params({'coriolis_form': f}), [0, 0, 0, 1.0, 0, 0],
                         commands(), DT, 'rk4').states for f in (0, 1)]
    np.testing.assert_allclose(straight[0], straight[1], rtol=0, atol=1e-12)


def test_the_azimuth_drive_lags_its_command_and_respects_its_rate_limit(tug):
    from mmg_tuner.core.integrate import actuator_outputs   # what the family's forces read
    a = math.radians(30)
    ctrl = kernel_inputs(tug.family, commands(cmd=(a, -a)))
    out = np.empty((T, 4))
    actuator_outputs(tug.kind, tug.params, ctrl, T, DT, out)
    alpha = out[:, 2]
    step = np.diff(alpha)
    assert step.max() <= tug['azimuth_rate_max'] * DT + 1e-12   # 0.8 rad/s drive limit
    assert alpha[1] < a and alpha[-1] == pytest.approx(a, abs=1e-6)
    np.testing.assert_allclose(out[:, 3], -alpha, atol=1e-12)
    assert out[0, 0] == pytest.approx(0.4 * 64)   # F = 0.4 n|n| at 8 rev/s
    # without the rate limit the exact second-order response (k1 = 4, k2 = 3.6):
    # alpha(t) = a (1 - e^(-zw t) (cos(wd t) + zw / wd sin(wd t)))
    free = tug.with_params({'azimuth_rate_max': 0.0})
    actuator_outputs(free.kind, free.params, ctrl, T, DT, out)
    # the angle acting over each step is the mean of its start and end
    t = DT * np.arange(0, 11)
    zw, wd = 1.8, math.sqrt(4.0 - 1.8 ** 2)
    exact = a * (1 - np.exp(-zw * t) * (np.cos(wd * t) + zw / wd * np.sin(wd * t)))
    np.testing.assert_allclose(out[:10, 2], 0.5 * (exact[:-1] + exact[1:]), rtol=1e-9,
                               atol=1e-12)
    # a 45 deg order asks for (k1 / k2) 0.785 = 0.87 rad/s, above the 0.8 rad/s limit: the
    # motor is asked for 0.8 rad/s and its rate rises with the drive's lag 1 / k2:
    # alpha(t) = 0.8 (t - (1 - e^(-k2 t)) / k2) while the loop stays saturated (two steps)
    big = kernel_inputs(tug.family, commands(cmd=(math.radians(45), 0.0)))
    actuator_outputs(tug.kind, tug.params, big, T, DT, out)
    t = DT * np.arange(3)
    slew = 0.8 * (t - (1 - np.exp(-3.6 * t)) / 3.6)
    np.testing.assert_allclose(out[:2, 2], 0.5 * (slew[:-1] + slew[1:]), rtol=1e-9)
    # the lag shows in the ship: slower to turn than with the angle set at once
    lag = simulate(tug, [0, 0, 0, 1.0, 0, 0], commands(cmd=(a, a)), DT, 'rk4')
    now = simulate(tug, [0, 0, 0, 1.0, 0, 0], commands(az=(a, a)), DT, 'rk4')
    assert 0 > lag.states[5, 5] > 0.9 * now.states[5, 5]
    assert lag.states[-1, 5] == pytest.approx(now.states[-1, 5], rel=1e-6)


def test_a_trial_without_a_channel_the_tug_needs_is_refused_naming_it(tug):
    cmd = commands()
    del cmd['azimuth_stbd']
    with pytest.raises(SimulationError, match="'azimuth_stbd'"):
        simulate(tug, [0, 0, 0, 1.0, 0, 0], cmd, DT)


def test_simplified6_runs_the_published_table4_and_its_tau_v_switch_matters():
    s6 = mt.load_ship('qiuxin_tug_simplified6')
    assert s6.model == 'simplified6' and s6['m33'] == 0.0632
    run = simulate(s6, [0, 0, 0, 0.0, 0, 0], commands(), DT, 'rk4', substeps=4)
    # linear surge: 2 k n^2 = d11 u
    assert run.ok and run.states[-1, 3] == pytest.approx(2 * 0.4 * 64 / 44.1878, rel=1e-4)
    a = math.radians(20)
    v = [simulate(s6.with_params({'tau_v': on}), [0, 0, 0, 1.0, 0, 0], commands(az=(a, a)),
                  DT, 'rk4', substeps=4).states[5, 4] for on in (1, 0)]
    assert abs(v[0] - v[1]) > 0.05, v   # with and without the thrusters' sway force


def test_the_otter_turns_under_differential_thrust():
    otter = mt.load_ship('otter_usv')
    assert otter.model == 'surge_decoupled' and otter['m22'] == 162.5
    straight = simulate(otter, [0, 0, 0, 0.0, 0, 0], commands((10.0, 10.0)), DT, 'rk4')
    # linear surge damping (otter.py): 2 k n^2 = -X_u u
    assert straight.states[-1, 3] == pytest.approx(2 * 0.43742 * 100 / 77.554, rel=1e-4)
    port = simulate(otter, [0, 0, 0, 1.0, 0, 0], commands((10.0, 5.0)), DT, 'rk4')
    stbd = simulate(otter, [0, 0, 0, 1.0, 0, 0], commands((5.0, 10.0)), DT, 'rk4')
    assert port.ok and stbd.ok
    r = port.states[-1, 5]
    assert 0.05 < r < 1.0, r   # more thrust to port: a turn to starboard
    np.testing.assert_allclose(stbd.states[:, 3:], port.states[:, 3:] * [1, -1, -1], atol=1e-9)
    # astern on one side spins it on the spot (reverse thrust 0.58 of ahead)
    spin = simulate(otter, [0, 0, 0, 0.0, 0, 0], commands((10.0, -10.0)), DT, 'rk4')
    assert spin.states[-1, 5] > 0.2 and abs(spin.states[-1, 3]) < 0.5


def test_generate_writes_the_paper_manoeuvres_as_readable_channel_trials(tmp_path, tug):
    from mmg_tuner.cli.generate import command
    import yaml
    out = tmp_path / 'tug'
    assert command(['--ship', 'qiuxin_tug', '--out', str(out), '--no-noise', '--only',
                    'zigzag_p20deg_5rps', 'straight_3rps', 'random_1']) == 0
    listing = yaml.safe_load((out / 'trials.yaml').read_text())
    assert listing['identification'] == ['straight_3rps', 'zigzag_p20deg_5rps']
    assert listing['validation'] == ['random_1'] and listing['rate_hz'] == 5.0
    header = (out / 'csv' / 'zigzag_p20deg_5rps.csv').read_text().splitlines()[0]
    assert header == ('t,x,y,psi,u,v,r,n_port,n_stbd,azimuth_port,azimuth_stbd,'
                      'azimuth_cmd_port,azimuth_cmd_stbd')
    trials = {t.name: t for t in mt.load_trials(out / 'csv')}
    assert sorted(trials) == ['random_1', 'straight_3rps', 'zigzag_p20deg_5rps']
    zz = trials['zigzag_p20deg_5rps']
    assert zz.dt == pytest.approx(0.2) and len(zz) == 501
    # the +20/20 zigzag: commands reverse on heading, +20 deg of azimuth turns to port first
    cmd = zz['azimuth_cmd_port']
    assert set(np.round(np.degrees(np.unique(cmd)), 6)) == {-20.0, 0.0, 20.0}
    k = int(np.argmax(cmd != 0))
    first = int(np.argmax(np.abs(cmd[k:] - cmd[k]) > 0)) + k
    turned = zz['psi'][first - 1] - zz['psi'][k]   # the sample that passed the check
    assert -math.radians(20) - 0.05 < turned <= -math.radians(20)
    assert np.count_nonzero(np.diff(cmd)) >= 5
    # noise-free: the recording is the model's own run, from the commands or from the angles
    for drop in ((), ('azimuth_cmd_port', 'azimuth_cmd_stbd')):
        inputs = {c: v for c, v in zz.inputs.items() if c not in drop}
        run = simulate(tug, zz.states[0], inputs, zz.dt, 'rk4')
        np.testing.assert_allclose(run.states, zz.states, rtol=0, atol=1e-6)
    # the bollard-pull table: n [rev/s], thrust [N per thruster], the stand-in 0.4 n|n|
    table = np.loadtxt(out / 'bollard_pull.csv', delimiter=',', skiprows=1)
    assert (out / 'bollard_pull.csv').read_text().startswith('n,thrust\n')
    np.testing.assert_allclose(table[:, 1], 0.4 * table[:, 0] ** 2, atol=1e-8)
    assert table[-1, 0] == 12.0 and np.all(np.diff(table[:, 1]) > 0)
    # nothing is overwritten: a second run writes beside
    assert command(['--ship', 'qiuxin_tug', '--out', str(out), '--only', 'straight_3rps']) == 0
    assert (out / 'csv' / 'straight_3rps_2.csv').is_file()
    assert (out / 'bollard_pull_2.csv').is_file()


def test_a_tug_trial_missing_channels_is_refused_naming_each(tmp_path, tug):
    f = tmp_path / 'partial.csv'
    rows = '\n'.join(f'{0.2 * k:g},0,0,0,1,0,0,5,0.1' for k in range(30))
    f.write_text('t,x,y,psi,u,v,r,n_port,azimuth_port\n' + rows + '\n')
    trial, = mt.load_trials(f)   # read by name: the reader does not know the ship
    assert sorted(trial.inputs) == ['azimuth_port', 'n_port']
    with pytest.raises(mt.errors.MmgTunerError) as exc:
        mt.simulate(tug, trial)
    assert "'n_stbd'" in str(exc.value) and "'azimuth_stbd'" in str(exc.value)
    assert 'partial' in str(exc.value)
    # a non-uniform time column is refused, naming the time
    f.write_text('t,x,y,psi,u,v,r,n_port,azimuth_port\n' + ''.join(
        f'{t:g},0,0,0,1,0,0,5,0\n' for t in (0, 0.2, 0.4, 0.7, 0.9)))
    with pytest.raises(mt.errors.TrialDataError, match='step 0.3 s at t = 0.4 s'):
        mt.load_trials(f)


def test_the_otter_gets_a_differential_thrust_catalogue(tmp_path):
    from mmg_tuner.data.generate import trial_kit
    otter = mt.load_ship('otter_usv')
    kit = trial_kit(otter)   # the catalogue its actuator declares (TRIALS)
    assert kit is not None and kit.__name__.endswith('twin_azimuth_trials')
    assert trial_kit(mt.load_ship('suzaku')) is None
    cat = {m.name: m for m in kit.catalogue(otter)}
    assert 'zigzag_p0_3_5rps' in cat and cat['zigzag_p0_3_5rps'].role == 'identification'
    truth, meas = kit.generate(otter, cat['zigzag_p0_3_5rps'], 5.0, kit.Noise(), 3)
    assert np.all(truth['azimuth_port'] == 0) and np.all(truth['azimuth_stbd'] == 0)
    n_p, n_s = truth['n_port'], truth['n_stbd']
    assert n_p.max() == pytest.approx(6.5) and n_s.max() == pytest.approx(6.5)
    # port faster first: a turn to starboard, reversed on heading
    k = int(np.argmax(n_p != n_s))
    assert n_p[k] > n_s[k] and truth['r'][k + 10] > 0
    assert np.ptp(truth['psi']) > math.radians(30)
    assert np.std(meas['x'] - truth['x']) == pytest.approx(0.015, rel=0.2)   # RTK class
