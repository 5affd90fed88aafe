"""The lines ``diagnose`` prints about the causes (cli/diagnose.py: verdict_lines)."""
from types import SimpleNamespace

from mmg_tuner.cli.diagnose import verdict_lines


def _dx(**fields):
    base = {'causes': [], 'mimicking': [], 'suspected': [], 'advice': [],
            'impossible_fits': [], 'structure': {}}
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
    cause = SimpleNamespace(summary='wind 8.0 m/s from 41 deg', heldout_gain=0.776)
    dx = _dx(mimicking=[cause],
             suspected=[{'effect': 'current', 'summary': 'current 0.1 m/s', 'gain': 0.2,
                         'gain_se': 0.3}],
             structure={'verdict': 'structure', 'summary': 'the model STRUCTURE'})
    assert verdict_lines(dx) == [
        'CAUSE: none named -- the model structure is the likely cause (see STRUCTURE)',
        'MIMICS THE STRUCTURAL GAP (not a cause): wind 8.0 m/s from 41 deg -- held-out gain '
        '77.6 %',
        'SUSPECTED (not named): current 0.1 m/s -- held-out gain 20.0 ± 30.0 %, the held-out '
        'trials disagree',
        'STRUCTURE: the model STRUCTURE']
