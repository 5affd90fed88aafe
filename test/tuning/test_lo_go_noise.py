"""
The tug identification on an independent-style twin with RTK-class noise (issue 43).

The twin is bench/tug_random.py's (its own hull integration, a thrust curve that is not
quadratic, a rate-saturated azimuth drive of another structure), coefficients moved by 12 %:
the integrated LO gives a positive definite mass matrix where the differentiated one does not,
the default LO -> GO does not diverge and fits at least as well as GO from the ship's values;
the bollard table's astern rows give the astern ratio; each unit mistake is a WARNING naming
its column.
"""
import logging
import math

from bench import tug_random as tr
import mmg_tuner as mt
from mmg_tuner.data.channel_units import bollard_unit_warnings, channel_unit_warnings
from mmg_tuner.tuning import lo_go
import numpy as np
import pytest


@pytest.fixture(scope='module')
def tug():
    return mt.load_ship('qiuxin_tug')


@pytest.fixture(scope='module')
def twin(tug):
    """Twin of 2 Hz, 1.8 x RTK noise, coefficients moved 12 % (alternately up and down)."""
    hull = {n: tug[n] * (1.12 if i % 2 else 0.88) for i, n in enumerate(tr.HULL)}
    tw = tr.TwinTug(1, hull, 'power', 0.474, 0.0, 1.97, 0.68, 2.59, 0.19, 0.69, 1.81, 2.0)
    man = [m for m in tr.IDENTIFICATION if m.name in tr.SUBSETS[12]]
    rng = np.random.default_rng(5)
    runs = tr.sail(tw, man)
    return {'twin': tw, 'train': tr.to_trials(tw, runs, True, rng),
            'bollard': tr.bollard_table(tw, rng)}


def _sway_yaw_det(p):
    return p['m22'] * p['m33'] - p['m23'] * p['m32']


def test_integrated_lo_keeps_the_mass_matrix_physical_where_differentiation_breaks_it(tug,
                                                                                      twin):
    b = twin['bollard']
    table = lo_go.check_bollard_table(b[:, 0], b[:, 1])
    work = tug.with_params(lo_go.fit_thrust(table).params)
    names = lo_go.coefficient_names(tug)
    old = lo_go.lo_fit(work, twin['train'], names, smooth_s=0.0, window_s=0.0, constrain=False)
    new = lo_go.lo_fit(work, twin['train'], names)
    p_new = dict(zip(names, new.theta))
    phys = lo_go.physics(work, names, lo_go._sample_velocities(twin['train'], 2.0))
    # the derivative form: not a ship (mass matrix or damping), or a sway mass a third of it
    assert (not phys.mass_ok(old.theta, lo_go.MASS_MARGIN) or not phys.dissipative(old.theta)
            or old.theta[names.index('m22')] < 0.3 * twin['twin'].hull['m22'])
    assert phys.mass_ok(new.theta, lo_go.MASS_MARGIN - 1e-9)
    assert phys.dissipative(new.theta, 1e-9)
    assert _sway_yaw_det(p_new) > 0 and p_new['m11'] > 0
    assert new.window_s == lo_go.LO_WINDOW_S > 0


def test_default_identification_is_physical_and_no_worse_than_go_alone(tug, twin):
    b = twin['bollard']
    res = mt.identify(tug, twin['train'], bollard_pull=lo_go.check_bollard_table(b[:, 0],
                                                                                 b[:, 1]))
    ship = res.identified_ship
    assert _sway_yaw_det(res.params) > 0
    pd, bounded = tr.physical(ship, twin['train'])
    assert pd and bounded
    g = res.go
    assert set(g.candidates) == {'LO', "the ship's values"}
    assert g.data_cost <= min(g.candidates.values()) + 1e-15
    assert 'won' in lo_go.go_start_line(g) and 'start_line' in res.report()['go']
    # the astern rows (n < 0) were used: the twin's ratio 0.68
    assert res.thrust.astern_ratio == pytest.approx(0.68, rel=0.05)
    assert res.params['thrust_astern_ratio'] == res.thrust.astern_ratio
    assert res.wall_s < 30


def test_bollard_astern_rows_give_the_astern_ratio():
    n = np.arange(-8.0, 12.5, 1.0)
    F = np.where(n >= 0, 0.4 * n * n, -0.7 * 0.4 * n * n)
    fit = lo_go.fit_thrust(lo_go.check_bollard_table(n, F))
    assert fit.astern_ratio == pytest.approx(0.7, rel=1e-6) and fit.astern_points == 8
    # astern given as magnitudes: the same
    fit2 = lo_go.fit_thrust(lo_go.check_bollard_table(n, np.abs(F)))
    assert fit2.astern_ratio == pytest.approx(0.7, rel=1e-6)
    with pytest.raises(mt.TuningError, match='mix of signs'):
        lo_go.check_bollard_table([-4, -2, 0, 2, 4, 6, 8], [-5, 2, 0, 2, 7, 14, 26])


def test_each_unit_mistake_is_a_warning_naming_its_column(tug, twin, caplog):
    tr0 = twin['train'][4]    # a zigzag: the azimuths move
    inputs = dict(tr0.inputs)
    rpm = mt.core.trial.Trial(tr0.t, tr0.states, name='rpm', inputs=dict(
        inputs, n_port=60 * inputs['n_port']))
    deg = mt.core.trial.Trial(tr0.t, tr0.states, name='deg', inputs=dict(
        inputs, azimuth_port=np.degrees(inputs['azimuth_port'])))
    assert channel_unit_warnings(tr0, tug) == []
    w = channel_unit_warnings(rpm, tug)
    assert len(w) == 1 and "'n_port'" in w[0] and 'rpm' in w[0]
    w = channel_unit_warnings(deg, tug)
    assert len(w) == 1 and "'azimuth_port'" in w[0] and 'degrees' in w[0]
    n = np.arange(0.0, 12.5, 1.0)
    F = 0.4 * n * n
    assert bollard_unit_warnings(tug, n, F) == []
    w = bollard_unit_warnings(tug, 60 * n, F)
    assert len(w) == 1 and "'n'" in w[0] and 'rpm' in w[0]
    w = bollard_unit_warnings(tug, n, F / 9.80665)
    assert len(w) == 1 and "'thrust'" in w[0] and 'kgf' in w[0]
    with caplog.at_level(logging.WARNING):
        lo_go.identify(tug, twin['train'][:1], method='lo',
                       bollard=lo_go.check_bollard_table(60 * n, F))
    assert any("column 'n'" in r.getMessage() and r.getMessage().startswith('WARNING')
               for r in caplog.records)
    assert math.isfinite(F.sum())


def test_a_bollard_table_with_load_cell_scatter_near_zero_is_fitted_not_refused():
    """Near n = 0 the pull is below the noise: rows dip and an astern row reads positive."""
    n = np.arange(-10.0, 12.5, 1.0)
    F = np.where(n >= 0, 0.4 * n * n, -0.75 * 0.4 * n * n)
    noisy = F + np.where(n == 1, -0.5, 0.0) + np.where(n == -1, 0.6, 0.0)   # 0.9 % of 57.6 N
    fit = lo_go.fit_thrust(lo_go.check_bollard_table(n, noisy))
    assert fit.params['thrust_p2'] == pytest.approx(0.4, rel=0.02)
    assert fit.astern_ratio == pytest.approx(0.75, rel=0.02)
    # a fall of 10 % of the largest pull is a wrong row, not scatter
    wrong = F.copy()
    wrong[n == 8] = F[n == 7][0] - 0.10 * F.max()
    with pytest.raises(mt.TuningError, match='not monotone'):
        lo_go.check_bollard_table(n, wrong)
