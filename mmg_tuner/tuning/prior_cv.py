"""
How hard to pull the tuned coefficients toward their published values: chosen by leaving days out.

A ship config's recipe may list prior weights to choose from (``tuning.recipe.prior_choices``;
``tune --prior-choices``) instead of fixing one. The tuning trials are then split into folds of
whole **sessions** (:func:`sessions`: the date in each trial's name, e.g. the pond's
``berthing_12-Nov-2020_11_07_23``); each fold is held out once, the physics is tuned on the
others with each prior weight, and scored on the held-out trials with the paper's index
(restarts every 100 s, sigma pooled over the fold). Runs of one day share their wind, water,
trim and calibration: a cross-validation that keeps a day on both sides of the split measures
what the same day sees again, not what a new day sees (the project's three folds by position
chose prior 0, which lost random and berthing runs of other days to the published values;
``bench/esso_prior_cv_preregistration.md``).

The rule (:func:`choose_prior`), registered there before it was run:

* per candidate c (each prior weight, and the published values themselves) and kind of run k,
  I(c, k) is the mean held-out index over the kind's trials, R(c, k) = I(c, k) / I(published, k);
* a candidate's score S(c) is its worst R over the kinds (the published values score 1: the
  rule never prefers a fit that this evidence says loses some kind to where it started);
* the lowest S wins; candidates within ``TIE`` of it count as tied and the most cautious of
  them (the largest weight; the published values above all) is chosen. A candidate that fails
  on a held-out trial scores infinity.
"""
from __future__ import annotations

from dataclasses import dataclass
import datetime
import math
import re
from typing import Any, Callable, Mapping, Sequence

from mmg_tuner.errors import TuningError
import numpy as np

PUBLISHED = 'published'
"""The candidate that tunes nothing (the config's values; the most cautious)."""
TIE = 0.01
"""Scores within this of the best are tied (bench/esso_prior_cv_preregistration.md)."""
MAX_FOLDS = 6
"""At most this many folds (each a fit per prior weight): sessions are merged round-robin."""

_MONTHS = {m: i for i, m in enumerate(('jan', 'feb', 'mar', 'apr', 'may', 'jun', 'jul', 'aug',
                                       'sep', 'oct', 'nov', 'dec'), 1)}
# (day, month, year) from a match; every format becomes one date, so 12-Nov-2020 and 20201112
# are the same day
_DATES: tuple[tuple[re.Pattern[str], Callable[[re.Match[str]], tuple[int, int, int]]], ...] = (
    (re.compile(r'(?<!\d)(\d{1,2})-([A-Za-z]{3})-(\d{4})(?!\d)'),   # 12-Nov-2020 (the pond's)
     lambda m: (int(m[1]), _MONTHS.get(m[2].lower(), 0), int(m[3]))),
    (re.compile(r'(?<!\d)((?:19|20)\d{2})[-_]([01]\d)[-_]([0-3]\d)(?!\d)'),
     lambda m: (int(m[3]), int(m[2]), int(m[1]))),   # 2020-11-12, rosbag2_2020_11_12-10_..
    (re.compile(r'(?<!\d)((?:19|20)\d{2})([01]\d)([0-3]\d)(?!\d)'),   # 20201112
     lambda m: (int(m[3]), int(m[2]), int(m[1]))))


def session_date(name: str) -> str | None:
    """Return the date in a trial's name as YYYY-MM-DD (None: none that is a real date)."""
    for pattern, parts in _DATES:
        for m in pattern.finditer(name):
            day, month, year = parts(m)
            try:
                return datetime.date(year, month, day).isoformat()
            except ValueError:   # not a date (a month word that is not one, day 31 of June)
                continue
    return None


def sessions(names: Sequence[str]) -> dict[str, str]:
    """
    Return each trial's session: the date in its name when every name has one and they differ.

    Otherwise (a name without a date, or one day for all) each trial is its own session: the
    folds then leave runs out, the best that can be done without knowing the days.
    """
    found = {n: session_date(n) for n in names}
    dates = {d for d in found.values() if d is not None}
    if len(dates) >= 2 and all(d is not None for d in found.values()):
        return {n: str(d) for n, d in found.items()}
    return {n: n for n in names}


def folds(session_of: Mapping[str, str], max_folds: int = MAX_FOLDS) -> list[list[str]]:
    """Return the folds, lists of trial names: whole sessions, sorted, dealt round-robin."""
    order = sorted(set(session_of.values()))
    k = min(max_folds, len(order))
    out: list[list[str]] = [[] for _ in range(k)]
    for i, s in enumerate(order):
        out[i % k] += [n for n in session_of if session_of[n] == s]
    return out


def label(prior: float) -> str:
    """Return a candidate's name: 'prior W'."""
    return f'prior {prior:.12g}'


@dataclass
class PriorChoice:
    """
    The cross-validation behind a chosen prior weight (:func:`choose_prior`).

    by_kind[candidate][kind]: mean held-out index (None: a fit failed on a held-out trial);
    ratio[candidate][kind]: that over the published values'; score[candidate]: the worst ratio;
    chosen: the candidate's name; prior: its weight (None: the published values, nothing
    tuned); folds: the held-out trial names of each fold.
    """

    chosen: str
    prior: float | None
    by_kind: dict[str, dict[str, float | None]]
    ratio: dict[str, dict[str, float]]
    score: dict[str, float]
    folds: list[list[str]]
    note: str = ''            # why nothing was held out, if so
    simulations: int = 0      # of the fits behind the table
    wall_s: float = 0.0

    @classmethod
    def unvalidated(cls, priors: Sequence[float], fold_names: list[list[str]]
                    ) -> 'PriorChoice':
        """
        Return the choice when nothing can be held out (one session): the largest weight.

        Without evidence the most cautious fit that still tunes: the data move only what
        they pull hard on.
        """
        w = float(max(priors))
        return cls(label(w), w, {}, {}, {}, fold_names,
                   note='the trials are one session: nothing to hold out, so the largest '
                   'weight is used without cross-validation')

    def markdown(self) -> str:
        """Return the table of held-out index per kind and ratio to published (choice marked)."""
        if not self.by_kind:
            return f'{self.chosen}: {self.note}\n'
        kinds = sorted({k for v in self.by_kind.values() for k in v})
        lines = ['| candidate | ' + ' | '.join(kinds) + ' | worst ratio to published |',
                 '|---|' + '---|' * (len(kinds) + 1)]
        for name, v in self.by_kind.items():
            cells = ['failed' if v[k] is None else
                     f'{v[k]:.4g} ({self.ratio[name][k]:.2f})' for k in kinds]
            mark = ' (chosen)' if name == self.chosen else ''
            sc = self.score[name]
            lines.append(f'| {name}{mark} | ' + ' | '.join(cells)
                         + f" | {'inf' if math.isinf(sc) else f'{sc:.3f}'} |")
        return '\n'.join(lines) + '\n'

    def to_dict(self) -> dict[str, Any]:
        return {'chosen': self.chosen, 'prior': self.prior, 'index_by_kind': self.by_kind,
                'ratio_to_published': {c: {k: (None if math.isinf(x) else x)
                                           for k, x in v.items()}
                                       for c, v in self.ratio.items()},
                'score': {c: (None if math.isinf(s) else s) for c, s in self.score.items()},
                'folds': self.folds, 'tie': TIE, 'note': self.note,
                'simulations': self.simulations, 'wall_s': self.wall_s}


def choose_prior(priors: Sequence[float], held_out: Mapping[str, Mapping[str, float | None]],
                 kind_of: Mapping[str, str], fold_names: list[list[str]]) -> PriorChoice:
    """
    Apply the module's rule.

    held_out[candidate][trial]: the held-out index of each trial (None: failed), for
    ``PUBLISHED`` and each ``label(prior)``; kind_of: trial -> kind of run.
    """
    names = [PUBLISHED] + [label(w) for w in priors]
    missing = [c for c in names if c not in held_out]
    if missing:
        raise TuningError(f'choose_prior: no held-out scores for {missing}')
    trials = list(held_out[PUBLISHED])
    kinds = sorted({kind_of.get(t, t) for t in trials})
    by_kind: dict[str, dict[str, float | None]] = {}
    for c in names:
        per: dict[str, list[float | None]] = {}
        for t in trials:
            per.setdefault(kind_of.get(t, t), []).append(held_out[c].get(t))
        by_kind[c] = {k: (None if any(x is None for x in v)
                          else float(np.mean([float(x) for x in v if x is not None])))
                      for k, v in per.items()}
    pub = by_kind[PUBLISHED]
    ratio: dict[str, dict[str, float]] = {}
    for c in names:
        ratio[c] = {}
        for k in kinds:
            a, b = by_kind[c][k], pub[k]
            # (published failing where c runs: c is better; both 0: level)
            ratio[c][k] = (math.inf if a is None else 0.0 if b is None
                           else a / b if b > 0 else 1.0 if a == 0 else math.inf)
    score = {c: max(ratio[c].values()) for c in names}
    best = min(score.values())
    tied = [c for c in names if score[c] <= best + TIE]
    # the most cautious of the tied: published, then the largest weight
    caution = {PUBLISHED: math.inf, **{label(w): float(w) for w in priors}}
    chosen = max(tied, key=lambda c: caution[c])
    prior = None if chosen == PUBLISHED else float(caution[chosen])
    return PriorChoice(chosen, prior, by_kind, ratio, score, fold_names)
