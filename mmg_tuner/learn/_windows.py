"""
Training windows: the recorded trials cut into short simulations (NumPy only).

Each window starts from a measured state at sample k0 (turned into the model's state), holds
the network's measured history before it, the inputs, actuators and wind of the H samples it
simulates and the measured (observed) states it is compared with.
"""
from __future__ import annotations

from dataclasses import dataclass

from mmg_tuner.core.correction import N_FEATURES
from mmg_tuner.core.integrate import actuator_outputs
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import Trial
from mmg_tuner.learn.residual import sample_winds, trial_rows
import numpy as np


@dataclass
class TrialArrays:
    """
    One trial as the training reads it.

    Feature rows (T, n_features), model states (T, 6), observed states (T, 6), the actuator
    tuples (T, n: ``Family.outputs``, e.g. n_P [rev/s], actual rudder [rad], thrusters
    [rev/s]) and wind (T, 2: speed [m/s], direction it blows from [rad]).
    """

    name: str
    rows: np.ndarray
    model_states: np.ndarray
    observed: np.ndarray
    act: np.ndarray
    wind: np.ndarray


def prepare(ship: ShipConfig, trial: Trial, physics_input: bool = False) -> TrialArrays:
    """
    Return the arrays of one trial, with the inputs as the kernels apply them.

    The ship's actuators, one step per sample (their effects included: rpm scale, rudder
    offset, steering-gear lag); measured wind held when missing; physics_input: the rows end
    with the physics' accelerations (``residual.trial_rows``).
    """
    rows, ms = trial_rows(ship, trial, physics_input)
    T = len(trial)
    ctrl = np.ascontiguousarray(trial.input_array(ship.family.channels))
    act = np.empty((T, len(ship.family.outputs)))
    actuator_outputs(ship.kind, ship.params, ctrl, T, float(trial.dt), act)
    wind = sample_winds(ship, trial)
    return TrialArrays(trial.name, rows, ms, np.asarray(trial.states, float), act, wind)


@dataclass
class Windows:
    """
    N windows of H steps.

    x0 (N, 6) model states, hist (N, W-1, NF) feature rows before, inp (N, H, 4) rpm,
    rudder, bow, stern for the features, act (N, H, 4), wind (N, H, 2), target (N, H, 6)
    measured observed states after each step.
    """

    x0: np.ndarray
    hist: np.ndarray
    inp: np.ndarray
    act: np.ndarray
    wind: np.ndarray
    target: np.ndarray

    def __len__(self) -> int:
        n: int = self.x0.shape[0]
        return n

    def take(self, idx: np.ndarray) -> 'Windows':
        return Windows(*(a[idx] for a in (self.x0, self.hist, self.inp, self.act, self.wind,
                                          self.target)))


def starts(T: int, window: int, horizon: int, stride: int) -> list[int]:
    """First samples of the windows of one trial (each needs window-1 samples of history)."""
    return list(range(window - 1, T - horizon, stride))


def cut(arrs: list[TrialArrays], window: int, horizon: int, stride: int) -> Windows:
    """All windows of the trials, in trial order."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ('x0', 'hist', 'inp', 'act', 'wind',
                                                          'target')}
    for a in arrs:
        for k0 in starts(a.rows.shape[0], window, horizon, stride):
            parts['x0'].append(a.model_states[k0])
            parts['hist'].append(a.rows[k0 - window + 1:k0])
            parts['inp'].append(a.rows[k0:k0 + horizon, 3:7])
            parts['act'].append(a.act[k0:k0 + horizon])
            parts['wind'].append(a.wind[k0:k0 + horizon])
            parts['target'].append(a.observed[k0 + 1:k0 + horizon + 1])
    if not parts['x0']:
        nf = arrs[0].rows.shape[1] if arrs else N_FEATURES
        return Windows(np.zeros((0, 6)), np.zeros((0, window - 1, nf)),
                       np.zeros((0, horizon, 4)),
                       np.zeros((0, horizon, arrs[0].act.shape[1] if arrs else 2)),
                       np.zeros((0, horizon, 2)), np.zeros((0, horizon, 6)))
    return Windows(*(np.ascontiguousarray(np.stack(parts[k]), dtype=float)
                     for k in ('x0', 'hist', 'inp', 'act', 'wind', 'target')))
