"""
tune --model auto (the candidates compared per kind), the ensemble's interval and coverage.

Also: issue 25's registered test was written down (bench/esso_fresh_preregistration.md)
before the seven fresh runs were added.
"""
from pathlib import Path

import mmg_tuner as mt
from mmg_tuner.errors import TuningError
from mmg_tuner.learn import ensemble, members
from mmg_tuner.learn.model import load_model
from mmg_tuner.learn.residual import ResidualNet, zero_net
from mmg_tuner.learn.train import split_validation
from mmg_tuner.tuning.choice import Choice, choose_model
from mmg_tuner.tuning.interval import (calibrate_interval, coverage, Interval,
                                       model_interval, with_interval)
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
KINDS = {'turning_p35': 'turning', 'turning_m25': 'turning', 'zigzag_p20': 'zigzag',
         'zigzag_m15': 'zigzag'}


@pytest.fixture(scope='module')
def trials(tmp_path_factory):
    from mmg_tuner.cli.generate import command as generate
    d = tmp_path_factory.mktemp('auto') / 'trials'
    assert generate(['--out', str(d), '--duration', '120', '--rate-hz', '1', '--maneuvers',
                     'turning:35', 'zigzag:20', 'turning:-25', 'zigzag:-15']) == 0
    return [mt.load_trials(d / n)[0] for n in KINDS]


def _kick(dr: float) -> ResidualNet:
    """Return a network whose output is a constant yaw acceleration dr [rad/s^2]."""
    net = zero_net(2, 1.0)
    b = list(net.biases)
    b[-1] = np.array([0.0, 0.0, dr])
    return ResidualNet(net.window, net.dt_s, net.weights, tuple(b), net.x_mean, net.x_std,
                       net.y_scale, True, seed=len(str(dr)))


def test_choose_model_takes_the_one_best_on_its_worst_kind(trials):
    ship = mt.load_ship('suzaku')   # the trials' own ship: best on every kind
    off = ship.with_params({'N_r': 1.3 * ship['N_r']})
    groups = {t.name: KINDS[t.name] for t in trials}
    c = choose_model({'off': off, 'true': ship}, trials, groups)
    assert c.chosen == 'true' and c.score['true'] == 1.0 and c.score['off'] > 1.0
    assert set(c.by_kind['off']) == {'turning', 'zigzag'}
    assert '(recommended)' in c.markdown() and c.to_dict()['chosen'] == 'true'


def test_members_split_an_ensemble_exactly():
    a, b = _kick(1e-4), _kick(-3e-4)
    ens = ensemble([a, b])
    for m, orig in zip(members(ens), (a, b)):
        for w, v in zip(m.weights + m.biases, orig.weights + orig.biases):
            np.testing.assert_array_equal(w, v)
    assert members(a) == [a]


def test_interval_calibrated_on_trials_covers_its_level_and_travels_with_the_model(trials):
    ship = mt.load_ship('suzaku')
    model = mt.Model(ship, ensemble([_kick(2e-4), _kick(-2e-4)]))
    iv = calibrate_interval(model, trials, 0.9, integrator='euler')
    cov = coverage(iv, trials, integrator='euler')
    # the level quantile of the same samples: at least 90 % inside, ties add a few
    assert 0.9 <= cov['all'] <= 0.95 and set(cov['trials']) == {t.name for t in trials}
    wide = coverage(Interval(iv.model, iv.members, (1e9,) * 6, 0.9), trials)
    narrow = coverage(Interval(iv.model, iv.members, (0.0,) * 6, 0.9), trials)
    assert wide['all'] == 1.0 and narrow['all'] < 0.1
    carried = model_interval(with_interval(iv))
    assert carried.scale == iv.scale and len(carried.members) == 2
    res = mt.evaluate(with_interval(iv), trials, integrator='euler')
    assert res.coverage['all'] == pytest.approx(cov['all'])
    assert 'Prediction interval (nominal 90 %)' in res.markdown()


def test_interval_members_given_are_used_and_not_stored(trials):
    """Members given (one with another physics) make the interval; it cannot be stored."""
    ship = mt.load_ship('suzaku')
    model = mt.Model(ship, ensemble([_kick(2e-4), _kick(-2e-4)]))
    own = calibrate_interval(model, trials, 0.9, integrator='euler')
    off = ship.with_params({'N_r': 1.2 * ship['N_r']})
    given = calibrate_interval(model, trials, 0.9, integrator='euler',
                               members=list(own.members) + [mt.Model(off, None)])
    assert len(given.members) == 3 and not given.own_members and own.own_members
    assert given.members[2].ship is off and given.members[2].residual is None
    # the third member changes the spread, so the calibrated factors, every one of them
    assert all(g != pytest.approx(o, rel=1e-3) for g, o in zip(given.scale, own.scale))
    assert coverage(given, trials, integrator='euler')['all'] >= 0.9   # its own calibration
    with pytest.raises(TuningError, match='members given'):
        with_interval(given)
    with pytest.raises(TuningError, match='at least 2 members'):
        calibrate_interval(model, trials, members=own.members[:1])


def test_interval_physics_members_are_stored_and_stepped_again(trials):
    """Physics alone joins the ensemble's members; stored as its differing parameters."""
    ship = mt.load_ship('suzaku')
    model = mt.Model(ship, ensemble([_kick(2e-4), _kick(-2e-4)]))
    off = ship.with_params({'N_r': 1.2 * ship['N_r'], 'Y_v': 0.9 * ship['Y_v']})
    iv = calibrate_interval(model, trials, 0.9, integrator='euler', physics=(ship, off))
    assert iv.own_members and len(iv.members) == 4
    assert [m.residual is None for m in iv.members] == [False, False, True, True]
    info = with_interval(iv).residual.meta['interval']
    assert info['physics_members'] == [{}, {'N_r': 1.2 * ship['N_r'], 'Y_v': 0.9 * ship['Y_v']}]
    carried = model_interval(with_interval(iv))
    np.testing.assert_array_equal(carried.members[3].ship.params, off.params)
    assert carried.scale == iv.scale
    assert coverage(carried, trials, integrator='euler') == coverage(iv, trials,
                                                                     integrator='euler')
    with pytest.raises(TuningError, match='not both'):
        calibrate_interval(model, trials, members=iv.members, physics=(off,))
    with pytest.raises(TuningError, match='physics member'):
        calibrate_interval(model, trials, physics=(mt.load_ship('kvlcc2'),))


def test_simulator_members_spread_grows_in_free_run_and_plain_models_have_none():
    # the sim_node's covariance (ros/uncertainty.py, no ROS needed): the members are stepped
    # with the simulator's commands; their calibrated spread grows in free run
    from types import SimpleNamespace
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.ros.uncertainty import EnsembleSpread, fill_covariance
    ship = mt.load_ship('suzaku')
    model = mt.Model(ship, ensemble([_kick(2e-4), _kick(-2e-4)]))
    iv = Interval(model, tuple(mt.Model(ship, n) for n in members(model.residual)),
                  (2.0,) * 6, 0.9)
    ens = with_interval(iv)
    sim = ShipSimulator(ship, 0.1, [0, 0, 0, 3.0, 0, 0], 100.0, residual=ens.residual)
    plain = ShipSimulator(ship, 0.1, [0, 0, 0, 3.0, 0, 0], 100.0)
    assert EnsembleSpread.of(plain, 'rk4') is None
    spread = EnsembleSpread.of(sim, 'rk4')
    msg = SimpleNamespace(pose=SimpleNamespace(covariance=[9.0] * 36),
                          twist=SimpleNamespace(covariance=[9.0] * 36))
    fill_covariance(msg, None, plain, 0, plain.observed())
    assert msg.pose.covariance == [0.0] * 36 and msg.twist.covariance == [0.0] * 36
    yaw = []
    for _ in range(6):
        sim.set_rudder(0.2)
        sim.step(100)
        fill_covariance(msg, spread, sim, 1, sim.observed())
        yaw.append(msg.pose.covariance[35])
        assert msg.pose.covariance[0] >= 0 and msg.twist.covariance[35] > 0
    assert np.all(np.diff(yaw) > 0) and yaw[0] > 0
    # c x the members' standard deviation: two members at +-d about the centre give c*d*sqrt(2)
    alone = [ShipSimulator(ship, 0.1, [0, 0, 0, 3.0, 0, 0], 100.0, 0.2, residual=m.residual)
             for m in iv.members]
    for a in alone:
        assert a.step(600)
    dev = np.array([a.observed()[2] for a in alone]) - sim.observed()[2]
    assert msg.pose.covariance[35] == pytest.approx(4.0 * np.sum(dev ** 2), rel=1e-6)
    sim.reset()   # a new run: the members start again with the simulator
    fill_covariance(msg, spread, sim, 2, sim.observed())
    assert msg.pose.covariance[35] == 0.0 and all(m.steps == 0 for m in spread.members)


def test_simulator_spread_with_the_start_error_adds_the_raised_starts():
    """A stored start error: the node steps the model from raised starts and adds sigma."""
    from mmg_tuner.core.stepper import ShipSimulator
    from mmg_tuner.ros.uncertainty import EnsembleSpread
    ship = mt.load_ship('suzaku')
    model = mt.Model(ship, ensemble([_kick(2e-4), _kick(-2e-4)]))
    sd = (0.0, 0.2, 0.01, 0.05, 0.0, 0.002)   # x, y, psi, u, v, r; x and v none
    iv = Interval(model, tuple(mt.Model(ship, n) for n in members(model.residual)),
                  (2.0,) * 6, 0.9, start_sigma=sd)
    sim = ShipSimulator(ship, 0.1, [0, 0, 0, 3.0, 0, 0], 100.0,
                        residual=with_interval(iv).residual)
    spread = EnsembleSpread.of(sim, 'rk4')
    assert spread.n_start == 4 and len(spread.members) == 6
    # at the start itself nothing (as at a calibration's restart); one step on, each raised
    # start departs by about its sigma and sigma is added: about 2 sigma^2
    np.testing.assert_array_equal(spread.sigma(sim.observed()), np.zeros(6))
    sim.step(1)
    spread.follow(sim, 1)
    s = spread.sigma(sim.observed())
    on = np.array(sd) > 0
    np.testing.assert_allclose(s[on], 2.0 * np.sqrt(2) * np.array(sd)[on], rtol=0.05)
    sim.set_rudder(0.2)
    sim.step(300)
    spread.follow(sim, 1)
    s = spread.sigma(sim.observed())
    # a yaw-rate error at the start turns into heading and then into position: x grows
    assert s[0] > 2.0 * 0.01 and s[2] > 2.0 * np.sqrt(2) * 0.01


def test_tune_model_auto_trains_compares_and_writes_the_recommended_model(trials, tmp_path):
    pytest.importorskip('jax')
    groups = {t.name: KINDS[t.name] for t in trials}
    res = mt.tune(mt.load_ship('suzaku'), trials, max_evals=40, model='auto',
                  residual_seeds=2, groups=groups, joint=True,
                  residual_options={'epochs': 2, 'hidden': (6,), 'horizon_s': 6.0})
    c = res.choice
    assert list(c.by_kind) == ['physics', 'hybrid', 'network', 'blend', 'joint']
    assert c.score[c.chosen] == min(c.score.values()) >= 1.0
    # every candidate compared is kept, each scoring as the table says (to score elsewhere)
    assert list(res.candidates) == list(c.by_kind)
    again = choose_model(res.candidates, split_validation(trials, 0.25, 5)[1], groups)
    assert again.by_kind == c.by_kind
    assert res.candidates['physics'].params is not None and \
        res.candidates['hybrid'].residual is not None
    res.write(tmp_path / 'out', plots=False)
    params = (tmp_path / 'out' / 'params.yaml').read_text()
    assert '## Model chosen (--model auto)' in (tmp_path / 'out' / 'report.md').read_text()
    if c.chosen == 'physics':
        assert res.residual is None and 'residual:' not in params
    else:   # with its interval, or a note why not (a 2-epoch member may diverge alone)
        assert 'residual:' in params
        assert ('interval' in res.residual.net.meta) != any(
            n.startswith('no prediction interval') for n in res.choice_notes), res.choice_notes
        back = load_model('suzaku', tmp_path / 'out' / 'params.yaml')
        assert back.kind == {'network': 'pure network', 'joint': 'hybrid'}.get(c.chosen,
                                                                               c.chosen)
    with pytest.raises(mt.MmgTunerError, match='model'):
        mt.TuneConfig(model='best')
    with pytest.raises(mt.MmgTunerError, match='joint'):   # a candidate of auto only
        mt.TuneConfig(joint=True)
    # without joint=True auto compares the four of before
    assert 'joint' not in mt.tune(mt.load_ship('suzaku'), trials[:2], max_evals=20,
                                  model='auto', residual_seeds=1, groups=groups,
                                  residual_options={'epochs': 1, 'hidden': (4,),
                                                    'horizon_s': 6.0}).candidates


def test_tune_gives_its_groups_to_the_residual_training(trials):
    """
    balance='group' needs the trials' groups: tune passes its own (a trial not named: its own).

    Before, the residual's training never saw them and refused ("needs groups").
    """
    pytest.importorskip('jax')
    groups = {t.name: KINDS[t.name] for t in trials[:3]}   # the fourth unnamed
    res = mt.tune(mt.load_ship('suzaku'), trials, max_evals=10, residual='hybrid',
                  groups=groups, residual_options={'epochs': 1, 'hidden': (4,),
                                                   'horizon_s': 6.0, 'balance': 'group'})
    assert set(res.residual.net.meta['share_by_group']) == {'turning', 'zigzag',
                                                            trials[3].name}


def test_a_recommended_ensemble_whose_interval_fails_is_written_without_one(
        trials, tmp_path, monkeypatch):
    """
    A member that diverges alone (the fresh clone's CI met it) costs the interval, not the run.

    The recommended model is written and loads back; the note says why it has no interval.
    """
    pytest.importorskip('jax')
    from mmg_tuner.api import tuning as api_tuning

    def fails(*a, **k):
        raise TuningError('the interval could not be calibrated: a member diverged')

    def network(cands, *a, **k):   # recommend an ensemble whatever the scores
        return Choice('network', {n: {'turning': 1.0} for n in cands},
                      dict.fromkeys(cands, 1.0))
    monkeypatch.setattr(api_tuning, 'calibrate_interval', fails)
    monkeypatch.setattr(api_tuning, 'choose_model', network)
    res = mt.tune(mt.load_ship('suzaku'), trials, max_evals=40, model='auto',
                  residual_seeds=2, groups={t.name: KINDS[t.name] for t in trials},
                  residual_options={'epochs': 2, 'hidden': (6,), 'horizon_s': 6.0})
    assert res.choice.chosen == 'network' and 'interval' not in res.residual.net.meta
    assert any(n.startswith('no prediction interval') for n in res.choice_notes)
    res.write(tmp_path / 'out', plots=False)
    assert load_model('suzaku', tmp_path / 'out' / 'params.yaml').kind == 'pure network'


def test_a_recommended_joint_model_writes_its_own_physics(trials, tmp_path, monkeypatch):
    """
    The joint candidate chosen: its coefficients are the physics written, J reported for it.

    Its physics starts from the tuned values, moves within the boxes, and is what params.yaml
    holds with the network; the report says so.
    """
    pytest.importorskip('jax')
    from mmg_tuner.api import tuning as api_tuning

    def joint(cands, *a, **k):   # recommend the joint model whatever the scores
        return Choice('joint', {n: {'turning': 1.0} for n in cands}, dict.fromkeys(cands, 1.0))

    monkeypatch.setattr(api_tuning, 'choose_model', joint)
    ship = mt.load_ship('suzaku')
    targets = ['N_r', 'Y_v', 'R_0']
    res = mt.tune(ship, trials, targets=targets, max_evals=40, model='auto', prior=0.1,
                  joint=True,
                  residual_seeds=2, groups={t.name: KINDS[t.name] for t in trials},
                  residual_options={'epochs': 3, 'hidden': (6,), 'horizon_s': 6.0,
                                    'learning_rate': 3e-2, 'significance': 0.0})
    assert res.choice.chosen == 'joint' and res.residual.kind == 'joint'
    coeffs = res.residual.config['coefficients']
    assert set(coeffs) == set(targets)
    written = res.candidates['joint'].ship
    for n in targets:   # in the box, and the physics written is the joint's
        assert res.space.lower[res.space.names.index(n)] <= coeffs[n] <= \
            res.space.upper[res.space.names.index(n)]
        assert res.params[n] == coeffs[n] == written[n]
    res.write(tmp_path / 'out', plots=False)
    back = load_model('suzaku', tmp_path / 'out' / 'params.yaml')
    assert back.kind == 'hybrid' and all(back.ship[n] == coeffs[n] for n in targets)
    assert any('joint' in n for n in res.choice_notes)
    assert 'Its physics coefficients were trained' in (tmp_path / 'out' / 'report.md').read_text()


def test_the_fresh_test_was_registered_with_its_hypotheses():
    reg = (ROOT / 'bench' / 'esso_fresh_preregistration.md').read_text()
    for what in ('H1', 'H2', 'H3', 'H4', 'bench/esso_fresh.py', '80 %', '95 %'):
        assert what in reg
    readme = (ROOT / 'data' / 'esso_osaka_frt_extra' / 'README.md').read_text()
    assert 'esso_fresh_preregistration.md' in readme
    assert (ROOT / 'data' / 'esso_osaka_frt_extra' / 'LICENSE').is_file()


def test_polish_alone_tunes_from_the_pre_determined_values(trials):
    # max_evals 0: no CMA-ES, the least-squares polish on the objective's residuals alone
    ship = mt.load_ship('suzaku')
    start = ship.with_params({'N_r': 1.2 * ship['N_r']})
    res = mt.tune(start, trials[:2], targets=['N_r'], max_evals=0, polish=60,
                  balance='group', groups={t.name: KINDS[t.name] for t in trials})
    assert 0 < res.evaluations <= 62 and res.J.tune < 0.5 * res.J_pre.tune
    assert res.params['N_r'] == pytest.approx(ship['N_r'], rel=0.05)
    with pytest.raises(mt.MmgTunerError, match='max_evals'):
        mt.TuneConfig(max_evals=0)


def test_residuals_square_to_the_balanced_objective_with_its_prior(trials):
    # the compiled residual kernel: its sum of squares is exactly what the objective minimises
    from mmg_tuner.tuning.identifiability import residuals
    from mmg_tuner.tuning.objective import Objective, Prior, TrialBatch
    from mmg_tuner.tuning.parameters import ParameterSpace
    ship = mt.load_ship('suzaku')
    space = ParameterSpace.around(ship, ['N_r', 'Y_v'])
    prior = Prior(space.indices, space.pre, space.upper - space.lower, 3.0)
    obj = Objective(ship, TrialBatch.from_trials(trials), np.array([1, 1, 50, 4, 4, 900.0]),
                    integrator='rk4', trial_weights=np.array([0.5, 2.0, 1.0, 0.0]),
                    prior=prior)
    P = space.full_params(ship.params, np.array([space.pre, 1.3 * space.pre]))
    r = residuals(obj, P)
    assert r.shape == (2, 6 * sum(len(t) - 1 for t in trials) + 2)
    np.testing.assert_allclose(np.sum(r * r, axis=1), obj(P), rtol=1e-9)
    assert np.sum(r[1] ** 2) > 10 * np.sum(r[0] ** 2)


def test_polish_of_many_parameters_converges_in_few_simulations(trials):
    # six targets: the Jacobian after the first is a Broyden update while steps go well, so
    # the fit costs far fewer than d + 1 = 7 simulations per step, and it ends at an optimum
    # (the generated trials carry effects the ship lacks: their truth is not the optimum)
    ship = mt.load_ship('suzaku')
    names = ['N_r', 'Y_v', 'N_v', 'Y_r', 'R_0', 't_P']
    start = ship.with_params({n: 1.15 * ship[n] for n in names})
    res = mt.tune(start, trials, targets=names, max_evals=0, polish=300)
    assert res.J.tune < 0.1 * res.J_pre.tune
    assert res.evaluations < 100
    again = mt.tune(start.with_params(res.params), trials, targets=names, max_evals=0,
                    polish=300)
    assert again.J.tune > 0.99 * res.J.tune


def test_ship_recipe_fills_only_the_options_not_given():
    from types import SimpleNamespace

    from mmg_tuner.cli.tune import apply_recipe, build_parser, explicit_options
    argv = ['runs/', '--ship', 'esso_osaka_3m', '--out', 'o', '--prior', '0.2']
    args = build_parser().parse_args(argv)
    ship = SimpleNamespace(extra={'tuning': {'recipe': {'prior': 0.05, 'segment': 100.0,
                                                        'max_evals': 0, 'polish': 700}}},
                           source='esso.yaml')
    applied = apply_recipe(args, explicit_options(build_parser(), argv), ship)
    assert args.prior == 0.2 and args.segment == 100.0 and args.max_evals == 0
    assert args.polish == 700 and 'prior=0.05' not in applied
    ship.extra['tuning']['recipe'] = {'nope': 1}
    with pytest.raises(Exception, match='nope'):
        apply_recipe(args, {}, ship)


def test_interval_start_error_measures_the_recorded_noise_and_covers_with_small_factors(
        trials):
    """
    Recorded states with a known white error: the start error finds it, and carries it.

    The model is the trials' own ship (two tiny kicks): the members' spread alone misses the
    recorded error, which every restart starts from and every sample carries, so its factors
    are large; with the start error the spread is the error's and the factors near a normal
    quantile's (1.6 at 90 %).
    """
    from dataclasses import replace
    from mmg_tuner.tuning.evaluate import predict
    ship = mt.load_ship('suzaku')
    sd = np.array([0.05, 0.05, 0.005, 0.01, 0.005, 0.001])   # x, y, psi, u, v, r
    rng = np.random.default_rng(3)
    # the truth: the ship itself, driven by the trials' inputs (the recordings have their own
    # sensor noise and antenna), recorded with the known error sd
    truth = [replace(t, states=predict(ship, t, 0.0)[0]) for t in trials]
    noisy = [replace(t, states=t.states + sd * rng.standard_normal(t.states.shape))
             for t in truth]
    model = mt.Model(ship, ensemble([_kick(2e-5), _kick(-2e-5)]))
    plain = calibrate_interval(model, noisy, 0.9, restart_every_s=10.0)
    iv = calibrate_interval(model, noisy, 0.9, restart_every_s=10.0, start_error=True)
    assert plain.start_sigma is None and iv.start_sigma is not None
    # 48 restarts: the estimate within about three of its standard errors (10 %)
    ratio = np.asarray(iv.start_sigma) / sd
    assert np.all((ratio > 0.7) & (ratio < 1.4)), ratio
    assert max(plain.scale) > 5.0 and max(iv.scale) < 3.0
    assert coverage(iv, noisy, restart_every_s=10.0)['all'] >= 0.9
    assert set(iv.to_dict()['start_sigma']) == {'x', 'y', 'psi', 'u', 'v', 'r'}
    # stored with the network, and read back: evaluate's coverage is the same interval's
    carried = model_interval(with_interval(iv))
    assert carried.start_sigma == pytest.approx(iv.start_sigma)
