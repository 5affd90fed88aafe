"""
How good is a model on recorded trials.

Simulate each trial driven by its recorded inputs (and measured wind), restarting from the measured
state every N seconds, and score it with the error index of Wakita et al. (2022, J. Mar. Sci.
Technol. 27, eq. 26; the NN-identification paper of the Esso Osaka data):

    index = 1 / T sum_k sum_i ((s_i,k - s^_i,k) / sigma_i)^2,   i in (x, u, y, v, psi, r)

the mean squared error of the standardised state vector: the squared errors of the six states,
each standardised by its standard deviation sigma_i *pooled over all the evaluated trials
together* (one sigma per state for the whole set, so indices of different trials compare),
summed over the states and averaged over the samples. (The paper's text does not show the
equation; summed over the states is the reading under which the published captive-test MMG
scores on our held-out runs in the range of the paper's Table 9 for it, e.g. random 0.24-1.2
here against 0.272 there, turning 0.9-2.8 against 0.858; averaged over the states would put
every figure six times lower. The paper's test runs are not in the data set.)

The paper restarts long runs every 100 s from the measured state "to avoid the accumulation
of error"; so does :func:`evaluate` (``restart_every_s``, 0: never). The heading error is
wrapped to [-pi, pi].

With ``horizons`` it also scores the n-step prediction (restart from the measured state at
every sample, predict n steps: RMSE of u, v, r, x, y, psi per horizon) and the free-running
relative errors ||y_model - y|| / ||y|| of u, v, r (the MBPE-LOGO paper's Table 5 measure):
``tuning/nstep.py``.

Outputs (:meth:`EvaluateResult.write`): ``evaluate.json``
``{"trials": {"<name>": {"index": ..., "rms": {"x": ..., ...}}}, ...}`` (with horizons also
``"n_step"`` and ``"relative_error"``), ``evaluate.md`` and one overlay plot per trial (states
recorded vs model, rudder and rpm beside them), plus ``evaluate_nstep.png`` with horizons.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from pathlib import Path
from typing import Any, cast, Sequence

from mmg_tuner._outdir import OutputDir
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.learn.model import as_model, Model
from mmg_tuner.learn.residual import simulate_segments
from mmg_tuner.tuning.nstep import (check_horizons, nstep_errors, nstep_figure, NSTEP_STATES,
                                    NStepScore, REL_STATES, relative_errors, RelativeErrors)
from mmg_tuner.tuning.plots import png_bytes, trial_figure, trial_title
from mmg_tuner.tuning.report import file_stems, json_text, unique_names
import numpy as np

INDEX_STATES = ('x', 'u', 'y', 'v', 'psi', 'r')
"""The six states of the paper's index, in its order."""
UNITS = {'x': 'm', 'y': 'm', 'psi': 'rad', 'u': 'm/s', 'v': 'm/s', 'r': 'rad/s'}
_COL = {n: STATE_NAMES.index(n) for n in INDEX_STATES}


def predict(model: ShipConfig | Model, trial: Trial, restart_every_s: float = 100.0,
            integrator: str = 'rk4', substeps: int = 1, params: np.ndarray | None = None
            ) -> tuple[np.ndarray, float | None, str]:
    """
    Return the model's states (T, 6) for a recorded trial.

    Restarted from the measured state at t = 0, N, 2N, ... s (N = restart_every_s; 0: only at the
    start), driven by the recorded inputs (rpm, rudder, measured wind, thrusters) held per sample;
    a model with a residual network (``Model.residual``) runs as the hybrid (or the pure
    network).
    Returns (states, time of the first failure [s from the trial's start] or None, its reason); a
    segment that failed is NaN from the failure to the next restart.
    """
    ship, net = as_model(model).ship, as_model(model).residual
    if net is not None:  # a hybrid (or pure network) from the params.yaml
        states, _, fail_t, why = simulate_segments(ship, net, trial, integrator,
                                                   float(restart_every_s or 0.0), substeps,
                                                   params)
        return states, fail_t, why
    inputs = trial.input_array(ship.family.channels)
    out = np.full((len(trial), 6), np.nan)
    fail_t, why = None, ''
    for a, b in trial.segments(restart_every_s):
        if b - a < 2:  # a one-sample tail: the restart itself
            out[a] = trial.states[a]
            continue
        run = simulate(ship, trial.states[a], inputs[a:b], trial.dt, integrator, substeps,
                       params=params, check=False)
        out[a:b] = run.states
        if not run.ok and fail_t is None:
            fail_t = float(trial.t[a] - trial.t[0] + run.fail_time_s)
            why = run.status
    return out, fail_t, why


def pooled_sigma(trials: Sequence[Trial]) -> dict[str, float]:
    """Return standard deviation of each index state over all samples of all trials together."""
    st = np.concatenate([t.states for t in trials])
    sig = {n: float(np.std(st[:, _COL[n]])) for n in INDEX_STATES}
    flat = [n for n, s in sig.items() if not s > 0]
    if flat:
        raise TuningError(f'the evaluated trials never vary in {flat}: the index standardises '
                          'each state by its standard deviation over all trials, which is 0')
    return sig


def errors(pred: np.ndarray, meas: np.ndarray) -> np.ndarray:
    """Model minus measurement (T, 6), heading wrapped to [-pi, pi]."""
    e: np.ndarray = pred - meas
    k = STATE_NAMES.index('psi')
    e[:, k] = (e[:, k] + math.pi) % (2 * math.pi) - math.pi
    return e


def index_of(err: np.ndarray, sigma: dict[str, float]) -> float:
    """
    Return the paper's index of an error history (T, 6).

    The squared standardised errors summed over the six states, averaged over the samples (NaN if
    any error is NaN).
    """
    z = np.column_stack([err[:, _COL[n]] / sigma[n] for n in INDEX_STATES])
    return float(np.mean(np.sum(z * z, axis=1)))


@dataclass
class TrialScore:
    """
    One trial's index, RMS errors and failure, with the restarted simulation.

    One trial: the paper's index, the RMS error of each state [SI, psi rad], and where the model
    failed (None: it did not); ``predicted`` holds the restarted simulation.
    """

    name: str
    index: float | None
    rms: dict[str, float | None]
    failed_at_s: float | None
    failure: str
    predicted: np.ndarray = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {'index': self.index, 'rms': dict(self.rms)}
        if self.failed_at_s is not None:
            d['failed_at_s'] = self.failed_at_s
            d['failure'] = self.failure
        return d


@dataclass
class EvaluateResult:
    """What :func:`evaluate` measured: per trial scores, the pooled sigmas, the settings."""

    trials: dict[str, TrialScore]
    sigma: dict[str, float]
    index_all: float | None              # the index over every sample of every trial
    restart_every_s: float
    integrator: str
    substeps: int
    model: Model = field(repr=False)
    recorded: list[Trial] = field(repr=False, default_factory=list)
    # share of samples inside the model's prediction interval (tuning/interval.py), if any
    coverage: dict[str, Any] | None = None
    nstep: NStepScore | None = None          # with horizons: over all trials
    nstep_per_trial: dict[str, NStepScore] = field(default_factory=dict)
    relative: RelativeErrors | None = None   # with horizons: free-run Table 5 errors

    @property
    def ship(self) -> ShipConfig:
        return self.model.ship

    def to_dict(self) -> dict[str, Any]:
        """evaluate.json's content."""
        return {'ship': self.ship.name, 'model': self.ship.model,
                'simulated_as': self.model.kind,
                'index': 'Wakita et al. 2022 eq. 26: mean over samples of the sum over the '
                         'states x, u, y, v, psi, r of ((model - measured) / sigma)^2, sigma '
                         'pooled over all evaluated trials',
                'restart_every_s': self.restart_every_s, 'integrator': self.integrator,
                'substeps': self.substeps, 'sigma': dict(self.sigma),
                'index_all': self.index_all, 'coverage': self.coverage,
                'trials': {n: s.to_dict() for n, s in self.trials.items()},
                **self._nstep_dict()}

    def _nstep_dict(self) -> dict[str, Any]:
        if self.nstep is None:
            return {}
        d: dict[str, Any] = {
            'n_step': {'definition': 'restart from the measured state at every sample, '
                                     'predict n steps with the measured inputs; RMSE of '
                                     'each state at step n [SI units, psi rad wrapped]',
                       **self.nstep.to_dict(),
                       'per_trial': {n: s.to_dict()['rmse']
                                     for n, s in self.nstep_per_trial.items()}}}
        if self.relative is not None:
            d['relative_error'] = self.relative.to_dict()
        return d

    def markdown(self) -> str:
        lines = [f'# evaluate: {self.ship.name} ({self.ship.model}, {self.model.kind})', '',
                 f'Restart from the measured state every {self.restart_every_s:g} s '
                 f'({self.integrator}, {self.substeps} substep(s)); index = Wakita et al. '
                 '(2022) eq. 26 with sigma pooled over these trials.', '',
                 '| trial | index | ' + ' | '.join(
                     f'rms {n} [{UNITS[n]}]' for n in INDEX_STATES) + ' |',
                 '|---|---' + '|---' * len(INDEX_STATES) + '|']
        for n, s in self.trials.items():
            idx = 'failed' if s.index is None else f'{s.index:.4g}'
            rms = ' | '.join('-' if s.rms[k] is None else f'{s.rms[k]:.4g}'
                             for k in INDEX_STATES)
            lines.append(f'| {n} | {idx} | {rms} |')
        if self.index_all is not None:
            lines += ['', f'All trials together: index {self.index_all:.4g}.']
        c = self.coverage
        if c is not None:
            lines += ['', f'Prediction interval (nominal {100 * c["level"]:.0f} %): '
                      f'{100 * c["all"]:.1f} % of the samples inside (' + ', '.join(
                          f'{n} {100 * x:.0f} %' for n, x in c['states'].items()) + ').']
        for n, s in self.trials.items():
            if s.failed_at_s is not None:
                lines.append(f'- {n}: the model failed at t = {s.failed_at_s:.2f} s '
                             f'({s.failure}); its index is not given.')
        if self.nstep is not None:
            lines += ['', nstep_markdown(self.nstep, self.relative)]
        return '\n'.join(lines) + '\n'

    def plots(self) -> dict[str, bytes]:
        """{file name: PNG}: per trial, states recorded vs model and the inputs beside them."""
        images = {}
        every = self.restart_every_s
        stems = file_stems(list(self.trials))
        for tr, (name, s), stem in zip(self.recorded, self.trials.items(), stems):
            # where predict() restarted from the measurement
            restarts = tr.t[[a for a, _ in tr.segments(every)][1:]]
            how = (f'restarted from the measured state every {every:g} s' if every
                   else 'one run from the start')
            title = trial_title(name, how, {'model': s.index},
                                error_name='index (Wakita 2022 eq. 26, lower is better)')
            fig = trial_figure(tr, {'model': s.predicted}, title,
                               states=('x', 'y', 'psi', 'r', 'u', 'v'), restarts_s=restarts)
            images[f'evaluate_{stem}.png'] = png_bytes(fig)
        if self.nstep is not None:
            scores = {'all trials': self.nstep}
            if 1 < len(self.nstep_per_trial) <= 6:   # more lines would be unreadable
                scores.update(self.nstep_per_trial)
            images['evaluate_nstep.png'] = png_bytes(nstep_figure(
                scores, f'{self.ship.name}: n-step prediction from the measured state at '
                        f'every sample ({self.integrator})'))
        return images

    def write(self, out: str | Path | OutputDir, plots: bool = True) -> list[Path]:
        """
        evaluate.md, the plots, and evaluate.json last (its presence means the set is complete).

        ``out``: a new or empty folder, or an open :class:`OutputDir`.
        """
        own = not isinstance(out, OutputDir)
        # (own: out is a path, else the open OutputDir; mypy does not narrow through own)
        od = OutputDir.open(cast('str | Path', out)) if own else cast(OutputDir, out)
        try:
            paths = [od.write_text('evaluate.md', self.markdown())]
            if plots:
                paths += [od.write_bytes(n, b) for n, b in self.plots().items()]
            paths.append(od.write_text('evaluate.json', json_text(self.to_dict())))
        finally:
            if own:
                od.close()
        return paths


def nstep_markdown(score: NStepScore, rel: RelativeErrors | None) -> str:
    """Return the n-step RMSE table (and the free-run relative errors) as Markdown."""
    lines = ['## n-step prediction (restart from the measured state at every sample)', '',
             '| n | t [s] | windows | failed | ' + ' | '.join(
                 f'RMSE {s} [{UNITS[s]}]' for s in NSTEP_STATES) + ' |',
             '|---|---|---|---' + '|---' * len(NSTEP_STATES) + '|']
    for i, h in enumerate(score.horizons):
        vals = ' | '.join('-' if score.rmse[s][i] is None else f'{score.rmse[s][i]:.4g}'
                          for s in NSTEP_STATES)
        lines.append(f'| {h} | {h * score.dt:g} | {score.windows[i]} | {score.failed[i]} | '
                     f'{vals} |')
    if rel is not None:
        lines += ['', '## Free-run relative errors ||y_model - y|| / ||y|| (MBPE-LOGO Table 5)',
                  '', '| trial | ' + ' | '.join(REL_STATES) + ' |',
                  '|---' + '|---' * len(REL_STATES) + '|']
        for n, v in [('all trials (pooled)', rel.pooled)] + list(rel.per_trial.items()):
            # (an error cast to float where it is checked not None)
            lines.append(f'| {n} | ' + ' | '.join(
                '-' if v[s] is None else f'{100 * cast(float, v[s]):.3g} %' for s in REL_STATES)
                + ' |')
        for n, t in rel.failed.items():
            lines.append(f'- {n}: the free run failed at t = {t:.2f} s.')
    return '\n'.join(lines)


def evaluate(model: ShipConfig | Model, trials: Sequence[Trial], restart_every_s: float = 100.0,
             integrator: str = 'rk4', substeps: int = 1, params: np.ndarray | None = None,
             sigma: dict[str, float] | None = None, horizons: Sequence[int] | None = None
             ) -> EvaluateResult:
    """
    Score a model on recorded trials.

    A ship, a ship with a residual network, or the parameter vector ``params``.

    (see the module docstring). ``sigma``: the standardising deviations to use (default: pooled
    over these trials, as the paper does). ``horizons`` [steps]: also the n-step prediction
    RMSE at these horizons and the free-run relative errors (``tuning/nstep.py``; a residual
    network restarts with its history window holding the measured samples before each window).
    """
    model = as_model(model)
    if horizons is not None:
        horizons = check_horizons(horizons)
    trials = list(trials)
    if not trials:
        raise TuningError('evaluate: no trials given')
    for tr in trials:
        if len(tr) < 2:
            raise TuningError(f'evaluate: trial {tr.name} has fewer than 2 samples')
    sig = pooled_sigma(trials) if sigma is None else dict(sigma)
    scores: dict[str, TrialScore] = {}
    all_err = []
    for tr, name in zip(trials, unique_names(trials)):
        pred, fail_t, why = predict(model, tr, restart_every_s, integrator, substeps, params)
        err = errors(pred, tr.states)
        ok = fail_t is None and bool(np.all(np.isfinite(err)))
        rms = {n: (float(np.sqrt(np.mean(err[:, _COL[n]] ** 2))) if ok else None)
               for n in INDEX_STATES}
        scores[name] = TrialScore(name, index_of(err, sig) if ok else None, rms, fail_t, why,
                                  pred)
        all_err.append(err)
    every = np.concatenate(all_err)
    index_all = index_of(every, sig) if np.all(np.isfinite(every)) else None
    res = EvaluateResult(scores, sig, index_all, float(restart_every_s), integrator,
                         int(substeps), model, trials)
    if horizons is not None:
        names = list(scores)
        renamed = [t if t.name == n else replace(t, name=n) for t, n in zip(trials, names)]
        res.nstep, per = nstep_errors(model, renamed, horizons, integrator, substeps, params)
        res.nstep_per_trial = per
        runs = [s.predicted if not restart_every_s else
                predict(model, tr, 0.0, integrator, substeps, params)[0]
                for tr, s in zip(trials, scores.values())]
        res.relative = relative_errors(names, trials, runs)
    return res


def compare_index(physics: ShipConfig | Model, model: ShipConfig | Model,
                  trials: Sequence[Trial],
                  restart_every_s: float = 100.0, integrator: str = 'rk4') -> dict[str, Any]:
    """
    Return the index over all ``trials`` of two models with one pooled sigma.

    E.g. the tuned physics and the same with a residual network. Returns {'physics': index,
    'model': index, 'gain': 1 - model / physics} (None where a model failed).
    """
    sig = pooled_sigma(trials)
    a = evaluate(physics, trials, restart_every_s, integrator, sigma=sig).index_all
    b = evaluate(model, trials, restart_every_s, integrator, sigma=sig).index_all
    gain = None if a is None or b is None or not a > 0 else 1.0 - b / a
    return {'physics': a, 'model': b, 'gain': gain}
