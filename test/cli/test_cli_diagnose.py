"""The lines ``diagnose`` prints about the causes (cli/diagnose.py: verdict_lines)."""
from types import SimpleNamespace

from mmg_tuner.cli.diagnose import verdict_lines


def _dx(**fields):
    base = {'causes': [], 'mimicking': [], 'suspected': [], 'advice': [],
            'impossible_fits': [], 'structure': {}, 'undecided': []}
    return SimpleNamespace(**{**base, **fields})


def test_a_suspected_effect_is_printed_with_what_would_settle_it():
    """A suspect no trial separates gets its measurement; one a trial separates, the trial."""
    dx = _dx(suspected=[{'effect': 'rudder_offset', 'summary': 'rudder offset 1.4 deg',
                         'gain': 0.457, 'gain_se': 0.398},
                        {'effect': 'wind', 'summary': 'wind 8.0 m/s from 47 deg',
                         'gain': 0.30, 'gain_se': 0.25}],
             advice=[{'about': 'rudder_offset', 'kind': 'suspected', 'degenerate': True,
                      'measure': 'check the rudder indicator against the blade',
                      'instruction': 'turning circle, 35 deg to port'},
                     {'about': 'wind', 'kind': 'suspected',
                      'instruction': 'zigzag 20/20 at 127 rpm'},
                     {'about': 'wind', 'kind': 'barely identifiable',
                      'instruction': 'not this one'}])
    lines = verdict_lines(dx)
    assert lines[0].startswith('CAUSE: none found')
    assert lines[1] == ('SUSPECTED (not named): rudder offset 1.4 deg -- held-out gain 45.7 ± '
                        '39.8 %, the held-out trials disagree; to settle it: check the rudder '
                        'indicator against the blade')
    assert lines[2].endswith('the held-out trials disagree; to settle it: zigzag 20/20 at '
                             '127 rpm')
    assert len(lines) == 3


def test_a_suspect_without_advice_and_a_structural_verdict():
    """An effect the verdict did not name says why; what remains is its own line."""
    cause = SimpleNamespace(effect='wind', summary='wind 8.0 m/s from 41 deg', heldout_gain=0.776)
    dx = _dx(mimicking=[cause],
             decision=[{'effect': 'wind', 'why': 'its value fitted on each trial alone '
                        'scatters by 0.92 of its size'}],
             suspected=[{'effect': 'current', 'summary': 'current 0.1 m/s', 'gain': 0.2,
                         'gain_se': 0.3}],
             structure={'verdict': 'structure', 'summary': "60 % of the base model's "
                        'held-out error remains, STRUCTURAL'})
    assert verdict_lines(dx) == [
        'CAUSE: none named -- what the fitted effects explain is not one value over the '
        'trials, or a hull change explains it better (see NOT A CAUSE)',
        'NOT A CAUSE: wind 8.0 m/s from 41 deg fits (held-out gain 77.6 %), but its value '
        'fitted on each trial alone scatters by 0.92 of its size',
        'SUSPECTED (not named): current 0.1 m/s -- held-out gain 20.0 ± 30.0 %, the held-out '
        'trials disagree',
        "REMAINS: 60 % of the base model's held-out error remains, STRUCTURAL"]


def test_a_cause_and_a_structural_remainder_are_both_said():
    """A cause is never withdrawn because something structural remains (issue 42)."""
    current = SimpleNamespace(effect='current', summary='current 0.35 m/s toward 109 deg',
                              heldout_gain=0.959, share=0.959, measured='',
                              indistinguishable_from=[])
    dx = _dx(causes=[current], structure={
        'verdict': 'structure',
        'summary': "4 % of the base model's held-out error remains, STRUCTURAL (a force or "
                   'moment the model lacks, beside any named cause)'})
    assert verdict_lines(dx) == [
        'CAUSE: current 0.35 m/s toward 109 deg -- 96 % of the held-out error (held-out gain '
        '95.9 %)',
        "REMAINS: 4 % of the base model's held-out error remains, STRUCTURAL (a force or "
        'moment the model lacks, beside any named cause)']


def test_a_cause_as_good_as_a_rival_is_undecided_with_the_trial_that_tells_them_apart():
    """Never the first of a rival set as the CAUSE: the set, and the pair's best settling trial."""
    offset = SimpleNamespace(effect='rudder_offset', summary='rudder offset -1.3 ± 0.2 deg',
                             heldout_gain=0.912,
                             indistinguishable_from=['yaw_moment_bias', 'wind'])
    current = SimpleNamespace(effect='current', summary='current 0.3 m/s toward 84 deg',
                              heldout_gain=0.7, measured='', indistinguishable_from=[])
    pair = {'kind': 'indistinguishable', 'settles': True}
    dx = _dx(causes=[current], undecided=[offset],
             advice=[{**pair, 'about': 'rudder_offset vs yaw_moment_bias', 'separation': 1.2,
                      'instruction': 'turning circle at 127 rpm'},
                     {**pair, 'about': 'rudder_offset vs wind', 'separation': 3.0,
                      'instruction': 'zigzag 20/20 at 85 rpm'},
                     {**pair, 'about': 'rudder_offset vs prop_side_force', 'separation': 9.0,
                      'instruction': 'not a rival of this cause'}])
    assert verdict_lines(dx) == [
        'CAUSE: current 0.3 m/s toward 84 deg -- held-out gain 70.0 %',
        'UNDECIDED: one of rudder offset -1.3 ± 0.2 deg or yaw moment bias, wind -- held-out '
        'gain 91.2 %, these trials cannot tell them apart; to tell them apart: zigzag 20/20 at '
        '85 rpm']
    dx = _dx(undecided=[offset], advice=[{**pair, 'about': 'rudder_offset vs wind',
                                          'settles': False, 'separation': 0.3,
                                          'instruction': 'zigzag'}])
    assert verdict_lines(dx) == [
        'CAUSE: none named alone -- see UNDECIDED',
        'UNDECIDED: one of rudder offset -1.3 ± 0.2 deg or yaw moment bias, wind -- held-out '
        'gain 91.2 %, these trials cannot tell them apart; no trial of the repertoire tells '
        'them apart']
