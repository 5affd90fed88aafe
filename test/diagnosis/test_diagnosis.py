"""
The diagnosis must find an effect hidden in generated data, and name nothing on clean data.

Small trials and budgets keep this part of the suite to a couple of minutes; the full-size runs
belong in the benchmark.
"""
import json
import math

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.diagnosis import diagnose, DiagnosisSettings
from mmg_tuner.tuning import ParameterSpace
import numpy as np
import pytest

SPECS = [('turning', 35, None), ('turning', -25, None), ('zigzag', 20, None), ('random', 30, None),
         ('zigzag', -15, None), ('turning', -35, None), ('random', 25, None), ('zigzag', 10, None)]
QUICK = {'base_evals': 6000, 'screen_evals': 300, 'effect_evals': 3000, 'screen': 3,
         'max_effects': 2}


def hidden(suzaku, effect: dict, seed: int = 3, targets=None):
    """
    Return trials of SUZAKU with the targets moved inside the box and an effect hidden.

    Trials of SUZAKU with the targets (default: the paper's 12) moved inside the box and an effect
    hidden.
    """
    space = ParameterSpace.around(suzaku, targets)
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-0.3, 0.3, space.dim)
    truth = suzaku.with_params({**dict(zip(space.names, theta)), **effect})
    trials = [generate_trial(truth, m, a, c, 106.0, 3.086, 300.0, 1.0, SensorNoise(),
                             10 + i, f'{m}{a:+d}')[1] for i, (m, a, c) in enumerate(SPECS)]
    return trials[::2], trials[1::2]


def run(suzaku, effect, seed: int = 3, **settings):
    tune, test = hidden(suzaku, effect, seed, settings.get('targets'))
    return diagnose(suzaku, tune, test, DiagnosisSettings(**{**QUICK, **settings}),
                    log=lambda m: None)


def _angle_deg(a: float, b: float) -> float:
    return abs((math.degrees(a - b) + 180.0) % 360.0 - 180.0)


def test_clean_data_names_nothing(suzaku):
    d = run(suzaku, {})
    assert d.causes == []
    assert d.final['J_test'] == d.baseline['J_test'] or d.final['heldout_gain_total'] < 0.3


def test_finds_a_hidden_rudder_offset(suzaku):
    d = run(suzaku, {'rudder_offset': math.radians(2.0)})
    assert [c.effect for c in d.causes] == ['rudder_offset']
    c = d.causes[0]
    assert math.degrees(c.parameters['rudder_offset']) == pytest.approx(2.0, abs=0.75)
    assert c.heldout_gain > 0.5


def test_diagnose_command_finds_a_current(tmp_path, capsys):
    from mmg_tuner.cli.diagnose import command
    from mmg_tuner.cli.generate import command as generate
    gen = tmp_path / 'gen'
    assert generate(['--out', str(gen), '--duration', '300', '--rate-hz', '2', '--maneuvers',
                     'turning:35', 'turning:-25', 'zigzag:20', 'random:30', 'zigzag:-15',
                     'turning:-35', 'random:25', 'zigzag:10', '--effect', 'current_speed=0.3',
                     '--effect', 'current_dir=2.0']) == 0
    out = tmp_path / 'diag'
    assert command([str(gen), '--out', str(out), '--budget', 'quick', '--max-effects', '2']) == 0
    doc = json.loads((out / 'diagnosis.json').read_text())
    assert [c['effect'] for c in doc['causes']] == ['current']
    p = doc['causes'][0]['parameters']
    assert p['current_speed'] == pytest.approx(0.3, abs=0.08)
    assert abs((math.degrees(p['current_dir'] - 2.0) + 180) % 360 - 180) < 25
    assert doc['causes'][0]['heldout_gain'] > 0.8
    assert doc['final']['J_test'] < 0.2 * doc['baseline']['J_test']
    assert 'CAUSE: current' in capsys.readouterr().out
    from mmg_tuner.core.ship import load_ship
    ship = load_ship('suzaku', out / 'params.yaml')  # the extended model loads for simulate
    assert ship['current_speed'] == pytest.approx(p['current_speed'])
    assert (out / 'residuals_vs_heading.png').is_file() and (out / 'diagnosis.md').is_file()


def test_every_effect_is_registered_with_bounds_containing_neutral(suzaku):
    from mmg_tuner.core.layout import EFFECT_NEUTRAL
    for e in EFFECTS.values():
        for p, (lo, hi) in zip(e.params, e.bounds(suzaku)):
            assert lo <= EFFECT_NEUTRAL[p] <= hi, (e.name, p)


def test_finds_a_hidden_wind(suzaku):
    d = run(suzaku, {'wind_speed': 10.0, 'wind_dir': -2.2})
    assert [c.effect for c in d.causes] == ['wind']
    p = d.causes[0].parameters
    assert p['wind_speed'] == pytest.approx(10.0, abs=1.5)
    assert _angle_deg(p['wind_dir'], -2.2) < 15
    assert d.causes[0].heldout_gain > 0.8


def test_finds_a_hidden_steering_gear_lag(suzaku):
    """
    The lag is named first.

    Its size is poorly determined by 1 Hz trials with a 2.3 deg/s gear while the rudder
    coefficients are tuned too (standard error ~3 s at the base optimum): here the estimate comes
    out about twice the truth and a -1 s time offset joins it as a second effect (the benchmark has
    the statistics; README, Diagnosis).
    """
    d = run(suzaku, {'rudder_lag_tau': 8.0})
    assert [c.effect for c in d.causes][:1] == ['rudder_lag']
    assert 4.0 < d.causes[0].parameters['rudder_lag_tau'] < 20.0
    assert d.causes[0].heldout_gain > 0.3


def test_finds_a_hidden_antenna_offset(suzaku):
    """
    One effect searched.

    Beside a 25 m antenna offset a wind of 5.1-5.5 m/s from about 155 deg joins as a second effect
    on three of four truth draws (seeds 1, 3, 4; CMA-ES and least-squares re-tunes alike, 5 m/s
    being the smallest wind worth finding), and the joint re-tune moves antenna_x by up to 4 m: the
    offset's own estimate is asserted here.
    """
    d = run(suzaku, {'antenna_x': -25.0, 'antenna_y': 2.0}, max_effects=1)
    assert [c.effect for c in d.causes][:1] == ['antenna_offset']
    p = d.causes[0].parameters
    assert p['antenna_x'] == pytest.approx(-25.0, abs=4.0)
    assert p['antenna_y'] == pytest.approx(2.0, abs=2.5)


def test_two_hidden_effects_are_both_named(suzaku):
    """
    Each must explain at least min_abs_gain (5 %) of the base model's held-out error.

    A 0.2 m/s current and a 3 deg rudder offset both do (a 2 deg offset beside a 0.3 m/s current
    explains 3 % and goes unnamed: the documented detection limit).

    Margins measured over five truth draws (seeds 1-5; natively and with
    NUMBA_CPU_NAME=generic, which agree to 1e-4 rad): speed 0.191-0.199 m/s, rudder offset
    2.9-3.2 deg, but the direction 20-28 deg off, always to the same side: the offset and
    the cross-track part of a weak current both bend the track, so at this size the
    direction carries a systematic bias of about 25 deg (the 25 deg once asserted here sat
    on it). 40 deg leaves 12 deg to the worst draw and still fails a sign, from/to or
    north/east convention error (90 deg or more); the speed bound is tightened so that the
    current vector stays within about 0.15 m/s.
    """
    d = run(suzaku, {'current_speed': 0.2, 'current_dir': 2.0,
                     'rudder_offset': math.radians(3.0)})
    assert sorted(c.effect for c in d.causes) == ['current', 'rudder_offset']
    p = {k: v for c in d.causes for k, v in c.parameters.items()}
    assert p['current_speed'] == pytest.approx(0.2, abs=0.05)
    assert _angle_deg(p['current_dir'], 2.0) < 40
    assert math.degrees(p['rudder_offset']) == pytest.approx(3.0, abs=1.0)


def test_rpm_scale_is_named_when_the_propulsion_coefficients_are_known(suzaku):
    """
    An rpm scale error is named when the propulsion coefficients are known.

    An rpm scale error and a changed wake fraction / thrust deduction produce the same thrust (J
    and K_T are unchanged when (1 - w_P) scales with n): with those tuned the diagnosis must say
    the effect is barely identifiable; with them held, it must find it.
    """
    d = run(suzaku, {'rpm_scale': 0.94}, effects=['rpm_scale', 'rudder_offset', 'current'])
    assert 'rpm_scale' in d.aliased
    hull_rudder = ['t_R', 'a_H', 'x_H', 'epsilon', 'kappa', 'l_R', 'gamma_Rp', 'gamma_Rn']
    d = run(suzaku, {'rpm_scale': 0.94}, targets=hull_rudder,
            effects=['rpm_scale', 'rudder_offset', 'current'])
    assert [c.effect for c in d.causes] == ['rpm_scale']
    assert d.causes[0].parameters['rpm_scale'] == pytest.approx(0.94, abs=0.02)


def test_an_estimate_pinned_on_its_bound_is_not_accepted():
    from mmg_tuner.diagnosis.stats import pinned_on_bound
    space = ParameterSpace(('R_0', 'antenna_x', 'antenna_y', 'current_dir', 'rudder_lag_tau'),
                           np.zeros(5), np.array([0, -40, -6.75, -math.pi, 0.0]),
                           np.array([1, 40, 6.75, math.pi, 20.0]))
    names = ('antenna_x', 'antenna_y', 'current_dir', 'rudder_lag_tau')
    assert pinned_on_bound(space, np.array([1.0, 3.0, -6.74, math.pi, 0.0]), names, 0.01) \
        == ['antenna_y']  # base targets, periodic angles and neutral bounds are not suspect
    assert pinned_on_bound(space, np.array([0.5, 39.9, 0.0, 0.0, 19.9]), names, 0.01) \
        == ['antenna_x', 'rudder_lag_tau']


def test_effects_too_small_to_matter_are_not_causes(suzaku):
    from mmg_tuner.core.ship import load_ship
    cur = EFFECTS['current']
    assert cur.too_small(suzaku, {'current_speed': 0.02, 'current_dir': 1.0})
    assert not cur.too_small(suzaku, {'current_speed': 0.25, 'current_dir': 1.0})
    ant = EFFECTS['antenna_offset']
    assert not ant.too_small(suzaku, {'antenna_x': 0.5, 'antenna_y': 2.0})  # one is enough
    # Froude scaling for a model: speeds and times by 1/sqrt(45.7), lengths by 1/45.7
    kv = load_ship('kvlcc2')
    assert cur.smallest_for(kv)[0] == pytest.approx(0.1 / math.sqrt(kv.scale_ratio))
    assert ant.smallest_for(kv)[0] == pytest.approx(5.0 / kv.scale_ratio)
    assert EFFECTS['rudder_offset'].smallest_for(kv) == EFFECTS['rudder_offset'].smallest


def test_a_time_offset_the_trials_cannot_see_is_reported_not_misnamed(suzaku):
    """
    A time offset the trials cannot resolve is reported, not blamed on another effect.

    A 1.5 s command delay under a 2.3 deg/s gear sampled at 1 Hz is below what these trials
    resolve: the diagnosis must say so and must not blame another effect for it.
    """
    d = run(suzaku, {'time_offset': 1.5})
    assert 'time_offset' in d.aliased
    assert d.aliased['time_offset']['se'] > 0.5 * d.aliased['time_offset']['smallest']
    assert [c.effect for c in d.causes] in ([], ['time_offset'])
