"""
bench/esso_hybrid_settings.py's index criterion (issue 14): what it scores and how.

The criterion must score the quarter ``train_residual`` holds out of each run with the held-out
scoring's own index (eq. 26, 100 s restarts, sigma pooled over the quarters), take the ratio
of the kind's means, and a residual scaled at inference must be exactly the scaled residual.
"""
import math

import mmg_tuner as mt
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.learn.residual import mlp_forward, N_FEATURES, ResidualNet
import numpy as np
import pytest


@pytest.fixture(scope='module')
def bench():
    from bench import esso_hybrid_settings   # imports JAX: only when these tests run
    return esso_hybrid_settings


def test_validation_quarter_index_is_the_held_out_scoring_on_the_last_quarter(bench, suzaku):
    trials = [generate_trial(suzaku, m, a, None, 106.0, 3.086, 480.0, 1.0, SensorNoise(), 3 + i,
                             f'{m}{a:+d}')[1]
              for i, (m, a) in enumerate((('turning', 30), ('zigzag', 20), ('random', 25)))]
    window = 5
    # a run repeated in training (berthing with balance window) is scored once
    quarters = bench.validation_quarters(trials + [trials[1]], window)
    assert [q.name for q in quarters] == [t.name for t in trials]
    by_hand = [t.slice(t.t[0] + 0.75 * t.duration_s - (window - 1) * t.dt, t.t[-1])
               for t in trials]
    for q, h in zip(quarters, by_hand):
        assert np.array_equal(q.t, h.t) and np.array_equal(q.states, h.states)
        assert q.duration_s > 100.0   # long enough for a restart to matter
    got = bench.held_out_scores([suzaku.with_params({'R_0': 0.05})], quarters)
    ref = mt.evaluate(suzaku.with_params({'R_0': 0.05}), by_hand, restart_every_s=100.0,
                      integrator='rk4')
    no_restart = mt.evaluate(suzaku.with_params({'R_0': 0.05}), by_hand, restart_every_s=0.0,
                             integrator='rk4')
    for h in by_hand:
        assert got[h.name][0] == pytest.approx(ref.trials[h.name].index, rel=1e-12)
    assert got['all'][0] == pytest.approx(ref.index_all, rel=1e-12)
    assert abs(no_restart.index_all - ref.index_all) > 1e-3 * ref.index_all


def test_index_ratio_is_the_ratio_of_the_kinds_means(bench):
    kind_of = {'a': 'turning', 'b': 'turning', 'c': 'zigzag', 'd': 'random', 'e': 'berthing'}
    physics = {'a': 1.0, 'b': 3.0, 'c': 2.0, 'd': 1.0, 'e': 4.0, 'all': 9.0}
    r = bench.index_ratios(physics, {'a': 1.0, 'b': 1.0, 'c': 2.0, 'd': None, 'e': 1.0},
                           kind_of)
    assert r['turning'] == pytest.approx(0.5)   # not the mean of the ratios (2/3)
    assert r['zigzag'] == 1.0 and r['berthing'] == 0.25 and r['random'] == math.inf
    runs = [{'index_ratio': r}, {'index_ratio': dict.fromkeys(r, 1.0)}]
    assert bench.score(runs, 'index_ratio')[0] == math.inf   # a failed seed is never chosen
    ok = [{'index_ratio': {**r, 'random': 1.0}}, {'index_ratio': dict.fromkeys(r, 1.0)}]
    assert bench.score(ok, 'index_ratio') == pytest.approx((0.84375, 1.0))


def test_shrunk_residual_is_exactly_scaled(bench):
    rng = np.random.default_rng(2)
    sizes = [3 * N_FEATURES, 8, 8, 3]
    net = ResidualNet(3, 0.5, tuple(rng.normal(0, 0.5, (o, i)) for i, o in
                                    zip(sizes[:-1], sizes[1:])),
                      tuple(rng.normal(0, 0.1, o) for o in sizes[1:]), np.zeros(N_FEATURES),
                      np.ones(N_FEATURES), np.ones(3), True, 0, {})
    half = bench.shrunk(net, 0.5)
    assert bench.shrunk(net, 1.0) is net and half.meta['shrink'] == 0.5
    x = rng.normal(0, 1, sizes[0])

    def out(n):
        s, flat = n.packed()
        return mlp_forward(s, flat, x, np.empty(32), np.empty(32))[:3].copy()

    assert np.linalg.norm(out(net)) > 0.1
    np.testing.assert_allclose(out(half), 0.5 * out(net), rtol=1e-12, atol=1e-15)


def test_spearman_ranks(bench):
    assert bench.spearman([1, 2, 3, 4], [10, 30, 20, 40]) == pytest.approx(0.8)
    assert bench.spearman([1, 2, 3], [3, 2, 1]) == pytest.approx(-1.0)
