"""Segments, trial weights and the prior of the tuning objective (the Esso Osaka tuning)."""
import math

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.objective import Objective, Prior, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.segments import segment_weights, split_trial, split_trials
from mmg_tuner.tuning.tuner import Tuner
import numpy as np
import pytest


@pytest.fixture(scope='module')
def ship():
    return load_ship('esso_osaka_3m')


def _recorded(ship, T, name, seed=0, rudder_deg=20.0):
    """Simulate a low-speed run (astern at the end) with measured wind and noisy states."""
    rng = np.random.default_rng(seed)
    rpm = np.where(np.arange(T) < 0.7 * T, 600.0, -400.0)
    ctrl = np.column_stack([rpm, np.full(T, math.radians(rudder_deg)),
                            np.full(T, -1.0), np.full(T, 0.5)])
    run = simulate(ship, [0, 0, 0, 0.3, 0, 0], ctrl, 0.5, 'rk4')
    assert run.ok
    st = run.states + rng.normal(0, 1e-3, run.states.shape)
    return Trial(run.t, st, ctrl[:, :2], name=name, wind=ctrl[:, 2:4])


def test_split_scores_every_transition_once():
    t = np.arange(101) * 0.5
    tr = Trial(t, np.zeros((101, 6)), np.zeros((101, 2)), name='a', wind=np.ones((101, 2)))
    segs = split_trial(tr, 20.0)                  # 40 samples each; tail of 20 >= 20 kept
    assert [s.start for s in segs] == [0, 40, 80]
    assert sum(s.transitions for s in segs) == 100
    for s0, s1 in zip(segs, segs[1:]):            # boundary sample shared, not skipped
        assert s0.trial.t[-1] == s1.trial.t[0]
    assert segs[1].trial.wind.shape == (41, 2) and segs[1].parent == 'a'
    short_tail = split_trial(tr, 30.0)            # tail of 40 samples >= 15 s: kept
    assert [s.start for s in short_tail] == [0, 60]
    merged = split_trial(tr, 45.0)                # starts 0, 90; tail 10 < 45 joins the piece
    assert [s.start for s in merged] == [0] and merged[0].transitions == 100
    assert split_trial(tr, 0.0)[0].trial is tr
    with pytest.raises(TuningError, match='unique'):
        split_trials([tr, tr], 10.0)


def test_segmented_objective_equals_restarts(ship):
    """Pieces simulated on their own = one run restarted at the same samples (the index)."""
    tr = _recorded(ship, 161, 'run')
    whole = Objective(ship, TrialBatch.from_trials([tr], x0_window_s=0.0), np.ones(6),
                      shoot_every_s=20.0, integrator='rk4')
    segs = split_trials([tr], 20.0)
    pieces = Objective(ship, TrialBatch.from_trials([s.trial for s in segs], x0_window_s=0.0),
                       np.ones(6), integrator='rk4')
    a = whole(ship.params[None])[0]
    b = pieces(ship.params[None])[0]
    assert b == pytest.approx(a, rel=1e-9)
    assert len(segs) == 4


def test_weights_balance_trials_and_groups(ship):
    long_, short = _recorded(ship, 401, 'long'), _recorded(ship, 81, 'short', seed=1)
    other = _recorded(ship, 81, 'other', seed=2)
    segs = split_trials([long_, short, other], 20.0)
    n = np.array([s.transitions for s in segs], float)
    assert np.all(segment_weights(segs, 'sample') == 1.0)
    w = segment_weights(segs, 'trial')
    total = {p: sum(wi * ni for wi, ni, s in zip(w, n, segs) if s.parent == p)
             for p in ('long', 'short', 'other')}
    assert total['long'] == pytest.approx(total['short']) == pytest.approx(total['other'])
    assert np.sum(w * n) == pytest.approx(n.sum())      # mean weight per sample is 1
    g = segment_weights(segs, 'group', {'long': 'turning', 'short': 'berthing',
                                        'other': 'berthing'})
    tot = {p: sum(wi * ni for wi, ni, s in zip(g, n, segs) if s.parent == p) for p in total}
    assert tot['long'] == pytest.approx(tot['short'] + tot['other'])
    assert tot['short'] == pytest.approx(tot['other'])
    with pytest.raises(TuningError, match='no group'):
        segment_weights(segs, 'group', {'long': 'turning'})
    with pytest.raises(TuningError, match='balance'):
        segment_weights(segs, 'kind')


def test_trial_weights_and_prior_enter_the_total(ship):
    trials = [_recorded(ship, 81, 'a'), _recorded(ship, 81, 'b', seed=1, rudder_deg=-10)]
    batch = TrialBatch.from_trials(trials, x0_window_s=0.0)
    space = ParameterSpace.around(ship, ('C_D', 'X_0F'))
    params = space.full_params(ship.params, np.array([[1.2, -0.03], [0.9665, -0.02139]]))
    plain = Objective(ship, batch, np.ones(6), integrator='rk4')
    J, _ = plain.per_trial(params)
    prior = Prior(space.indices, space.pre, space.upper - space.lower, 7.0)
    obj = Objective(ship, batch, np.ones(6), integrator='rk4',
                    trial_weights=np.array([2.0, 0.5]), prior=prior)
    z = (params[:, space.indices] - space.pre) / (space.upper - space.lower)
    expect = J @ np.array([2.0, 0.5]) + 7.0 * np.sum(z * z, axis=1)
    assert obj(params) == pytest.approx(expect, rel=1e-12)
    assert prior(params)[1] == 0.0 and prior(params)[0] > 0
    with pytest.raises(TuningError, match='trial_weights'):
        Objective(ship, batch, np.ones(6), trial_weights=np.array([1.0, -1.0]))


def test_checkpoint_knows_the_prior(ship, tmp_path):
    batch = TrialBatch.from_trials([_recorded(ship, 41, 'a')], x0_window_s=0.0)
    space = ParameterSpace.around(ship, ('C_D',))
    ck = tmp_path / 'ck.pkl'
    Tuner(space, Objective(ship, batch, np.ones(6), integrator='rk4'), max_evaluations=12,
          checkpoint=ck).run()
    prior = Prior(space.indices, space.pre, space.upper - space.lower, 1.0)
    again = Tuner(space, Objective(ship, batch, np.ones(6), integrator='rk4', prior=prior),
                  max_evaluations=24, checkpoint=ck)
    with pytest.raises(TuningError, match='another problem'):
        again.run(resume=True)


def test_tune_options_segments_balance_prior(ship):
    import mmg_tuner as mt
    truth = ship.with_params({'C_D': 1.3})
    trials = [_recorded(truth, 121, 'a'), _recorded(truth, 61, 'b', seed=1, rudder_deg=-15)]
    free = mt.tune(ship, trials, targets=['C_D'], segment_s=20.0, balance='trial',
                   max_evals=60, integrator='rk4', weights=(1, 1, 1, 1, 1, 1))
    held = mt.tune(ship, trials, targets=['C_D'], segment_s=20.0, balance='trial', prior=1e6,
                   max_evals=60, integrator='rk4', weights=(1, 1, 1, 1, 1, 1))
    lo, hi = ship.tuning_bounds['C_D']
    assert abs(free.params['C_D'] - 1.3) < abs(ship['C_D'] - 1.3) / 2   # the data pull it
    assert abs(held.params['C_D'] - ship['C_D']) < 0.01 * (hi - lo)    # the prior holds it
    with pytest.raises(TuningError, match='balance'):
        mt.TuneConfig(balance='everything')
    with pytest.raises(TuningError, match='prior'):
        mt.TuneConfig(prior=-1.0)
    with pytest.raises(TuningError, match='segment_s'):
        mt.TuneConfig(segment_s=math.nan)


def test_bench_params_file_is_refused_when_its_inputs_changed(tmp_path, monkeypatch, capsys):
    """bench/esso_osaka.py's params file: esso_hybrid.py must not reuse it on other inputs."""
    from bench import esso_osaka as bench
    cfg, run = tmp_path / 'ship.yaml', tmp_path / 'a.csv'
    cfg.write_text('ship: x\n')
    run.write_text('t,x\n0,1\n')
    monkeypatch.setattr(bench, 'runs_by_kind', lambda: {'zigzag': [run]})
    params = tmp_path / 'params.yaml'

    def refused(what):
        with pytest.raises(SystemExit) as exc:
            bench.check_provenance(params, cfg)
        err = capsys.readouterr().err
        assert exc.value.code == 2 and str(params) in err and bench.PARAMS_COMMAND in err, err
        assert what in err, err

    refused('does not exist')
    params.write_text('params: {C_D: 0.8}\n')
    refused('no provenance')
    params.write_text('params: {C_D: 0.8}\nprovenance: {inputs_sha256: '
                      f'{bench.inputs_fingerprint(cfg)}, evaluations: 10}}\n')
    assert bench.check_provenance(params, cfg)['evaluations'] == 10
    run.write_text('t,x\n0,2\n')          # a run file edited
    refused('other inputs')
    run.write_text('t,x\n0,1\n')
    cfg.write_text('ship: y\n')           # the ship config edited
    refused('other inputs')


def test_bench_params_files_differ_per_fold():
    """bench/esso_osaka.py writes each fold's tuning to its own file; fold 1's is the default."""
    from bench import esso_osaka as bench
    from mmg_tuner.data.esso import FOLDS
    assert bench.params_path(1) == bench.PARAMS_OUT
    paths = {bench.params_path(f) for f in FOLDS} | {bench.params_path(None)}
    assert len(paths) == len(FOLDS) + 1
