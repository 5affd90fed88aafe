"""
bench/tug_logo.py's judging helpers, without an identification (seconds, no compile).

The twin's noise beside its signal, the pairing of the noisy twin with its truth, and the
verdicts on the issue's goals, on hand-made figures whose verdicts are known.
"""
import math

from bench.tug_logo import check_paired, goals, noise_table
from mmg_tuner.core.trial import Trial
import numpy as np
import pytest

DT = 0.2


def _straight(n=3000, name='straight'):
    """Return a straight run north at 1 m/s, sway 0.2 m/s: poses consistent with u, v."""
    t = DT * np.arange(n)
    st = np.zeros((n, 6))
    st[:, 0], st[:, 1], st[:, 3], st[:, 4] = t, 0.2 * t, 1.0, 0.2
    st[:, 5] = math.radians(2.0)   # r: a signal for its ratio only (psi stays 0: not a turn)
    cmd = np.zeros(n)
    return Trial(t, st, name=name, inputs={'n_port': np.full(n, 5.0), 'n_stbd': np.full(n, 5.0),
                                           'azimuth_port': cmd, 'azimuth_stbd': cmd,
                                           'azimuth_cmd_port': cmd, 'azimuth_cmd_stbd': cmd})


def _noisy(tr, sd, seed=1):
    rng = np.random.default_rng(seed)
    st = tr.states + rng.normal(0, 1, tr.states.shape) * np.asarray(sd)
    return Trial(tr.t, st, name=tr.name, inputs=dict(tr.inputs))


def test_noise_table_gives_the_noise_its_share_of_the_signal_and_what_differences_give():
    truth = _straight()
    sd = [0.015, 0.015, math.radians(0.3), 0.01, 0.01, math.radians(0.2)]
    rows = {r['state'].split()[0]: r for r in noise_table([_noisy(truth, sd)], [truth])}
    for k, (name, s) in enumerate(zip(('x', 'y', 'psi', 'u', 'v', 'r'), sd)):
        f = math.degrees(1.0) if name in ('psi', 'r') else 1.0
        assert rows[name]['noise sd'] == pytest.approx(f * s, rel=0.08), name
    assert rows['u']['signal RMS'] == pytest.approx(1.0)
    assert rows['u']['noise sd / RMS %'] == pytest.approx(1.0, rel=0.08)
    assert rows['v']['noise sd / RMS %'] == pytest.approx(5.0, rel=0.08)
    assert rows['u']['paper Table 5 x RMS'] == pytest.approx(0.0233)
    # central differences of 1.5 cm white positions at 0.2 s: 0.015 / (sqrt(2) 0.2) m/s
    assert rows['u']['from poses: noise sd'] == pytest.approx(0.015 / (math.sqrt(2) * DT),
                                                              rel=0.1)
    assert rows['u']['from poses: noise sd'] > 4 * rows['u']['noise sd']


def test_check_paired_refuses_a_truth_sailed_with_other_commands():
    truth = _straight()
    check_paired([_noisy(truth, [0.01] * 6)], [truth])
    other = _straight()
    other.inputs['azimuth_cmd_port'][100:] = 0.1
    with pytest.raises(RuntimeError, match='straight'):
        check_paired([_noisy(truth, [0.01] * 6)], [other])


def _by(logo_m, logo_t, lo_t=(0.05, 0.05, 0.05), go20_t=(0.002, 0.002, 0.002)):
    """Held-out rows as main() passes them: (vs measured, vs truth, median coef %, wall s)."""
    def rel(x):
        return dict(zip('uvr', x))
    floor = rel((0.0125, 0.0428, 0.0239))
    return {'LO -> GO': (rel(logo_m), rel(logo_t), 16.0, 2.0),
            'truth (Table 3)': (floor, rel((0.0, 0.0, 0.0)), 0.0, 0.0),
            'LO': (rel((0.04, 0.05, 0.09)), rel(lo_t), 80.0, 0.6),
            'GO (empirical start)': (rel((1.1, 1.9, 9.7)), rel((1.5, 2.7, 11.8)), 100.0, 5.0),
            'GO (+-20 % start)': (rel((0.0125, 0.043, 0.0247)), rel(go20_t), 10.0, 1.0)}


def test_goals_name_the_noise_floor_and_judge_against_the_truth():
    g = goals(_by((0.0125, 0.043, 0.0246), (0.0013, 0.0053, 0.006)), None, 1.6)
    half = g["held-out relative errors <= half the paper's Table 5"]
    assert half['target'] == '1.165 / 2.225 / 2.925 % (u / v / r)'
    assert 'measurements met in r only' in half['verdict']
    assert 'above the target in u, v' in half['verdict']
    assert 'truth met in u, v and r' in half['verdict']
    assert g['identification of the 12 manoeuvres <= 60 s']['verdict'].startswith('met')


def test_lo_go_better_than_either_alone_fails_when_lo_alone_is_better():
    good = goals(_by((0.0125, 0.043, 0.0246), (0.0013, 0.0053, 0.006)), None, 1.6)
    assert good['LO -> GO better than either alone']['verdict'].startswith('holds')
    bad = goals(_by((0.0125, 0.043, 0.0246), (0.0013, 0.0053, 0.006),
                    lo_t=(0.001, 0.001, 0.001)), None, 1.6)
    verdict = bad['LO -> GO better than either alone']['verdict']
    assert verdict.startswith('does not hold') and 'below LO (vs truth) in none' in verdict
    conv = {'starts': 20, 'methods': {'LO -> GO': {'summary': {'reached': 12}},
                                      'GO alone': {'summary': {'reached': 15}}}}
    fewer = goals(_by((0.0125, 0.043, 0.0246), (0.0013, 0.0053, 0.006)), conv, 1.6)
    assert fewer['LO -> GO better than either alone']['verdict'].startswith('does not hold')
