"""
How sure a model is: a prediction interval from an ensemble's spread, and its coverage.

An ensemble of networks trained alike but from different seeds (``tune --residual-seeds``,
``learn.ensemble``) predicts one trajectory (the mean network's); its members, simulated one
by one, disagree where the data did not pin the network down. The interval of state i at a
sample is

    prediction_i ± c_i × (standard deviation of the members' predictions of state i),

each simulation restarted from the measured state every ``restart_every_s`` as the index's
are. A handful of seeds underestimates the error (their spread says nothing about what all of
them miss), so the factors c_i are calibrated: on trials the models did not train on (the
validation part of the training runs), c_i is the ``level`` quantile of |error_i| / spread_i,
so that share of their samples falls inside. Coverage on other held-out trials then says
whether the interval holds (a nominal 90 % interval should cover about 90 % of the samples).

The start error (``calibrate_interval(start_error=True)``): every member restarts from the
*recorded* state, so the members' spread starts at zero, while the recorded state has its
own error, which every simulation carries from its start and which the recorded value it is
compared with carries again. sigma_j, the recorded state j's error, is the RMS over every
restart of the centre model's error one sample after it, / sqrt 2 (two readings; the model
can hardly err in one sample); the spread then adds, in quadrature, the centre model's
change when restarted with state j raised by sigma_j (for each j) and sigma_i itself:

    spread_i^2 = members' spread_i^2 + sum_j (s_i(start + sigma_j e_j) - s_i)^2 + sigma_i^2.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, cast, Sequence, TYPE_CHECKING

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.learn.model import as_model, Model
from mmg_tuner.learn.train import members as net_members
from mmg_tuner.tuning.evaluate import errors, INDEX_STATES, predict
from mmg_tuner.tuning.report import unique_names
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.learn.residual import ResidualNet

TINY = 1e-12
"""A spread below this is zero (a restart sample, where every member starts from the
measurement): an error there is outside unless it is zero too."""
_COL = {n: STATE_NAMES.index(n) for n in INDEX_STATES}


@dataclass(frozen=True)
class Interval:
    """
    A calibrated prediction interval: the model, its members, a factor per state.

    model: the ensemble (its prediction is the interval's centre); members: the networks it
    averages, each with the same physics, then any physics alone (``calibrate_interval(physics=
    ...)``, members that differ in physics); scale: c_i per state of INDEX_STATES (x, u, y, v,
    psi, r); level: the nominal share of samples inside (e.g. 0.9); own_members: False when
    the members were given (``calibrate_interval(members=...)``), which a network cannot store;
    start_sigma: the recorded state's error per state of STATE_NAMES (x, y, psi [m, rad], u, v
    [m/s], r [rad/s]) when the spread carries the start error (see the module), else None.
    """

    model: Model
    members: tuple[Model, ...]
    scale: tuple[float, ...]
    level: float
    own_members: bool = True   # the members are the ensemble's own networks (storable)
    start_sigma: tuple[float, ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {'level': self.level, 'members': len(self.members),
                               'scale': dict(zip(INDEX_STATES, self.scale))}
        if self.start_sigma is not None:
            out['start_sigma'] = dict(zip(STATE_NAMES, self.start_sigma))
        return out


def ensemble_members(model: Model) -> tuple[Model, ...]:
    """Return the member models of an ensemble model (its physics, each member's network)."""
    net = as_model(model).residual
    if net is None:
        raise TuningError('an interval needs an ensemble network (tune --residual-seeds N, '
                          'N >= 2); this model is the physics alone')
    nets = net_members(net)
    if len(nets) < 2:
        raise TuningError('an interval needs an ensemble of at least 2 networks '
                          '(tune --residual-seeds N, N >= 2); this network is one')
    return tuple(Model(model.ship, n) for n in nets)


def _restarts(trial: Trial, restart_every_s: float) -> np.ndarray:
    """Return the samples a simulation restarts from the recorded state (as ``predict``)."""
    return np.array([a for a, _ in trial.segments(restart_every_s)], dtype=int)


def _wrapped(d: np.ndarray) -> np.ndarray:
    """Return state differences (..., 6) with the heading's wrapped to [-pi, pi]."""
    k = _COL['psi']
    d[..., k] = (d[..., k] + np.pi) % (2 * np.pi) - np.pi
    return d


def start_sigma(model: Model, trials: Sequence[Trial], restart_every_s: float = 100.0,
                integrator: str = 'rk4') -> tuple[float, ...]:
    """
    Return the recorded state's error sigma_j per state of STATE_NAMES (see the module).

    The RMS over every restart of ``trials`` of the model's error one sample after it,
    / sqrt 2.
    """
    first = []
    for tr in trials:
        pred, _, _ = predict(model, tr, restart_every_s, integrator)
        k = _restarts(tr, restart_every_s) + 1
        k = k[k < len(tr)]
        first.append(errors(pred, tr.states)[k])
    e = np.concatenate(first) if first else np.empty((0, 6))
    e = e[np.all(np.isfinite(e), axis=1)]
    if len(e) == 0:
        raise TuningError('the start error needs a restart followed by a simulated sample '
                          'in the calibration trials; none had one')
    return tuple(float(x) for x in np.sqrt(np.mean(e ** 2, axis=0) / 2.0))


def _start_variance(model: Model, trial: Trial, pred: np.ndarray, sigma: Sequence[float],
                    restart_every_s: float, integrator: str) -> np.ndarray:
    """Return sum_j (model restarted with state j + sigma_j - model)^2 + sigma^2 (T, 6)."""
    starts = _restarts(trial, restart_every_s)
    var = np.zeros((len(trial), 6))
    for j, s_j in enumerate(sigma):
        if not s_j > 0:
            continue
        states = trial.states.copy()
        states[starts, j] += s_j
        moved, _, _ = predict(model, replace(trial, states=states), restart_every_s,
                              integrator)
        # a raised start that fails counts as no departure (as the simulator node counts it)
        var += np.nan_to_num(_wrapped(moved - pred)) ** 2
    var += np.asarray(sigma)[None] ** 2
    var[starts] = 0.0   # the restart itself is the recorded state (error 0 there)
    return var


def _centre_and_spread(model: Model, members: Sequence[Model], trial: Trial,
                       restart_every_s: float, integrator: str,
                       sigma: Sequence[float] | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the model's error (T, 6) and the spread (T, 6), in STATE_NAMES order.

    The spread: the members' about the model's prediction; with sigma (the recorded state's
    error), and the start error's added in quadrature (see the module).
    """
    pred, _, _ = predict(model, trial, restart_every_s, integrator)
    err = errors(pred, trial.states)
    runs = np.stack([predict(m, trial, restart_every_s, integrator)[0] for m in members])
    # heading: spread of the members' differences from the centre, wrapped
    dev = _wrapped(runs - pred[None])
    var = np.sum(dev ** 2, axis=0) / max(len(members) - 1, 1)
    if sigma is not None:
        var = var + _start_variance(model, trial, pred, sigma, restart_every_s, integrator)
    return err, np.sqrt(var)


def _ratios(model: Model, members: Sequence[Model], trials: Sequence[Trial],
            restart_every_s: float, integrator: str,
            sigma: Sequence[float] | None = None) -> list[np.ndarray]:
    out = []
    for tr in trials:
        err, spread = _centre_and_spread(model, members, tr, restart_every_s, integrator,
                                         sigma)
        cols = [_COL[n] for n in INDEX_STATES]
        e, s = np.abs(err[:, cols]), spread[:, cols]
        r = np.where(s > TINY, e / np.maximum(s, TINY), np.where(e > TINY, np.inf, 0.0))
        out.append(np.where(np.isfinite(err[:, cols]), r, np.inf))
    return out


def calibrate_interval(model: Model, trials: Sequence[Trial], level: float = 0.9,
                       restart_every_s: float = 100.0, integrator: str = 'rk4',
                       members: Sequence[Model] | None = None,
                       start_error: bool = False,
                       physics: Sequence[ShipConfig] = ()) -> Interval:
    """
    Return the interval of an ensemble ``model`` with factors calibrated on ``trials``.

    ``trials``: trials the networks did not train on (e.g. the validation part of the
    training runs); per state, c = the ``level`` quantile of |error| / spread over their
    samples. members: the models whose spread about ``model``'s prediction is the interval's
    (default: the ensemble's own networks, each with its physics; give others, e.g. with a
    different physics, to compare; at least 2). Only the default is stored with a network
    (:func:`with_interval`): the simulator node steps the ensemble's own members (members
    given are never stored, even the ensemble's own passed explicitly). start_error: the
    spread also carries the recorded start's error (see the module; sigma estimated on
    ``trials``). physics: ships (of the model's family) whose physics alone joins the
    ensemble's own members, e.g. the tuned physics and the one the tuning started from: members
    that differ in physics as well as in weights; stored with the network as their parameters
    that differ from the model's ship.
    """
    if not 0 < level < 1:
        raise TuningError(f'interval level {level!r}: give a share in (0, 1), e.g. 0.9')
    model = as_model(model)
    if members is not None and physics:
        raise TuningError('calibrate_interval: give members= or physics=, not both (physics '
                          "adds to the ensemble's own members)")
    for ship in physics:
        if ship.model != model.ship.model:
            raise TuningError(f'calibrate_interval: the physics member {ship.name!r} is a '
                              f'{ship.model} model, the ensemble a {model.ship.model} one')
    mem = ensemble_members(model) + tuple(Model(ship, None) for ship in physics) \
        if members is None else tuple(as_model(m) for m in members)
    if len(mem) < 2:
        raise TuningError(f'an interval needs at least 2 members; {len(mem)} given')
    trials = list(trials)
    sigma = start_sigma(model, trials, restart_every_s, integrator) if start_error else None
    R = np.concatenate(_ratios(model, mem, trials, restart_every_s, integrator, sigma))
    # the order statistic at or above the level (no interpolation): at least that share of
    # the calibration samples is inside
    scale = tuple(float(np.quantile(R[:, i], level, method='higher'))
                  for i in range(len(INDEX_STATES)))
    if not all(np.isfinite(scale)):
        raise TuningError('the interval could not be calibrated: the model failed on a '
                          'calibration trial (its errors are not finite), or its members agree '
                          'exactly where it errs (a zero spread; start_error=True adds the '
                          "recorded state's error)")
    return Interval(model, mem, scale, float(level), members is None, sigma)


def coverage(interval: Interval, trials: Sequence[Trial], restart_every_s: float = 100.0,
             integrator: str = 'rk4') -> dict[str, Any]:
    """
    Return the share of samples inside the interval on ``trials``.

    {'all': share of (sample, state) pairs inside over every trial and state, 'states':
    {state: share}, 'trials': {trial: share}, 'level': the nominal share}.
    """
    trials = list(trials)
    R = _ratios(interval.model, interval.members, trials, restart_every_s, integrator,
                interval.start_sigma)
    c = np.asarray(interval.scale)
    inside = [r <= c[None, :] for r in R]
    every = np.concatenate(inside)
    return {'level': interval.level, 'all': float(every.mean()),
            'states': {n: float(every[:, i].mean()) for i, n in enumerate(INDEX_STATES)},
            'trials': {n: float(x.mean()) for n, x in zip(unique_names(trials), inside)}}


def with_interval(interval: Interval) -> Model:
    """
    Return the interval's model with the calibration stored in its network's meta.

    Saved with the network (params.residual.npz), so ``evaluate`` reports the coverage and the
    simulator node the uncertainty of a model loaded from its params.yaml
    (:func:`model_interval`).
    """
    if not interval.own_members:
        raise TuningError('this interval was calibrated with members given by the caller; a '
                          "network stores only its own members' interval (the node steps "
                          'those): calibrate without members= to store it')
    # an interval's model is an ensemble: it has a network (ensemble_members checked)
    net = cast('ResidualNet', interval.model.residual)
    info: dict[str, Any] = {'level': interval.level, 'scale': list(interval.scale),
                            'states': list(INDEX_STATES)}
    if interval.start_sigma is not None:   # in STATE_NAMES order
        info['start_sigma'] = dict(zip(STATE_NAMES, interval.start_sigma))
    alone = [m.ship for m in interval.members if m.residual is None]
    if alone:   # each as the parameters that differ from the model's ship
        info['physics_members'] = [_differ(interval.model.ship, ship) for ship in alone]
    meta = {**net.meta, 'interval': info}
    return Model(interval.model.ship, replace(net, meta=meta))


def _differ(base: ShipConfig, ship: ShipConfig) -> dict[str, float]:
    """Return the parameters of ``ship`` that differ from ``base``'s, by name."""
    a, b = base.as_dict(), ship.as_dict()
    return {k: v for k, v in b.items() if not (v == a[k] or (np.isnan(v) and np.isnan(a[k])))}


def model_interval(model: Model) -> Interval | None:
    """Return the interval a model's network carries (:func:`with_interval`), or None."""
    model = as_model(model)
    net = model.residual
    info = None if net is None or not isinstance(net.meta, dict) else net.meta.get('interval')
    if not info:
        return None
    sigma = info.get('start_sigma')
    alone = tuple(Model(model.ship.with_params(d, 'the interval of the network meta'), None)
                  for d in info.get('physics_members', []))
    return Interval(model, ensemble_members(model) + alone,
                    tuple(float(c) for c in info['scale']),
                    float(info['level']),
                    start_sigma=None if sigma is None else
                    tuple(float(sigma[n]) for n in STATE_NAMES))
