"""
The one objective factory: (ship, trials, spec) -> what CMA-ES minimises.

Whole trials, or pieces of ``segment_s`` seconds, each starting from its measured sample;
per-sample, per-trial or per-group balance; a prior toward the pre-determined values; error
weights; restarts every ``shoot_every_s``. The API's ``tune``, the commands and every
benchmark build their objective here.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.objective import Objective, paper_weights, Prior, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.report import unique_names
from mmg_tuner.tuning.segments import segment_weights, split_trials
import numpy as np


@dataclass(frozen=True)
class ObjectiveSpec:
    """
    How trials become the objective.

    weights: six error weights on x, y, psi, u, v, r (None: the paper's L, L, pi/4, 0, 0, 0);
    shoot_every_s: restart from the measured state every H s (0: never); integrator, substeps:
    the simulation; segment_s: cut the trials into pieces of this length [s] (0: whole
    trials); balance: 'sample', 'trial' or 'group' (with group_of: trial name -> group);
    prior: pull toward the pre-determined values of the tuned parameters, in J per sample per
    unit squared box-scaled distance (0: none; needs the parameter space); x0_window_s: the
    start-state fit window [s] (None: 0 for pieces, which start from their measured sample,
    else 10 s).
    """

    weights: tuple[float, ...] | None = None
    shoot_every_s: float = 0.0
    integrator: str = 'euler'
    substeps: int = 1
    segment_s: float = 0.0
    balance: str = 'sample'
    prior: float = 0.0
    group_of: Mapping[str, str] | None = None
    x0_window_s: float | None = None

    @property
    def plain(self) -> 'ObjectiveSpec':
        """Return the same objective on whole trials, samples alike, no prior (for J)."""
        return replace(self, segment_s=0.0, balance='sample', prior=0.0, group_of=None,
                       x0_window_s=None)


def make_objective(ship: ShipConfig, trials: Sequence[Trial], spec: ObjectiveSpec | None = None,
                   space: ParameterSpace | None = None) -> Objective:
    """Return the objective of ``spec`` on ``trials`` (``space``: needed for a prior)."""
    spec = spec or ObjectiveSpec()
    trials = list(trials)
    if not trials:
        raise TuningError('no trials to build the objective from')
    weights = (np.asarray(spec.weights, dtype=float) if spec.weights is not None
               else paper_weights(ship.L_pp))
    whole = not spec.segment_s and spec.balance == 'sample' and not spec.prior
    if whole:
        x0_window = 10.0 if spec.x0_window_s is None else spec.x0_window_s
        return Objective(ship, TrialBatch.from_trials(trials, x0_window_s=x0_window), weights,
                         spec.shoot_every_s, spec.integrator, spec.substeps)
    segs = split_trials([replace(t, name=n) for t, n in zip(trials, unique_names(trials))],
                        spec.segment_s)
    # a piece starts from its measured sample, as the evaluation index's restarts do
    x0_window = ((0.0 if spec.segment_s else 10.0) if spec.x0_window_s is None
                 else spec.x0_window_s)
    batch = TrialBatch.from_trials([s.trial for s in segs], x0_window_s=x0_window)
    prior = None
    if spec.prior:
        if space is None:
            raise TuningError('a prior needs the parameter space (the tuned names and boxes)')
        samples = float(batch.lengths.sum() - len(segs))
        prior = Prior(space.indices, space.pre, space.upper - space.lower, spec.prior * samples)
    return Objective(ship, batch, weights, spec.shoot_every_s, spec.integrator, spec.substeps,
                     trial_weights=segment_weights(segs, spec.balance, spec.group_of),
                     prior=prior)
