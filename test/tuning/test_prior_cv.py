"""The prior weight chosen by leaving days out (tuning/prior_cv.py, tune's prior_choices)."""
import math

from mmg_tuner.core.ship import load_ship
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.prior_cv import choose_prior, folds, label, PUBLISHED, sessions
import numpy as np
import pytest


def test_sessions_are_the_dates_in_the_names():
    names = ['turn_14-Sep-2020_13_39_32', 'turn_14-Sep-2020_13_51_45', 'berthing_12-Nov-2020_1']
    assert sessions(names) == {names[0]: '2020-09-14', names[1]: '2020-09-14',
                               names[2]: '2020-11-12'}
    bags = ['rosbag2_2024_05_01-10_00_00', 'rosbag2_2024_05_02-09_00_00']   # ros2 bag record
    assert set(sessions(bags).values()) == {'2024-05-01', '2024-05-02'}
    # every way of writing a day is the same day
    mixed = ['a_12-Nov-2020', 'b_2020-11-12', 'c_20201112', 'd_2020_11_13']
    assert list(sessions(mixed).values()) == ['2020-11-12'] * 3 + ['2020-11-13']
    # no dates, a name without one, a month word that is not one, or one day for all: each
    # run its own session
    for names in (['a', 'b', 'c'], ['a_20240501', 'b'], ['test1-rpm-1200', 'test2-rpm-1300'],
                  ['x_12-Nov-2020', 'y_12-Nov-2020'], ['r_2024_13_45', 'r_2024_02_30']):
        assert sessions(names) == {n: n for n in names}


def test_folds_hold_whole_sessions_each_once():
    of = {f'r{i}': f'day{i % 8}' for i in range(20)}
    fs = folds(of)
    assert len(fs) == 6                                  # at most MAX_FOLDS fits per weight
    assert sorted(n for f in fs for n in f) == sorted(of)
    for f in fs:   # no day on both sides
        days = {of[n] for n in f}
        assert not days & {of[n] for n in of if n not in f}
    assert len(folds({'a': 'a', 'b': 'b'})) == 2


def _held(table):
    """held-out scores per candidate from {candidate: {kind: index}} (two runs per kind)."""
    return {c: {f'{k}{i}': v for k, v in per.items() for i in (1, 2)}
            for c, per in table.items()}


KIND = {f'{k}{i}': k for k in ('turning', 'berthing') for i in (1, 2)}


def test_the_worst_kind_decides_and_never_loses_to_the_start():
    held = _held({PUBLISHED: {'turning': 2.0, 'berthing': 1.0},
                  label(0): {'turning': 0.1, 'berthing': 1.2},     # wins turning, loses berthing
                  label(0.5): {'turning': 0.3, 'berthing': 0.8},
                  label(5): {'turning': 1.0, 'berthing': 0.9}})
    c = choose_prior([0, 0.5, 5], held, KIND, [['turning1']])
    assert c.chosen == label(0.5) and c.prior == 0.5
    assert c.score[label(0)] == pytest.approx(1.2) and c.score[PUBLISHED] == 1.0
    assert c.ratio[label(0.5)] == pytest.approx({'turning': 0.15, 'berthing': 0.8})
    assert '(chosen)' in c.markdown() and c.to_dict()['prior'] == 0.5


def test_a_tie_goes_to_the_more_cautious_and_every_loser_keeps_the_published():
    held = _held({PUBLISHED: {'turning': 2.0, 'berthing': 1.0},
                  label(0): {'turning': 0.1, 'berthing': 0.800},
                  label(5): {'turning': 1.0, 'berthing': 0.805}})   # within 0.01 of the best
    assert choose_prior([0, 5], held, KIND, []).chosen == label(5)
    held = _held({PUBLISHED: {'turning': 2.0, 'berthing': 1.0},
                  label(0): {'turning': 0.1, 'berthing': 1.3},
                  label(5): {'turning': 1.0, 'berthing': 1.05}})
    c = choose_prior([0, 5], held, KIND, [])
    assert c.chosen == PUBLISHED and c.prior is None
    held[label(0)]['turning1'] = None   # a failed fit scores infinity
    assert math.isinf(choose_prior([0, 5], held, KIND, []).score[label(0)])
    with pytest.raises(TuningError, match='prior 0.5'):
        choose_prior([0.5], held, KIND, [])
    held = _held({PUBLISHED: {'turning': 2.0, 'berthing': 1.0},
                  label(5): {'turning': 1.0, 'berthing': 0.995}})   # tied with the start
    assert choose_prior([5], held, KIND, []).chosen == PUBLISHED


def _run(ship, name, seed, rudder_deg):
    """Return a 60 s low-speed run (astern at the end) with noisy states."""
    rng = np.random.default_rng(seed)
    T = 121
    rpm = np.where(np.arange(T) < 0.7 * T, 600.0, -400.0)
    ctrl = np.column_stack([rpm, np.full(T, math.radians(rudder_deg))])
    run = simulate(ship, [0, 0, 0, 0.3, 0, 0], ctrl, 0.5, 'rk4')
    assert run.ok
    return Trial(run.t, run.states + rng.normal(0, 1e-3, run.states.shape), ctrl, name=name)


def test_tune_frees_what_new_days_confirm_and_keeps_what_they_refute(tmp_path):
    import mmg_tuner as mt
    ship = load_ship('esso_osaka_3m')
    n0 = ship['N_r']
    opts = {'targets': ['N_r'], 'max_evals': 0, 'polish': 30, 'segment_s': 20.0,
            'balance': 'trial', 'integrator': 'rk4', 'weights': 'index',
            'prior_choices': (0.0, 1e6)}
    days = ('01-Jan-2021', '02-Jan-2021', '03-Jan-2021')
    # every day the same ship, not the published one: the days held out confirm the fit
    same = [_run(ship.with_params({'N_r': 1.3 * n0}), f'run_{d}', i, 20 - 15 * i)
            for i, d in enumerate(days)]
    res = mt.tune(ship, same, config=mt.TuneConfig(**opts))
    pc = res.prior_choice
    assert pc.chosen == label(0.0) and pc.score[label(0.0)] < 0.5   # measured 0.14
    assert res.params['N_r'] == pytest.approx(1.3 * n0, rel=0.05)
    assert pc.folds == [[t.name] for t in same]
    # each day its own yaw damping, scattered around the published value: a fit on two days
    # predicts the third worse than the published value does; nothing is tuned
    scattered = [_run(ship.with_params({'N_r': (1 + dn) * n0}), f'run_{d}', i, 20 - 15 * i)
                 for i, (d, dn) in enumerate(zip(days, (0.3, -0.3, 0.0)))]
    res = mt.tune(ship, scattered, config=mt.TuneConfig(**opts))
    pc = res.prior_choice
    assert pc.score[label(0.0)] > 1.5                                 # measured 2.9
    assert pc.prior in (None, 1e6)   # the start, or held to it
    assert res.params['N_r'] == pytest.approx(n0, rel=1e-3)
    assert res.report()['prior_choice']['chosen'] == pc.chosen
    res.write(tmp_path / 'out', plots=False)
    md = (tmp_path / 'out' / 'report.md').read_text()
    assert 'Prior chosen by leaving days out' in md and f'| {pc.chosen} (chosen) |' in md
    with pytest.raises(TuningError, match='prior_choices'):
        mt.TuneConfig(prior=0.5, prior_choices=(0.0, 1.0))
    with pytest.raises(TuningError, match='prior_choices'):
        mt.TuneConfig(prior_choices=(-1.0,))
    with pytest.raises(TuningError, match='at least 3'):   # a polish that could not step
        mt.tune(ship, scattered, targets=['N_r'], max_evals=0, polish=2)


def test_the_choice_survives_odd_names_and_one_trial(caplog):
    import mmg_tuner as mt
    ship = load_ship('esso_osaka_3m')
    n0 = ship['N_r']
    opts = {'targets': ['N_r'], 'max_evals': 0, 'polish': 30, 'segment_s': 20.0,
            'integrator': 'rk4', 'weights': 'index', 'prior_choices': (0.0, 1e6)}
    # two runs of one name on one day, one name with a byte that is not text
    runs = [_run(ship.with_params({'N_r': 1.3 * n0}), name, i, 20 - 15 * i)
            for i, name in enumerate(('run_01-Jan-2021', 'run_01-Jan-2021',
                                      'run_02-Jan-2021_\udcff'))]
    res = mt.tune(ship, runs, config=mt.TuneConfig(**opts))
    pc = res.prior_choice
    assert len(pc.folds) == 2 and sorted(map(len, pc.folds)) == [1, 2]
    # each run scored on its own: the two runs of one name are different runs
    first, second = (pc.by_kind[PUBLISHED][k] for k in sorted(pc.by_kind[PUBLISHED])[:2])
    assert first != second
    assert pc.simulations > 0 and res.evaluations >= pc.simulations
    # one trial: nothing to hold out; the largest weight, and the report says why
    res = mt.tune(ship, runs[:1], config=mt.TuneConfig(**opts))
    assert res.prior_choice.prior == 1e6 and not res.prior_choice.by_kind
    assert 'nothing to hold out' in res.prior_choice.markdown()
    assert 'nothing to hold out' in caplog.text


def test_recipe_prior_choices_unless_a_prior_is_given():
    from types import SimpleNamespace

    from mmg_tuner.cli.tune import apply_recipe, build_parser, explicit_options, tune_config
    from mmg_tuner.errors import MmgTunerError
    recipe = {'prior_choices': [0.0, 0.5], 'prior': 0.0, 'max_evals': 0, 'polish': 5,
              'weights': 'index'}
    ship = SimpleNamespace(extra={'tuning': {'recipe': recipe}}, source='esso.yaml')
    for extra, choices, prior, weights in (
            ([], (0.0, 0.5), 0.0, 'index'), (['--prior', '0.2'], (), 0.2, 'index'),
            (['--prior-choices', '1', '2'], (1.0, 2.0), 0.0, 'index'),
            (['--weights'] + ['2'] * 6, (0.0, 0.5), 0.0, (2.0,) * 6)):
        argv = ['runs/', '--ship', 'esso_osaka_3m', '--out', 'o'] + extra
        args = build_parser().parse_args(argv)
        apply_recipe(args, explicit_options(build_parser(), argv), ship)
        cfg = tune_config(args)
        assert (cfg.prior_choices, cfg.prior, cfg.weights) == (choices, prior, weights)
    # a command-line choice cancels a recipe's non-zero prior
    recipe['prior'] = 0.05
    argv = ['runs/', '--ship', 'esso_osaka_3m', '--out', 'o', '--prior-choices', '1']
    args = build_parser().parse_args(argv)
    apply_recipe(args, explicit_options(build_parser(), argv), ship)
    assert tune_config(args).prior == 0.0
    for bad in ({'prior_choices': 0.5}, {'weights': 1.0}, {'targets': 'N_r'}):
        ship.extra['tuning']['recipe'] = bad
        with pytest.raises(MmgTunerError, match=next(iter(bad))):
            apply_recipe(build_parser().parse_args(['runs/', '--out', 'o']), {}, ship)


def test_index_weights_are_the_index_standardisation():
    import mmg_tuner as mt
    from mmg_tuner.cli.tune import build_parser, tune_config
    from mmg_tuner.tuning.evaluate import pooled_sigma
    base = ['runs/', '--ship', 'esso_osaka_3m', '--out', 'o']
    assert tune_config(build_parser().parse_args(base + ['--index-weights'])).weights \
        == 'index'
    # --weights takes six numbers and leaves the trials after it alone
    args = build_parser().parse_args(['--weights'] + ['2'] * 6 + ['runs/', '--out', 'o'])
    assert tune_config(args).weights == (2.0,) * 6 and args.trials == ['runs/']
    ship = load_ship('esso_osaka_3m')
    runs = [_run(ship, 'a', 0, 20), _run(ship, 'b', 1, -10)]
    spec = mt.TuneConfig(weights='index').objective_spec(runs)
    sig = pooled_sigma(runs)
    assert spec.weights == pytest.approx([1 / sig[n] ** 2 for n in ('x', 'y', 'psi', 'u', 'v',
                                                                    'r')])
    with pytest.raises(TuningError, match='weights'):
        mt.TuneConfig(weights='heavy')
