"""
A new kind of vessel is new files only: a toy family and a toy actuator from test code.

The toy is a control-oriented model (its own mass matrix and linear damping, no MMG
formulas) driven by a water-jet-like actuator with its own input channels, internal state (a
nozzle angle behind a first-order lag) and forces. Both live in a temporary folder, are
registered through the plugin environment variables (``core/plugins.py``) and never touch
``mmg_tuner/core``; the subprocess then loads a ship of the family, simulates it, checks the
physics the toy defines, tunes two of its coefficients back from a simulated trial, sails the
catalogue its actuator declares with the ``generate`` command, writes its recordings to
rosbag2 and reads them back, inspects them, and runs the ``tune`` and ``diagnose`` commands
on them (a hidden current is named).
"""
from pathlib import Path
import subprocess
import sys

from toy_plugin import toy_plugin_env, TOY_SHIP_YAML

SCRIPT = """
import math
import os
import numpy as np
import mmg_tuner as mt
from mmg_tuner.core.models import family, REGISTRY
from mmg_tuner.core.ship import ship_from_dict
from mmg_tuner.core.simulate import simulate
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import SimulationError

assert REGISTRY[-1] == 'toy_family', REGISTRY
fam = family('toy_family')
assert fam.channels == ('jet_thrust', 'jet_angle', 'wind_n', 'wind_e'), fam.channels
ship = ship_from_dict({'name': 'toy', 'model': 'toy_family', 'particulars': {
    'rho': 1025.0, 'L_pp': 10.0, 'B': 3.0, 'd': 1.0, 'm': 20000.0, 'I_zG': 150000.0,
    'toy_Xu': 2000.0, 'toy_Yv': 8000.0, 'toy_Nr': 60000.0, 'toy_x_jet': -5.0,
    'toy_tau_nozzle': 2.0},
    'tuning': {'targets': ['toy_Xu', 'toy_Nr']}})

# straight ahead: the surge speed settles where thrust = X_u u
T = 1201
run = simulate(ship, [0, 0, 0, 0.0, 0, 0], {'jet_thrust': np.full(T, 4000.0)}, 0.1, 'rk4')
assert run.ok and abs(run.states[-1, 3] - 2.0) < 1e-3, run.states[-1]
# a nozzle step turns it; the lag state makes the first second's yaw rate smaller
t = np.arange(T) * 0.1
cmd = {'jet_thrust': np.full(T, 4000.0), 'jet_angle': np.where(t > 10, 0.2, 0.0)}
turn = simulate(ship, [0, 0, 0, 2.0, 0, 0], cmd, 0.1, 'rk4')
assert turn.ok and turn.states[-1, 5] > 0.01, turn.states[-1]
fast = simulate(ship.with_params({'toy_tau_nozzle': 0.01}), [0, 0, 0, 2.0, 0, 0], cmd, 0.1,
                'rk4')
k = int(11.0 / 0.1)
assert 0 < turn.states[k, 5] < 0.8 * fast.states[k, 5], (turn.states[k], fast.states[k])
# the toy jet's own effect (EFFECTS module beside it) joins the table and the layout, acts in
# its kernel: a nozzle offset turns the craft with the nozzle ordered straight
from mmg_tuner.core.effects import EFFECTS
assert EFFECTS['toy_nozzle_offset'].actuator == 'toy_jet', EFFECTS['toy_nozzle_offset']
straight = {'jet_thrust': np.full(T, 4000.0)}
off = simulate(ship.with_params({'toy_nozzle_offset': 0.05}), [0, 0, 0, 2.0, 0, 0], straight,
               0.1, 'rk4')
assert off.ok and off.states[-1, 5] > 0.005 and abs(run.states[-1, 5]) < 1e-9, off.states[-1]
# a trial without the required channel is refused, naming it
try:
    simulate(ship, [0, 0, 0, 2.0, 0, 0], {'jet_angle': np.zeros(T)}, 0.1)
    raise AssertionError('no error for a missing channel')
except SimulationError as exc:
    assert "'jet_thrust'" in str(exc), exc

# the plausibility checks from the plugin's own PLAUSIBILITY declarations: the toy passes;
# a negative damping is impossible, a nozzle ahead of the centre turns the wrong way
from mmg_tuner.core.plausibility import check_model
assert check_model(ship) == [], check_model(ship)
bad = check_model(ship.with_params({'toy_Yv': -8000.0}))
assert bad and all(isinstance(f.what, str) for f in bad), bad
assert any('toy_Yv' in f.text for f in bad if f.level == 'error')
wrong = check_model(ship.with_params({'toy_x_jet': 5.0}))
assert [f.what for f in wrong] == ['turn direction'], wrong
# a plugin author's misspelt name is an error naming the module, not a KeyError deep in a
# command (a coefficient) or a check silently switched off (an actuator output)
from mmg_tuner.core.actuators import actuator
from mmg_tuner.errors import ConfigError
for owner, typo, name in ((fam, {'signs': {'toy_Yvv': -1}}, 'toy_Yvv'),
                          (actuator('toy_jet'), {'helm': {'nozle': 'rudder'}}, 'nozle')):
    good = owner.plausibility
    object.__setattr__(owner, 'plausibility', dict(good, **typo))
    try:
        check_model(ship)
        raise AssertionError(f'no error for {name}')
    except ConfigError as exc:
        assert name in str(exc) and 'toyplug' in str(exc) and 'PLAUSIBILITY' in str(exc), exc
    object.__setattr__(owner, 'plausibility', good)
assert check_model(ship) == []
# tuning through the plugin: two coefficients back from a simulated trial
truth = ship.with_params({'toy_Xu': 2600.0, 'toy_Nr': 45000.0})
rec = simulate(truth, [0, 0, 0, 2.0, 0, 0], cmd, 0.1, 'rk4')
trial = Trial(rec.t, rec.states, inputs=rec.inputs, name='toy_turn')
res = mt.tune(ship, [trial], config=mt.TuneConfig(max_evals=1500, integrator='rk4', seed=1))
print(res.params)
assert abs(res.params['toy_Xu'] / 2600.0 - 1) < 0.02, res.params
assert abs(res.params['toy_Nr'] / 45000.0 - 1) < 0.02, res.params

# the generate command sails the catalogue the toy actuator declares (TRIALS): channel CSVs
# the data layer reads back, with the toy's noise, listed by role in trials.yaml
import io, contextlib, yaml
from mmg_tuner.cli.generate import command as generate
open('toy.yaml', 'w').write(TOY_SHIP_YAML)
with contextlib.redirect_stdout(io.StringIO()):
    assert generate(['--ship', 'toy.yaml', '--out', 'gen']) == 0
listing = yaml.safe_load(open('gen/trials.yaml'))
assert listing['identification'] == ['step_port'] and listing['validation'] == ['step_stbd']
assert listing['rate_hz'] == 10.0 and listing['noise']['position_m'] == 0.05, listing
from mmg_tuner.data.load import load_trials
(gen,) = load_trials('gen/csv/step_port.csv')
assert len(gen) == 601 and np.ptp(gen.inputs['jet_angle']) > 0.19, gen
assert 0.01 < np.std(gen.states[:100, 1]) < 0.2   # the toy's position noise (0.05 m) is in

# the data layer from the channel table: the toy's channels have topic-map sections (the
# angle in degrees here) and go through a rosbag2 and back
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.topics import topic_map_from_dict
tm = topic_map_from_dict({'jet_angle': {'topic': '/nozzle_deg', 'unit': 'deg'},
                          'resample': {'dt': 0.1}})
assert tm.topic('jet_thrust') == '/jet/thrust'
assert abs(tm.factor('jet_angle') - math.pi / 180) < 1e-15
write_trial_bag(trial, 'toy_bag', tm=tm)
(back,) = load_trials('toy_bag', tm)
assert set(back.inputs) >= {'jet_thrust', 'jet_angle'}, back.inputs
k = min(len(back), len(trial))
for ch in ('jet_thrust', 'jet_angle'):
    assert np.allclose(back.inputs[ch][:k], trial.inputs[ch][:k], atol=1e-6), ch
assert np.allclose(back.states[:k, 3:], trial.states[:k, 3:], atol=1e-3)
try:   # a recording without the required channel names it and its topic
    load_trials('toy_bag', topic_map_from_dict({
        'jet_thrust': {'topic': '/nothing'}, 'jet_angle': {'topic': '/nozzle_deg', 'unit': 'deg'},
        'resample': {'dt': 0.1}}))
    raise AssertionError('no error for a missing channel topic')
except Exception as exc:
    assert "'jet_thrust'" in str(exc) and '/nothing' in str(exc), exc

# inspect reads the toy's recording with the same map and the ship's YAML
from mmg_tuner.cli.inspect import command as inspect
open('toy_map.yaml', 'w').write('{jet_angle: {topic: /nozzle_deg, unit: deg}, '
                                'resample: {dt: 0.1}}')
buf = io.StringIO()
with contextlib.redirect_stdout(buf):
    rc = inspect(['toy_bag', '--topics', 'toy_map.yaml', '--ship', 'toy.yaml'])
assert rc == 0, (rc, buf.getvalue())
assert 'jet_thrust' in buf.getvalue() or 'toy_bag' in buf.getvalue(), buf.getvalue()

# the commands a user runs on the toy's recordings: tune, then diagnose four runs in a
# hidden 0.3 m/s current (two held out); the current is found and named
import json
from mmg_tuner.cli.diagnose import command as diagnose
from mmg_tuner.cli.tune import command as tune
drift = truth.with_params({'current_speed': 0.3, 'current_dir': 2.0})
for i, a in enumerate((0.2, -0.2, 0.15, -0.1)):
    order = {'jet_thrust': np.full(T, 4000.0),
             'jet_angle': np.where(t > 10, a, 0.0) * np.sign(np.sin(t / (12 + 4 * i)))}
    run = simulate(drift, [0, 0, 0, 2.0, 0, 0], order, 0.1, 'rk4')
    write_trial_bag(Trial(run.t, run.states, inputs=run.inputs, name=f'run{i}'),
                    f'runs/run{i}', tm=tm)
with contextlib.redirect_stdout(io.StringIO()):
    assert tune(['runs/run0', 'runs/run1', '--topics', 'toy_map.yaml', '--ship', 'toy.yaml',
                 '--out', 'tuned', '--no-plots']) == 0
    assert diagnose(['runs/run0', 'runs/run1', '--test', 'runs/run2', 'runs/run3',
                     '--topics', 'toy_map.yaml', '--ship', 'toy.yaml', '--out', 'dx',
                     '--budget', 'quick', '--effects', 'current', 'antenna_offset',
                     '--max-effects', '1', '--no-plots', '--quiet']) == 0
assert os.path.isfile('tuned/params.yaml')
dx = json.load(open('dx/diagnosis.json'))
assert [c['effect'] for c in dx['causes']] == ['current'], dx['causes']
assert abs(dx['causes'][0]['parameters']['current_speed'] - 0.3) < 0.06, dx['causes']
print('TOY OK')
"""


def test_a_toy_family_and_actuator_from_test_code_simulate_and_tune(tmp_path):
    repo = Path(__file__).resolve().parents[2]
    env = {'PATH': '/usr/bin:/bin', 'HOME': str(tmp_path),
           'NUMBA_CACHE_DIR': str(tmp_path / 'cache'), **toy_plugin_env(tmp_path)}
    env['PYTHONPATH'] += f':{repo}'
    script = f'TOY_SHIP_YAML = {TOY_SHIP_YAML!r}\n' + SCRIPT
    out = subprocess.run([sys.executable, '-c', script], env=env, cwd=tmp_path,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0 and 'TOY OK' in out.stdout, out.stdout + out.stderr[-4000:]
    assert not list((repo / 'mmg_tuner' / 'core').rglob('toy_*')), 'the toy must stay outside core'
