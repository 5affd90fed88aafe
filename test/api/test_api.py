"""The public Python API: the README's notebook example, end to end, on small generated trials."""
import json
import logging

import mmg_tuner as mt
import numpy as np
import pytest


@pytest.fixture(scope='module')
def trial_dir(tmp_path_factory):
    from mmg_tuner.cli.generate import command as generate
    d = tmp_path_factory.mktemp('api') / 'trials'
    assert generate(['--out', str(d), '--duration', '120', '--rate-hz', '1', '--maneuvers',
                     'turning:35', 'zigzag:20', 'turning:-25', 'random:30', 'zigzag:-15',
                     'turning:-35', '--effect', 'current_speed=0.3',
                     '--effect', 'current_dir=2.0']) == 0
    return d


def test_readme_notebook_example(trial_dir, tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)
    caplog.set_level(logging.INFO, logger='mmg_tuner')
    # --- the README's example (budgets cut to keep the test short) ---
    ship = mt.load_ship('suzaku')
    trials = mt.load_trials([trial_dir], ship=ship)
    fit = mt.tune(ship, trials[:4], test=trials[4:], max_evals=600)
    fit.write('tuned')
    dx = mt.diagnose(ship, trials[:4], test=trials[4:], budget='quick',
                     effects=['current', 'rudder_offset'], max_effects=1,
                     base_evals=1500, screen_evals=100, effect_evals=800)
    dx.write('diag')
    run = mt.simulate(ship.with_params(dx.params), trials[5])
    # --- what it must give ---
    assert len(trials) == 6
    assert isinstance(fit, mt.TuneResult) and isinstance(fit.J, mt.Fit)
    assert set(fit.params) == set(ship.tuning_targets)
    assert set(fit.J.per_trial) == {t.name for t in trials}
    assert fit.J.tune == pytest.approx(sum(fit.J.per_trial[t.name] for t in trials[:4]))
    assert fit.J.tune < fit.J_pre.tune
    assert fit.history and fit.history[-1][0] >= 600
    rep = json.loads((tmp_path / 'tuned' / 'report.json').read_text())
    assert rep['J']['tuned']['tune'] == pytest.approx(fit.J.tune)
    assert isinstance(dx, mt.DiagnosisResult)
    assert [c.effect for c in dx.causes] == ['current']   # a 0.3 m/s current is unmissable
    c = dx.causes[0]
    assert isinstance(c, mt.Cause) and set(c.parameters) == {'current_speed', 'current_dir'}
    assert set(c.uncertainty) == set(c.parameters)
    assert c.heldout_gain > 0.5 and c.heldout_gain_se >= 0
    assert dx.final.J_test < dx.baseline.J_test
    doc = json.loads((tmp_path / 'diag' / 'diagnosis.json').read_text())
    assert doc['causes'][0]['effect'] == 'current' and 'summary' in doc['causes'][0]
    assert doc['final']['J_test'] == pytest.approx(dx.final.J_test)
    # the prediction is Trial-shaped, on the recorded grid, and close to the recording
    assert isinstance(run, mt.api.Trial) and run.states.shape == trials[5].states.shape
    assert np.array_equal(run.t, trials[5].t)
    pos = np.hypot(*(run.states[:, :2] - trials[5].states[:, :2]).T)
    assert np.all(np.isfinite(pos)) and pos.mean() < 0.5 * ship.L_pp
    assert any('tuning the base model' in r.getMessage() for r in caplog.records)


def test_simulate_starts_from_the_objectives_fitted_state(trial_dir, suzaku):
    """
    One way to simulate a recorded trial.

    The residuals in reports describe the run that was tuned (J from the simulation equals the
    objective's J).
    """
    from mmg_tuner.tuning.objective import Objective, TrialBatch, initial_state
    tr = mt.load_trials(trial_dir / 'zigzag_p20')[0]
    run = mt.simulate(suzaku, tr, integrator='euler')
    assert np.allclose(run.states[0], initial_state(tr, 10.0))
    assert not np.allclose(run.states[0], tr.states[0])   # not the raw noisy first sample
    obj = Objective(suzaku, TrialBatch.from_trials([tr]))
    e = run.states - tr.states
    e[:, 2] = (e[:, 2] + np.pi) % (2 * np.pi) - np.pi
    J_sim = float(np.sum(e[1:] ** 2 @ obj.weights))
    J_obj = float(obj.per_trial(suzaku.params[None])[0][0, 0])
    assert J_sim == pytest.approx(J_obj, rel=1e-6)


def test_configs_validate_like_the_cli(suzaku):
    for bad in ({'popsize': 0}, {'seed': -1}, {'weights': (0,) * 6}, {'substeps': 0},
                {'shoot_every_s': -5.0}, {'max_evals': 0}, {'a_r': float('nan')},
                {'a_r': 0.0}, {'bounds': {'R_0': (1.0, 0.5)}}, {'integrator': 'rk9'},
                {'max_popsize': 4, 'popsize': 12}):
        with pytest.raises(mt.TuningError, match=next(iter(bad)).split('_s')[0]):
            mt.TuneConfig(**bad)
    for bad in ({'budget': 'huge'}, {'max_effects': 0}, {'effects': ['nope']},
                {'seed': -1}):
        with pytest.raises(mt.DiagnosisError):
            mt.DiagnoseConfig(**bad)
