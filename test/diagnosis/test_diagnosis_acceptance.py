"""The one acceptance rule: a test trial getting worse vetoes only when it matters."""
from mmg_tuner.diagnosis import acceptance, DiagnosisSettings
import numpy as np


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
