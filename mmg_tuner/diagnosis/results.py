"""
What a diagnosis returns: the candidates of each round, the named causes, the whole result.

Moved from ``select.py`` unchanged.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
import math
from typing import Any

from mmg_tuner.core.effects import describe_values, EFFECTS
from mmg_tuner.diagnosis.context import Setting
from mmg_tuner.diagnosis.settings import MEASURED


@dataclass
class Candidate:
    effect: str
    J_test: float
    per_trial_gain: list[float]
    gain: float
    gain_se: float
    accepted: bool
    values: dict[str, float]
    screen_drop: float = 0.0
    on_bound: list[str] = field(default_factory=list)
    J_ref: float = math.nan          # held-out J of the model it is compared with
    impossible: str = ''             # why it cannot exist in this setting ('' if it can)
    diverged: str = ''               # 'diverged on trial X at t = ...' ('' if it did not)
    significant: bool = False        # passed the acceptance rule (named only if also possible,
    #                                  not on a bound and not too small)
    implausible: str = ''            # why the fit is implausible for the ship (plausible.py)
    inconsistent: str = ''           # why it is not one value for all trials, or makes a
    #                                  held-out trial clearly worse ('' if neither)
    # fitted on each held-out
    per_trial_estimates: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class Cause:
    """
    A named cause.

    The effect, its estimated parameters (SI, radians) with Gauss-Newton standard errors, and the
    held-out gain (1 - J_test(with it) / J_test(without)) with its jackknife standard error over
    test trials. A measured signal used as a cause (e.g. ``measured_wind``) has no parameters.
    ``measured``: the source of the measurement that sized it, when the trials could not (its
    values and errors are then the measurement's, held in every model; '' when the trials
    sized it).
    """

    effect: str
    parameters: dict[str, float]
    uncertainty: dict[str, float]
    heldout_gain: float
    heldout_gain_se: float
    indistinguishable_from: list[str] = field(default_factory=list)
    description: str = ''
    measured: str = ''
    share: float | None = None    # of the base model's held-out error it explains (decide.py)

    @property
    def summary(self) -> str:
        """
        Human wording, e.g.

        'current 0.30 ± 0.0013 m/s toward 115 ± 0.54 deg'.
        """
        if self.effect in MEASURED:
            return self.effect.replace('_', ' ') + ' used'
        return describe_values(EFFECTS[self.effect], self.parameters, self.uncertainty)

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), 'summary': self.summary}


def split_undecided(causes: list[Cause]) -> tuple[list[Cause], list[Cause]]:
    """
    Return (named, undecided): a cause the trials cannot tell from a rival is not named.

    A cause with ``indistinguishable_from`` won its round by less than the combined uncertainty
    of its and a rival's held-out gains: the trials say "one of these", not which. Naming the
    first member was a false cause whenever the truth was a rival (seeds 3-5 of
    bench/bench_diagnosis.py: a rudder offset named as a yaw moment bias, twice the offset
    beside a current named as a propeller side force), and a false cause is worse than a missed
    one. It stays in the fitted model (it explains the trials as well as its rivals do); the
    verdict names the set, with the trial that would separate them (the advice's rival pairs).
    A rival that is itself a cause of the final model is no rival any more (both are needed:
    the backward step kept each), so only rivals outside it count, and only they are listed.
    """
    fitted = {c.effect for c in causes}
    out = [replace(c, indistinguishable_from=[r for r in c.indistinguishable_from
                                              if r not in fitted]) for c in causes]
    return ([c for c in out if not c.indistinguishable_from],
            [c for c in out if c.indistinguishable_from])


@dataclass
class Diagnosis:
    causes: list[Cause]
    baseline: dict[str, Any]
    final: dict[str, Any]
    rounds: list[list[Candidate]] = field(default_factory=list)
    params: dict[str, float] = field(default_factory=dict)
    base_params: dict[str, float] = field(default_factory=dict)
    wall_s: float = 0.0
    aliased: dict[str, dict[str, Any]] = field(default_factory=dict)
    setting: Setting = field(default_factory=Setting)
    impossible: dict[str, str] = field(default_factory=dict)   # effect -> why, this setting
    # significant but impossible
    impossible_fits: list[dict[str, Any]] = field(default_factory=list)
    measured: list[dict[str, Any]] = field(default_factory=list)  # measured signals: with/without
    timings_s: dict[str, float] = field(default_factory=dict)  # wall time per stage
    measured_wind_used: bool = False     # the final model is driven by the measured wind
    advice: list[dict[str, Any]] = field(default_factory=list)  # see diagnosis/advice.py
    # the sensor noise estimated from the held-out recordings and the held-out J it alone
    # leaves with the base model (diagnosis/noise.py): {'sigma': {state: sd}, 'J', 'J_se', ...}
    noise: dict[str, Any] = field(default_factory=dict)
    # effects the last round hints at but cannot name (select._suspects): {effect, values,
    # gain, gain_se, round, summary, beside}; never causes, each with an advised trial
    suspected: list[dict[str, Any]] = field(default_factory=list)
