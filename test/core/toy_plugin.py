"""
The toy vessel of the plugin tests: a water-jet actuator and a control-oriented family.

Written to a temporary folder and registered through the plugin environment variables
(``core/plugins.py``); used by test/core/test_plugins.py and test/ros/test_plugin_ros.py.
"""
from pathlib import Path
import textwrap

TOY_ACTUATOR = """
'''Toy water jet: thrust [N] and a nozzle angle behind a first-order lag.'''
PARAMS = ('toy_x_jet', 'toy_tau_nozzle')
INPUTS = ('jet_thrust', 'jet_angle')
CHANNELS = {'jet_thrust': ('N', 'toy jet thrust, + ahead', None, '/jet/thrust'),
            'jet_angle': ('rad', 'toy nozzle angle order, + pushes the stern to port', 0.0,
                          '/jet/angle')}
OUTPUTS = ('thrust', 'nozzle')
STATES = ('nozzle',)
DESCRIPTION = 'toy water jet (test plugin)'
# what holds the service speed and what is starboard helm, for the plausibility checks
PLAUSIBILITY = {'propulsion': ['thrust'], 'helm': {'nozzle': 'rudder'}}
# what `generate` sails for a craft it drives (the module beside this one)
TRIALS = 'toy_jet_trials'
# an effect of its own: a nozzle whose zero is off (the module beside this one)
EFFECTS = 'toy_jet_effects'
# the nozzle as a joint sim_node publishes (its angle; no rate state)
JOINTS = {'nozzle_joint': ('nozzle',)}

import math

from mmg_tuner.core.layout import OK, PARAM_INDEX
from numba import njit

_X = PARAM_INDEX['toy_x_jet']
_TAU = PARAM_INDEX['toy_tau_nozzle']
_OFF = PARAM_INDEX['toy_nozzle_offset']


@njit(inline='always')
def start(p, cmd, a, i):
    a[i] = cmd[1]


@njit(inline='always')
def hold(p, cmd, h, astern):
    return OK, (cmd[0], cmd[1], math.exp(-h / p[_TAU]))


@njit(inline='always')
def output(p, held, a, i):
    a[i] = held[1] + (a[i] - held[1]) * held[2]
    return (held[0], a[i] + p[_OFF])


@njit(inline='always')
def forces(p, u, v, r, act, k):
    T = act[k]
    Y = -T * math.sin(act[k + 1])
    return T * math.cos(act[k + 1]), Y, Y * p[_X]
"""

TOY_EFFECTS = """
'''The toy jet's effect: a nozzle angle indicator that is off.'''
import math

from mmg_tuner.core.effect import Effect, pm

EFFECTS = (
    Effect('toy_nozzle_offset', ('toy_nozzle_offset',), ('rad',),
           'constant error of the toy nozzle angle (actual = ordered + offset)',
           smallest=(math.radians(1.0),), neutral=(0.0,),
           boxes=((-math.radians(5), math.radians(5)),), periodic=(False,),
           words=lambda v, e: f"nozzle offset {pm(v, e, 'toy_nozzle_offset', 57.3, '.2f')} deg"),
)
"""

TOY_TRIALS = """
'''What `generate` sails for a toy-jet craft: two nozzle steps, noisy position and heading.'''
from dataclasses import dataclass
import math

import numpy as np
from mmg_tuner.core.noise import Sigmas
from mmg_tuner.core.simulate import simulate
from mmg_tuner.core.trial import Trial

RATE_HZ = 10.0
ASSUMPTIONS = 'a toy: no real craft behind it'


@dataclass(frozen=True)
class Noise(Sigmas):
    position_m: float = 0.05
    heading_rad: float = math.radians(0.1)

    def apply(self, trial, rng):
        st = trial.states.copy()
        st[:, 0:2] += rng.normal(0, self.position_m, (len(trial), 2))
        st[:, 2] += rng.normal(0, self.heading_rad, len(trial))
        return Trial(trial.t, st, name=trial.name, inputs=dict(trial.inputs),
                     notes=trial.notes + ['sensor noise added: ' + self.describe()])


@dataclass(frozen=True)
class Maneuver:
    name: str
    nozzle_rad: float
    role: str = 'identification'
    duration_s: float = 60.0


def catalogue(ship):
    return [Maneuver('step_port', 0.2), Maneuver('step_stbd', -0.2, 'validation')]


def generate(ship, m, rate_hz, noise, seed):
    t = np.arange(int(round(m.duration_s * rate_hz)) + 1) / rate_hz
    order = {'jet_thrust': np.full(t.size, 4000.0),
             'jet_angle': np.where(t > 10.0, m.nozzle_rad, 0.0)}
    run = simulate(ship, [0, 0, 0, 2.0, 0, 0], order, 1.0 / rate_hz, 'rk4')
    truth = Trial(run.t, run.states, name=m.name, inputs=run.inputs)
    return truth, noise.apply(truth, np.random.default_rng(seed + 1))


def tables(ship, noise, seed):
    return {}
"""

TOY_FAMILY = """
'''Toy control-oriented family: M nu_dot + D nu = tau, diagonal M and D (SI units).'''
PARAMS = ('toy_Xu', 'toy_Yv', 'toy_Nr', 'toy_x_jet', 'toy_tau_nozzle')
REQUIRED = ('rho', 'L_pp', 'B', 'd', 'm', 'I_zG') + PARAMS
DEFAULTS = {'x_G': 0.0}
ACTUATORS = ('toy_jet',)
ASTERN_RPM = True
ASTERN_SURGE = True
DESCRIPTION = 'toy control-oriented family (test plugin)'
# impossible below zero; the straight-ahead resistance probed with its own forces
PLAUSIBILITY = {'positive': ['m', 'I_zG'], 'non_negative': ['toy_Xu', 'toy_Yv', 'toy_Nr'],
                'resistance': 'probe'}

from mmg_tuner.core.layout import PARAM_INDEX
from numba import njit

_XU, _YV, _NR = (PARAM_INDEX[k] for k in ('toy_Xu', 'toy_Yv', 'toy_Nr'))
_M, _IZ = PARAM_INDEX['m'], PARAM_INDEX['I_zG']


@njit(inline='always')
def forces(p, u, v, r, act):
    return -p[_XU] * u, -p[_YV] * v, -p[_NR] * r


@njit(inline='always')
def motion(p, u, v, r, X, Y, N):
    m = p[_M]
    return X / m + v * r, Y / m - u * r, N / p[_IZ]


@njit(inline='always')
def mass_solve(p, X, Y, N):
    return X / p[_M], Y / p[_M], N / p[_IZ]
"""

TOY_SHIP_YAML = """
name: toy
model: toy_family
particulars: {rho: 1025.0, L_pp: 10.0, B: 3.0, d: 1.0, m: 20000.0, I_zG: 150000.0,
              toy_Xu: 2000.0, toy_Yv: 8000.0, toy_Nr: 60000.0, toy_x_jet: -5.0,
              toy_tau_nozzle: 2.0}
tuning: {targets: [toy_Xu, toy_Yv, toy_Nr]}
"""


def toy_plugin_env(folder: Path) -> dict:
    """Write the toy plugin package into ``folder``; return the environment that registers it."""
    pkg = folder / 'toyplug'
    pkg.mkdir(exist_ok=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'toy_jet.py').write_text(textwrap.dedent(TOY_ACTUATOR))
    (pkg / 'toy_family.py').write_text(textwrap.dedent(TOY_FAMILY))
    (pkg / 'toy_jet_trials.py').write_text(textwrap.dedent(TOY_TRIALS))
    (pkg / 'toy_jet_effects.py').write_text(textwrap.dedent(TOY_EFFECTS))
    return {'PYTHONPATH': str(folder), 'MMG_TUNER_FAMILIES': 'toyplug.toy_family',
            'MMG_TUNER_ACTUATORS': 'toyplug.toy_jet'}
