"""The one acceptance rule: a test trial getting worse vetoes only when it matters; rivals."""
from mmg_tuner.diagnosis import acceptance, DiagnosisSettings
from mmg_tuner.diagnosis.report import markdown
from mmg_tuner.diagnosis.results import Cause, split_undecided
import numpy as np
import pytest


def _pieces():
    """Return held-out J of 20 pieces: 19 the model fits poorly, one it fits almost exactly."""
    J_ref = np.full(20, 100.0)
    J_ref[0] = 1.0
    return J_ref


def test_tiny_trial_many_times_worse_but_negligible_is_accepted():
    s = DiagnosisSettings()
    J_ref = _pieces()
    J_new = J_ref * 0.5            # the effect halves the error where it shows ...
    J_new[0] = 12.0                # ... and the near-exact piece gets 12x worse by 11 of 1901
    v = acceptance(J_ref, J_new, 2, float(J_ref.sum()), s)
    assert v.worst == 12.0         # the ratio is still reported
    assert v.significant, v.reason
    assert v.reason == ''


def test_large_trial_much_worse_is_vetoed():
    s = DiagnosisSettings()
    J_ref = _pieces()
    J_new = J_ref * 0.3
    J_new[5] = 400.0               # a piece with its share of the error gets 4x worse
    v = acceptance(J_ref, J_new, 2, float(J_ref.sum()), s)
    assert v.gain > 0.5 and v.gain > s.min_gain_z * v.gain_se   # the pooled gain alone passes
    assert not v.significant
    assert 'a test trial gets worse (4.00 x' in v.reason


def test_same_ratio_vetoes_once_it_matters_in_absolute_terms():
    """The tiny piece's worsening is judged by its share of the total held-out J."""
    s = DiagnosisSettings()
    J_ref = _pieces()
    J_new = J_ref * 0.5
    J_ref[0], J_new[0] = 30.0, 12 * 30.0   # the same 12x, now +330 of 1930 (17 %): vetoed
    v = acceptance(J_ref, J_new, 2, float(J_ref.sum()), s)
    assert not v.significant and 'worse (12.00 x' in v.reason


def test_a_trial_worse_by_less_than_its_noise_floor_does_not_veto():
    """
    Near the noise, a trial worse by less than its noise floor vetoes nothing.

    What noise alone leaves on a trial is no evidence against an effect (issue 26, seventh
    session): the bench's wind + rudder offset
    at their true values made one held-out trial 2.6 x worse than a wind bent to take the
    offset's share, +10 % of the held-out error but 0.7 of that trial's noise floor.
    """
    s = DiagnosisSettings()
    J_ref = np.array([0.64, 3.9, 3.9, 3.9, 4.06]) * 1e6   # 1.64e7 held out, 1.3 floors
    J_new = np.array([2.31, 1.1, 1.4, 3.3, 0.8]) * 1e6    # 45 % better, trial 0 2.6 x worse
    floors = np.full(5, 2.52e6)                           # 1.26e7 over five trials
    vetoed = acceptance(J_ref, J_new, 1, 5.9e8, s, 1.26e7)
    assert not vetoed.significant and 'a test trial gets worse (3.61 x' in vetoed.reason
    v = acceptance(J_ref, J_new, 1, 5.9e8, s, 1.26e7, floors)
    assert v.significant, v.reason
    # worse by more than its floor: vetoed as before
    v = acceptance(J_ref, J_new, 1, 5.9e8, s, 1.26e7, floors * 0.5)
    assert not v.significant and 'gets worse' in v.reason


# ---------------------------------------------------------------- suspected, not named (i26)
def _round_two(effect: str, values: dict, J_test: float, gain_se: float = 0.398, **kw):
    """
    Return a second round's candidate with held-out J J_test.

    Held-out J 1.64e7 without it (the bench's wind beside an offset, 1.3 x the noise floor
    1.26e7).
    """
    from mmg_tuner.diagnosis.results import Candidate
    J_ref = 1.64e7
    return Candidate(effect, J_test, [], 1 - J_test / J_ref, gain_se, False, values,
                     J_ref=J_ref, **kw)


def test_an_effect_the_held_out_trials_disagree_on_is_suspected_with_its_rival(suzaku):
    """
    An effect gaining but with held-out trials disagreeing is suspected, not named.

    A rudder offset beside a named wind, as the bench found it (seed 0): held-out gain
    46 % +- 40 %, not named for one held-out trial 2.6 x worse. Its reduction is a sliver of
    the base error (1.2 % of 5.9e8) but 0.6 noise floors: evidence, so it is suspected, with
    the models without and with it for the advice; a candidate that fails any other part of
    the rule is not.
    """
    from mmg_tuner.diagnosis.select import suspected_effects
    s, base_J, floor = DiagnosisSettings(), 5.9e8, 1.26e7
    now, with_it = np.zeros(3), np.ones(3)
    offset = {'rudder_offset': np.radians(1.5)}

    def run(cand, J_floor=floor, params_now=now):
        return suspected_effects(suzaku, [(cand, with_it)], s, base_J, J_floor, 2, ['wind'],
                                 params_now)

    got = run(_round_two('rudder_offset', offset, 0.89e7))
    assert [x['effect'] for x in got] == ['rudder_offset'] and got[0]['beside'] == ['wind']
    assert got[0]['gain'] == pytest.approx(0.457, abs=0.01) and got[0]['round'] == 2
    rival = got[0]['rival']
    assert rival['kind'] == 'suspected' and rival['about'] == 'rudder_offset'
    assert rival['params_a'] is now and rival['params_b'] is with_it
    # without the noise floor the same reduction is no evidence (below 5 % of the base error)
    assert run(_round_two('rudder_offset', offset, 0.89e7), J_floor=None) == []
    # a gain below the least for one parameter (12 %), too small an offset (0.3 deg), on its
    # bound, impossible here, or already named: not suspected
    assert run(_round_two('rudder_offset', offset, 1.5e7)) == []
    assert run(_round_two('rudder_offset', {'rudder_offset': np.radians(0.3)}, 0.89e7)) == []
    assert run(_round_two('rudder_offset', offset, 0.89e7, on_bound=['rudder_offset'])) == []
    assert run(_round_two('rudder_offset', offset, 0.89e7, impossible='indoors')) == []
    named = _round_two('rudder_offset', offset, 0.89e7)
    named.accepted = True
    assert run(named) == []
    # a model the measured wind drives cannot be simulated apart: suspected, without a rival
    got = run(_round_two('rudder_offset', offset, 0.89e7), params_now=None)
    assert got and 'rival' not in got[0]


def test_a_cause_as_good_as_a_rival_outside_the_model_is_undecided_not_named():
    """One of a set is not named; a rival that is itself in the final model is no rival."""
    current = Cause('current', {}, {}, 0.9, 0.1, ['rudder_offset'])
    offset = Cause('rudder_offset', {}, {}, 0.5, 0.1, ['yaw_moment_bias', 'current'])
    wind = Cause('wind', {}, {}, 0.4, 0.1, [])
    named, undecided = split_undecided([current, offset, wind])
    assert [c.effect for c in named] == ['current', 'wind']
    assert [(c.effect, c.indistinguishable_from) for c in undecided] == [
        ('rudder_offset', ['yaw_moment_bias'])]
    assert split_undecided([offset]) == ([], [offset])


def test_the_report_names_an_undecided_cause_as_one_of_a_set(suzaku):
    offset = Cause('rudder_offset', {'rudder_offset': -0.023}, {'rudder_offset': 0.004}, 0.912,
                   0.05, ['yaw_moment_bias', 'wind'])
    doc = {'baseline': {'J_test': 1.0}, 'final': {'J_test': 0.1}, 'causes': [],
           'undecided': [offset.to_dict()], 'candidates': [], 'advice': [],
           'residuals': {'base_model': {'per_trial': {}, 'correlation': {}},
                         'final_model': {'per_trial': {}}}}
    md = markdown(doc, suzaku)
    assert '**No cause is named alone:**' in md
    assert 'No effect in the library explains' not in md
    line = next(x for x in md.splitlines() if x.startswith('- one of **rudder_offset**'))
    assert line.endswith(') or yaw_moment_bias, wind') and offset.summary in line


def test_the_evidence_verdicts_search_accepts_by_the_held_out_test_alone():
    """
    A small second effect beside a dominant one: refused by the sizes, accepted by the test.

    Seed 401 of the mismatch benchmark: a rudder offset beside a current, held-out gain 6 %
    (about three standard errors), 0.2 % of the base model's error (the current took the rest).
    """
    J_ref = np.array([10.0, 12.0, 8.0, 11.0, 9.0])
    J_new = J_ref * np.array([0.92, 0.95, 0.93, 0.96, 0.94])
    J_base = 50 * J_ref.sum()
    sized = acceptance(J_ref, J_new, 1, J_base, DiagnosisSettings())
    assert not sized.significant and '<= 12.0 %' in sized.reason
    by_test = DiagnosisSettings(held_out_test_only=True, min_gain_z=2.0)
    v = acceptance(J_ref, J_new, 1, J_base, by_test)
    assert v.significant, v.reason
    # ... and the test still refuses a gain within two standard errors, and a trial made worse
    noisy = J_ref * np.array([0.7, 1.2, 0.8, 1.15, 0.95])
    assert 'standard error' in acceptance(J_ref, noisy, 1, J_base, by_test).reason
    hurt = J_new.copy()
    hurt[1] = 3 * J_ref[1]
    assert 'gets worse' in acceptance(J_ref, hurt, 1, J_base, by_test).reason
