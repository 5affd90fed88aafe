"""
Test the hybrid model's application side.

params.yaml naming a residual, tune --residual, the message without JAX, the node's stepper,
and the diagnosis's structure verdict and learnable structure.
"""
from dataclasses import replace
import json
import math
import sys

import mmg_tuner as mt
from mmg_tuner.diagnosis import structure
from mmg_tuner.errors import ConfigError
from mmg_tuner.learn.residual import ResidualNet, zero_net
import numpy as np
import pytest
import yaml

TUNE = ['turning_p35', 'zigzag_p20', 'turning_m25', 'random_p30']
TEST = ['zigzag_m15', 'turning_m35']


def _generate(path, *extra):
    from mmg_tuner.cli.generate import command as generate
    assert generate(['--out', str(path), '--duration', '150', '--rate-hz', '1',
                     '--maneuvers', 'turning:35', 'zigzag:20', 'turning:-25', 'random:30',
                     'zigzag:-15', 'turning:-35', *extra]) == 0
    return path


@pytest.fixture(scope='module')
def trial_dir(tmp_path_factory):
    return _generate(tmp_path_factory.mktemp('hyb') / 'trials', '--effect',
                     'rudder_lag_tau=6')


def _yaw_kick(window: int = 2, dt: float = 1.0, dr: float = 2e-4) -> ResidualNet:
    """Make a network whose output is a constant yaw acceleration dr [rad/s^2]."""
    net = zero_net(window, dt)
    b = list(net.biases)
    b[-1] = np.array([0.0, 0.0, dr])
    return ResidualNet(net.window, net.dt_s, net.weights, tuple(b), net.x_mean, net.x_std,
                       net.y_scale, True)


def _params_dir(tmp_path, net, name='p'):
    d = tmp_path / name
    d.mkdir()
    net.save(d / 'params.residual.npz')
    (d / 'params.yaml').write_text(yaml.safe_dump(
        {'ship': 'suzaku', 'params': {'t_P': 0.08}, 'residual': 'params.residual.npz'}))
    return d / 'params.yaml'


# ----------------------------------------------------------------- params.yaml with a residual
def test_params_with_residual_round_trip_through_simulate_and_evaluate(
        trial_dir, tmp_path, capsys):
    from mmg_tuner.cli.evaluate import command as evaluate
    from mmg_tuner.cli.simulate import command as simulate
    zero = _params_dir(tmp_path, zero_net(3, 1.0), 'zero')
    kick = _params_dir(tmp_path, _yaw_kick(), 'kick')
    ship = mt.load_model('suzaku', kick)   # a model: the ship and the network its params name
    assert isinstance(ship.residual, ResidualNet) and ship.residual.physics
    physics = mt.load_ship('suzaku', kick)   # a ship config owns no network
    assert np.array_equal(physics.params, ship.ship.params) and not hasattr(physics, 'residual')
    assert mt.load_model('suzaku').residual is None
    tr = mt.load_trials(trial_dir / 'zigzag_m15')[0]
    plain = mt.simulate(mt.load_ship('suzaku'), tr)
    # a zero residual is the physics; a constant yaw acceleration turns the ship away
    assert np.allclose(mt.simulate(mt.load_model('suzaku', zero), tr).states, plain.states,
                       atol=1e-9)
    kicked = mt.simulate(ship, tr).states
    assert np.all(np.isfinite(kicked)) and kicked[-1, 2] - plain.states[-1, 2] > 0.1
    # the evaluate command runs the hybrid named by --params
    idx = {}
    for name, extra in (('phys', []), ('zero', ['--params', str(zero)]),
                        ('kick', ['--params', str(kick)])):
        assert evaluate([str(trial_dir / t) for t in TEST] + [
            '--ship', 'suzaku', '--out', str(tmp_path / f'ev_{name}'), '--no-plots',
            '--quiet'] + extra) == 0
        doc = json.loads((tmp_path / f'ev_{name}' / 'evaluate.json').read_text())
        idx[name] = doc['index_all']
        assert doc['simulated_as'] == ('physics' if name == 'phys' else 'hybrid')
    assert idx['zero'] == pytest.approx(idx['phys'], rel=1e-9)
    assert idx['kick'] > 1.5 * idx['phys']
    # the simulate command too: turning and the closed-loop zigzag
    out = {}
    for name, extra in (('phys', []), ('zero', ['--params', str(zero)]),
                        ('kick', ['--params', str(kick)])):
        for m in ('turning', 'zigzag'):
            capsys.readouterr()
            assert simulate(['--maneuver', m, '--rudder-deg', '20', '--duration', '300']
                            + extra) == 0
            out[name, m] = capsys.readouterr().out.split('\n', 1)[1]
    for m in ('turning', 'zigzag'):
        assert out['zero', m] == out['phys', m]
        assert out['kick', m] != out['phys', m]


def test_params_naming_a_missing_or_corrupt_residual_is_refused(tmp_path, capsys):
    from mmg_tuner.cli.simulate import main
    p = _params_dir(tmp_path, zero_net(2, 1.0))
    (tmp_path / 'p' / 'params.residual.npz').unlink()
    with pytest.raises(ConfigError, match=r'params\.yaml.*params\.residual\.npz'):
        mt.load_model('suzaku', p)
    (tmp_path / 'p' / 'params.residual.npz').write_bytes(b'not a zip')
    with pytest.raises(SystemExit) as e:
        main(['--params', str(p), '--duration', '10'])
    err = capsys.readouterr().err
    assert e.value.code == 2 and 'params.yaml' in err and 'params.residual.npz' in err
    assert 'Traceback' not in err
    # a network trained on another step is refused by option name
    p2 = _params_dir(tmp_path, zero_net(2, 0.5), 'half')
    with pytest.raises(SystemExit) as e:
        main(['--params', str(p2), '--duration', '10', '--dt', '1'])
    assert e.value.code == 2 and '--dt' in capsys.readouterr().err


# ----------------------------------------------------------------- tune --residual
def test_tune_residual_end_to_end(trial_dir, tmp_path, capsys):
    pytest.importorskip('jax')
    from mmg_tuner.cli.evaluate import command as evaluate
    from mmg_tuner.cli.tune import command as tune
    out = tmp_path / 'tuned'
    assert tune([str(trial_dir / t) for t in TUNE] + ['--test'] + [
        str(trial_dir / t) for t in TEST] + [
        '--ship', 'suzaku', '--out', str(out), '--max-evals', '200', '--residual',
        '--residual-epochs', '8', '--residual-hidden', '8', '--no-plots', '--quiet']) == 0
    printed = capsys.readouterr().out
    assert 'hybrid network: share of the acceleration' in printed
    doc = yaml.safe_load((out / 'params.yaml').read_text())
    assert doc['residual'] == 'params.residual.npz' and (out / doc['residual']).is_file()
    rep = json.loads((out / 'report.json').read_text())
    r = rep['residual']
    assert r['kind'] == 'hybrid' and 0 <= r['share'] <= 1 and r['epochs'] >= 1
    assert set(r['index']) == {'tune', 'test'} and r['heldout_gain'] is not None
    assert '## Neural residual (hybrid)' in (out / 'report.md').read_text()
    ship = mt.load_model('suzaku', out / 'params.yaml')
    assert ship.residual.physics and ship.residual.meta['config']['hidden'] == [8]
    assert evaluate([str(trial_dir / t) for t in TEST] + [
        '--ship', 'suzaku', '--params', str(out / 'params.yaml'), '--out',
        str(tmp_path / 'ev'), '--no-plots', '--quiet']) == 0
    ev = json.loads((tmp_path / 'ev' / 'evaluate.json').read_text())
    # the same held-out index as tune reported (same sigma pooling, restarts, integrator)
    assert ev['index_all'] == pytest.approx(r['index']['test']['model'], rel=1e-6)


def test_tune_residual_seeds_keep_the_mean_of_their_networks(trial_dir, tmp_path):
    # --residual-seeds 2: the saved network is the exact mean of the seeds' networks, each
    # trained as a single-seed run with that seed would train it
    pytest.importorskip('jax')
    from mmg_tuner.learn import ResidualConfig, train_residual
    trials = [mt.load_trials(trial_dir / t)[0] for t in TUNE]
    cfg = mt.TuneConfig(max_evals=100, residual='hybrid', residual_seeds=2,
                        residual_options={'epochs': 4, 'hidden': (6,)})
    res = mt.tune(mt.load_ship('suzaku'), trials, config=cfg)
    r = res.residual
    assert r.seeds == 2 and r.seed == 0 and 'the mean of 2 networks' in r.markdown()
    physics = res.ship.with_params(res.params)
    rc = ResidualConfig(**{**r.config, 'hidden': tuple(r.config['hidden'])})
    alone = [train_residual(physics, trials, config=replace(rc, seed=k)).net for k in (0, 1)]
    assert r.net.meta['ensemble_of_seeds'] == [0, 1]
    # hidden units side by side, the output layer averaging them
    np.testing.assert_allclose(r.net.weights[0], np.vstack([n.weights[0] for n in alone]))
    np.testing.assert_allclose(r.net.weights[-1],
                               np.hstack([n.weights[-1] for n in alone]) / 2)
    np.testing.assert_allclose(r.net.biases[-1], (alone[0].biases[-1] + alone[1].biases[-1]) / 2)
    with pytest.raises(mt.MmgTunerError, match='residual_seeds'):
        mt.TuneConfig(residual='hybrid', residual_seeds=0)
    with pytest.raises(mt.MmgTunerError, match='residual_seeds'):   # before any tuning
        mt.TuneConfig(residual='hybrid', residual_seeds=2, seed=2 ** 31 - 1)


def test_tune_residual_options_are_checked(trial_dir, tmp_path, capsys):
    from mmg_tuner.cli.tune import main
    base = [str(trial_dir / 'turning_p35'), '--out', str(tmp_path / 'x')]
    for argv, what in ((['--residual', '--residual-only'], 'not allowed with'),
                       (['--residual-epochs', '3'], 'only with --residual'),
                       (['--residual-seeds', '2'], '--residual-seeds: only with'),
                       (['--residual', '--residual-seeds', '0'], 'residual seeds'),
                       (['--residual', '--residual-window', '0'], '--residual-window'),
                       (['--residual-physics-input'], '--residual-physics-input: only with')):
        with pytest.raises(SystemExit) as e:
            main(base + argv)
        err = capsys.readouterr().err
        assert e.value.code == 2 and what in err and 'Traceback' not in err
    from mmg_tuner.cli.tune import build_parser, tune_config
    args = build_parser().parse_args(base + ['--model', 'auto', '--residual-physics-input'])
    assert tune_config(args).residual_options == {'physics_input': True}
    with pytest.raises(mt.MmgTunerError, match='residual'):
        mt.TuneConfig(residual='both')
    with pytest.raises(mt.MmgTunerError, match='nope'):
        mt.TuneConfig(residual='hybrid', residual_options={'nope': 1})


def test_without_jax_the_hybrid_commands_say_how_to_install_it(trial_dir, tmp_path, capsys,
                                                               monkeypatch):
    from mmg_tuner.cli.tune import main
    for mod in ('jax', 'equinox', 'optax'):
        monkeypatch.setitem(sys.modules, mod, None)   # import raises ImportError
    with pytest.raises(SystemExit) as e:
        main([str(trial_dir / 'turning_p35'), '--out', str(tmp_path / 'nojax'),
              '--residual', '--max-evals', '50', '--quiet'])
    err = capsys.readouterr().err
    assert e.value.code == 2 and 'pip install jax equinox optax' in err
    assert 'Traceback' not in err
    with pytest.raises(mt.MmgTunerError, match='pip install jax'):
        mt.diagnose(mt.load_ship('suzaku'), [], residual=True)
    # everything else still works, including running a saved hybrid
    p = _params_dir(tmp_path, _yaw_kick())
    run = mt.simulate(mt.load_model('suzaku', p), mt.load_trials(trial_dir / 'zigzag_m15')[0])
    assert np.all(np.isfinite(run.states))


# ----------------------------------------------------------------- structure verdict
def test_structure_asymmetry_and_verdict_on_a_ship_the_model_cannot_mirror(tmp_path):
    """
    Measure an asymmetry the model cannot produce, and blame the structure for it.

    Trials of SUZAKU with a constant yaw moment (a port/starboard asymmetry) against the
    plain model: the side-independent yaw-rate error is material and the verdict, given an
    impossible effect that fits, blames the structure; on the clean ship neither.
    """
    ship = mt.load_ship('suzaku')
    out = {}
    for name, extra in (('asym', ['--effect', 'yaw_moment_bias=0.0015']), ('clean', [])):
        trials = mt.load_trials(_generate(tmp_path / name, *extra), ship=ship)
        sims = [mt.simulate(ship, t).states for t in trials]
        out[name] = structure.asymmetry(trials, sims)
    a, c = out['asym'], out['clean']
    assert {r['side'] for r in a['trials']} == {'port', 'starboard'}
    assert a['significant'] and abs(a['r_a']) > 5 * abs(c['r_a'])
    assert not c['significant']
    assert abs(a['r_a']) > abs(a['r_b'])      # the error does not flip with the side
    doc = {'baseline': {'J_test': 1.0}, 'final': {'J_test': 0.9},
           'would_fit_but_impossible': [{'effect': 'wind', 'gain': 0.4, 'gain_se': 0.1,
                                         'reason': 'no wind indoors (tank)'}]}
    v = structure.verdict(doc, *structure.evidence(doc, ship), a)
    assert v['verdict'] == 'structure' and 'STRUCTURAL' in v['summary']
    v0 = structure.verdict({'baseline': {'J_test': 1.0}, 'final': {'J_test': 1.0}}, [], [], c)
    assert v0['verdict'] == 'none'
    lines = '\n'.join(structure.markdown_lines({'structure': v}))
    assert 'Port/starboard' in lines and 'starboard' in lines


def test_named_effect_near_its_bound_is_evidence(suzaku):
    e = mt.api.EFFECTS['antenna_offset']
    (xlo, xhi), (ylo, yhi) = e.bounds(suzaku)
    doc = {'causes': [{'effect': 'antenna_offset',
                       'parameters': {'antenna_x': 0.0, 'antenna_y': ylo + 0.05 * (yhi - ylo)}}]}
    strong, _ = structure.evidence(doc, suzaku)
    assert strong and 'antenna_y' in strong[0]
    doc['causes'][0]['parameters']['antenna_y'] = 0.5 * (ylo + yhi)
    assert structure.evidence(doc, suzaku)[0] == []


# ----------------------------------------------------------------- learnable structure
def test_learnable_structure_finds_nothing_on_clean_data(tmp_path):
    pytest.importorskip('jax')
    ship = mt.load_ship('suzaku')
    trials = mt.load_trials(_generate(tmp_path / 'clean'), ship=ship)
    by = {t.name: t for t in trials}
    res = structure.learnable(ship, [by[n] for n in TUNE], [by[n] for n in TEST],
                              {'epochs': 15, 'hidden': (8,), 'seed': 0})
    assert not res['significant'], res['line']
    assert res['line'].startswith('unexplained but learnable structure:')
    assert 'nan' not in res['line']
    assert not math.isnan(res['share'])


def test_the_node_stepper_runs_the_hybrid_like_the_offline_simulation(tmp_path):
    """
    Run the hybrid in the node's stepper as offline.

    ShipSimulator with a params.yaml naming a network equals simulate_hybrid of the same
    held commands (the sim_node's engine), and a zero network equals the physics.
    """
    from mmg_tuner.learn.residual import simulate_hybrid
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.core.trial import Trial
    x0 = [0.0, 0.0, 0.0, 3.0, 0.0, 0.0]
    model = mt.load_model('suzaku', _params_dir(tmp_path, _yaw_kick(window=3, dt=0.5)))
    sim = ShipSimulator(model.ship, dt=0.25, x0=x0, rpm=100.0, rudder_rad=0.1,
                        residual=model.residual)
    assert sim.step(400)
    T = 201
    tr = Trial(np.arange(T) * 0.5, np.tile(x0, (T, 1)),
               np.column_stack([np.full(T, 100.0), np.full(T, 0.1)]))
    # the offline run integrates 0.5 s samples; the node 2 steps of 0.25 s each: compare with
    # the offline run at two substeps, the same integration grid
    off = simulate_hybrid(model.ship, model.residual, tr, restart_every_s=0.0, substeps=2)
    assert np.allclose(sim.observed(), off.states[-1], rtol=1e-9, atol=1e-9)
    plain = ShipSimulator(mt.load_ship('suzaku'), dt=0.25, x0=x0, rpm=100.0, rudder_rad=0.1)
    plain.step(400)
    assert not np.allclose(plain.observed(), sim.observed(), atol=1e-3)
    zm = mt.load_model('suzaku', _params_dir(tmp_path, zero_net(3, 0.5), 'z'))
    zero = ShipSimulator(zm.ship, dt=0.25, x0=x0, rpm=100.0, rudder_rad=0.1,
                         residual=zm.residual)
    zero.step(400)
    assert np.allclose(plain.observed(), zero.observed(), rtol=1e-12, atol=1e-9)
    with pytest.raises(mt.MmgTunerError, match='must divide'):
        ShipSimulator(model.ship, dt=0.3, x0=x0, rpm=100.0, residual=model.residual)


def test_marin_kvlcc2_asymmetry_is_structural():
    """
    Measure MARIN's port/starboard asymmetry against the standard model.

    The pre-determined KVLCC2 errs the same way on both sides (yaw-rate error about -6 % of
    the mean |r|, the side-flipping part a few times smaller): an asymmetry of the ship.
    """
    from mmg_tuner.data.marin import MARIN_FILES, marin_data_dir
    ship = mt.load_ship('kvlcc2')
    trials = mt.load_trials([str(marin_data_dir() / f) for f in MARIN_FILES.values()],
                            ship=ship, dt=0.1, trial_scale='full')
    a = structure.asymmetry(trials, [mt.simulate(ship, t).states for t in trials])
    assert sorted(r['side'] for r in a['trials']) == ['port'] * 3 + ['starboard'] * 3
    assert a['significant'] and a['r_a'] < -0.03 and abs(a['r_b']) < 0.5 * abs(a['r_a'])
    assert 'yaws further to starboard' in a['text']


def test_diagnose_reports_structure_and_learnable_structure(trial_dir, tmp_path, capsys):
    """The diagnose command with --residual: the structure section, the line and the plot."""
    pytest.importorskip('jax')
    from mmg_tuner.cli.diagnose import command as diagnose
    out = tmp_path / 'dx'
    assert diagnose([str(trial_dir / t) for t in TUNE] + ['--test'] + [
        str(trial_dir / t) for t in TEST] + [
        '--ship', 'suzaku', '--out', str(out), '--budget', 'quick', '--effects',
        'rudder_offset', '--max-effects', '1', '--residual', '--quiet']) == 0
    printed = capsys.readouterr().out
    assert 'unexplained but learnable structure:' in printed
    doc = json.loads((out / 'diagnosis.json').read_text())
    st = doc['structure']
    assert st['verdict'] in ('structure', 'unexplained', 'none')
    lr = st['learnable']
    assert lr['line'].startswith('unexplained but learnable structure:')
    assert set(lr['regimes']) == set(structure.REGIMES) and '_plot' not in lr
    assert 'structure' in doc['timings_s']
    assert (out / 'learnable_structure.png').is_file()
    md = (out / 'diagnosis.md').read_text()
    assert '## Model structure' in md and 'unexplained but learnable structure' in md
    assert 'nan' not in md
