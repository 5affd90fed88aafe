"""
Train a neural residual on the accelerations through the simulation (Wakita et al. 2022).

The loss is the paper's simulation-based one: windows of ``horizon_s`` are simulated from
measured states with the recorded inputs and measured wind, and the simulated positions,
heading and velocities are compared with the measured ones, each standardised by its standard
deviation over the training trials. Gradients flow through every step of the simulation: the
physics is the compiled kernel (``_bridge``/``_engine``). Early stopping on a validation set,
seeds fixed and recorded.

JAX, equinox and optax are imported when :func:`train_residual` runs, not when this module
is imported.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
import math
import time
from typing import Any, Callable, cast, Mapping, Sequence, TYPE_CHECKING

from mmg_tuner.core.correction import feature_names, FEATURE_PARAMS, features_fit
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import common_dt, Trial
from mmg_tuner.errors import ConfigError, MissingDependencyError, TuningError
from mmg_tuner.learn._windows import cut, prepare, starts, TrialArrays, Windows
from mmg_tuner.learn.residual import ResidualNet
import numpy as np

if TYPE_CHECKING:   # annotations only: JAX is imported when a network is trained
    from mmg_tuner.learn._engine import Coefficients, Joint, MLP

INSTALL_HINT = 'the hybrid model needs JAX: pip install jax equinox optax'
BALANCE = ('window', 'trial', 'group')
SELECT = ('mean', 'every_group')


def require_jax() -> None:
    """
    Raise MissingDependencyError when JAX, equinox or optax is missing.

    The message says how to install them; the rest of mmg_tuner works without them.
    """
    try:
        import equinox  # noqa: F401
        import jax  # noqa: F401
        import optax  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(f'{INSTALL_HINT} ({exc})') from None


def _bad(option: str, value: object, what: str) -> ConfigError:
    return ConfigError(f'ResidualConfig: {option} = {value!r} must be {what}')


@dataclass(frozen=True)
class ResidualConfig:
    """
    Options of :func:`train_residual`, validated on creation.

    window: samples of history the network sees (the current one included); hidden: sizes of
    the tanh hidden layers; horizon_s: length of each simulated training window [s];
    epochs: maximum passes over the windows; learning_rate: Adam's step; l2: weight of the
    regulariser keeping the residual small (the mean squared residual in units of the
    physics' RMS accelerations; for the pure network, the mean squared weight); patience:
    epochs without a better validation loss before stopping; seed: initial weights and
    minibatch order; physics: True = hybrid, False = the network alone (Wakita et al. 2022
    Type-1); integrator: 'rk4' (default: as ``mt.simulate`` and ``evaluate`` run the
    hybrid; a network trained through Euler learns Euler's discretisation error too) or
    'euler' (the paper's), one step per sample;
    batch_size: windows per minibatch; stride_s: spacing of window starts [s] (None:
    horizon_s / 2); validation_fraction: without validation trials, the last part of each
    training trial held out for early stopping; max_seconds: stop after this wall time;
    significance: the best epoch's residual is kept only when its validation loss beats the
    physics alone by this many standard errors of the paired per-window differences (0: any
    improvement); otherwise the residual is zero, so noise is not learned.
    balance: how windows weigh in the training and validation losses (and the regulariser):
    'window' every window alike (a long trial counts by its length), 'trial' every trial the
    same total, 'group' every group the same total (``groups`` of :func:`train_residual`, e.g.
    the manoeuvre kind), its trials alike within it: as the physics tuning's segments
    (tuning/segments.py), so a kind with few short runs is not drowned.
    select: which epoch is kept (and when to stop early): 'mean' the lowest (balanced)
    validation loss; 'every_group' the lowest worst ratio, over the groups (without
    ``groups``: over the trials), of a group's validation loss to the physics' alone, so an
    epoch that helps on average but hurts one regime is not kept: the residual stays zero
    unless the validation says it helps on every group.
    physics_input: the network also reads the physics' accelerations at each sample (the
    prediction it corrects, ``core.correction.PHYSICS_FEATURES``): of the ship's coefficients
    (with ``coefficients``, of the trained ones inside the simulated windows, of the ship's
    in the measured history before them and in the standardisation; a run of the result
    uses the trained ones throughout).
    """

    window: int = 5
    hidden: tuple[int, ...] = (32, 32)
    horizon_s: float = 10.0
    epochs: int = 200
    learning_rate: float = 3e-3
    l2: float = 1e-2
    patience: int = 20
    seed: int = 0
    physics: bool = True
    integrator: str = 'rk4'
    batch_size: int = 64
    stride_s: float | None = None
    validation_fraction: float = 0.25
    max_seconds: float | None = None
    significance: float = 2.0
    balance: str = 'window'
    select: str = 'mean'
    physics_input: bool = False

    def __post_init__(self) -> None:
        def whole(x: object, lo: int) -> bool | np.bool_:
            return isinstance(x, (int, np.integer)) and not isinstance(x, bool) and x >= lo

        def pos(x: object) -> bool:
            return isinstance(x, (int, float)) and not isinstance(x, bool) and \
                math.isfinite(x) and x > 0

        object.__setattr__(self, 'hidden', tuple(self.hidden))
        for name, ok, what in (
                ('window', whole(self.window, 1), 'a whole number >= 1'),
                ('hidden', len(self.hidden) >= 1 and all(whole(h, 1) for h in self.hidden),
                 'one or more layer sizes >= 1'),
                ('horizon_s', pos(self.horizon_s), 'a positive number of seconds'),
                ('epochs', whole(self.epochs, 1), 'a whole number >= 1'),
                ('learning_rate', pos(self.learning_rate), 'a positive number'),
                ('l2', pos(self.l2) or self.l2 == 0, 'a number >= 0'),
                ('patience', whole(self.patience, 1), 'a whole number >= 1'),
                ('seed', whole(self.seed, 0) and self.seed < 2**31, 'a whole number in '
                 '[0, 2^31)'),
                ('physics', isinstance(self.physics, bool), 'True or False'),
                ('physics_input', isinstance(self.physics_input, bool), 'True or False'),
                ('integrator', self.integrator in ('euler', 'rk4'), "'euler' or 'rk4'"),
                ('batch_size', whole(self.batch_size, 1), 'a whole number >= 1'),
                ('stride_s', self.stride_s is None or pos(self.stride_s),
                 'a positive number of seconds or None'),
                ('validation_fraction', isinstance(self.validation_fraction, float) and
                 0 < self.validation_fraction < 1, 'a fraction in (0, 1)'),
                ('max_seconds', self.max_seconds is None or pos(self.max_seconds),
                 'a positive number of seconds or None'),
                ('significance', pos(self.significance) or self.significance == 0,
                 'a number of standard errors >= 0'),
                ('balance', self.balance in BALANCE, f'one of {list(BALANCE)}'),
                ('select', self.select in SELECT, f'one of {list(SELECT)}')):
            if not ok:
                raise _bad(name, getattr(self, name), what)


@dataclass(frozen=True)
class JointCoefficients:
    """
    Physics coefficients :func:`train_residual` trains together with the network.

    names: the coefficients (the tuning's targets; never the wind's, the current's or the
    antenna's); start: their values training starts from (the tuned ones); lower, upper:
    their box; centre: the prior's centre (the values the tuning started from); weight: the
    prior's pull, per unit of the physics' own training loss: the loss gains weight x
    (that loss) x sum(((theta - centre) / (upper - lower))^2), so a coefficient moves only
    where the simulated windows pull harder (``tune``'s prior weight over its mean J per
    sample keeps the tuning's balance between data and prior).
    """

    names: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    centre: tuple[float, ...]
    weight: float = 0.0

    def __post_init__(self) -> None:
        k = len(self.names)
        if not k or any(len(x) != k for x in (self.start, self.lower, self.upper, self.centre)):
            raise ConfigError(f'joint coefficients: {k} names need as many start, lower, upper '
                              'and centre values')
        if len(set(self.names)) != k:
            raise ConfigError(f'joint coefficients: a name given twice in {list(self.names)}')
        lo, hi, st = (np.asarray(x, dtype=float) for x in (self.lower, self.upper, self.start))
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)
                and np.all((lo <= st) & (st <= hi))):
            raise ConfigError('joint coefficients: every box must be finite with lower < '
                              f'upper and hold its start ({dict(zip(self.names, st))})')
        if not (math.isfinite(self.weight) and self.weight >= 0):
            raise ConfigError(f'joint coefficients: weight {self.weight!r} must be >= 0')


@dataclass
class ResidualFit:
    """
    What :func:`train_residual` produced.

    net: the trained network (the best validation epoch); history: one dict per epoch
    (epoch, train, val, seconds); train_loss, val_loss: the data loss (standardised squared
    state error of the simulated windows) of the best network on the training and validation
    windows; share: the residual's share of the total acceleration on the training trials
    (RMS ratio, 0..1; 1 for the pure network); seconds: wall time; epochs: epochs run;
    physics_train_loss, physics_val_loss: the same losses of the physics part alone (zero
    residual; None for the pure network), so the gain is 1 - val_loss / physics_val_loss;
    val_by_group: per group (``groups``; else per trial) the validation loss of the physics
    alone and of the kept network ({'physics': .., 'hybrid': ..}); share_by_group: the share
    on each group's training trials.
    """

    net: ResidualNet
    history: list[dict[str, Any]]
    train_loss: float
    val_loss: float
    share: float
    seconds: float
    epochs: int
    seed: int
    physics_train_loss: float | None = None
    physics_val_loss: float | None = None
    best_epoch: int = 0
    notes: list[str] = field(default_factory=list)
    val_by_group: dict[str, dict[str, float]] = field(default_factory=dict)
    share_by_group: dict[str, float] = field(default_factory=dict)
    # trained together with the network (coefficients=...): their values, by name
    coefficients: dict[str, float] = field(default_factory=dict)

    @property
    def val_gain(self) -> float | None:
        """
        Return 1 - val_loss / physics_val_loss.

        The held-out share of the error the residual removes (None for the pure network).
        """
        if self.physics_val_loss is None or not self.physics_val_loss > 0:
            return None
        return 1.0 - self.val_loss / self.physics_val_loss


def window_weights(names: Sequence[str], balance: str,
                   groups: Mapping[str, str] | None = None) -> np.ndarray:
    """
    Return the weight of each window (its trial's name given), scaled to mean 1.

    balance 'window': all 1; 'trial': every trial the same total; 'group': every group
    (``groups``: trial name -> group) the same total, its trials alike within it.
    """
    names = list(names)
    if balance not in BALANCE:
        raise _bad('balance', balance, f'one of {list(BALANCE)}')
    if not names or balance == 'window':
        return np.ones(len(names))
    count: dict[str, int] = {}
    for n in names:
        count[n] = count.get(n, 0) + 1
    if balance == 'trial':
        share = {n: 1.0 / len(count) for n in count}
    else:
        members: dict[str, list[str]] = {}
        for n in count:
            members.setdefault(_group(n, groups), []).append(n)
        share = {n: 1.0 / (len(members) * len(ns)) for ns in members.values() for n in ns}
    w = np.array([share[n] / count[n] for n in names])
    scaled: np.ndarray = w / w.mean()
    return scaled


def group_losses(losses: np.ndarray, weights: np.ndarray, labels: np.ndarray,
                 names: Sequence[str]) -> np.ndarray:
    """Return the weighted mean loss of the windows of each group in ``names``."""
    lw = np.asarray(losses) * np.asarray(weights)
    return np.array([lw[labels == g].sum() / np.asarray(weights)[labels == g].sum()
                     for g in names])


def selection_score(select: str, mean: float, groups: np.ndarray,
                    physics_groups: np.ndarray) -> float:
    """
    Return the validation score an epoch is kept by (lower is better; the physics alone).

    'mean': the (balanced) mean validation loss; 'every_group': the worst ratio over the
    groups of the loss to the physics' alone (1 for the physics itself), so only an epoch
    better than the physics on every group can replace it.
    """
    if select == 'mean':
        return float(mean)
    return float(np.max(np.asarray(groups) / np.maximum(physics_groups, 1e-300)))


def _group(name: str, groups: Mapping[str, str] | None) -> str:
    if groups is None:
        return name
    if name not in groups:
        raise TuningError(f'train_residual: trial {name!r} has no group in groups (known: '
                          f'{sorted(groups)[:5]}...); give every trial its group')
    return str(groups[name])


def _check_start(net: ResidualNet, cfg: ResidualConfig, dt: float, ship: ShipConfig
                 ) -> ResidualNet:
    """Return ``net`` if training can go on from it with ``cfg`` on ``ship``'s trials."""
    why = []
    if net.window != cfg.window:
        why.append(f"its window is {net.window} samples, the training's {cfg.window}")
    if abs(dt - net.dt_s) > 1e-6 * net.dt_s:   # (residual._check_dt's tolerance)
        why.append(f"its sample step is {net.dt_s:g} s, the trials' {dt:g} s")
    if float(net.physics) != float(cfg.physics):
        why.append(f"its physics weight is {net.physics:g}, the training's "
                   f'{float(cfg.physics):g} (a blend cannot train on)')
    if not features_fit(net.features, ship.family):   # (as residual.check_fits reads them)
        why.append(f'it reads the features of another family than {ship.family}')
    if net.physics_input != cfg.physics_input:
        does = 'reads' if net.physics_input else 'does not read'
        why.append(f"it {does} the physics' accelerations, the training's network "
                   + ('does' if cfg.physics_input else 'does not'))
    if why:
        raise TuningError('train_residual: cannot train on from the given network: '
                          + '; '.join(why))
    return net


def _block_masks(net: ResidualNet) -> list[tuple[int, np.ndarray]]:
    """
    Return (layer, mask) of an ensemble's block-diagonal layers (see :func:`ensemble`).

    The first layer (members' rows stacked) and the output layer (their columns side by
    side) are dense; each deeper hidden layer is zero outside the members' diagonal blocks.
    """
    k = n_members(net)
    if k < 2:
        return []
    return [(i, np.kron(np.eye(k), np.ones((w.shape[0] // k, w.shape[1] // k))))
            for i, w in enumerate(net.weights[1:-1], 1)]


def _layers(model: MLP | Joint) -> list[Any]:
    """Return the network's layers of an ``MLP`` or a ``Joint`` model (or their gradients)."""
    return cast(list[Any], (model.net if hasattr(model, 'net') else model).layers)


def _ensemble_meta(start: ResidualNet, bias: np.ndarray) -> dict[str, Any]:
    """
    Return the ensemble keys of a network trained on from the ensemble ``start``.

    The ensemble's output bias is the mean of its members' (each kept in the meta): training
    moved the mean, so each member's moves by as much.
    """
    meta = dict(start.meta)
    seeds = meta['ensemble_of_seeds']
    shift = np.asarray(bias, float) - np.asarray(start.biases[-1], float)
    own = meta.get('member_output_biases') or [start.biases[-1]] * len(seeds)
    # (the members' own training figures no longer describe their weights: not carried)
    return {'ensemble_of_seeds': seeds,
            'members': [{'seed': s, 'trained_on': 'with the ensemble (train_residual start=): '
                         "its figures are the ensemble's"} for s in seeds],
            'member_physics': meta.get('member_physics', [start.physics] * len(own)),
            'member_output_biases': [(np.asarray(b, float) + shift).tolist() for b in own]}


def _derivatives(kind: int, p: np.ndarray, S: np.ndarray, A: np.ndarray, Wd: np.ndarray
                 ) -> np.ndarray:
    """Return the family's ds/dt (B, 6) at rows of states, actuator tuples and winds."""
    from mmg_tuner.core.dynamics import family_tag
    from mmg_tuner.learn._bridge import batch_derivative
    F = np.empty((S.shape[0], 6))
    batch_derivative(family_tag(kind), p, S, A, Wd, F, np.empty((1, 6, 6)), False)
    return F


def n_members(net: ResidualNet) -> int:
    """Return how many networks an :func:`ensemble` averages (1 for one network)."""
    seeds = net.meta.get('ensemble_of_seeds') if isinstance(net.meta, dict) else None
    return len(seeds) if seeds and len(seeds) >= 2 else 1


def _significant(gain: np.ndarray, z: float) -> bool:
    """Return whether the paired per-window gains are > z standard errors above zero."""
    if z <= 0:
        return True
    n = gain.size
    if n < 2:
        return bool(gain.mean() > 0)
    return bool(gain.mean() > z * gain.std(ddof=1) / np.sqrt(n))


def split_validation(trials: list[Trial], fraction: float, window: int
                     ) -> tuple[list[Trial], list[Trial]]:
    """Hold out the last ``fraction`` of each trial (with the window's history before it)."""
    train, val = [], []
    for tr in trials:
        t_cut = tr.t[0] + (1.0 - fraction) * tr.duration_s
        train.append(tr.slice(tr.t[0], t_cut))
        val.append(tr.slice(t_cut - (window - 1) * tr.dt, tr.t[-1]))
    return train, val


def _check_trials(trials: Sequence[Trial], what: str, ship: ShipConfig) -> float:
    """Return the trials' one sample step; refuse none, mixed steps or non-finite features."""
    channels = [c for c in feature_names(ship.family)[3:-2] if c]
    dt = common_dt(trials, f'train_residual ({what})')
    for tr in trials:   # the channels the network reads (a missing one: its default)
        inputs = tr.input_array(channels)
        if not (np.all(np.isfinite(tr.states)) and np.all(np.isfinite(inputs))):
            raise TuningError(f'train_residual: {what} trial {tr.name} has non-finite states '
                              f'or commands ({", ".join(channels)})')
    return dt


def _versions() -> dict[str, str]:
    import equinox
    import jax
    import numba
    import optax

    from mmg_tuner import __version__
    return {'mmg_tuner': __version__, 'jax': jax.__version__, 'equinox': equinox.__version__,
            'optax': optax.__version__, 'numpy': np.__version__, 'numba': numba.__version__}


def _entering(jc: JointCoefficients, ship: ShipConfig, S: np.ndarray, A: np.ndarray,
              Wd: np.ndarray) -> tuple[JointCoefficients, list[str]]:
    """
    Return the coefficients the dynamics read on these rows, and the names of the others.

    A coefficient acting before the kernel (an actuator's command scale or lag, a time
    offset: the training's inputs are computed once) has a zero parameter Jacobian: only the
    prior would move it, and the physics written would differ from the one trained.
    """
    from mmg_tuner.core.dynamics import family_tag
    from mmg_tuner.learn._bridge import batch_param_jacobian, param_steps
    rows = np.unique(np.linspace(0, len(S) - 1, min(len(S), 2000)).astype(int))
    S, A, Wd = (np.ascontiguousarray(x[rows]) for x in (S, A, Wd))
    k = len(jc.names)
    p = ship.params.copy()
    slots = np.array([PARAM_INDEX[n] for n in jc.names])
    p[slots] = jc.start
    steps = param_steps(jc.start, jc.lower, jc.upper)
    Jp = np.empty((len(rows), 6, k))
    F = _derivatives(ship.kind, p, S, A, Wd)
    batch_param_jacobian(family_tag(ship.kind), p, S, A, Wd, F, slots, steps, Jp)
    reads = np.nan_to_num(np.abs(Jp)).max(axis=(0, 1)) > 0
    if not reads.any():
        raise TuningError(f'train_residual: the dynamics read none of {list(jc.names)} on the '
                          'training rows: nothing to train with the network')
    keep = np.flatnonzero(reads)

    def pick(x: Sequence[float]) -> tuple[float, ...]:
        return tuple(float(x[int(i)]) for i in keep)

    names = tuple(jc.names[int(i)] for i in keep)
    return (JointCoefficients(names, pick(jc.start), pick(jc.lower), pick(jc.upper),
                              pick(jc.centre), jc.weight),
            [n for n, r in zip(jc.names, reads) if not r])


@dataclass
class _Sets:
    """What one training reads: its windows, their weights and groups, and its scales."""

    dt: float
    train_trials: list[Trial]
    val_trials: list[Trial]
    val_note: str
    horizon: int          # samples per window
    stride: int           # samples between window starts
    tr_arrs: list[TrialArrays]
    w_tr: Windows
    w_va: Windows
    wt_tr: np.ndarray     # the windows' weights (balance)
    wt_va: np.ndarray
    g_va: np.ndarray      # each validation window's group
    group_names: list[str]
    x_mean: np.ndarray    # input standardisation (the training rows)
    x_std: np.ndarray
    y_scale: np.ndarray   # output scale (the physics' RMS accelerations)
    sigma: np.ndarray     # the loss's per-state deviation over the training trials
    ms: np.ndarray        # the training rows: model states, actuator tuples, winds
    act: np.ndarray
    wind: np.ndarray
    F: np.ndarray         # the physics' derivative at those rows


def _sets(ship: ShipConfig, trials: Sequence[Trial], validation: Sequence[Trial] | None,
          groups: Mapping[str, str] | None, cfg: ResidualConfig) -> _Sets:
    """Return the windows, weights and scales :func:`train_residual` trains on (raises)."""
    trials = list(trials)
    dt = _check_trials(trials, 'training', ship)
    if validation is None:
        train_trials, val_trials = split_validation(trials, cfg.validation_fraction, cfg.window)
        val_note = f'validation: the last {cfg.validation_fraction:.0%} of each training trial'
    else:
        val_trials = list(validation)
        if abs(_check_trials(val_trials, 'validation', ship) - dt) > 1e-9:
            raise TuningError('train_residual: validation trials have a different sample step '
                              f'from the training trials ({dt:g} s)')
        train_trials = trials
        val_note = 'validation: ' + ', '.join(t.name for t in val_trials)
    H = max(1, int(round(cfg.horizon_s / dt)))
    stride = max(1, int(round((cfg.stride_s or cfg.horizon_s / 2) / dt)))
    tr_arrs = [prepare(ship, t, cfg.physics_input) for t in train_trials]
    va_arrs = [prepare(ship, t, cfg.physics_input) for t in val_trials]
    w_tr = cut(tr_arrs, cfg.window, H, stride)
    w_va = cut(va_arrs, cfg.window, H, stride)
    if cfg.balance == 'group' and groups is None:
        raise TuningError("train_residual: balance 'group' needs groups (trial name -> group)")

    def names_of(ts: Sequence[Trial], arrs: Sequence[TrialArrays]) -> list[str]:
        return [t.name for t, a in zip(ts, arrs)
                for _ in starts(a.rows.shape[0], cfg.window, H, stride)]

    n_tr, n_va = names_of(train_trials, tr_arrs), names_of(val_trials, va_arrs)
    wt_tr = window_weights(n_tr, cfg.balance, groups)
    wt_va = window_weights(n_va, cfg.balance, groups)
    for t in train_trials:   # (raises now, not after the training, for a missing one)
        _group(t.name, groups)
    g_va = np.array([_group(n, groups) for n in n_va])
    group_names = list(dict.fromkeys(g_va))
    for what, w, ts in (('training', w_tr, train_trials), ('validation', w_va, val_trials)):
        if len(w) == 0:
            raise TuningError(f'train_residual: the {what} trials ({", ".join(t.name for t in ts)}'
                              f') are too short for one window of {cfg.horizon_s:g} s after '
                              f'{cfg.window - 1} samples of history')

    # standardisation: inputs by the training rows, outputs by the physics' RMS accelerations,
    # the loss by each state's deviation over the training trials (as the paper does)
    rows = np.concatenate([a.rows for a in tr_arrs])
    x_mean = rows.mean(axis=0)
    x_std = rows.std(axis=0)
    x_std = np.where(x_std > 1e-9 * (1.0 + np.abs(x_mean)), x_std, 1.0)
    ms = np.ascontiguousarray(np.concatenate([a.model_states for a in tr_arrs]))
    act = np.ascontiguousarray(np.concatenate([a.act for a in tr_arrs]))
    wind = np.ascontiguousarray(np.concatenate([a.wind for a in tr_arrs]))
    F = _derivatives(ship.kind, ship.params, ms, act, wind)
    y_scale = np.sqrt(np.mean(F[:, 3:6] ** 2, axis=0))
    y_scale = np.maximum(y_scale, max(1e-3 * float(y_scale.max()), 1e-9))
    obs = np.concatenate([a.observed for a in tr_arrs])
    sigma = obs.std(axis=0)
    sigma = np.where(sigma > 0, sigma, 1.0)

    return _Sets(dt, train_trials, val_trials, val_note, H, stride, tr_arrs, w_tr, w_va, wt_tr,
                 wt_va, g_va, group_names, x_mean, x_std, y_scale, sigma, ms, act, wind, F)


def _free(coefficients: JointCoefficients | None, ship: ShipConfig, ds: _Sets,
          cfg: ResidualConfig
          ) -> tuple[Coefficients | None, JointCoefficients | None, ShipConfig, list[str]]:
    """
    Return the coefficients trained with the network (``_engine.Coefficients`` or None).

    With the checked names (those the dynamics read), the ship at their start values and the
    notes; the prior's weight is 0 here: it is set once the physics' own loss is known.
    """
    from mmg_tuner.learn import _engine as E
    free = None
    jc: JointCoefficients | None = None
    joint_notes: list[str] = []
    if coefficients is not None:
        if not cfg.physics:
            raise TuningError('train_residual: coefficients are trained with the physics (a '
                              'hybrid), not with the network alone')
        jc = coefficients
        bad = [n for n in jc.names if n not in PARAM_INDEX]
        if bad:
            raise TuningError(f'train_residual: unknown coefficients {bad}')
        fixed = [n for n in jc.names if n in FEATURE_PARAMS]
        if fixed:
            raise TuningError(f'train_residual: {fixed} cannot be trained with the network '
                              '(its features read the current, the wind and the antenna)')
        jc, dropped = _entering(jc, ship, ds.ms, ds.act, ds.wind)
        if dropped:
            joint_notes.append(f'not trained with the network: {", ".join(dropped)} (the '
                               'dynamics do not read them: they act before the kernel, e.g. '
                               'on the actuator commands, or not at all here)')
        # the prior's weight is set by train_residual, once the physics' own loss is known

        def arr(x: Sequence[float]) -> np.ndarray:
            return np.asarray(x, dtype=float)

        free = E.Coefficients(np.array([PARAM_INDEX[n] for n in jc.names]), arr(jc.start),
                              arr(jc.lower), arr(jc.upper), arr(jc.centre), 0.0)
        ship = ship.with_params(dict(zip(jc.names, jc.start)), 'joint coefficients')
    return free, jc, ship, joint_notes


def train_residual(ship: ShipConfig, trials: Sequence[Trial], *,
                   validation: Sequence[Trial] | None = None,
                   groups: Mapping[str, str] | None = None,
                   config: ResidualConfig = ResidualConfig(),
                   coefficients: JointCoefficients | None = None,
                   start: ResidualNet | None = None) -> ResidualFit:
    """
    Train the residual (or the pure network) of ``ship`` on recorded trials.

    The physics part keeps the ship's (tuned) parameters and only the network trains: the
    physics was identified first (CMA-ES, with its boxes and identifiability checks), so its
    coefficients keep their physical meaning and its extrapolation to manoeuvres the trials
    do not cover; the network, regularised to stay small, only takes up what the physics
    structure cannot produce. ``coefficients``: train those physics coefficients together
    with the network (within their boxes, pulled toward their prior centre), through the same
    simulation; they then trade off with the network, held by the prior and the regulariser
    (the fit's ``coefficients``; the net's physics is ``ship.with_params(fit.coefficients)``).
    ``start``: train on from this network (e.g. a trained hybrid, to refine it with
    ``coefficients``) instead of from a zero output: its weights are rewritten exactly in this
    training's scales, an ensemble's members keep their own blocks (no weight joins two
    members; they train together on their mean's loss, so they may co-adapt), and the kept
    epoch must beat that start, not the physics alone.

    trials: the training set (one sample interval); validation: held-out trials for early
    stopping (default: the last ``validation_fraction`` of each training trial); groups: trial
    name -> group (e.g. the manoeuvre kind) for ``balance='group'`` and
    ``select='every_group'`` (default: each trial its own group).

    Example::

        fit = train_residual(ship, trials[:6], validation=trials[6:],
                             config=ResidualConfig(epochs=50, seed=1))
        fit.net.save('residual.npz')
    """
    require_jax()
    import equinox as eqx
    import jax

    from mmg_tuner.learn import _engine as E
    from mmg_tuner.learn._bridge import teacher_residuals

    t_start = time.perf_counter()
    cfg = config
    ds = _sets(ship, trials, validation, groups, cfg)
    free, jc, ship, joint_notes = _free(coefficients, ship, ds, cfg)
    sim = E.make_simulator(ship.kind, ship.params, cfg.physics, cfg.integrator == 'rk4', ds.dt,
                           ds.x_mean, ds.x_std, ds.y_scale, free, cfg.physics_input)
    data_loss, total = E.make_loss(sim, ds.sigma, ds.y_scale, cfg.l2, cfg.physics, free)
    sizes = [cfg.window * ds.x_mean.shape[0], *cfg.hidden, 3]
    net0 = E.MLP(sizes, jax.random.PRNGKey(cfg.seed))
    model: MLP | Joint = net0 if free is None else \
        E.Joint(net0, jax.numpy.zeros(len(free.slots)))
    warm: ResidualNet | None = None
    blocks: list[tuple[int, np.ndarray]] = []
    if start is not None:
        warm = restandardised(_check_start(start, cfg, ds.dt, ship), ds.x_mean, ds.x_std,
                              ds.y_scale)
        blocks = _block_masks(warm)
    opt = E.optimiser(cfg.learning_rate)

    @eqx.filter_jit
    def train_step(model: MLP | Joint, opt_state: Any, b: Mapping[str, np.ndarray],
                   w: np.ndarray) -> tuple[MLP | Joint, Any, jax.Array]:
        (_, d), grads = eqx.filter_value_and_grad(total, has_aux=True)(model, b, w)
        if blocks:   # an ensemble's members stay apart: no gradient outside their blocks
            # (before the step: the clip's global norm must not count them)
            grads = eqx.tree_at(lambda g: [_layers(g)[i].weight for i, _ in blocks], grads,
                                [_layers(grads)[i].weight * mask for i, mask in blocks])
        updates, opt_state = opt.update(grads, opt_state, eqx.filter(model, eqx.is_array))
        new = eqx.apply_updates(model, updates)
        if isinstance(new, E.Joint):   # the coefficients back into their boxes
            assert free is not None
            new = eqx.tree_at(lambda m: m.z, new, free.project(new.z))
        if blocks:   # (and exactly zero there whatever the optimiser's rounding)
            new = eqx.tree_at(lambda m: [_layers(m)[i].weight for i, _ in blocks], new,
                              [_layers(new)[i].weight * mask for i, mask in blocks])
        return new, opt_state, d

    @eqx.filter_jit
    def window_losses(model: MLP | Joint, b: Mapping[str, np.ndarray], w: np.ndarray) -> jax.Array:
        return data_loss(model, b, w)[2]

    B = min(cfg.batch_size, len(ds.w_tr))

    def as_batch(w: Windows, idx: np.ndarray) -> dict[str, np.ndarray]:
        t = w.take(idx)
        return {'x0': t.x0, 'hist': t.hist, 'inp': t.inp, 'act': t.act, 'wind': t.wind,
                'target': t.target}

    def per_window(model: MLP | Joint, w: Windows) -> np.ndarray:
        """Return the data loss of each window of w (fixed-size chunks: one shape)."""
        n = len(w)
        out = []
        for a in range(0, n, B):
            idx = np.arange(a, a + B)
            wt = (idx < n).astype(float)
            idx = np.where(idx < n, idx, 0)
            out.append(np.asarray(window_losses(model, as_batch(w, idx), wt))[:int(wt.sum())])
        return np.concatenate(out)

    def mean_loss(model: MLP | Joint, w: Windows, wt: np.ndarray) -> float:
        return float(np.mean(per_window(model, w) * wt))

    def by_group(losses: np.ndarray) -> np.ndarray:
        return group_losses(losses, ds.wt_va, ds.g_va, ds.group_names)

    rng = np.random.default_rng(cfg.seed)
    physics_windows = per_window(model, ds.w_va)   # the zero-initialised output: physics alone
    physics_val = float(np.mean(physics_windows * ds.wt_va))
    physics_train = mean_loss(model, ds.w_tr, ds.wt_tr)
    physics_groups = by_group(physics_windows)
    if free is not None and coefficients is not None and coefficients.weight > 0:
        # the prior in loss units: its pull relative to the physics' own training loss
        if not math.isfinite(physics_train):
            raise TuningError('train_residual: the physics alone diverges on a training '
                              "window: the coefficients' prior has no loss to be measured in")
        free = replace(free, weight=coefficients.weight * physics_train)
        total = E.make_loss(sim, ds.sigma, ds.y_scale, cfg.l2, cfg.physics, free)[1]

    def criterion(val: float, losses: np.ndarray) -> float:
        if not cfg.physics:
            return val
        return selection_score(cfg.select, val, by_group(losses), physics_groups)

    start_windows, start_val, start_train = physics_windows, physics_val, physics_train
    if warm is not None:   # training goes on from the given network
        wnet = E.MLP.of(warm.weights, warm.biases)
        model = wnet if free is None else E.Joint(wnet, jax.numpy.zeros(len(free.slots)))
        start_windows = per_window(model, ds.w_va)
        start_val = float(np.mean(start_windows * ds.wt_va))
        start_train = mean_loss(model, ds.w_tr, ds.wt_tr)
    initial = model
    opt_state = opt.init(eqx.filter(model, eqx.is_array))
    crit0 = criterion(start_val, start_windows)
    best = (crit0, model, 0, start_windows, start_val)
    z = cfg.significance if cfg.physics else 0.0
    history = [{'epoch': 0, 'train': start_train, 'val': start_val, 'criterion': crit0,
                'seconds': time.perf_counter() - t_start}]
    notes = [ds.val_note, *joint_notes]
    skipped = 0
    epoch = 0
    for epoch in range(1, cfg.epochs + 1):
        perm = rng.permutation(len(ds.w_tr))
        losses = []
        for a in range(0, len(perm), B):
            idx = perm[a:a + B] if a + B <= len(perm) else perm[-B:]
            new_model, new_state, d_arr = train_step(model, opt_state, as_batch(ds.w_tr, idx),
                                                     ds.wt_tr[idx])
            d = float(d_arr)
            if not math.isfinite(d):  # a diverging window: skip the step, keep going
                skipped += 1
                continue
            model, opt_state = new_model, new_state
            losses.append(d)
        val_windows = per_window(model, ds.w_va)
        val = float(np.mean(val_windows * ds.wt_va))
        crit = criterion(val, val_windows)
        history.append({'epoch': epoch, 'train': float(np.mean(losses)) if losses else math.nan,
                        'val': val, 'criterion': crit, 'seconds': time.perf_counter() - t_start})
        if crit < best[0]:
            best = (crit, model, epoch, val_windows, val)
        elif epoch - best[2] >= cfg.patience:
            notes.append(f'early stop at epoch {epoch}: no better validation loss for '
                         f'{cfg.patience} epochs')
            break
        if cfg.max_seconds is not None and time.perf_counter() - t_start > cfg.max_seconds:
            notes.append(f'stopped at epoch {epoch}: max_seconds = {cfg.max_seconds:g} s')
            break
    if best[2] > 0 and not _significant((start_windows - best[3]) * ds.wt_va, z):
        where = 'the physics alone' if warm is None else 'the network it started from'
        notes.append(f'the best epoch ({best[2]}) did not beat {where} by {z:g} standard '
                     'errors of the paired validation windows: '
                     + ('the residual is zero' if warm is None else 'that network is kept'))
        best = (crit0, initial, 0, start_windows, start_val)
    elif best[2] == 0 and cfg.physics and cfg.select == 'every_group':
        notes.append('no epoch beat the physics alone on every validation group: the residual '
                     'is zero' if warm is None else 'no epoch beat the network it started '
                     'from (the worst group against the physics alone): it is kept')
    if skipped:
        notes.append(f'{skipped} minibatch step(s) skipped: a simulated window diverged')
    _, model, best_epoch, best_windows, val_loss = best
    val_by_group = ({g: {'physics': float(a), 'hybrid': float(b)} for g, a, b in
                     zip(ds.group_names, by_group(physics_windows), by_group(best_windows))}
                    if cfg.physics else {})
    train_loss = mean_loss(model, ds.w_tr, ds.wt_tr)
    trained: dict[str, float] = {}
    if isinstance(model, E.Joint):
        assert free is not None and jc is not None
        trained = dict(zip(jc.names, map(float, np.asarray(free.values(model.z)))))
        ship = ship.with_params(trained, 'joint coefficients')
        # the share: of the trained physics
        ds = replace(ds, F=_derivatives(ship.kind, ship.params, ds.ms, ds.act, ds.wind))
        notes.append('coefficients trained with the network: ' + (', '.join(
            f'{n} {jc.start[i]:.6g} -> {v:.6g}' for i, (n, v) in enumerate(trained.items()))
            if best_epoch else 'none moved (the start was kept)'))
        model = model.net
    weights, biases = model.export()
    features = feature_names(ship.family, cfg.physics_input)
    net = ResidualNet(cfg.window, ds.dt, weights, biases, ds.x_mean, ds.x_std, ds.y_scale,
                      cfg.physics, cfg.seed, features=features)
    share, parts = _share(net, ds.tr_arrs, ds.F, teacher_residuals)
    share_by_group = _shares_by_group(net, ds, groups)
    seconds = time.perf_counter() - t_start
    meta = {'ship': ship.name, 'model': ship.model, 'features': list(features),
            'trials': [t.name for t in ds.train_trials],
            'validation': [t.name for t in ds.val_trials], 'windows_train': len(ds.w_tr),
            'windows_val': len(ds.w_va), 'horizon_samples': ds.horizon,
            'stride_samples': ds.stride,
            'epochs': epoch, 'best_epoch': best_epoch, 'train_loss': train_loss,
            'val_loss': val_loss,
            'physics_train_loss': physics_train if cfg.physics else None,
            'physics_val_loss': physics_val if cfg.physics else None,
            'share': share, 'share_by_component': parts, 'share_by_group': share_by_group,
            'val_by_group': val_by_group, 'seconds': seconds, 'coefficients': trained,
            'seed': cfg.seed, 'config': asdict(cfg), 'sigma': ds.sigma.tolist(),
            'versions': _versions(), 'notes': notes,
            'loss': 'Wakita et al. 2022 simulation-based loss: mean over windows, steps and '
                    'the states x, y, psi, u, v, r of ((simulated - measured) / sigma)^2'}
    if warm is not None:
        meta['start'] = {'members': n_members(warm),
                         'hidden': [int(w.shape[0]) for w in warm.weights[:-1]]}
        if n_members(warm) > 1:
            meta.update(_ensemble_meta(warm, biases[-1]))
    net = ResidualNet(cfg.window, ds.dt, weights, biases, ds.x_mean, ds.x_std, ds.y_scale,
                      cfg.physics, cfg.seed, meta, features)
    return ResidualFit(net, history, train_loss, val_loss, share, seconds, epoch, cfg.seed,
                       physics_train if cfg.physics else None,
                       physics_val if cfg.physics else None, best_epoch, notes, val_by_group,
                       share_by_group, trained)


def ensemble(nets: Sequence[ResidualNet]) -> ResidualNet:
    """
    Return one network whose accelerations are the mean of those of ``nets``.

    The nets (e.g. one per seed) must share the window, sample interval, depth and hidden
    sizes. Exact, not a distillation: the hidden layers are stacked side by side (first
    layer: rows stacked; deeper ones: block-diagonal) and the output layer averages them, so
    inference runs it as any other network. Members standardised otherwise (a pure network
    trained on the published physics' scales beside a hybrid on the tuned one's) are first
    rewritten exactly in the first member's standardisation (:func:`restandardised`).

    Hybrid and pure networks may be mixed (a *blend*): a hybrid member's acceleration is the
    physics plus its output, a pure one's its output alone, so their mean is the hybrids'
    share times the physics plus the mean output: ``physics`` is that share. Used with the
    physics the hybrids were trained on (a blend keeps the hybrid's physics).
    """
    nets = list(nets)
    if not nets:
        raise ConfigError('ensemble: no networks given')
    a = nets[0]
    for i, n in enumerate(nets[1:], 1):
        same = (n.window == a.window and n.dt_s == a.dt_s and len(n.weights) == len(a.weights)
                and all(x.shape == y.shape for x, y in zip(n.weights[:-1], a.weights[:-1]))
                and n.features == a.features)
        if not same:
            raise ConfigError(f'ensemble: network {i} (seed {n.seed}) differs from network 0 '
                              'in window, dt_s, depth, hidden sizes or features: train them '
                              'with the same options for one ship')
    nets = [a] + [restandardised(n, a.x_mean, a.x_std, a.y_scale) for n in nets[1:]]
    k, L = len(nets), len(a.weights)
    ws: list[np.ndarray] = []
    bs: list[np.ndarray] = []
    for layer in range(L):
        W = [n.weights[layer] for n in nets]
        b = [n.biases[layer] for n in nets]
        if layer == L - 1:   # (a sum of arrays is an array)
            ws.append(np.hstack(W) / k if L > 1 else cast(np.ndarray, sum(W)) / k)
            bs.append(cast(np.ndarray, sum(b)) / k)
        elif layer == 0:
            ws.append(np.vstack(W))
            bs.append(np.concatenate(b))
        else:
            out = np.zeros((sum(w.shape[0] for w in W), sum(w.shape[1] for w in W)))
            r = c = 0
            for w in W:
                out[r:r + w.shape[0], c:c + w.shape[1]] = w
                r, c = r + w.shape[0], c + w.shape[1]
            ws.append(out)
            bs.append(np.concatenate(b))
    # each member's output bias (the ensemble keeps only their mean) and physics weight:
    # members() splits them back
    meta = {'ensemble_of_seeds': [n.seed for n in nets],
            'members': [n.meta for n in nets],
            'member_output_biases': [np.asarray(n.biases[-1], float).tolist() for n in nets],
            'member_physics': [float(n.physics) for n in nets]}
    return ResidualNet(a.window, a.dt_s, tuple(ws), tuple(bs), a.x_mean, a.x_std, a.y_scale,
                       float(np.mean([n.physics for n in nets])), a.seed, meta, a.features)


def restandardised(net: ResidualNet, x_mean: np.ndarray, x_std: np.ndarray,
                   y_scale: np.ndarray) -> ResidualNet:
    """
    Return ``net`` rewritten, exactly, to read inputs and give outputs in other scales.

    The first layer absorbs the change of input standardisation (W (x - m') / s' = W diag(s /
    s') z + W (m - m') / s' with z = (x - m) / s, per feature, over the window), the last
    layer's rows the change of output scale (y' / y). The accelerations are unchanged (to
    rounding).
    """
    if (np.array_equal(net.x_mean, x_mean) and np.array_equal(net.x_std, x_std)
            and np.array_equal(net.y_scale, y_scale)):
        return net
    ws = [np.array(w, float) for w in net.weights]
    bs = [np.array(b, float) for b in net.biases]
    gain = np.tile(np.asarray(x_std, float) / net.x_std, net.window)
    shift = np.tile((np.asarray(x_mean, float) - net.x_mean) / net.x_std, net.window)
    bs[0] = bs[0] + ws[0] @ shift
    ws[0] = ws[0] * gain[None, :]
    out = net.y_scale / np.asarray(y_scale, float)
    ws[-1] = ws[-1] * out[:, None]
    bs[-1] = bs[-1] * out
    meta = dict(net.meta)
    if 'member_output_biases' in meta:   # an ensemble's members' own biases, rescaled alike
        meta['member_output_biases'] = [(np.asarray(b, float) * out).tolist()
                                        for b in meta['member_output_biases']]
    return ResidualNet(net.window, net.dt_s, tuple(ws), tuple(bs), np.asarray(x_mean, float),
                       np.asarray(x_std, float), np.asarray(y_scale, float), net.physics,
                       net.seed, meta, net.features)


def members(net: ResidualNet) -> list[ResidualNet]:
    """
    Return the networks an :func:`ensemble` was made of (exactly), or ``[net]`` for one net.

    The ensemble's hidden layers are the members' stacked side by side (block-diagonal), so
    each member is a block: its rows of the first layer, its diagonal block of each deeper
    one, its columns of the output layer times the number of members. Their spread is the
    ensemble's uncertainty (``tuning/interval.py``).
    """
    seeds = net.meta.get('ensemble_of_seeds') if isinstance(net.meta, dict) else None
    if not seeds or len(seeds) < 2:
        return [net]
    k, L = len(seeds), len(net.weights)
    infos = net.meta.get('members') or [{}] * k
    out = []
    for m in range(k):
        ws, bs = [], []
        for layer in range(L):
            W, b = net.weights[layer], net.biases[layer]
            if layer == L - 1:
                h = W.shape[1] // k
                ws.append(W[:, m * h:(m + 1) * h] * k)
                own = net.meta.get('member_output_biases')
                # the ensemble averaged the members' output biases; each kept its own in meta
                bs.append(np.asarray(own[m], float) if own else b)
            else:
                h = W.shape[0] // k
                cols = slice(None) if layer == 0 else slice(m * (W.shape[1] // k),
                                                            (m + 1) * (W.shape[1] // k))
                ws.append(W[m * h:(m + 1) * h, cols])
                bs.append(b[m * h:(m + 1) * h])
        phys = net.meta.get('member_physics')   # a blend's members: hybrid or pure each
        out.append(ResidualNet(net.window, net.dt_s, tuple(ws), tuple(bs), net.x_mean,
                               net.x_std, net.y_scale, phys[m] if phys else net.physics,
                               int(seeds[m]),
                               dict(infos[m]) if m < len(infos) else {}, net.features))
    return out


def _shares_by_group(net: ResidualNet, ds: _Sets, groups: Mapping[str, str] | None
                     ) -> dict[str, float]:
    """Return the residual's share (:func:`_share`) on each group's training trials."""
    from mmg_tuner.learn._bridge import teacher_residuals
    out: dict[str, float] = {}
    if groups is None:
        return out
    off = np.cumsum([0] + [a.rows.shape[0] for a in ds.tr_arrs])
    for g in dict.fromkeys(_group(t.name, groups) for t in ds.train_trials):
        ks = [i for i, t in enumerate(ds.train_trials) if _group(t.name, groups) == g]
        Fg = np.concatenate([ds.F[off[i]:off[i + 1]] for i in ks])
        out[g] = _share(net, [ds.tr_arrs[i] for i in ks], Fg, teacher_residuals)[0]
    return out


def _share(net: ResidualNet, arrs: Sequence[TrialArrays], F_phys: np.ndarray,
           teacher_residuals: Callable[..., None]) -> tuple[float, dict[str, float]]:
    """
    Return the residual's share of the total acceleration on the training histories.

    RMS of the residual over RMS of physics + residual (each component in units of y_scale),
    clipped to [0, 1]; per component too. The pure network's share is 1.
    """
    names = ('du', 'dv', 'dr')
    if not net.physics:
        return 1.0, dict.fromkeys(names, 1.0)
    sizes, flat = net.packed()
    res = []
    for a in arrs:
        out = np.empty((a.rows.shape[0], 3))
        teacher_residuals(np.ascontiguousarray(a.rows), net.window, sizes, flat, net.x_mean,
                          net.x_std, net.y_scale, out)
        res.append(out)
    r = np.concatenate(res) / net.y_scale
    tot = F_phys[:, 3:6] / net.y_scale + r

    def ratio(a: np.ndarray, b: np.ndarray) -> float:
        den = math.sqrt(float(np.mean(b ** 2)))
        return min(1.0, math.sqrt(float(np.mean(a ** 2))) / den) if den > 0 else 0.0

    return ratio(r, tot), {n: ratio(r[:, i], tot[:, i]) for i, n in enumerate(names)}
