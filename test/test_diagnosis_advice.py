"""
Advice on the next trial (issue 15): information, the pair, and what generate runs.

A barely identifiable effect is advised the trial that most lowers its standard error with the
base targets free; the figure without a trial must be the one the identifiability flag used.
Every advised trial comes with its twin to the other side (one tuned on, one held out).
"""
import json
import math

from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.diagnosis.advice import (advise_information, load_advice, mirrored, repertoire,
                                        TrialSpec)
from mmg_tuner.tuning import ParameterSpace
from mmg_tuner.tuning.identifiability import aliasing
from mmg_tuner.tuning.objective import Objective, TrialBatch
import numpy as np
import pytest


def test_resolution_matches_the_identifiability_flag_and_a_trial_only_adds(suzaku):
    trials = [generate_trial(suzaku, m, a, None, 106.0, 3.086, 200.0, 1.0, SensorNoise(),
                             i, f'{m}{a:+d}')[1]
              for i, (m, a) in enumerate([('zigzag', 10), ('turning', 20)])]
    obj = Objective(suzaku, TrialBatch.from_trials(trials), integrator='rk4')
    base = ParameterSpace.around(suzaku)
    effects = ['rpm_scale', 'time_offset']
    out = {a['about']: a for a in advise_information(suzaku, base, base.pre, obj, effects,
                                                     trials)}
    assert set(out) == set(effects)
    # the flag's own figure (select._aliased_effects): all probes at their smallest, base free
    from mmg_tuner.core.effects import EFFECTS
    from mmg_tuner.core.layout import EFFECT_NEUTRAL
    from mmg_tuner.diagnosis.select import _Model
    m = _Model(suzaku, base, [EFFECTS[e] for e in effects])
    th = np.concatenate([base.pre, [EFFECT_NEUTRAL[EFFECTS[e].params[0]]
                                    + EFFECTS[e].smallest_for(suzaku)[0] for e in effects]])
    flag = aliasing(obj, m.space, th, [EFFECTS[e].params[0] for e in effects])
    for e, a in out.items():
        assert a['se_recorded'] == pytest.approx(flag[EFFECTS[e].params[0]]['se'], rel=1e-6)
        # information only adds: a trial never makes the effect less resolved
        assert a['separation'] >= a['separation_recorded'] * (1 - 1e-9)
        assert a['settles'] == (a['separation'] >= 1.0
                                and a['separation'] > 1.5 * a['separation_recorded'])
        spec, pair = TrialSpec.from_dict(a['spec']), TrialSpec.from_dict(a['pair'])
        assert pair == mirrored(spec) and pair.rudder_deg == -spec.rudder_deg
        assert 'twice' in a['instruction']


def test_the_pair_is_generated_and_the_repertoire_steps_down(suzaku, tmp_path):
    reps = repertoire(suzaku, 106.0, 3.0, 300.0)
    assert any(s.rpm_after is not None and s.rpm_after < s.rpm for s in reps)
    assert all(abs(s.rudder_deg) <= math.degrees(suzaku.max_rudder_rad) for s in reps)
    spec = TrialSpec('turning', 35.0, 120.0, 300.0, 1.0, 2.3)
    doc = {'advice': [{'about': 'rpm_scale', 'kind': 'barely identifiable',
                       'spec': spec.to_dict(), 'pair': mirrored(spec).to_dict(), 'version': 1},
                      {'about': 'time_offset', 'kind': 'barely identifiable',
                       'spec': mirrored(spec).to_dict(), 'version': 1}]}
    (tmp_path / 'diagnosis.json').write_text(json.dumps(doc))
    # each trial once, the twin right after its advised trial
    assert load_advice(tmp_path) == [spec, mirrored(spec)]
