"""
The diagnosis on the twin-azimuth tug (issue 24): a current and the actuator's own effects.

Each test hides one effect in the qiuxin_tug twin (generate's catalogue, its RTK-class noise)
and asserts that the diagnosis names it, with the estimate within its standard error band of
the truth (3 standard errors: the larger of Gauss-Newton's and the trial-robust ones), and
that clean data names nothing. The base model starts from the published
coefficients (the twin's truth): what ``diagnose --ship qiuxin_tug`` does without --params.
Cost: three tuning and three held-out manoeuvres of 100 s at 2.5 Hz, the quick budget.
"""
import json
import math

import mmg_tuner as mt
from mmg_tuner.core.actuators import twin_azimuth_trials as twin
import numpy as np
import pytest

# a zigzag, a turn and a differential-thrust run (one thruster loaded more than the other),
# each mirrored in the held-out set
TUNE = ('zigzag_p20deg_7rps', 'turning_p20deg_7rps', 'differential_1')
TEST = ('zigzag_m20deg_7rps', 'turning_m20deg_7rps', 'differential_2')
RATE_HZ = 2.5
BASE_EVALS = 1000   # the base tune starts at the truth's coefficients: a short CMA-ES, polished
BAND = 3.0          # standard errors


def sail(truth, names, seed0):
    cat = {m.name: m for m in twin.catalogue(truth)}
    return [twin.generate(truth, cat[n], RATE_HZ, twin.Noise(), seed0 + i)[1]
            for i, n in enumerate(names)]


_RUNS: dict = {}


def diagnose(hidden):
    """Diagnose the twin with ``hidden`` (once per module: two tests read one run)."""
    key = tuple(sorted(hidden.items()))
    if key not in _RUNS:
        tug = mt.load_ship('qiuxin_tug')
        truth = tug.with_params(hidden)
        _RUNS[key] = mt.diagnose(tug, sail(truth, TUNE, 0), sail(truth, TEST, 50),
                                 budget='quick', base_evals=BASE_EVALS,
                                 verdict='rules')   # free runs, as the figures were measured
    return _RUNS[key]


def within_band(cause, param, truth):
    est, se = cause.parameters[param], cause.uncertainty[param]
    assert math.isfinite(se) and se > 0, (param, se)
    assert abs(est - truth) <= BAND * se, (param, est, se, truth)


def test_clean_tug_data_names_nothing():
    d = diagnose({})
    assert [c.effect for c in d.causes] == []


CURRENT = {'current_speed': 0.2, 'current_dir': math.radians(60)}
FOULED = {'thrust_scale_stbd': 0.85}


def test_finds_a_current_on_the_tug():
    d = diagnose(CURRENT)
    assert [c.effect for c in d.causes] == ['current']
    assert 0.1 < d.causes[0].parameters['current_speed'] < 0.3


def test_the_current_lies_within_its_standard_error_band():
    """
    Measured: 0.2001 +- 0.0003 m/s toward 60.14 +- 0.08 deg.

    Gauss-Newton's errors alone: +- 0.0001 m/s, +- 0.02 deg.

    Before the screen from the pre-determined values it came out 0.149 +- 0.005 m/s: the
    re-tune started where the base tune had bent the coefficients to absorb the current.
    """
    c = diagnose(CURRENT).causes[0]
    within_band(c, 'current_speed', 0.2)
    dd = (c.parameters['current_dir'] - math.radians(60) + math.pi) % (2 * math.pi) - math.pi
    assert abs(dd) <= BAND * c.uncertainty['current_dir']


AZ_OFFSET = {'azimuth_offset_port': math.radians(3.0)}


def test_an_azimuth_offset_is_told_from_a_yaw_moment_bias():
    """
    The held-out trials tell a 3 deg port offset from its rivals by far.

    The offset's side force acts at the port thruster and scales with that thruster's thrust
    (the differential-thrust run loads it 0.5-1.7 x at one speed), a yaw moment bias with U^2.
    Measured: the offset's held-out J 62 (noise alone: 36), the yaw moment bias 5349, the
    starboard offset 5066, the port thrust scale 3540. (Once named as a yaw moment bias:
    every re-tune started where the base tune had bent the coefficients, 700 x the truth's
    held-out J, and the four tied.)
    """
    d = diagnose(AZ_OFFSET)
    assert [c.effect for c in d.causes] == ['azimuth_offset_port']
    first = {c.effect: c.J_test for c in d.candidates[0]}
    for rival in ('yaw_moment_bias', 'azimuth_offset_stbd', 'thrust_scale_port'):
        if rival in first:   # re-tuned (among the screen's top)
            assert first[rival] > 10 * first['azimuth_offset_port'], (rival, first)
    assert 'yaw_moment_bias' in first


def test_a_held_out_trial_that_tells_the_rivals_apart_names_the_offset():
    """
    The evidence verdict (10 s restarts) names the port offset alone, not one of a set.

    Over 10 s restarts the starboard offset fits the turn and the zigzag as well as the port
    one (held-out gains 0.89 +- 0.10 and 0.86 +- 0.13 pooled: within their combined error), and
    the differential-thrust run tells them apart: the starboard offset leaves 3.3 x the port
    offset's J there, a yaw moment bias 3.7 x. Before the rival rule looked at single trials the
    port offset was left undecided against the starboard one.
    """
    tug = mt.load_ship('qiuxin_tug')
    truth = tug.with_params(AZ_OFFSET)
    d = mt.diagnose(tug, sail(truth, TUNE, 0), sail(truth, TEST, 50), budget='quick',
                    base_evals=BASE_EVALS, verdict='evidence')
    assert [c.effect for c in d.causes] == ['azimuth_offset_port'] and not d.undecided
    first = {c.effect: c for c in d.candidates[0]}
    port = 1 - np.asarray(first['azimuth_offset_port'].per_trial_gain)
    stbd = 1 - np.asarray(first['azimuth_offset_stbd'].per_trial_gain)
    assert np.max(stbd / port) > 2


def test_finds_an_azimuth_offset_on_the_port_thruster():
    """Measured: 3.003 +- 0.139 deg for 3 deg (Gauss-Newton alone: +- 0.022 deg)."""
    d = diagnose(AZ_OFFSET)
    assert [c.effect for c in d.causes] == ['azimuth_offset_port']
    within_band(d.causes[0], 'azimuth_offset_port', math.radians(3.0))
    assert d.causes[0].heldout_gain > 0.5


def test_finds_a_fouled_starboard_propeller():
    d = diagnose(FOULED)
    assert [c.effect for c in d.causes] == ['thrust_scale_stbd']
    assert d.causes[0].parameters['thrust_scale_stbd'] == pytest.approx(0.85, abs=0.02)


def test_the_fouled_propeller_lies_within_its_standard_error_band():
    """Measured: 0.8545 +- 0.0044 for 0.85 (Gauss-Newton alone: +- 0.0014, 3.2 of them off)."""
    within_band(diagnose(FOULED).causes[0], 'thrust_scale_stbd', 0.85)


def test_the_tug_screens_only_effects_it_can_show():
    """The screw-and-rudder effects are left out; a list of only those is refused."""
    tug = mt.load_ship('qiuxin_tug')
    with pytest.raises(mt.DiagnosisError, match='none of the effects'):
        mt.diagnose(tug, sail(tug, TUNE[:2], 0), sail(tug, TEST[:2], 50),
                    effects=('rudder_offset', 'rpm_scale'))


def test_a_trial_lacking_the_tug_channels_is_refused_naming_them(tmp_path):
    tug = mt.load_ship('qiuxin_tug')
    trials = sail(tug, TUNE[:2], 0) + sail(tug, TEST[:2], 50)
    f = tmp_path / 'one_thruster.csv'   # a log of the port thruster only
    t = trials[0]
    cols = np.column_stack([t.t, t.states, t.inputs['n_port'], t.inputs['azimuth_port']])
    f.write_text('t,x,y,psi,u,v,r,n_port,azimuth_port\n' + ''.join(
        ','.join(f'{x:.9g}' for x in row) + '\n' for row in cols))
    partial, = mt.load_trials(f)
    with pytest.raises(mt.MmgTunerError) as exc:
        mt.diagnose(tug, [partial, trials[1]], trials[2:], budget='quick')
    text = str(exc.value)
    assert 'n_stbd' in text and 'azimuth_stbd' in text and 'one_thruster' in text


def test_a_bollard_table_too_short_for_its_degree_is_refused():
    from mmg_tuner.tuning import lo_go
    n = np.array([0.0, 4.0, 8.0, 12.0])
    table = lo_go.check_bollard_table(n, 0.4 * n * n)
    assert lo_go.fit_thrust(table, 2).params['thrust_p2'] == pytest.approx(0.4)
    with pytest.raises(mt.TuningError, match='too short for degree 3: 4 rows.*at least 5'):
        lo_go.fit_thrust(table, 3)
    with pytest.raises(mt.TuningError, match='not monotone'):
        lo_go.check_bollard_table([0, 4, 8, 12], [0, 7, 2, 60])   # > 5 %: no scatter


def test_the_advice_sails_the_tugs_own_catalogue_and_generate_runs_it(tmp_path):
    """
    A craft without a screw and rudder is advised from its actuator's catalogue (TRIALS).

    Rivals: the published tug against one with a 3 deg port azimuth offset, judged on a zigzag
    and a straight run. The advised trial is a catalogue manoeuvre that separates them better
    than the recorded trials, its held-out twin the same manoeuvre mirrored, and ``generate
    --from-advice`` sails both as the tug's channel recordings.
    """
    from mmg_tuner.cli.generate import command as generate
    from mmg_tuner.diagnosis.advice import advise, CatalogueSpec, load_advice, mirrored, \
        repertoire, residual_scale

    tug = mt.load_ship('qiuxin_tug')
    specs = repertoire(tug, math.nan, 1.0, 100.0)
    assert [s.catalogue for s in specs] == [m.name for m in twin.catalogue(tug)]
    assert all(isinstance(s, CatalogueSpec) and mirrored(s).mirror == s.mirrorable
               for s in specs)
    # a zigzag or a turn has another side; a straight run none, a random one a drawn sign
    assert {s.kind for s in specs if s.mirrorable} == {'zigzag', 'turning', 'differential'}
    trials = sail(tug, ('zigzag_p20deg_7rps', 'straight_5rps'), 0)
    offset = tug.with_params({'azimuth_offset_port': math.radians(3.0)})
    (a,) = advise(tug, [{'about': 'azimuth_offset_port', 'kind': 'indistinguishable',
                         'params_a': tug.params, 'params_b': offset.params}],
                  trials, residual_scale(tug, tug.params, trials))
    assert a['spec']['catalogue'] in {m.name for m in twin.catalogue(tug)}
    assert a['pair'] == {**a['spec'], 'mirror': a['spec']['mirrorable']}
    assert a['separation'] > 1.5 * a['separation_recorded'] and a['settles']
    (tmp_path / 'diagnosis.json').write_text(json.dumps({'advice': [a]}))
    # the twin: the other side, or the same manoeuvre sailed again
    assert [s.mirror for s in load_advice(tmp_path)] == [False, a['spec']['mirrorable']]
    assert generate(['--ship', 'qiuxin_tug', '--out', str(tmp_path / 'gen'), '--from-advice',
                     str(tmp_path), '--rate-hz', '2.5']) == 0
    csvs = sorted(p.name for p in (tmp_path / 'gen' / 'csv').iterdir())
    assert len(csvs) == 2 and all(c.startswith(f"advice_{a['spec']['catalogue']}")
                                  for c in csvs)
    (back,) = mt.load_trials(tmp_path / 'gen' / 'csv' / csvs[0])
    assert {'n_port', 'azimuth_port'} <= set(back.inputs)
