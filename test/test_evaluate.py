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
