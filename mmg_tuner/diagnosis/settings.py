"""
Settings of the diagnosis: budgets, re-tune methods, measured signals as candidates.

Moved from ``select.py`` unchanged; the search is :func:`mmg_tuner.diagnosis.select.diagnose`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable, Mapping, Sequence, TypeVar

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.diagnosis.context import Setting


T = TypeVar('T')
R = TypeVar('R')
MapFn = Callable[[Callable[[T], R], Sequence[T]], list[R]]

# evaluations: base tuning, screening per candidate, re-tune per candidate
BUDGETS = {
    'quick': (6_000, 300, 3_000),
    'standard': (20_000, 400, 6_000),
    'full': (60_000, 800, 15_000),
}
RETUNE_METHODS = ('lsq', 'cmaes')
# measured signals that can drive the model, as candidates: {name: (effect it measures, text)}
MEASURED = {'measured_wind': ('wind', "the measured wind drives the model (the family's wind "
                                      'loads from the recorded true wind, sample by sample)')}


@dataclass
class DiagnosisSettings:
    targets: Sequence[str] | None = None     # base targets (default: the ship's)
    a_r: float | None = None
    effects: Sequence[str] = tuple(EFFECTS)
    integrator: str = 'rk4'
    base_evals: int = 20_000
    screen_evals: int = 400
    effect_evals: int = 6_000
    screen: int = 4
    max_effects: int = 3
    min_gain: float = 0.10
    param_penalty: float = 0.02
    # and the reduction must be this fraction of the base model's held-out error: below it
    # lies what no effect explains (discretisation, the noise's own drift)
    min_abs_gain: float = 0.05
    # a real effect helps where it shows and hurts nowhere: no test trial may get worse by more
    # than the factor 1 + worse_tol ...
    worse_tol: float = 0.5
    # ... with an increase of its J above this fraction of the reference's total held-out J.
    # A ratio alone is brittle on real data: a piece the model happens to fit almost exactly
    # (tiny J) can get 10x worse by a negligible amount. An absolute share rather than the
    # jackknife SE: the SE grows with the spread a wrong effect causes, so it would excuse the
    # very worsening the veto is for; the share equals min_abs_gain, the smallest reduction
    # counted as evidence for an effect, so a smaller increase is no evidence against one.
    worse_abs: float = 0.05
    # the gain must also exceed this many jackknife standard errors (the spread over trials)
    min_gain_z: float = 1.0
    # the evidence verdict's search: a candidate is accepted by its held-out test alone (the
    # gain above min_gain_z standard errors, no trial clearly worse), without the fixed sizes
    # min_gain, param_penalty, min_abs_gain and noise_margin: the verdict weighs each effect
    # on its own evidence after the search, and a sized rule refused a rudder offset of 1.6 deg
    # beside a current (held-out gain 6.0 +- 2.1 %, 0.2 % of the base error)
    held_out_test_only: bool = False
    # an effect parameter this close to a bound (fraction of the box width) is suspect
    bound_tol: float = 0.01
    seed: int = 0
    # the base tune (CMA-ES, the paper's method) stops on stagnation rather than spending the
    # tune command's full IPOP budget: one run from population base_popsize (IPOP doubling up
    # to base_max_popsize), over when the generation's best improved by less than base_rtol
    # for the Tuner's patience, then a local least-squares polish of at most base_polish
    # simulations. On the benchmark's cases this reaches the full budget's J (within 0.1 %)
    # in a quarter of the time; every candidate is re-tuned from it anyway.
    base_popsize: int = 12
    base_max_popsize: int = 12
    base_rtol: float = 1e-3
    base_polish: int = 600
    # re-tunes: 'lsq' (local bounded least squares, warm-started) or 'cmaes' (as the base)
    retune: str = 'lsq'
    # where the trials were recorded (None: the ship YAML's setting:, else the trial files')
    setting: Setting | None = None
    # a measured wind is a candidate (True) or always drives the model (False)
    measured_signals: bool = True
    # advise the trial that would separate each barely identifiable effect and rival pair
    advice: bool = True
    # a reduction of the held-out J above this many noise floors (diagnosis/noise.py: the mean
    # held-out J noise alone leaves) is evidence whatever its share of the base error, and
    # never noise-fitting: held-out, an effect fitted to noise gains nothing (on clean data
    # every candidate's held-out gain is negative)
    noise_margin: float = 0.5
    # a held-out trial this much worse (J ratio - 1), by more than its noise floor, vetoes a
    # cause (a wrong effect helps some trials and hurts others: +18 %, -24 %, +27 % ...)
    clearly_worse: float = 0.2
    # when effects compete (significant, none acceptable alone): fit the pairs of the top
    # `pairs` screened candidates jointly (0 or 1: never)
    pairs: int = 3
    # measured coefficients {name: diagnosis.measured.Measurement(value, se)}: priors of every
    # tuning with their standard errors (never fixed values; diagnosis/measured.py)
    measurements: Mapping[str, object] = field(default_factory=dict)
    # every tuning and held-out judgement of the diagnosis restarts the simulation from the
    # recorded state every this many seconds (0: one free run per trial; restart_period)
    restart_every_s: float = 0.0


RESTART_FROUDE = 40.0
"""The evidence verdict's restart period, in units of sqrt(L_pp / g) (SUZAKU, 83 m: 116 s)."""


def restart_period(L_pp_m: float) -> float:
    """
    Return the restart period [s] of the evidence verdict: RESTART_FROUDE sqrt(L_pp / g).

    A free run of several hundred seconds is ruled by how its start was read: a heading 0.2 deg
    off moves the end of a 400 s run by metres, so sensor noise alone leaves a held-out error
    that hides a 20 m antenna offset or an 8 m/s wind (bench_diagnosis_mismatch, zero mismatch:
    noise alone left 1.0e7 of a base model's 1.7e7). Restarting from the recorded state every
    period (multiple shooting: the prediction error over a horizon, not the simulation error
    over the whole run) keeps what a missing force does within one period -- about four ship
    lengths sailed, longer than a turn's yaw time constant -- and drops the drift of the start.
    Froude-scaled, so a model-scale ship gets the same horizon in ship lengths (Esso Osaka, 3 m:
    22 s). 20 (two ship lengths) was set before the first registered benchmark
    (bench/bench_diagnosis_mismatch_preregistration.md); 40 since the registration of seeds
    700-701 (bench/bench_diagnosis_mismatch_preregistration_700.md): on the seen seeds 500-501
    and 600-601 (realistic level, 44 cases) a rudder offset or a steering lag, which builds up
    over a run, showed within 116 s and not within 58 s (singles 15 -> 18 of 20, pairs 2 -> 4.5
    of 12, false causes 4 -> 3 of 44).
    """
    return RESTART_FROUDE * math.sqrt(L_pp_m / 9.80665)
