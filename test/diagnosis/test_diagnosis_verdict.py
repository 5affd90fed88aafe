"""
Issue 26: one verdict, causes that are plausible and consistent, what is left against the noise.

Effects hidden with the project's generator (``generate_trial``, its ``hull_scale`` and
``scale`` options for changes outside the library), ten SUZAKU trials of 200 s as a user
would sail them (turning +-10/20/35/40 deg, zigzags 10/10 and 20/20; five tuned, five held
out), the diagnose API with the quick budget.
"""
import importlib.util
import math

import mmg_tuner as mt
from mmg_tuner.data.generate import generate_trial, out_of_library, SensorNoise
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.decide import D_MAX, dispersion
from mmg_tuner.diagnosis.noise import describe, sensor_noise
from mmg_tuner.diagnosis.plausible import disagreement, implausible, plausible_range
from mmg_tuner.diagnosis.structure import one_verdict, verdict
from mmg_tuner.errors import ConfigError
from mmg_tuner.tuning import ParameterSpace
import numpy as np
import pytest

SPECS = [('turning', 35, None), ('turning', -20, None), ('zigzag', 10, 10.0),
         ('zigzag', -20, 20.0), ('turning', 10, None), ('turning', -35, None),
         ('zigzag', -10, 10.0), ('zigzag', 20, 20.0), ('turning', -10, None),
         ('turning', 40, None)]


def _truth(ship, seed: int = 3):
    """Return SUZAKU with its 12 targets moved inside the box: the hidden truth."""
    space = ParameterSpace.around(ship)
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-0.3, 0.3, space.dim)
    return ship.with_params(dict(zip(space.names, theta)))


def _trials(ship, effect: dict, seed: int = 3, **change):
    """Return (tune, test): SUZAKU's 12 targets moved inside the box, an effect hidden."""
    truth = _truth(ship, seed).with_params(effect)
    trials = [generate_trial(truth, m, a, c, 106.0, 3.086, 200.0, 1.0, SensorNoise(), 10 + i,
                             f'{m}{a:+d}', **change)[1] for i, (m, a, c) in enumerate(SPECS)]
    return trials[::2], trials[1::2]


def _diagnose(ship, tune, test, **options):
    # this module tests the rules verdict (structure.one_verdict, free runs); the default
    # evidence verdict has its own tests (test_diagnosis_evidence.py)
    options.setdefault('verdict', 'rules')
    return mt.diagnose(ship, tune, test, budget='quick', max_effects=2, **options)


# ------------------------------------------------------------------------ quick, no search
def test_the_generator_scales_hull_forces_outside_the_library(suzaku):
    changed = out_of_library(suzaku, 1.45)
    assert changed['N_r'] == pytest.approx(1.45 * suzaku['N_r'])
    assert changed['R_0'] == pytest.approx(1.45 * suzaku['R_0'])
    assert changed['t_P'] == suzaku['t_P']           # propeller and rudder untouched
    one = out_of_library(suzaku, scale={'N_r': 1.45})
    assert one['N_r'] == pytest.approx(1.45 * suzaku['N_r']) and one['Y_v'] == suzaku['Y_v']
    with pytest.raises(ConfigError, match='no parameter N_xyz'):
        out_of_library(suzaku, scale={'N_xyz': 2.0})
    t1 = generate_trial(suzaku, 'turning', 35, None, 106.0, 3.086, 60.0, 1.0,
                        SensorNoise.none(), 1, 't', hull_scale=1.45)[0]
    t0 = generate_trial(suzaku, 'turning', 35, None, 106.0, 3.086, 60.0, 1.0,
                        SensorNoise.none(), 1, 't')[0]
    assert 'out of library: hull forces x 1.45' in t1.notes
    assert abs(t1.states[-1, 5]) < 0.95 * abs(t0.states[-1, 5])   # more damped: turns slower


def test_sensor_noise_is_estimated_from_the_residuals():
    """Second differences of the residuals: a smooth model error does not count."""
    rng = np.random.default_rng(0)
    t = np.arange(400.0)
    smooth = np.column_stack([5 * np.sin(t / 50), 3 * np.cos(t / 70), 0.1 * np.sin(t / 40),
                              0.2 * np.sin(t / 30), 0.1 * np.cos(t / 35), 0.01 * np.sin(t / 20)])
    sd = np.array([0.5, 0.5, math.radians(0.2), 0.02, 0.02, math.radians(0.05)])
    rec = Trial(t, smooth + rng.normal(0, 1, smooth.shape) * sd, np.zeros((400, 2)))
    sim = smooth + np.array([10.0, -4.0, 0.05, 0.1, 0.0, 0.0]) * (t[:, None] / 400) ** 2
    est = sensor_noise([rec], [sim])
    for name, want in zip(('x', 'y', 'psi', 'u', 'v', 'r'), sd):
        assert est[name] == pytest.approx(want, rel=0.15), name
    assert describe(1.0e6, {'J': 1.0e6, 'J_bound': 2.5e6})[0] is True
    assert describe(3.0e6, {'J': 1.0e6, 'J_bound': 2.5e6})[0] is False
    assert describe(3.0e6, {})[0] is None


def test_plausible_ranges_are_data_and_scale_with_the_ship(suzaku, kvlcc2):
    lo, hi, why = plausible_range(suzaku, 'antenna_x')
    assert hi == pytest.approx(0.45 * suzaku.L_pp) and lo == -hi and 'hull' in why
    assert implausible(suzaku, 'antenna_offset', {'antenna_x': 39.0, 'antenna_y': 0.0})
    assert not implausible(suzaku, 'antenna_offset', {'antenna_x': 30.0, 'antenna_y': 3.0})
    assert implausible(suzaku, 'wind', {'wind_speed': 16.0, 'wind_dir': 0.0})
    assert not implausible(suzaku, 'wind', {'wind_speed': 13.0, 'wind_dir': 0.0})
    # a 1:45.7 model: speeds by 1/sqrt(45.7), but a current not below the real water's 0.3 m/s
    assert plausible_range(kvlcc2, 'wind_speed')[1] == pytest.approx(
        13.8 / math.sqrt(kvlcc2.scale_ratio))
    assert 1.0 / math.sqrt(kvlcc2.scale_ratio) < 0.3
    assert plausible_range(kvlcc2, 'current_speed')[1] == pytest.approx(0.3)
    assert plausible_range(suzaku, 'current_speed')[1] == pytest.approx(1.0)


def test_a_trial_pointing_the_other_way_contradicts_a_cause(suzaku):
    joint = {'antenna_x': 25.0, 'antenna_y': 2.0}
    agree = [{'antenna_x': 25.0 + d, 'antenna_x_se': 1.0, 'antenna_y': 2.0, 'antenna_y_se': 0.5}
             for d in (-8.0, 0.5, 9.0)]     # sizes differ (start-state errors): no matter
    assert disagreement(suzaku, 'antenna_offset', agree, joint) == ''
    apart = agree + [{'antenna_x': -10.0, 'antenna_x_se': 1.0, 'antenna_y': 2.0,
                      'antenna_y_se': 0.5}]
    assert 'trial 4 points the other way' in disagreement(suzaku, 'antenna_offset', apart,
                                                          joint)
    # the other way, but on the box's edge: that trial alone does not determine it
    edge = agree + [{'antenna_x': -41.5, 'antenna_x_se': 1.0, 'antenna_y': -6.75,
                     'antenna_y_se': 1.0, 'on_bound': True}]
    assert disagreement(suzaku, 'antenna_offset', edge, joint) == ''
    # the other way, but within the smallest worth finding (5 m): no contradiction
    near = agree + [{'antenna_x': -3.0, 'antenna_x_se': 0.1, 'antenna_y': 2.0,
                     'antenna_y_se': 0.5}]
    assert disagreement(suzaku, 'antenna_offset', near, joint) == ''
    # a current along the joint direction: 0.3 m/s either side of it agrees, against it not
    cur = [{'current_speed': 0.3, 'current_speed_se': 0.01, 'current_dir': d,
            'current_dir_se': 0.02} for d in (0.3, -0.3)]
    joint = {'current_speed': 0.3, 'current_dir': 0.0}
    assert disagreement(suzaku, 'current', cur, joint) == ''
    cur[1]['current_dir'] = math.pi
    assert 'points the other way' in disagreement(suzaku, 'current', cur, joint)


def test_one_value_over_the_trials_is_consistent_a_value_that_follows_the_manoeuvre_is_not(
        suzaku):
    """
    The test of a mimic (diagnosis/decide.py): the scatter of per-trial estimates.

    A real current has one value over the trials of a day (its estimates on each trial
    alone scatter by their errors); an effect bending to absorb a missing force takes the
    value each manoeuvre needs.
    """
    same = [{'current_speed': 0.35 + ds, 'current_dir': 1.9 + da}
            for ds, da in ((0.02, 0.05), (-0.03, -0.04), (0.01, 0.0), (0.0, 0.06), (0.03, -0.1))]
    D, n = dispersion(suzaku, 'current', same)
    assert n == 5 and D < 0.2
    follows = [{'current_speed': sp, 'current_dir': d}
               for sp, d in ((0.3, 0.0), (0.35, 2.0), (0.2, -2.5), (0.4, 1.0), (0.25, -1.2))]
    D, _ = dispersion(suzaku, 'current', follows)
    assert D > D_MAX
    # a scalar: a rudder offset of +1.5 deg on every trial, or +2, -1.5, +0.5 deg ...
    deg = math.radians
    assert dispersion(suzaku, 'rudder_offset', [{'rudder_offset': deg(x)}
                                                for x in (1.4, 1.6, 1.5, 1.3)])[0] < 0.2
    assert dispersion(suzaku, 'rudder_offset', [{'rudder_offset': deg(x)}
                                                for x in (2.0, -1.5, 0.5, 2.5)])[0] > D_MAX
    # estimates run to a far edge of the box say nothing of the effect; with fewer than
    # three left, the test cannot be made (None), never a verdict of "inconsistent"
    edge = [{'current_speed': 1.5, 'current_dir': 0.3}] * 3 + same[:2]
    assert dispersion(suzaku, 'current', edge) == (None, 2)
    # at neutral is no edge: a trial that finds no current counts against a 0.35 m/s one
    assert dispersion(suzaku, 'current', same[:3] + [{'current_speed': 0.0,
                                                      'current_dir': 0.0}] * 3)[0] > D_MAX


def test_one_verdict_never_names_a_cause_beside_a_structural_gap():
    causes = ['a', 'b']
    st = {'verdict': 'structure', 'remaining_is_noise': True}
    assert one_verdict(causes, st, 4.0e6, {'J': 1.0e6, 'J_bound': 2.0e6}) == ([], causes)
    assert st['remaining_is_noise'] is False and 'after the named causes: none' in st['noise']
    assert one_verdict(causes, {'verdict': 'unexplained'}) == (causes, [])
    assert one_verdict(causes, {'verdict': 'none'}) == (causes, [])


def test_a_cause_a_measurement_sized_stays_a_cause_beside_a_structural_gap():
    from mmg_tuner.diagnosis.results import Cause
    lag = Cause('rudder_lag', {'rudder_lag_tau': 5.0}, {'rudder_lag_tau': 0.5}, 0.1, 0.05,
                measured='rudder-angle feedback')
    fitted = Cause('current', {'current_speed': 0.2, 'current_dir': 0.0}, {}, 0.5, 0.1)
    assert one_verdict([fitted, lag], {'verdict': 'structure'}) == ([lag], [fitted])
    assert one_verdict([lag], {'verdict': 'structure'}) == ([lag], [])
    # the recorded wind driving the model fits nothing either (Esso Osaka: 85 % of the error)
    wind = Cause('measured_wind', {}, {}, 0.85, 0.04)
    assert one_verdict([wind, fitted], {'verdict': 'structure'}) == ([wind], [fitted])


def test_causes_that_leave_most_of_an_error_above_the_noise_beside_bent_coefficients():
    """
    A cause that leaves much above the noise beside bent coefficients mimics a gap.

    Such a cause leaves >= 30 % of the base error, above the noise, while the base
    coefficients sit on their bounds. (Bench case hull_scale seed 0: every hull force 29 %
    larger was named a 5.4 m/s wind that left 65 % of the error, 3.9 x what noise leaves,
    with 8 of 12 coefficients on a bound.)
    """
    noise = {'J': 1.0, 'J_bound': 2.7}
    bent = ['base coefficients on a bound of their box: t_P, C_w']

    def doc(J_final, causes=('wind',), J_base=6.0):
        return {'baseline': {'J_test': J_base}, 'final': {'J_test': J_final}, 'noise': noise,
                'causes': [{'effect': c} for c in causes]}
    assert verdict(doc(3.9), [], bent, None)['verdict'] == 'structure'
    # the same error, no coefficient bent: nothing says the structure; unexplained
    assert verdict(doc(3.9), [], [], None)['verdict'] == 'unexplained'
    # a cause that explained 85 % (the rest above the noise): believed, the rest unexplained
    assert verdict(doc(3.0, J_base=20.0), [], bent, None)['verdict'] == 'unexplained'
    # what remains is noise: the cause stands (a rudder lag explains 29 % and leaves noise)
    assert verdict(doc(2.5), [], bent, None)['verdict'] == 'none'
    # nothing named: the report keeps 'unexplained' (no cause to doubt)
    assert verdict(doc(3.9, ()), [], bent, None)['verdict'] == 'unexplained'


# ------------------------------------------------------------------- hidden, then diagnosed
@pytest.mark.slow
def test_hull_forces_45_percent_larger_are_no_library_cause(suzaku):
    """
    Every hull force and moment 45 % larger: out of the library, structural.

    Before issue 26 this named a propeller side force (C_YPS -0.024, per held-out trial
    -14 %, +32 %, -4 %, +48 %, +2 %) and a yaw moment bias as CAUSES while the same report
    said the model structure was the likely cause.
    """
    tune, test = _trials(suzaku, {}, hull_scale=1.45)
    # residual 'auto' (the default): what remains is far above the noise, so with JAX the
    # network is trained and says where the error lives (a small one: this is no benchmark)
    dx = _diagnose(suzaku, tune, test, residual_options={'hidden': (16, 16), 'epochs': 40})
    assert dx.causes == [], [c.summary for c in dx.causes]
    assert dx.structure['verdict'] in ('structure', 'unexplained'), dx.structure['summary']
    assert dx.structure['remaining_is_noise'] is False   # after the named causes: none
    doc = dx.to_dict()
    assert doc['causes'] == [] and 'no sign of a structural gap' not in dx.structure['summary']
    res = dx.structure['residual']
    if importlib.util.find_spec('jax') is None:
        assert res['trained'] is False and 'jax' in res['why'].lower()
        pytest.skip('JAX is not installed: the residual network was (rightly) not trained')
    assert res['mode'] == 'auto' and res['trained'] is True, res
    assert res['why'].startswith('trained: what remains is not noise'), res['why']
    learn = dx.structure['learnable']
    assert {'u', 'v', 'r'} <= set(learn['per_state_gain'])
    assert set(learn['regimes']) == {'speed', 'drift angle', 'rudder', 'propeller load'}
    assert learn['line'].startswith('unexplained but learnable structure')


def test_wind_and_a_rudder_offset_are_both_named(suzaku):
    """
    Wind 9 m/s from 45 deg and a rudder offset of +1.5 deg: two causes at once, both named.

    Before issue 26 the offset, second, was rejected for explaining only 3 % of the base
    error (a base error the wind made 29 x the clean case's). Then the joint fit of the wind
    with the offset gained 33.7 % +- 8.5 % over the wind alone on the held-out trials, but the
    offset came out at +0.68 deg on the five tuning trials (turning +-10 and 35 deg, zigzags
    10/10): every size from 0.7 to 1.5 deg fits them within 2 % once the rudder coefficients
    are re-tuned, and the re-tune stops at the first. The held-out trials (20 to 40 deg)
    settle it, so a significant pair is sized on all ten trials: measured wind 9.3 m/s from
    44 deg, offset +1.79 deg (truth 9 m/s, 45 deg, 1.5 deg); what remains is noise (1.5 x the
    floor).
    """
    tune, test = _trials(suzaku, {'wind_speed': 9.0, 'wind_dir': math.radians(45.0),
                                  'rudder_offset': math.radians(1.5)})
    dx = _diagnose(suzaku, tune, test)
    named = sorted(c.effect for c in dx.causes)
    assert named == ['rudder_offset', 'wind'], [c.summary for c in dx.causes]
    p = {k: v for c in dx.causes for k, v in c.parameters.items()}
    assert p['wind_speed'] == pytest.approx(9.0, abs=1.5)
    assert abs((math.degrees(p['wind_dir']) - 45.0 + 180) % 360 - 180) < 20
    # above the 1 deg worth finding (else not named), below 2.5 deg: twice the error of the
    # tuning trials' own +0.68 deg, on the other side
    assert 1.0 < math.degrees(p['rudder_offset']) < 2.5
    assert dx.structure['remaining_is_noise'] is True, dx.structure['summary']


@pytest.mark.slow
def test_a_current_and_a_rudder_offset_are_named_in_place_of_the_wind_they_imitate(suzaku):
    """
    Current 0.25 m/s toward 200 deg and a rudder offset of +1.5 deg: both named.

    Alone, a wind (held-out gain 78 %) and the current (74 %) explain the trials about as
    well; the wind is named, the offset fits to nothing beside it, and before the eighth
    session nothing was named at all (the wind moved to mimicking a structural gap). The
    current, the wind's rival, fitted jointly with the offset from before the wind was named,
    leaves a held-out J 4.4 x smaller than the wind's: named in its place (current 0.14 m/s
    toward 221 deg, offset +1.56 deg; what remains is noise).
    """
    tune, test = _trials(suzaku, {'current_speed': 0.25, 'current_dir': math.radians(200.0),
                                  'rudder_offset': math.radians(1.5)})
    dx = _diagnose(suzaku, tune, test)
    named = sorted(c.effect for c in dx.causes)
    assert named == ['current', 'rudder_offset'], [c.summary for c in dx.causes]
    p = {k: v for c in dx.causes for k, v in c.parameters.items()}
    se = {k: v for c in dx.causes for k, v in c.uncertainty.items()}
    assert abs(p['current_speed'] - 0.25) < 3 * se['current_speed']
    assert abs((math.degrees(p['current_dir']) - 200.0 + 180) % 360 - 180) < 45
    assert 1.0 < math.degrees(p['rudder_offset']) < 2.5
    assert any(c.effect == 'current+rudder_offset' and c.accepted
               for r in dx.candidates for c in r)
    assert dx.structure['remaining_is_noise'] is True, dx.structure['summary']


def test_clean_trials_stay_clean_and_what_remains_is_noise(suzaku):
    """Nothing named; "no sign of a structural gap" backed by the noise (1.0 x here)."""
    tune, test = _trials(suzaku, {})
    dx = _diagnose(suzaku, tune, test)
    assert dx.causes == [] and dx.mimicking == []
    assert dx.structure['remaining_is_noise'] is True
    assert dx.structure['summary'].startswith('no sign of a structural gap: what remains is '
                                              'noise')
    sigma = dx.noise['sigma']
    assert sigma['x'] == pytest.approx(0.5, rel=0.2) and sigma['y'] == pytest.approx(0.5, rel=0.2)


def test_one_hull_derivative_45_percent_larger_is_no_library_cause(suzaku):
    """N_r x 1.45 alone: the tuned rudder and hull targets absorb it; nothing is named."""
    tune, test = _trials(suzaku, {}, scale={'N_r': 1.45})
    dx = _diagnose(suzaku, tune, test)
    assert dx.causes == [], [c.summary for c in dx.causes]


@pytest.mark.slow
def test_a_current_and_a_steering_gear_lag_name_no_false_cause(suzaku):
    """
    Current 0.25 m/s toward 200 deg and a 5 s steering-gear lag.

    The current is named (measured: 0.21 m/s toward 204 deg). The lag, after it, lowers the
    held-out error by 16 % +- 3 % of what remains, a reduction within half the noise floor:
    not named, and flagged barely identifiable. Not the threshold's fault: a time offset
    lowers it by more (22 % +- 5 %), so a looser rule would name a false cause; on these
    trials a 2.3 deg/s rudder ramp through a 5 s lag is a delay (the lag's standard error
    5.8 s; fitted jointly with the current, from the base optimum or by CMA-ES, 1.2-1.6 s).
    A false cause is worse than a missed one.
    """
    tune, test = _trials(suzaku, {'current_speed': 0.25, 'current_dir': math.radians(200.0),
                                  'rudder_lag_tau': 5.0})
    dx = _diagnose(suzaku, tune, test)
    named = [c.effect for c in dx.causes]
    assert named[:1] == ['current'] and set(named) <= {'current', 'rudder_lag'}, named
    p = dx.causes[0].parameters
    assert p['current_speed'] == pytest.approx(0.25, abs=0.08)
    assert abs((math.degrees(p['current_dir']) - 200.0 + 180) % 360 - 180) < 30
    if named == ['current']:
        assert 'rudder_lag' in dx.barely_identifiable
    assert 'noise' in dx.structure['summary']


# ------------------------------------------------------------- measurements as priors (i26)
def test_a_measurements_file_is_checked_and_names_what_is_wrong(tmp_path):
    from mmg_tuner.diagnosis.measured import load, Measurement
    good = tmp_path / 'm.yaml'
    good.write_text('measured:\n  R_0: {value: 0.0224, se: 0.0005, source: resistance test}\n')
    assert load(good) == {'R_0': Measurement(0.0224, 0.0005, 'resistance test')}
    assert mt.DiagnoseConfig(measured=str(good)).settings().measurements['R_0'].se == 0.0005
    for text, what in (('measured:\n  R_x: {value: 1, se: 1}\n', "no parameter 'R_x'"),
                       ('measured:\n  R_0: {value: 0.02, se: 0}\n', 'se > 0'),
                       ('measured:\n  R_0: 0.02\n', 'measured.R_0: must be'),
                       ('R_0: 0.02\n', "no 'measured:' mapping")):
        bad = tmp_path / 'bad.yaml'
        bad.write_text(text)
        with pytest.raises(ConfigError, match=what) as e:
            load(bad)
        assert str(bad) in str(e.value)


def test_a_loose_measurement_leaves_room_for_the_antenna_and_a_tight_one_holds(suzaku):
    """
    R_0, t_P and w_P0 measured 8 % off the truth, an antenna 20 m forward, 3 m to starboard.

    Held fixed at such values (the advice's re-run before issue 26), the other coefficients
    absorb the measurements' error; as priors with a loose standard error the trials move
    them and the antenna is found. With a tight one the coefficient stays at its measurement.
    """
    from mmg_tuner.diagnosis.measured import Measurement
    truth = _truth(suzaku)
    tune, test = _trials(suzaku, {'antenna_x': 20.0, 'antenna_y': 3.0})
    off = {n: 1.08 * truth[n] for n in ('R_0', 't_P', 'w_P0')}
    kw = {'budget': 'quick', 'max_effects': 1, 'residual': False,
          'effects': ['antenna_offset', 'prop_side_force']}
    loose = mt.diagnose(suzaku, tune, test, measured={
        n: Measurement(v, 0.2 * abs(v)) for n, v in off.items()}, **kw)
    assert [c.effect for c in loose.causes] == ['antenna_offset'], \
        [c.summary for c in loose.causes]
    # forward within its smallest worth finding (5 m); athwartships is the weaker direction
    # (0.8 m for 3 m here): not asserted
    assert loose.causes[0].parameters['antenna_x'] == pytest.approx(20.0, abs=5.0)
    tight = mt.diagnose(suzaku, tune, test, measured={
        n: Measurement(v, 1e-4 * abs(v)) for n, v in off.items()}, **kw)
    for n, v in off.items():
        assert tight.params[n] == pytest.approx(v, rel=2e-3), n   # (8 % off the truth)


@pytest.mark.slow
def test_a_measured_steering_gear_lag_is_named_as_measured_beside_the_current(suzaku):
    """
    The case the trials cannot settle (test above), with the advised measurement.

    The rudder-angle feedback gives the lag, 5.0 +- 0.5 s: it is held in every model, not
    searched, and named as measured beside the current the trials find. A feedback that shows
    no lag (0.3 +- 0.5 s) names none, and a lag measured with the wrong sign is refused before
    any work.
    """
    from mmg_tuner.diagnosis.measured import Measurement
    tune, test = _trials(suzaku, {'current_speed': 0.25, 'current_dir': math.radians(200.0),
                                  'rudder_lag_tau': 5.0})
    fb = 'rudder-angle feedback'
    dx = _diagnose(suzaku, tune, test, residual=False,
                   measured={'rudder_lag_tau': Measurement(5.0, 0.5, fb)})
    by = {c.effect: c for c in dx.causes}
    assert set(by) == {'current', 'rudder_lag'}, [c.summary for c in dx.causes]
    assert by['rudder_lag'].measured == fb and not by['current'].measured
    assert by['rudder_lag'].parameters == {'rudder_lag_tau': 5.0}
    assert dx.params['rudder_lag_tau'] == 5.0      # in the written model
    # 0.14 +- 0.055 m/s on these 200 s trials (0.21 without the measurement): within three
    # of its own trial-robust standard errors, which is what the report claims
    cur = by['current']
    assert abs(cur.parameters['current_speed'] - 0.25) < 3 * cur.uncertainty['current_speed']
    none = _diagnose(suzaku, tune, test, residual=False,
                     measured={'rudder_lag_tau': Measurement(0.3, 0.5, fb)})
    assert 'rudder_lag' not in [c.effect for c in none.causes]
    assert none.params['rudder_lag_tau'] == 0.3
    with pytest.raises(ConfigError, match='rudder_lag_tau must not be negative'):
        _diagnose(suzaku, tune, test, measured={'rudder_lag_tau': Measurement(-1.0, 0.5)})


def test_a_measurement_the_trials_contradict_is_not_named(suzaku):
    """
    A rudder offset of +2 deg, which these trials size, "measured" at -2 +- 0.2 deg.

    Fitted by the trials alone the offset is far from the measurement: it is not named as
    measured (the report says to check the measurement).
    """
    from mmg_tuner.diagnosis.measured import Measurement
    from mmg_tuner.diagnosis.select import diagnose as search
    tune, test = _trials(suzaku, {'rudder_offset': math.radians(2.0)})
    lines = []
    dx = search(
        suzaku, tune, test, mt.DiagnoseConfig(
            budget='quick', max_effects=1, residual=False, measured={
                'rudder_offset': Measurement(math.radians(-2.0), math.radians(0.2))}
        ).settings(), log=lines.append)
    assert 'rudder_offset' not in [c.effect for c in dx.causes]
    assert any('check the measurement' in x for x in lines), lines


def test_a_measured_clock_still_lets_the_structure_check_see_a_stronger_hull(suzaku):
    """
    Hull forces x 1.45 with the time offset measured (one clock): 0.0 +- 0.1 s.

    Unmeasured, a time offset pinned on its bound is the evidence that the structure, not an
    effect, is wrong. Measured, it is no longer searched; its trials-alone fit is what still
    shows it: the trials want a delay the clock rules out, so it is listed as would-fit-but-
    impossible and no effect is named as a cause.
    """
    from mmg_tuner.diagnosis.measured import Measurement
    tune, test = _trials(suzaku, {}, hull_scale=1.45)
    dx = _diagnose(suzaku, tune, test, residual=False,
                   measured={'time_offset': Measurement(0.0, 0.1, 'one clock')})
    assert dx.causes == [], [c.summary for c in dx.causes]
    assert dx.structure['verdict'] in ('structure', 'unexplained'), dx.structure['summary']
    if dx.structure['verdict'] == 'structure':
        assert any(x['effect'] == 'time_offset' for x in dx.impossible_fits) or dx.mimicking
