"""
Which model to recommend: the candidates compared on validation trials, per kind of run.

``tune --model auto`` (and ``mt.tune(..., model='auto')``) trains the candidates a user's data
supports (the tuned physics; the pure network and the hybrid when JAX is there and the data
are enough) and recommends one by this rule (bench/esso_fresh_preregistration.md):

* each candidate is scored with the paper's index (:func:`~mmg_tuner.tuning.evaluate.evaluate`,
  restarts every ``restart_every_s``, sigma pooled over all the validation trials, the same
  sigma for every candidate);
* per kind of run (``groups``: trial name -> kind; default each trial its own kind) the mean
  index over the kind's trials;
* a candidate's score is its worst ratio over the kinds to the best candidate of that kind
  (1.0: best on every kind); a candidate that fails on any trial scores infinity;
* the lowest score wins; a tie goes to the simpler model, in the order the candidates are
  given (physics first).

Why the worst kind and not the mean: the goal is a model that is not far from the best on
any kind of manoeuvre the user sails, not one that trades a kind away for another.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, cast, Mapping, Sequence

from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.learn.model import Model
from mmg_tuner.tuning.evaluate import evaluate, pooled_sigma
from mmg_tuner.tuning.report import unique_names
import numpy as np


@dataclass
class Choice:
    """
    The comparison of :func:`choose_model`.

    by_kind[candidate][kind]: mean index over the kind's validation trials (None: failed);
    score[candidate]: worst ratio over the kinds to the best of the kind; chosen: the name.
    """

    chosen: str
    by_kind: dict[str, dict[str, float | None]]
    score: dict[str, float]
    trials: dict[str, str] = field(default_factory=dict)   # validation trial -> kind

    def markdown(self) -> str:
        """Return the table of the candidates per kind (the recommended one marked)."""
        kinds = sorted({k for v in self.by_kind.values() for k in v})
        lines = ['| candidate | ' + ' | '.join(kinds) + ' | worst ratio to the best |',
                 '|---|' + '---|' * (len(kinds) + 1)]
        for name, v in self.by_kind.items():
            cells = ['failed' if v[k] is None else f'{v[k]:.4g}' for k in kinds]
            mark = ' (recommended)' if name == self.chosen else ''
            sc = self.score[name]
            lines.append(f'| {name}{mark} | ' + ' | '.join(cells)
                         + f" | {'inf' if math.isinf(sc) else f'{sc:.3f}'} |")
        return '\n'.join(lines) + '\n'

    def to_dict(self) -> dict[str, Any]:
        return {'chosen': self.chosen, 'index_by_kind': self.by_kind,
                'score': {k: (None if math.isinf(v) else v) for k, v in self.score.items()},
                'validation_trials': dict(self.trials)}


def choose_model(candidates: Mapping[str, ShipConfig | Model], trials: Sequence[Trial],
                 groups: Mapping[str, str] | None = None, restart_every_s: float = 100.0,
                 integrator: str = 'rk4') -> Choice:
    """Return the recommended candidate and the table behind it (see the module docstring)."""
    trials = list(trials)
    if not candidates or not trials:
        raise TuningError('choose_model: needs at least one candidate and one validation trial')
    names = unique_names(trials)
    kind = {n: (groups or {}).get(t.name, n) for n, t in zip(names, trials)}
    sig = pooled_sigma(trials)
    by_kind: dict[str, dict[str, float | None]] = {}
    for cname, model in candidates.items():
        res = evaluate(model, trials, restart_every_s, integrator, sigma=sig)
        per: dict[str, list[float | None]] = {}
        for n in names:
            per.setdefault(kind[n], []).append(res.trials[n].index)
        # (the mean is taken where no index is None)
        by_kind[cname] = {k: (None if any(x is None for x in v)
                              else float(np.mean(cast(list[float], v))))
                          for k, v in per.items()}
    kinds = sorted(set(kind.values()))
    # (a kind's index cast to float where it is checked not None)
    best = {k: min((cast(float, v[k]) for v in by_kind.values() if v[k] is not None),
                   default=None)
            for k in kinds}
    score = {}
    for cname, v in by_kind.items():
        if any(v[k] is None or best[k] is None for k in kinds):
            score[cname] = math.inf
            continue
        # (no None among them, as just checked)
        vk, bk = cast(dict[str, float], v), cast(dict[str, float], best)
        score[cname] = max((vk[k] / bk[k]) if bk[k] > 0 else
                           (1.0 if vk[k] == 0 else math.inf) for k in kinds)
    chosen = min(candidates, key=lambda c: score[c])   # min keeps the first of a tie
    if math.isinf(score[chosen]):
        raise TuningError('choose_model: every candidate failed on a validation trial ('
                          + ', '.join(f'{c}: {[k for k in kinds if by_kind[c][k] is None]}'
                                      for c in candidates) + ')')
    return Choice(chosen, by_kind, score, kind)
