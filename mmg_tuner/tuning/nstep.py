"""
n-step prediction and the free-running relative errors: the yardstick of a control model.

An MPC predicts a few seconds ahead from the state it measures now, again at every sample; what
matters is how far off an n-step prediction is, for the n the controller uses. The MBPE-LOGO
paper (arXiv 2312.05644, sec. 5) validates its tug model this way (n = 1 ... 50 at 5 Hz) and by
the relative errors of a free run (its Table 5). Both work for every family:

* :func:`nstep_errors`: from *every* sample k of a trial, restart from the measured state,
  drive the model n_max steps with the measured inputs, and compare the prediction n steps on
  with the measurement at k + n. All the windows of all trials run as one batch through the
  core's compiled kernel (``core.simulate.simulate_batch``: one window = one trajectory), so no
  Python loop integrates anything. RMSE per state (x, y, psi wrapped, u, v, r) per horizon.
* :func:`relative_errors`: the free run (one simulation from the first measured state),
  ||y_model - y||_2 / ||y||_2 of u, v, r per trial and pooled over all trials (the sums of
  squares added before the ratio, so a straight run whose v and r are ~0 does not blow the
  figure up: per trial it is given too, as it is).

The actuators restart with every window from the inputs at its first sample
(``actuate_start``), as they do at every restart of a simulation.

A learned model (``learn.Model`` with a residual network: hybrid or pure network) is scored
the same way: every window restarts from the measured state, and the network's history
window holds the *measured* feature rows of the samples before it (as ``evaluate``'s restarts
do; before a trial's first sample it is padded with that sample's row). Its windows run one
by one through the residual's compiled kernel (``learn.residual.simulate_hybrid_one``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, cast, Sequence, TYPE_CHECKING

from mmg_tuner.core.dynamics import family_tag
from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code, simulate_batch
from mmg_tuner.core.trial import common_dt
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.learn.model import Model
from mmg_tuner.learn.residual import simulate_hybrid_one, trial_rows
import numpy as np

if TYPE_CHECKING:   # annotations only: matplotlib is imported where a figure is drawn
    from matplotlib.figure import Figure
    from mmg_tuner.learn.residual import ResidualNet

NSTEP_STATES = ('u', 'v', 'r', 'x', 'y', 'psi')
"""States scored by the n-step RMSE, in the order the reports list them."""
REL_STATES = ('u', 'v', 'r')
"""States of the paper's Table 5 relative errors."""
PAPER_HORIZONS = (1, 5, 10, 20, 30, 40, 50)
"""Horizons [samples] of the paper's n-step figures (5 Hz: 0.2 s to 10 s)."""
MAX_HORIZON = 100_000
_CHUNK = 4096   # windows per compiled call: bounds the memory of one batch (~4096 x 51 x 6)
_PSI = STATE_NAMES.index('psi')


def check_horizons(horizons: Sequence[int]) -> tuple[int, ...]:
    """Return the horizons sorted and unique, or a TuningError naming the bad one."""
    hs = list(horizons)
    if not hs:
        raise TuningError('horizons: give at least one horizon (steps ahead, e.g. 1 5 10)')
    for h in hs:
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) \
                or not 1 <= h <= MAX_HORIZON:
            raise TuningError(f'horizons: {h!r} is not a whole number of steps in '
                              f'[1, {MAX_HORIZON}]')
    return tuple(sorted({int(h) for h in hs}))


@dataclass
class NStepScore:
    """
    n-step prediction errors of one set of trials.

    horizons [samples]; rmse[state][i]: RMSE at horizons[i] (SI units, psi rad, wrapped) over
    every window that reaches that far (None: no window does, or every one failed);
    windows[i]: how many windows were scored at horizons[i]; failed[i]: how many windows
    failed (diverged, left the family's range, or grew too large to square) before horizons[i]
    (they are not in the RMSE, and are reported so a model that fails often cannot look good).
    """

    horizons: tuple[int, ...]
    dt: float
    rmse: dict[str, list[float | None]]
    windows: list[int]
    failed: list[int]

    def to_dict(self) -> dict[str, Any]:
        return {'horizons': list(self.horizons),
                'horizons_s': [h * self.dt for h in self.horizons],
                'rmse': {k: list(v) for k, v in self.rmse.items()},
                'windows': list(self.windows), 'failed': list(self.failed)}


@dataclass
class RelativeErrors:
    """Free-run ||y_model - y|| / ||y|| of u, v, r [-]: per trial and pooled (None: failed)."""

    per_trial: dict[str, dict[str, float | None]]
    pooled: dict[str, float | None]
    failed: dict[str, float] = field(default_factory=dict)   # trial -> failure time [s]

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            'definition': '||y_model - y||_2 / ||y||_2 over the samples of a free run from '
                          'the first measured state (MBPE-LOGO Table 5); pooled: the sums of '
                          'squares of all trials added before the ratio',
            'pooled': dict(self.pooled),
            'per_trial': {n: dict(v) for n, v in self.per_trial.items()}}
        if self.failed:
            d['failed_at_s'] = dict(self.failed)
        return d


def _window_arrays(trial: Trial, inputs: np.ndarray, n_max: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return x0s (M, 6), controls (M, n_max + 1, n) and lengths (M,) of every window."""
    T = len(trial)
    M = T - 1
    L = n_max + 1
    pad = np.concatenate([inputs, np.repeat(inputs[-1:], n_max, axis=0)])
    idx = np.arange(M)[:, None] + np.arange(L)[None, :]
    ctrl = pad[idx]
    lengths = np.minimum(L, T - np.arange(M)).astype(np.int64)
    return np.ascontiguousarray(trial.states[:M]), np.ascontiguousarray(ctrl), lengths


def _learned_windows(model: Model, trial: Trial, x0s: np.ndarray, ctrl: np.ndarray,
                     lengths: np.ndarray, first: int, integrator: str, substeps: int,
                     p: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """States (m, n_max + 1, 6) of the windows starting at samples first ... first + m - 1."""
    net = cast('ResidualNet', model.residual)   # called only for a model with a network
    sizes, flat = net.packed()
    w = int(net.window)
    method = integrator_code(integrator)
    tag = family_tag(model.ship.kind)
    out = np.full((len(x0s), ctrl.shape[1], 6), np.nan)
    res = np.empty((ctrl.shape[1], 3))
    empty = np.zeros((max(1, w - 1), net.n_features))
    for i in range(len(x0s)):
        k = first + i
        lo = max(0, k - (w - 1))
        hist = np.ascontiguousarray(rows[lo:k]) if k > lo else empty
        L = int(lengths[i])
        seg = np.full((L, 6), np.nan)
        simulate_hybrid_one(tag, p, x0s[i], hist, k - lo, np.ascontiguousarray(ctrl[i, :L]),
                            L, float(trial.dt), int(substeps), method, w, sizes, flat,
                            net.x_mean, net.x_std, net.y_scale, float(net.physics), seg,
                            res[:L])
        out[i, :L] = seg
    return out


def nstep_errors(ship: ShipConfig | Model, trials: Sequence[Trial], horizons: Sequence[int],
                 integrator: str = 'rk4', substeps: int = 1, params: np.ndarray | None = None
                 ) -> tuple[NStepScore, dict[str, NStepScore]]:
    """
    Return the n-step prediction RMSE over all ``trials`` and per trial (by name).

    Every sample k < T - 1 of every trial starts a window from the measured state k, driven by
    the measured inputs k, k + 1, ...; its prediction n steps on is compared with sample k + n
    (windows that run past the trial's end score only the horizons inside it). ``params``:
    a parameter vector instead of ``ship.params``. All trials must share one sample step.
    ``ship`` may be a ``learn.Model``: with a residual network, its history window holds the
    measured samples before each window's start (module docstring); the trials' step must
    be the network's.
    """
    model = ship if isinstance(ship, Model) else Model(ship)
    ship = model.ship
    net = model.residual
    hs = check_horizons(horizons)
    trials = list(trials)
    common_dt(trials, 'n-step prediction')
    dt = trials[0].dt
    if net is not None and abs(dt - net.dt_s) > 1e-6 * net.dt_s:
        raise TuningError(f'n-step prediction: trial {trials[0].name} has a sample step of '
                          f'{dt:g} s, but the residual network was trained on {net.dt_s:g} s '
                          f'samples; resample the trials to dt = {net.dt_s:g} s')
    p = np.ascontiguousarray(ship.params if params is None else params, dtype=float)
    n_max = hs[-1]
    cols = [STATE_NAMES.index(s) for s in NSTEP_STATES]
    H = np.asarray(hs)
    total_sq = np.zeros((len(hs), len(cols)))
    total_n = np.zeros(len(hs), dtype=np.int64)
    total_f = np.zeros(len(hs), dtype=np.int64)
    per = {}
    for tr in trials:
        if len(tr) < 2:
            raise TuningError(f'n-step prediction: trial {tr.name} has fewer than 2 samples')
        inputs = tr.input_array(ship.family.channels)
        x0s, ctrl, lengths = _window_arrays(tr, inputs, n_max)
        rows = trial_rows(ship, tr, net.physics_input, p)[0] if net is not None else None
        sq = np.zeros_like(total_sq)
        cnt = np.zeros(len(hs), dtype=np.int64)
        fail = np.zeros(len(hs), dtype=np.int64)
        for a in range(0, len(x0s), _CHUNK):
            b = min(len(x0s), a + _CHUNK)
            if net is None:
                out, _, _ = simulate_batch(ship.kind, p, x0s[a:b], ctrl[a:b], dt,
                                           lengths[a:b], integrator, substeps)
            else:
                # (rows are computed with the network)
                out = _learned_windows(model, tr, x0s[a:b], ctrl[a:b], lengths[a:b], a,
                                       integrator, substeps, p, cast(np.ndarray, rows))[None]
            k = np.arange(a, b)
            target = k[:, None] + H[None, :]            # (m, nh) sample index predicted
            inside = target < len(tr)
            pred = out[0][np.arange(b - a)[:, None], np.minimum(H[None, :],
                                                                lengths[a:b, None] - 1)]
            meas = tr.states[np.minimum(target, len(tr) - 1)]
            err = pred - meas
            err[..., _PSI] = (err[..., _PSI] + math.pi) % (2 * math.pi) - math.pi
            err = err[..., cols]
            with np.errstate(over='ignore', invalid='ignore'):   # a diverging window
                e2 = np.where(np.isfinite(err), err, 0.0) ** 2
            ok = inside & np.all(np.isfinite(err), axis=-1) & np.all(np.isfinite(e2), axis=-1)
            fail += np.sum(inside & ~ok, axis=0)
            cnt += np.sum(ok, axis=0)
            sq += np.sum(np.where(ok[..., None], e2, 0.0), axis=0)
        per[tr.name] = _score(hs, dt, sq, cnt, fail)
        total_sq += sq
        total_n += cnt
        total_f += fail
    return _score(hs, dt, total_sq, total_n, total_f), per


def _score(hs: tuple[int, ...], dt: float, sq: np.ndarray, cnt: np.ndarray, fail: np.ndarray
           ) -> NStepScore:
    rmse = {s: [float(math.sqrt(sq[i, j] / cnt[i])) if cnt[i] else None
                for i in range(len(hs))] for j, s in enumerate(NSTEP_STATES)}
    return NStepScore(hs, float(dt), rmse, [int(c) for c in cnt], [int(f) for f in fail])


def relative_errors(names: Sequence[str], trials: Sequence[Trial],
                    free_runs: Sequence[np.ndarray]) -> RelativeErrors:
    """
    Return the Table 5 relative errors of free runs (T, 6) against their trials.

    A run with a NaN (it failed) is reported under ``failed`` and left out of the pooled figure.
    """
    cols = {s: STATE_NAMES.index(s) for s in REL_STATES}
    num = dict.fromkeys(REL_STATES, 0.0)
    den = dict.fromkeys(REL_STATES, 0.0)
    per: dict[str, dict[str, float | None]] = {}
    failed = {}
    for name, tr, run in zip(names, trials, free_runs):
        bad = ~np.all(np.isfinite(run), axis=1)
        if bad.any():
            failed[name] = float(tr.t[int(np.argmax(bad))] - tr.t[0])
            per[name] = dict.fromkeys(REL_STATES)
            continue
        per[name] = {}
        for s, j in cols.items():
            e2 = float(np.sum((run[:, j] - tr.states[:, j]) ** 2))
            y2 = float(np.sum(tr.states[:, j] ** 2))
            num[s] += e2
            den[s] += y2
            per[name][s] = math.sqrt(e2 / y2) if y2 > 0 else None
    pooled = {s: (math.sqrt(num[s] / den[s]) if den[s] > 0 else None) for s in REL_STATES}
    if len(failed) == len(per):
        pooled = dict.fromkeys(REL_STATES)
    return RelativeErrors(per, pooled, failed)


def nstep_figure(scores: dict[str, NStepScore], title: str = '') -> Figure:
    """
    Return a Figure of the n-step RMSE against the horizon, one panel per state.

    ``scores``: model (or trial set) name -> its score; the horizon axis in seconds.
    """
    from matplotlib.figure import Figure

    from mmg_tuner.tuning.plots import STATE_AXES

    fig = Figure(figsize=(11, 6.5))
    axes = fig.subplots(2, 3).ravel()
    for a, s in zip(axes, NSTEP_STATES):
        label, factor = STATE_AXES[s]
        for name, sc in scores.items():
            y = np.array([np.nan if v is None else v * factor for v in sc.rmse[s]])
            a.plot(np.asarray(sc.horizons) * sc.dt, y, 'o-', ms=3, label=name)
        a.set_xlabel('prediction horizon [s]')
        a.set_ylabel('RMSE of ' + label.replace('\n', ' '), fontsize=8)
        a.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title or 'n-step prediction from the measured state at every sample',
                 fontsize=10)
    fig.tight_layout()
    return fig
