"""
Multiple shooting at the data level: trials cut into segments, and weights that balance them.

The evaluation index (Wakita et al. 2022, eq. 26) restarts every simulation from the measured
state every N s; a tuning objective that matches it simulates the same pieces. Cutting the
trials themselves into sub-trials (rather than restarting inside one long run) lets each piece
carry its own weight, so that a long run does not outweigh a short one and a kind of manoeuvre
with few samples (berthing) is not drowned by one with many (random, turning):

    >>> segs = split_trials(trials, segment_s=100.0)
    >>> w = segment_weights(segs, group_of={t.name: kind[t.name] for t in trials})
    >>> obj = Objective(ship, TrialBatch.from_trials([s.trial for s in segs]), weights,
    ...                 trial_weights=w)

Consecutive segments share their boundary sample (one ends where the next starts, from the
measured state there), so every recorded transition is scored exactly once.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
import numpy as np

BALANCE = ('sample', 'trial', 'group')
"""How segment weights share the objective: every sample alike, every trial alike (its samples
share the trial's weight), or every group alike (e.g. manoeuvre kind; trials alike within)."""


@dataclass(frozen=True)
class Segment:
    """One piece of a trial: the sub-trial and where it came from."""

    trial: Trial          # the piece, its own first sample the measured starting state
    parent: str           # name of the trial it was cut from
    start: int            # index of its first sample in the parent

    @property
    def transitions(self) -> int:
        """Scored steps (samples after the first)."""
        return len(self.trial) - 1


def split_trial(trial: Trial, segment_s: float, min_s: float | None = None) -> list[Segment]:
    """
    Cut one trial into pieces of segment_s seconds (0: the whole trial as one piece).

    A tail shorter than min_s (default: half a segment) joins the piece before it, so no piece
    is too short to say anything about the dynamics. Names are '<trial>@<start s>'.
    """
    if not segment_s >= 0:
        raise TuningError(f'segment length must be >= 0 s, got {segment_s!r}')
    T = len(trial)
    if T < 2:
        raise TuningError(f'trial {trial.name}: fewer than 2 samples, nothing to segment')
    if segment_s == 0:
        return [Segment(trial, trial.name, 0)]
    K = max(1, int(round(segment_s / trial.dt)))
    min_k = max(1, int(round((0.5 * segment_s if min_s is None else min_s) / trial.dt)))
    starts = list(range(0, T - 1, K))
    if len(starts) > 1 and (T - 1) - starts[-1] < min_k:
        starts.pop()
    out = []
    for i, a in enumerate(starts):
        b = starts[i + 1] if i + 1 < len(starts) else T - 1
        out.append(Segment(_piece(trial, a, b + 1), trial.name, a))
    return out


def _piece(trial: Trial, a: int, b: int) -> Trial:
    """Make samples a..b-1 a trial of their own (time kept, name tagged with the start)."""
    # every input channel by name (a twin-azimuth trial has no rpm/rudder pair)
    return replace(trial, t=trial.t[a:b], states=trial.states[a:b],
                   inputs={n: v[a:b] for n, v in trial.inputs.items()},
                   notes=list(trial.notes), name=f'{trial.name}@{trial.t[a] - trial.t[0]:.0f}s')


def split_trials(trials: Sequence[Trial], segment_s: float, min_s: float | None = None
                 ) -> list[Segment]:
    """:func:`split_trial` for each trial, in order."""
    names = [t.name for t in trials]
    if len(set(names)) != len(names):
        raise TuningError('trial names must be unique to segment them (segments refer to '
                          'their trial by name)')
    return [s for t in trials for s in split_trial(t, segment_s, min_s)]


def segment_weights(segments: Sequence[Segment], balance: str = 'trial',
                    group_of: Mapping[str, str] | None = None) -> np.ndarray:
    """
    Weight per segment (M,), scaled so that the mean weight per scored sample is 1.

    balance 'sample': all 1 (a long trial counts in proportion to its length); 'trial': every
    trial the same total; 'group': every group (group_of maps trial name -> group, e.g. the
    manoeuvre kind) the same total, its trials alike within it. With the mean per-sample weight
    1, the weighted J divided by the number of samples stays an index-like mean.
    """
    if balance not in BALANCE:
        raise TuningError(f'balance must be one of {list(BALANCE)}, got {balance!r}')
    if not segments:
        raise TuningError('no segments to weigh')
    n = np.array([s.transitions for s in segments], dtype=float)
    if balance == 'sample':
        return np.ones(len(segments))
    per_trial: dict[str, float] = {}
    for s in segments:
        per_trial[s.parent] = per_trial.get(s.parent, 0.0) + s.transitions
    if balance == 'trial':
        share = {p: 1.0 / len(per_trial) for p in per_trial}
    else:
        if group_of is None:
            raise TuningError("balance 'group' needs group_of (trial name -> group)")
        missing = sorted(p for p in per_trial if p not in group_of)
        if missing:
            raise TuningError(f'no group given for trial(s) {missing}')
        groups: dict[str, list[str]] = {}
        for p in per_trial:
            groups.setdefault(group_of[p], []).append(p)
        share = {p: 1.0 / (len(groups) * len(ps)) for ps in groups.values() for p in ps}
    w = np.array([share[s.parent] / per_trial[s.parent] for s in segments])
    weights: np.ndarray = w * n.sum() / float(np.sum(w * n))
    return weights
