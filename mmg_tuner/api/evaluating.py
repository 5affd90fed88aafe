"""Simulate a recorded trial and score models on held-out trials."""
from __future__ import annotations

from dataclasses import dataclass
import logging
from typing import Any, Sequence

from mmg_tuner.api._common import _as_list, _check, _config, _finite, _is_int
from mmg_tuner.core.layout import INTEGRATORS
from mmg_tuner.core.plausibility import refuse_impossible, warn_once
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.learn.model import as_model, Model
from mmg_tuner.learn.plausibility import warn_network_once
from mmg_tuner.learn.residual import ResidualNet
from mmg_tuner.learn.residual import simulate_hybrid as _simulate_hybrid
from mmg_tuner.tuning.evaluate import evaluate as _evaluate
from mmg_tuner.tuning.evaluate import EvaluateResult
from mmg_tuner.tuning.interval import coverage, model_interval
from mmg_tuner.tuning.nstep import MAX_HORIZON
from mmg_tuner.tuning.report import simulate_recorded


logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split


def simulate(model: ShipConfig | Model, trial: Trial, *, integrator: str = 'rk4',
             substeps: int = 1) -> Trial:
    """
    Return the model's prediction of a recorded trial (a ship, or a ship and its network).

    As a :class:`Trial` on the same time grid (compare ``run.states`` with ``trial.states`` sample
    by sample). It starts from the state the tuning objective uses (a quadratic fit over the first
    10 s) and is driven by the recorded rpm, rudder, measured wind and thrusters. A run that
    diverges or leaves the model's range has NaN states from then on and a note saying when and
    why.
    """
    _check('integrator', integrator, integrator in INTEGRATORS, f'one of {sorted(INTEGRATORS)}')
    _check('substeps', substeps, _is_int(substeps) and 1 <= substeps <= 1000,
           'a whole number in [1, 1000]')
    ship, net = _checked(model, 'simulate')
    if net is not None:  # a hybrid (or pure network) named by the params.yaml
        return _simulate_hybrid(ship, net, trial, integrator=integrator, substeps=substeps)
    traj = simulate_recorded(ship, trial, None, integrator, substeps)
    notes = [f'simulated by mmg_tuner ({ship.name}, {integrator}, {substeps} substep(s)) from '
             'the fitted start state']
    if not traj.ok:
        msg = (f'the simulation stopped at t = {traj.fail_time_s:.2f} s: {traj.status}; '
               'states are NaN from there')
        notes.append(msg)
        logger.warning('%s: %s', trial.name, msg)
    # every input channel by name (a twin-azimuth trial has no rpm/rudder pair)
    return Trial(trial.t.copy(), traj.states, name=trial.name,
                 source=f'simulated: {trial.source or trial.name}', notes=notes,
                 start_s=trial.start_s, inputs={n: v.copy() for n, v in trial.inputs.items()})


def _checked(model: ShipConfig | Model, entry: str
             ) -> tuple[ShipConfig, ResidualNet | None]:
    """
    Refuse a model that cannot be a ship; warn once on an implausible one; return (ship, net).

    The API's own entry check (``ship.with_params`` in memory never passed ``load_ship``): one
    ConfigError line for an impossible model (``core/plausibility.refuse_impossible``: a mass
    <= 0, a singular mass matrix ...), each implausible finding of the physics and of its
    network (full rudder each way: ``learn/plausibility.py``) a ``WARNING:`` line, once per
    model. Never inside a tuner's objective.
    """
    m = as_model(model)
    where = f'{m.ship.name}, as given to {entry}'   # its values may be in memory only
    refuse_impossible(m.ship, where)
    warn_once(m.ship, where)
    warn_network_once(m.ship, m.residual, where)
    return m.ship, m.residual


@dataclass(frozen=True)
class EvaluateConfig:
    """
    Options of :func:`evaluate` (the ``evaluate`` command's flags), validated on creation.

    restart_every_s: restart each simulation from the measured state every N s (Wakita et al.
    2022 use 100 s; 0: never); integrator, substeps: as for simulate; horizons: n-step
    prediction horizons [samples] (e.g. (1, 5, 10, 20, 30, 40, 50), the MBPE-LOGO paper's):
    also the n-step RMSE and the free-run relative errors (``tuning/nstep.py``; None: not).
    """

    restart_every_s: float = 100.0
    integrator: str = 'rk4'
    substeps: int = 1
    horizons: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        _check('restart_every_s', self.restart_every_s,
               _finite(self.restart_every_s) and self.restart_every_s >= 0,
               'a finite number >= 0 [s] (0: never)')
        _check('integrator', self.integrator, self.integrator in INTEGRATORS,
               f'one of {sorted(INTEGRATORS)}')
        _check('substeps', self.substeps, _is_int(self.substeps) and 1 <= self.substeps <= 1000,
               'a whole number in [1, 1000]')
        if self.horizons is not None:
            _check('horizons', self.horizons, isinstance(self.horizons, (list, tuple)) and len(
                self.horizons) > 0 and all(_is_int(h) and 1 <= h <= MAX_HORIZON
                                           for h in self.horizons),
                   f'a non-empty list of whole numbers of steps in [1, {MAX_HORIZON}]')
            object.__setattr__(self, 'horizons', tuple(sorted(set(self.horizons))))


def evaluate(ship: ShipConfig | Model, trials: Trial | Sequence[Trial],
             config: EvaluateConfig | None = None, **options: Any) -> 'EvaluateResult':
    """
    How good ``ship``'s model is on recorded ``trials``.

    Each is simulated with its recorded inputs (and measured wind), restarting from the measured
    state every ``restart_every_s`` s, and scored per trial by the RMS error of each state and the
    index of Wakita et al. (2022) eq. 26 (standardised by deviations pooled over all the trials).
    ``options`` are :class:`EvaluateConfig` fields. ``result.write(out)`` writes evaluate.json,
    evaluate.md and the plots. A model whose ensemble network carries a calibrated prediction
    interval (``tune --model auto`` or ``--residual-seeds N``, N >= 2) also gets
    ``result.coverage``: the share of samples inside its interval (``tuning/interval.py``).

    Examples
    --------
    >>> ship = mt.load_ship('esso_osaka_3m')
    >>> trials = mt.load_trials(['data/esso_osaka_frt/berthing'], ship=ship)
    >>> res = mt.evaluate(ship, trials, restart_every_s=100)
    >>> {n: s.index for n, s in res.trials.items()}

    """
    cfg = _config(EvaluateConfig, config, options)
    trials = _as_list(trials)
    _checked(ship, 'evaluate')
    res = _evaluate(ship, trials, cfg.restart_every_s, cfg.integrator, cfg.substeps,
                    horizons=cfg.horizons)
    interval = model_interval(as_model(ship))
    if interval is not None:   # an ensemble with a calibrated interval: does it hold here?
        res.coverage = coverage(interval, trials, cfg.restart_every_s, cfg.integrator)
    return res
