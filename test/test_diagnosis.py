"""The diagnosis must find an effect hidden in generated data, and name nothing on clean data.
Small trials and budgets keep this part of the suite to a couple of minutes; the full-size
runs belong in the benchmark."""
import json
import math

import numpy as np
import pytest

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.data.generate import SensorNoise, generate_trial
from mmg_tuner.diagnosis import DiagnosisSettings, diagnose
from mmg_tuner.tuning import ParameterSpace

SPECS = [('turning', 35, None), ('turning', -25, None), ('zigzag', 20, None), ('random', 30, None),
         ('zigzag', -15, None), ('turning', -35, None), ('random', 25, None), ('zigzag', 10, None)]
QUICK = dict(base_evals=6000, screen_evals=300, effect_evals=3000, screen=3, max_effects=2)


def hidden(suzaku, effect: dict, seed: int = 3):
    """Trials of SUZAKU with the 12 targets moved inside the box and an effect hidden."""
    space = ParameterSpace.around(suzaku)
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-0.3, 0.3, space.dim)
    truth = suzaku.with_params({**dict(zip(space.names, theta)), **effect})
    trials = [generate_trial(truth, m, a, c, 106.0, 3.086, 300.0, 1.0, SensorNoise(),
                             10 + i, f'{m}{a:+d}')[1] for i, (m, a, c) in enumerate(SPECS)]
    return trials[::2], trials[1::2]


def run(suzaku, effect):
    tune, test = hidden(suzaku, effect)
    return diagnose(suzaku, tune, test, DiagnosisSettings(**QUICK), log=lambda m: None)


def test_clean_data_names_nothing(suzaku):
    d = run(suzaku, {})
    assert d.causes == []
    assert d.final['J_test'] == d.baseline['J_test'] or d.final['heldout_gain_total'] < 0.3


def test_finds_a_hidden_rudder_offset(suzaku):
    d = run(suzaku, {'rudder_offset': math.radians(2.0)})
    assert [c['effect'] for c in d.causes] == ['rudder_offset']
    c = d.causes[0]
    assert math.degrees(c['parameters']['rudder_offset']) == pytest.approx(2.0, abs=0.75)
    assert c['heldout_gain'] > 0.5


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
