"""
The diagnosis at the edges of what it can know (issue 15).

Effects at the small end of their realistic range are still named; a change of the ship
outside the effects library (shallow water altering the hull derivatives) is not blamed on a
library effect; a measured wind at low speed is weighed against a model tuned as hard
without it. Quick budget, 8 trials of 300 s.
"""
import math

from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.diagnosis import diagnose, DiagnosisSettings
from mmg_tuner.tuning import ParameterSpace
from mmg_tuner.tuning.objective import Objective, TrialBatch
import numpy as np
import pytest

SPECS = [('turning', 35, None), ('turning', -25, None), ('zigzag', 20, None), ('random', 30, None),
         ('zigzag', -15, None), ('turning', -35, None), ('random', 25, None), ('zigzag', 10, None)]
QUICK = {'base_evals': 6000, 'screen_evals': 300, 'effect_evals': 3000, 'screen': 3,
         'max_effects': 2}
# the library's usual suspects for a hull that turns differently: a lag, an offset, a bias,
# a current or wind that bends the track, commands out of step
SUSPECTS = ['rudder_offset', 'rudder_lag', 'current', 'yaw_moment_bias', 'wind', 'time_offset']
# hull derivatives in shallow water (h/d ~ 1.5) relative to deep water, of the size Kijima's
# and Ankudinov's corrections give: the ship becomes more course-stable and turns wider
SHALLOW = {'Y_v': 1.8, 'Y_r': 1.4, 'N_v': 1.7, 'N_r': 1.35, 'Y_vvv': 1.5, 'Y_vrr': 1.5,
           'N_vvr': 1.5, 'X_vv': 1.5}


def _truth(ship, effect: dict, seed: int = 3, factors: dict | None = None):
    """
    Return SUZAKU with its 12 targets moved inside the box and an effect hidden.

    factors: other (untuned) coefficients multiplied by these.
    """
    space = ParameterSpace.around(ship)
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-0.3, 0.3, space.dim)
    truth = ship.with_params({**dict(zip(space.names, theta)), **effect})
    if factors:
        truth = truth.with_params({k: truth[k] * f for k, f in factors.items()})
    return truth


def _trials(truth):
    trials = [generate_trial(truth, m, a, c, 106.0, 3.086, 300.0, 1.0, SensorNoise(), 10 + i,
                             f'{m}{a:+d}')[1] for i, (m, a, c) in enumerate(SPECS)]
    return trials[::2], trials[1::2]


def _diagnose(ship, tune, test, **settings):
    return diagnose(ship, tune, test, DiagnosisSettings(**{**QUICK, **settings}),
                    log=lambda m: None)


# ------------------------------------------------------------------ small but worth finding
def test_a_current_at_the_small_end_of_its_range_is_named(suzaku):
    """
    Name a current of 1.5 x the smallest worth finding (0.1 m/s).

    Measured here: 0.149 m/s, held-out gain 97 %; the direction 37 deg off (at this size the
    tuned rudder coefficients take up part of the cross-track drift, as in
    test_two_hidden_effects_are_both_named): 60 deg still fails a from/to or north/east
    convention error.
    """
    tune, test = _trials(_truth(suzaku, {'current_speed': 0.15, 'current_dir': 2.0}))
    d = _diagnose(suzaku, tune, test, effects=SUSPECTS)
    assert [c.effect for c in d.causes] == ['current'], [c.summary for c in d.causes]
    p = d.causes[0].parameters
    assert p['current_speed'] == pytest.approx(0.15, abs=0.05)
    assert abs((math.degrees(p['current_dir']) - math.degrees(2.0) + 180) % 360 - 180) < 60


@pytest.mark.slow
def test_a_rudder_offset_at_the_small_end_of_its_range_is_named(suzaku):
    """
    Name a rudder offset of 1.5 x the smallest worth finding (1 deg).

    Measured here: 1.95 deg, held-out gain 89 %; a wrong sign or a miss fails.
    """
    tune, test = _trials(_truth(suzaku, {'rudder_offset': math.radians(1.5)}))
    d = _diagnose(suzaku, tune, test, effects=SUSPECTS)
    assert [c.effect for c in d.causes] == ['rudder_offset'], [c.summary for c in d.causes]
    assert math.degrees(d.causes[0].parameters['rudder_offset']) == pytest.approx(1.5, abs=0.75)


# ----------------------------------------------------------------------- outside the library
def test_a_shallow_water_hull_is_not_named_as_a_library_effect(suzaku):
    """
    Blame no library effect for hull derivatives changed as in shallow water.

    None of them is a tuning target: the tuned base model cannot follow, and no effect of the
    library may take the blame; the error that remains is unexplained (measured here: 28 x
    what the truth leaves on the same trials, nothing named).
    """
    truth = _truth(suzaku, {}, factors=SHALLOW)
    tune, test = _trials(truth)
    d = _diagnose(suzaku, tune, test, effects=SUSPECTS)
    assert d.causes == [], [c.summary for c in d.causes]
    obj = Objective(suzaku, TrialBatch.from_trials(test), integrator='rk4')
    J_truth = obj.per_trial(truth.params[None])[0][0].sum()
    assert d.final['J_test'] > 3 * J_truth


# ------------------------------------------------------------- a measured wind, real data
def test_the_measured_wind_is_named_on_the_esso_osaka_low_speed_runs():
    """
    Name the measured wind where it drives a 3 m model at low speed.

    The 13 FRT-DS-ESSO random and berthing runs (a pond; true wind measured, gusts of
    several m/s against ship speeds of 0.1-0.5 m/s), every second held out, as a new user
    would run them. The published coefficients already predict these runs 2-5 x better with
    the wind; on the zigzag and turning runs the wind makes them worse, which is why a
    diagnosis of the zigzags alone named nothing. Measured here with free runs (the rules
    verdict): held-out gain 85.7 % +- 20.7 % (J 4.3e6 without, 6.1e5 with); with the default
    evidence verdict, whose simulations restart every 22 s, 41 % (J 698 without, 413 with: a
    free run's drift is most of what the wind explains). The measured-wind candidate's numbers
    do not depend on which other effects are searched (the same null and re-tune), so two keep
    it quick (about 30 s).
    """
    import mmg_tuner as mt
    from mmg_tuner.data.esso import esso_data_dir
    from mmg_tuner.diagnosis.report import markdown
    ship = mt.load_ship('esso_osaka_3m')
    d = esso_data_dir()
    trials = mt.load_trials([d / 'random', d / 'berthing'], ship=ship, dt=1.0)
    assert len(trials) == 13 and all(t.wind is not None for t in trials)
    dx = mt.diagnose(ship, trials, budget='quick', effects=['current', 'rudder_offset'],
                     max_effects=1, residual=False)   # (what remains: not this test's)
    assert dx.setting.venue == 'pond'
    assert [c.effect for c in dx.causes] == ['measured_wind']
    m = dx.measured[0]
    assert m['named'] and m['J_test_with'] < 0.7 * m['J_test_without']
    assert dx.causes[0].heldout_gain > 0.3 and 0 < dx.causes[0].heldout_gain_se < 0.5
    md = markdown(dx.to_dict(), ship)
    assert '**measured_wind** — measured wind used. Held-out gain' in md
