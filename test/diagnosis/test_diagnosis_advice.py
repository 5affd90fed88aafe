"""
Advice on the next trial (issue 15): information, the pair, and what generate runs.

A barely identifiable effect is advised the trial that most lowers its standard error with the
base targets free; the figure without a trial must be the one the identifiability flag used.
Every advised trial comes with its twin to the other side (one tuned on, one held out). One
trial is chosen for all suspects jointly and put first; an effect no trial can settle says so
and names the measurement that would (rpm_scale: degenerate with the propulsion coefficients,
shown exactly below).
"""
import json
import math

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.simulate import simulate_batch
from mmg_tuner.data.generate import generate_trial, SensorNoise
from mmg_tuner.diagnosis.advice import (_Item, advise_all, advise_information, DEGENERATE_BELOW,
                                        joint_choice, load_advice, mirrored, repertoire,
                                        TrialSpec)
from mmg_tuner.tuning import ParameterSpace
from mmg_tuner.tuning.identifiability import aliasing
from mmg_tuner.tuning.objective import Objective, TrialBatch
import numpy as np
import pytest


def _two_trials(suzaku):
    """Return a 10 deg zigzag and a 20 deg turn (200 s, 1 Hz, noisy), their objective, space."""
    trials = [generate_trial(suzaku, m, a, None, 106.0, 3.086, 200.0, 1.0, SensorNoise(),
                             i, f'{m}{a:+d}')[1]
              for i, (m, a) in enumerate([('zigzag', 10), ('turning', 20)])]
    obj = Objective(suzaku, TrialBatch.from_trials(trials), integrator='rk4')
    return trials, obj, ParameterSpace.around(suzaku)


def test_resolution_matches_the_identifiability_flag_and_a_trial_only_adds(suzaku):
    trials, obj, base = _two_trials(suzaku)
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
        # a degenerate effect keeps its best trial only as a record; others are sailed twice
        assert 'twice' in a['best_trial' if a.get('degenerate') else 'instruction']


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


def test_one_trial_is_chosen_for_all_suspects_not_for_the_first():
    # three trials, two suspects: the first is best for a (b stays flagged), the second best
    # for b, the third lifts both -- advice per effect would sail the first (a comes first)
    specs = [TrialSpec('zigzag', a, 100.0, 300.0, 3.0, 2.3, check_deg=a)
             for a in (10.0, 20.0, 35.0)]
    a = _Item('a', 'barely identifiable', np.array([3.0, 0.4, 1.6]), 0.5)
    b = _Item('b', 'barely identifiable', np.array([0.3, 2.5, 1.6]), 0.5)
    j = joint_choice([a, b], specs)
    assert j['kind'] == 'joint' and TrialSpec.from_dict(j['spec']) == specs[2]
    assert sorted(j['lifts']) == ['a', 'b'] and j['settles']
    assert TrialSpec.from_dict(j['pair']) == mirrored(specs[2])
    # equal counts (d settled by the first two): the information added to all of them
    # decides, the sum of log ratios (2.20 for the second, 1.39 for the first), not the
    # largest figure (8 on the first)
    c = _Item('c', 'indistinguishable', np.array([0.2, 0.9, 0.1]), 0.8)
    d = _Item('d', 'barely identifiable', np.array([8.0, 4.0, 0.6]), 0.5)
    j = joint_choice([c, d], specs)
    assert j['lifts'] == ['d'] and TrialSpec.from_dict(j['spec']) == specs[1]
    # nothing to choose jointly with a single suspect
    assert joint_choice([a], specs) is None


def test_advise_all_puts_the_joint_trial_first_and_degenerate_effects_say_what_to_measure(
        suzaku, tmp_path):
    trials = [generate_trial(suzaku, m, a, None, 106.0, 3.086, 200.0, 1.0, SensorNoise(),
                             i, f'{m}{a:+d}')[1]
              for i, (m, a) in enumerate([('zigzag', 10), ('turning', 20)])]
    obj = Objective(suzaku, TrialBatch.from_trials(trials), integrator='rk4')
    base = ParameterSpace.around(suzaku)
    effects = ['rpm_scale', 'time_offset', 'yaw_moment_bias', 'rudder_offset', 'rudder_lag',
               'prop_side_force']
    out = advise_all(suzaku, base, base.pre, obj, effects, trials, effects, [])
    per = {a['about']: a for a in out if a['kind'] != 'joint'}
    assert set(per) == set(effects)
    # rpm_scale and time_offset: far below any trial's reach here (~0.08 vs 0.5); the yaw
    # moment bias (~0.7) and the rudder offset (~1.2) are clear of it: a joint trial for them
    for e in ('rpm_scale', 'time_offset'):
        assert per[e]['degenerate'] and per[e]['separation'] < DEGENERATE_BELOW
        assert per[e]['settle_by'] == EFFECTS[e].settle_by and EFFECTS[e].settle_by
        assert 'no trial can settle it' in per[e]['instruction']
        assert EFFECTS[e].settle_by in per[e]['instruction']
    settleable = [e for e in effects if not per[e].get('degenerate')]
    joints = [a for a in out if a['kind'] == 'joint']
    assert {'yaw_moment_bias', 'rudder_offset'} <= set(settleable)
    assert len(joints) == 1
    j = joints[0]
    assert out[0] is j and set(j['figures']) == set(settleable)
    assert set(j['not_settled_by_a_trial']) >= {'rpm_scale', 'time_offset'}
    assert j['settles'] == (j['separation'] >= 1.0
                            and j['separation'] > 1.5 * j['separation_recorded'])
    # the report: the joint trial printed first as the one to sail, the measurements stated
    from mmg_tuner.diagnosis.report import markdown
    md = markdown({'baseline': {'J_test': 1.0}, 'final': {'J_test': 0.5}, 'causes': [],
                   'candidates': [], 'advice': out,
                   'residuals': {'base_model': {'per_trial': {}, 'correlation': {}},
                                 'final_model': {'per_trial': {}}}}, suzaku)
    sec = md[md.index('## The trial that would settle it'):]
    assert EFFECTS['rpm_scale'].settle_by in sec and EFFECTS['time_offset'].settle_by in sec
    assert sec.index('**Sail first**') < sec.index(j['instruction']) < sec.index('| about |')
    assert ('No single trial settles them all apart' in sec) == (not j['lifts'])
    # generate --from-advice: the first trial sailed is the first advised, never a degenerate
    # effect's record
    (tmp_path / 'diagnosis.json').write_text(json.dumps({'advice': out}, default=float))
    specs = load_advice(tmp_path)
    assert specs[0] == TrialSpec.from_dict(out[0]['spec'])
    degenerate = {TrialSpec.from_dict(per[e]['spec']) for e in ('rpm_scale', 'time_offset')}
    sailed = {TrialSpec.from_dict(a['spec']) for a in out if not a.get('degenerate')}
    assert not (degenerate - sailed) & set(specs)


def test_load_advice_with_only_degenerate_effects_says_what_to_measure(tmp_path):
    spec = TrialSpec('turning', 35.0, 120.0, 300.0, 1.0, 2.3)
    doc = {'advice': [{'about': 'rpm_scale', 'kind': 'barely identifiable', 'degenerate': True,
                       'settle_by': EFFECTS['rpm_scale'].settle_by, 'spec': spec.to_dict(),
                       'version': 1}]}
    (tmp_path / 'diagnosis.json').write_text(json.dumps(doc))
    with pytest.raises(Exception, match='tachometer'):
        load_advice(tmp_path)


def _rpm_scale_pair(suzaku, k: float, side_force: bool):
    """
    Return (actual rpm k x recorded, plain model with the mapped propulsion coefficients).

    n -> k n keeps the advance angle phi = atan(u_P / (0.7 pi n D)) when 1 - w_P -> (1 - w_P) / k,
    the thrust q_P (1 - t_P) K_T(phi) when 1 - t_P -> k^2 (1 - t_P) (q_P scales with n^2), the
    rudder inflow u_R* when epsilon -> k epsilon and the floor u_R** = 0.7 pi n D u_R0 when
    u_R0 -> k u_R0. w_P = w_P0 exp(C_w beta_P^2) maps for every drift angle only with C_w = 0;
    the side force q_P C_PY and moment q_P L C_PN scale with n^2 and map not at all.
    """
    get = suzaku.__getitem__
    common = {'C_w': 0.0}
    if not side_force:
        common.update(dict.fromkeys(('CPY_0', 'CPY_1', 'CPY_2', 'CPN_lo_0', 'CPN_lo_1',
                                     'CPN_hi_0', 'CPN_hi_1'), 0.0))
    scaled = suzaku.with_params({**common, 'rpm_scale': k})
    mapped = suzaku.with_params({**common, 'rpm_scale': 1.0,
                                 'w_P0': 1.0 - (1.0 - get('w_P0')) / k,
                                 't_P': 1.0 - k ** 2 * (1.0 - get('t_P')),
                                 'epsilon': k * get('epsilon'), 'u_R0': k * get('u_R0')})
    return scaled.params, mapped.params


def test_rpm_scale_is_reproduced_exactly_by_the_propulsion_coefficients(suzaku):
    """
    Why no trial settles rpm_scale: its signature is the base targets' (up to C_PY, C_PN, C_w).

    A 35 deg turn, a zigzag and an rpm step (drift angles to ~0.4 rad, the u_R** floor at the
    low-speed, high-rpm start): with the side-force coefficients zero and C_w = 0 the two
    models agree to ~1e-9; with SUZAKU's C_PY, C_PN they do not (so the check can fail).
    """
    T, dt = 301, 1.0
    t = np.arange(T) * dt
    rpm = np.where(t < 150, 106.0, 80.0)
    turn = np.column_stack([rpm, np.radians(np.clip(2.3 * (t - 10), 0, 35))])
    zig = np.column_stack([np.full(T, 120.0), np.radians(20.0) * np.sign(np.sin(t / 40.0))])
    x0 = np.array([[0.0, 0.0, 0.0, 3.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.5, 0.0, 0.0]])
    for k in (0.95, 1.08):
        for side_force, agree in ((False, True), (True, False)):
            pa, pb = _rpm_scale_pair(suzaku, k, side_force)
            out, _, k_fail = simulate_batch(suzaku.kind, np.vstack([pa, pb]), x0,
                                            np.stack([turn, zig]), dt, None, 'rk4', 10)
            assert np.all(k_fail >= T)
            scale = np.max(np.abs(out[0]), axis=(0, 1))   # per state
            rel = np.max(np.abs(out[0] - out[1]), axis=(0, 1)) / scale
            if agree:
                assert np.all(rel < 1e-9), rel
            else:
                assert np.max(rel) > 1e-3, rel


def test_a_measurement_that_pins_base_targets_comes_with_the_re_run_and_settles_rpm_scale(
        suzaku):
    """
    rpm_scale's measurement fixes R_0, t_P and w_P0: the advice says how to re-run without them.

    With them held the recorded trials resolve rpm_scale (~4.6 here, from ~0.04 with them
    tuned). t_P and w_P0 alone are not enough (~0.14): under the propeller law thrust and
    resistance both go with u^2, so a tuned R_0 absorbs the k^2 -- why R_0 is in pinned_by.
    time_offset's measurement (one clock, the blade angle) settles the delay itself and pins
    no coefficient.
    """
    trials, obj, base = _two_trials(suzaku)
    effects = ['rpm_scale', 'time_offset']
    assert EFFECTS['rpm_scale'].pinned_by == ('R_0', 't_P', 'w_P0')
    assert EFFECTS['time_offset'].pinned_by == ()
    out = advise_all(suzaku, base, base.pre, obj, effects, trials, effects, [])
    per = {a['about']: a for a in out}
    rpm, toff = per['rpm_scale'], per['time_offset']
    assert rpm['degenerate'] and toff['degenerate']
    assert rpm['pinned_by'] == ['R_0', 't_P', 'w_P0']
    rest = [n for n in base.names if n not in ('R_0', 't_P', 'w_P0')]
    assert rpm['targets_pinned'] == rest and len(rest) == base.dim - 3
    assert '--targets ' + ' '.join(rest) in rpm['instruction']
    assert 'held at the measured values' in rpm['instruction'] and '--params' in rpm['instruction']
    assert EFFECTS['rpm_scale'].settle_by in rpm['instruction']
    assert 'pinned_by' not in toff and '--targets' not in toff['instruction']
    # the pin makes it settleable on the recorded trials, far from the 1 needed either way
    assert rpm['resolution_pinned'] > 2.0
    assert rpm['resolution_pinned'] > 20 * rpm['separation_recorded']
    assert rpm['resolution_pinned_trial'] >= rpm['resolution_pinned'] * (1 - 1e-9)
    assert 'these trials resolve it' in rpm['instruction']
    # without R_0 held the tuned resistance still absorbs the scale
    from mmg_tuner.diagnosis.advice import _information
    info = _information(suzaku, base, base.pre, obj, effects, trials)
    assert info.resolution(info.r_rec, 'rpm_scale', held=['t_P', 'w_P0']) < 0.5
    assert info.resolution(info.r_rec, 'rpm_scale', held=['R_0', 't_P', 'w_P0']) \
        == pytest.approx(rpm['resolution_pinned'], rel=1e-9)
    # the report repeats the re-run where it lists what no trial can settle
    from mmg_tuner.diagnosis.report import markdown
    md = markdown({'baseline': {'J_test': 1.0}, 'final': {'J_test': 0.5}, 'causes': [],
                   'candidates': [], 'advice': out,
                   'residuals': {'base_model': {'per_trial': {}, 'correlation': {}},
                                 'final_model': {'per_trial': {}}}}, suzaku)
    assert '--targets ' + ' '.join(rest) in md[md.index('## The trial that would settle it'):]


def test_a_suspected_effect_no_trial_separates_is_advised_its_measurement(suzaku):
    """
    A suspected effect no trial separates from its absence is advised its measurement.

    A suspected effect (diagnosis: the held-out trials disagree on it) comes as a rival pair,
    the model without it and with it. When no trial of the repertoire separates them (a
    0.01 deg rudder offset apart: best 0.26), the advice is the effect's own measurement (the
    rudder indicator against the blade), marked degenerate so that no trial is sailed for it
    and the joint trial does not serve it. 0.05 deg apart a trial settles it (1.3 against 0.88
    recorded): a trial, and one for it and a rival pair jointly.
    """
    trials = [generate_trial(suzaku, m, a, None, 106.0, 3.086, 200.0, 1.0, SensorNoise(),
                             i, f'{m}{a:+d}')[1]
              for i, (m, a) in enumerate([('zigzag', 10), ('turning', 20)])]
    obj = Objective(suzaku, TrialBatch.from_trials(trials), integrator='rk4')
    base = ParameterSpace.around(suzaku)
    now = suzaku.params.copy()

    def advice(offset_deg: float) -> list[dict]:
        rivals = [{'about': 'rudder_offset', 'kind': 'suspected', 'params_a': now,
                   'params_b': suzaku.with_params(
                       {'rudder_offset': math.radians(offset_deg)}).params},
                  {'about': 'yaw_moment_bias vs wind', 'kind': 'indistinguishable',
                   'params_a': now,
                   'params_b': suzaku.with_params({'yaw_moment_bias': 0.003}).params}]
        return advise_all(suzaku, base, base.pre, obj, [], trials, [], rivals, (1.0, 0.01))

    out = advice(0.01)
    per = {a['about']: a for a in out}
    s = per['rudder_offset']
    assert s['kind'] == 'suspected' and s.get('degenerate') and not s['settles']
    assert s['separation'] < 1.0
    assert s['settle_by'] == EFFECTS['rudder_offset'].settle_by == s['measure']
    assert s['instruction'].startswith('no trial separates the model with it')
    assert EFFECTS['rudder_offset'].settle_by in s['instruction']
    assert not per['yaw_moment_bias vs wind'].get('degenerate')
    assert all(a['kind'] != 'joint' for a in out)   # one trial-worthy item: nothing joint
    from mmg_tuner.diagnosis.report import markdown
    doc = {'baseline': {'J_test': 1.0}, 'final': {'J_test': 0.5}, 'causes': [],
           'candidates': [], 'advice': out,
           'suspected': [{'effect': 'rudder_offset', 'summary': 'rudder offset 1.50 deg',
                          'gain': 0.456, 'gain_se': 0.398, 'round': 2, 'beside': ['wind']}],
           'residuals': {'base_model': {'per_trial': {}, 'correlation': {}},
                         'final_model': {'per_trial': {}}}}
    md = markdown(doc, suzaku)
    assert '**Suspected, not named.**' in md
    assert '- rudder_offset: rudder offset 1.50 deg, held-out gain 45.6 % ± 39.8 % (round 2, ' \
        'beside wind)' in md
    assert EFFECTS['rudder_offset'].settle_by in md[md.index('## The trial that would'):]
    out = advice(0.05)
    per = {a['about']: a for a in out}
    assert per['rudder_offset']['settles'] and not per['rudder_offset'].get('degenerate')
    assert out[0]['kind'] == 'joint' and 'rudder_offset (suspected)' in out[0]['figures']
