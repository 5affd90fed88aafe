"""
Evaluate (tuning/evaluate.py, api.evaluate, the ``evaluate`` command): the Wakita et al.

(2022) eq. 26 index on synthetic cases with a known answer, the command end to end on two Esso
Osaka runs, and tuning lowspeed parameters on synthetic lowspeed trials.
"""
import json
import math

import mmg_tuner as mt
from mmg_tuner.cli.common import run_command
from mmg_tuner.cli.evaluate import command
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.esso import esso_data_dir
from mmg_tuner.data.trial import Trial
from mmg_tuner.tuning.evaluate import INDEX_STATES
import numpy as np
import pytest


@pytest.fixture(scope='module')
def esso():
    return mt.load_ship('esso_osaka_3m')


def _trial(ship, seed, T=400, dt=0.5, name='run'):
    """Return a low-speed run with astern propeller, measured wind and a thruster."""
    rng = np.random.default_rng(seed)
    m = T // 40
    ctrl = {'rpm': 60 * np.repeat(rng.uniform(-12, 14, m), 40),
            'rudder': np.repeat(rng.uniform(-0.6, 0.6, m), 40),
            'wind_n': np.full(T, 1.0), 'wind_e': np.full(T, -0.5),
            'bow_thruster': np.repeat(rng.uniform(-15, 15, m), 40),
            'stern_thruster': np.zeros(T)}
    tr = simulate(ship, [0, 0, 0.2, 0.1, 0, 0], ctrl, dt, 'rk4')
    assert tr.ok
    return Trial(tr.t, tr.states, inputs=ctrl, name=name)


def test_perfect_model_scores_zero(esso):
    trials = [_trial(esso, 1, name='a'), _trial(esso, 2, name='b')]
    res = mt.evaluate(esso, trials, restart_every_s=50)
    for s in res.trials.values():
        assert s.index < 1e-20 and all(v < 1e-10 for v in s.rms.values())
        assert set(s.rms) == set(INDEX_STATES)


def test_known_offset_gives_the_known_index_with_restarts_and_pooled_sigma(esso):
    """
    Measured x = model x + c after the first sample.

    Without restarts the error is -c on every later sample; with a restart every K samples the
    model restarts from the shifted measurement (x-invariant dynamics), so only the first segment
    has the error. sigma_x is pooled over both trials.
    """
    c = 0.7
    a, b = _trial(esso, 3, name='a'), _trial(esso, 4, T=320, name='b')
    shifted = a.states.copy()
    shifted[1:, 0] += c
    a2 = Trial(a.t, shifted, a.controls, name='a', wind=a.wind, thrusters=a.thrusters)
    sig_x = np.std(np.concatenate([shifted[:, 0], b.states[:, 0]]))
    T = len(a2)
    res = mt.evaluate(esso, [a2, b], restart_every_s=0)
    assert res.sigma['x'] == pytest.approx(sig_x, rel=1e-12)
    assert res.trials['a'].index == pytest.approx((T - 1) / T * (c / sig_x) ** 2, rel=1e-9)
    assert res.trials['a'].rms['x'] == pytest.approx(c * math.sqrt((T - 1) / T), rel=1e-9)
    assert res.trials['b'].index < 1e-20
    K = 40  # 20 s at 0.5 s
    res = mt.evaluate(esso, [a2, b], restart_every_s=20)
    assert res.trials['a'].index == pytest.approx((K - 1) / T * (c / sig_x) ** 2, rel=1e-9)
    # the heading error is wrapped: a whole turn off is no error
    turned = a.states.copy()
    turned[1:, 2] += 2 * math.pi
    res = mt.evaluate(esso, [Trial(a.t, turned, a.controls, wind=a.wind,
                                   thrusters=a.thrusters), b], restart_every_s=0)
    assert res.trials['trial'].rms['psi'] < 1e-9


def test_options_are_checked(esso):
    with pytest.raises(mt.ConfigError, match='restart_every_s'):
        mt.evaluate(esso, [_trial(esso, 1)], restart_every_s=-1)
    with pytest.raises(mt.ConfigError, match='integrator'):
        mt.evaluate(esso, [_trial(esso, 1)], integrator='rk45')


def test_command_on_two_esso_runs(tmp_path, capsys):
    runs = [esso_data_dir() / 'berthing' / f'berthing_12-Nov-2020_{n}.csv'
            for n in ('13_09_11', '13_37_05')]
    out = tmp_path / 'ev'
    rc = run_command(command, [str(r) for r in runs]
                     + ['--ship', 'esso_osaka_3m', '--restart-every', '50', '--out', str(out)])
    assert rc == 0
    doc = json.loads((out / 'evaluate.json').read_text())
    assert set(doc['trials']) == {r.stem for r in runs}
    for v in doc['trials'].values():
        assert v['index'] > 0 and set(v['rms']) == set(INDEX_STATES)
    assert doc['restart_every_s'] == 50 and set(doc['sigma']) == set(INDEX_STATES)
    assert len(list(out.glob('evaluate_*.png'))) == 2 and (out / 'evaluate.md').is_file()
    assert 'index' in capsys.readouterr().out
    # a bad option: one ERROR line, exit 2, nothing written
    rc = run_command(command, [str(runs[0]), '--ship', 'esso_osaka_3m', '--restart-every', '-5',
                               '--out', str(tmp_path / 'x')])
    assert rc == 2 and 'ERROR' in capsys.readouterr().err
    assert not (tmp_path / 'x').exists()


def test_tuning_lowspeed_parameters_recovers_them(esso):
    """
    CMA-ES on synthetic low-speed trials recovers cross-flow drag and yaw damping.

    CMA-ES on synthetic low-speed trials of a 'true' ship whose cross-flow drag and yaw damping
    differ from the published ones: J falls and both come back roughly.
    """
    truth = {'C_D': 1.25, 'N_r': -0.075}
    true_ship = esso.with_params(truth)
    trials = [_trial(true_ship, s, name=f't{s}') for s in (11, 12)]
    fit = mt.tune(esso, trials, targets=['C_D', 'N_r'], max_evals=400, integrator='rk4',
                  weights=(1.0, 1.0, 1.0, 0.0, 0.0, 0.0), seed=1)
    assert fit.J.tune < 0.1 * fit.J_pre.tune
    for k, v in truth.items():
        assert fit.params[k] == pytest.approx(v, rel=0.25), k


# ------------------------------------------------------------ n-step prediction (issue 24)
@pytest.fixture(scope='module')
def suzaku_runs():
    """SUZAKU zigzag and turning from the generator: (truth, noisy measured) pairs."""
    from mmg_tuner.data.generate import generate_trial, SensorNoise
    ship = mt.load_ship('suzaku')
    runs = [generate_trial(ship, m, a, None, 106.0, 3.086, 120.0, 1.0, SensorNoise(), 7 + i,
                           m) for i, (m, a) in enumerate((('zigzag', 20.0), ('turning', 25.0)))]
    return ship, runs


def test_nstep_perfect_model_is_exact_and_errors_grow_with_the_horizon(suzaku_runs):
    """
    On noise-free data the true model predicts every horizon exactly.

    On noisy data horizon 1 is at the noise level while a wrong model's error grows with n.
    """
    ship, runs = suzaku_runs
    hs = (1, 5, 10, 20, 30)
    # the generator's truth moves the rudder within a sample (steering gear, 10 substeps):
    # re-simulated with its logged inputs as evaluate runs them, the true model is exact
    clean = []
    for t, _ in runs:
        sim = simulate(ship, t.states[0], t, t.dt, 'rk4')
        clean.append(Trial(t.t, sim.states, inputs=t.inputs, name=t.name))
    res = mt.evaluate(ship, clean, horizons=list(hs))
    assert res.nstep.horizons == hs
    for s, v in res.nstep.rmse.items():
        assert max(v) < 1e-8, (s, v)
    # every sample but the last starts a window; horizon n reaches T - n of them
    T = sum(len(t) for t in clean)
    assert res.nstep.windows == [T - len(clean) * h for h in hs]
    assert max(res.relative.pooled.values()) < 1e-10
    # a wrong model (weaker yaw damping) on the noisy recordings
    noisy = [m for _, m in runs]
    wrong = ship.with_params({'N_r': 0.6 * ship['N_r']})
    res = mt.evaluate(wrong, noisy, horizons=list(hs))
    r = res.nstep.rmse
    noise = 0.02   # SensorNoise().speed_ms: horizon 1 sees about one noise sigma
    assert r['u'][0] < 2 * noise and r['v'][0] < 2 * noise
    for s in ('psi', 'r'):   # (x, y: the 0.5 m GNSS noise dominates at these horizons)
        assert r[s][-1] > 3 * r[s][0], (s, r[s])
        assert all(a <= b * 1.05 for a, b in zip(r[s], r[s][1:])), (s, r[s])
    assert res.relative.pooled['r'] > 0.1   # the free run of the wrong model is off
    per = res.relative.per_trial
    assert set(per) == {'zigzag', 'turning'} and all(v['u'] > 0 for v in per.values())


def test_nstep_matches_a_python_loop_of_simulate(suzaku_runs):
    """One horizon checked against single simulations from the measured states."""
    from mmg_tuner.tuning.nstep import nstep_errors
    ship, runs = suzaku_runs
    meas = runs[0][1]
    wrong = ship.with_params({'N_r': 0.7 * ship['N_r']})
    score, per = nstep_errors(wrong, [meas], [7], 'rk4')
    inputs = meas.input_array(ship.family.channels)
    err = []
    for k in range(len(meas) - 7):
        run = simulate(wrong, meas.states[k], inputs[k:k + 8], meas.dt, 'rk4', check=False)
        err.append(run.states[7] - meas.states[k + 7])
    err = np.array(err)
    assert score.rmse['u'][0] == pytest.approx(np.sqrt(np.mean(err[:, 3] ** 2)), rel=1e-9)
    assert score.rmse['x'][0] == pytest.approx(np.sqrt(np.mean(err[:, 0] ** 2)), rel=1e-9)
    assert per[meas.name].rmse['r'] == score.rmse['r']


def test_evaluate_command_with_horizons_writes_json_and_plot(suzaku_runs, tmp_path, capsys):
    from mmg_tuner.data.csv_io import write_trial_csv
    ship, runs = suzaku_runs
    paths = []
    for _, m in runs:
        p = tmp_path / f'{m.name}.csv'
        write_trial_csv(m, p)
        paths.append(str(p))
    out = tmp_path / 'ev'
    rc = run_command(command, paths + ['--ship', 'suzaku', '--horizons', '1', '5', '10',
                                       '--out', str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert 'n-step RMSE' in text and 'free-run relative error' in text
    doc = json.loads((out / 'evaluate.json').read_text())
    assert doc['n_step']['horizons'] == [1, 5, 10]
    assert set(doc['n_step']['rmse']) == {'u', 'v', 'r', 'x', 'y', 'psi'}
    assert set(doc['relative_error']['pooled']) == {'u', 'v', 'r'}
    assert (out / 'evaluate_nstep.png').stat().st_size > 1000
    assert 'n-step prediction' in (out / 'evaluate.md').read_text()


def test_horizons_are_checked(esso):
    with pytest.raises(mt.ConfigError, match='horizons'):
        mt.EvaluateConfig(horizons=(0, 5))
    with pytest.raises(mt.ConfigError, match='horizons'):
        mt.EvaluateConfig(horizons=())
    assert mt.EvaluateConfig(horizons=(10, 1, 10)).horizons == (1, 10)


def test_one_sample_step_is_required_alike_by_the_objective_nstep_and_training(esso):
    """
    Trials on two grids are refused with one message, naming where, by each batch user.

    (``core.trial.common_dt``: before, three copies with their own messages.)
    """
    from mmg_tuner.core.trial import common_dt
    from mmg_tuner.tuning.nstep import nstep_errors
    from mmg_tuner.tuning.objective import TrialBatch
    tr = _trial(esso, 0)
    mixed = [tr, tr.resampled(2 * tr.dt)]
    assert common_dt([tr], 'x') == pytest.approx(0.5)
    for where, call in (('the objective', lambda: TrialBatch.from_trials(mixed)),
                        ('n-step prediction', lambda: nstep_errors(esso, mixed, (1,))),
                        ('nothing', lambda: common_dt([], 'nothing'))):
        with pytest.raises(mt.TuningError, match=f'^{where}: '):
            call()
