"""
A neural residual on the accelerations: the inference half of the hybrid model (issue 14).

A hybrid model is a physics family plus a small MLP that adds (du, dv_m, dr) to the family's
accelerations; with ``physics=False`` the MLP alone gives them (Wakita et al. 2022's Type-1
network, kept for comparison). As in that paper, the network sees a finite window of the
most recent samples (the current one included) of

    u, v_m, r (the model state, through the water), the family's first four command channels
    (a screw-and-rudder ship's rpm [rev/min], rudder [rad] and thrusters [rev/s], a tug's shaft
    speeds and measured azimuths; zero where it has fewer) and the apparent wind (air velocity
    relative to the ship) in body axes [m/s]: ``core.correction.feature_names``; optionally
    then the family's own accelerations at the sample (``PHYSICS_FEATURES``, the prediction
    the network corrects: ``ResidualConfig.physics_input``),

each standardised by ``x_mean``/``x_std`` and ordered oldest first. The residual is
evaluated once per sample from the sampled window and held over the sample interval, as the
recorded inputs are (zero-order hold; with Euler this is the paper's scheme). Before the first
sample of a run the window is padded with that sample; a restart from a measured state takes
the measured history before it.

A network stores its feature names and is refused for a ship whose family reads other
channels (:func:`check_fits`). Only NumPy and numba here (a ROS install without JAX runs
trained hybrids); training lives in ``learn/train.py``. The weights are stored in a portable
``.npz`` (no pickle). The runs step the core's one ``integrate.advance`` with the network's
accelerations.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import io
import json
import math
from pathlib import Path
from typing import Any, cast, Sequence, TYPE_CHECKING

from mmg_tuner._atomic import write_atomic
from mmg_tuner._limits import json_default, json_loads, load_yaml, read_npz
from mmg_tuner.core._jit import FASTMATH
from mmg_tuner.core.correction import (feature_names, feature_row, FEATURES, features_fit,
                                       N_COMMAND_SLOTS, N_FEATURES, PHYSICS_FEATURES,
                                       reads_physics, window_residual)
from mmg_tuner.core.correction import mlp_forward  # noqa: F401  (re-exported: the tests')
from mmg_tuner.core.dynamics import family_tag
from mmg_tuner.core.integrate import (actuator_outputs, drive, has_measured_wind, input_row,
                                      N_ENV, RECORD, start_state, STEERED, use_measured_wind)
from mmg_tuner.core.layout import OK, PARAM_INDEX, STATUS_TEXT
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.simulate import simulate as _simulate
from mmg_tuner.core.stepper import apparent_wind_body  # noqa: F401  (re-exported: the node's)
from mmg_tuner.core.trial import fitted_first_state, Trial
from mmg_tuner.errors import ConfigError, SimulationError
from mmg_tuner.learn._bridge import batch_derivative
from numba import njit
import numpy as np

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray, IntArray

FORMAT = 'mmg_tuner.residual/1'
FORMAT_BLEND = 'mmg_tuner.residual/2'
"""Format 2: as 1, with 'physics' a weight in (0, 1) (an ensemble of hybrid and pure nets)."""
X0_WINDOW_S = 10.0
"""The start-state fit of ``mt.simulate`` (tuning.objective.initial_state's default)."""

_toff = PARAM_INDEX['time_offset']
_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']


# ------------------------------------------------------------------------------- the network
@dataclass(frozen=True, eq=False)
class ResidualNet:
    """
    A trained residual (or pure) network, ready for inference.

    window: samples of history fed to the net (the current one included); dt_s: the sample
    interval the window is built on [s]; weights[l] (out, in) and biases[l] (out,) of the
    MLP layers (tanh between them, linear output); x_mean, x_std: (n_features,) input
    standardisation, applied to every row of the window; y_scale (3,): output scale, du
    [m/s^2], dv [m/s^2], dr [rad/s^2]; physics: the weight of the physics' accelerations
    added to the network's output, 1.0 (True) = physics + residual (hybrid), 0.0 (False) =
    the network alone (Wakita et al. 2022 Type-1), between for an ensemble of hybrid and pure
    networks (:func:`~mmg_tuner.learn.train.ensemble`: the hybrids' share); seed: the
    training seed; meta: training facts (trials, epochs, losses, share, seconds, versions);
    features: the names of a feature row (``core.correction.feature_names`` of the family it
    was trained for; ending with ``PHYSICS_FEATURES`` when it reads the physics' prediction):
    a ship whose family reads other channels is refused (:func:`check_fits`).
    """

    window: int
    dt_s: float
    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    x_mean: np.ndarray
    x_std: np.ndarray
    y_scale: np.ndarray
    physics: float = 1.0
    seed: int = 0
    meta: dict[str, Any] = field(default_factory=dict)
    features: tuple[str, ...] = FEATURES

    def __post_init__(self) -> None:
        """Check shapes once, so the compiled kernels never read out of bounds."""
        _check_net(self, '<ResidualNet>')
        object.__setattr__(self, 'physics', float(self.physics))

    def stepper(self) -> 'ResidualStepper':
        """Return the network one sample at a time (what the interactive simulator calls)."""
        return ResidualStepper(self)

    @property
    def n_features(self) -> int:
        """Length of one feature row (N_FEATURES, plus 3 when it reads the physics)."""
        return len(self.features)

    @property
    def physics_input(self) -> bool:
        """Whether the network reads the physics' accelerations (``PHYSICS_FEATURES``)."""
        return reads_physics(self.features)

    @property
    def n_inputs(self) -> int:
        """Length of the standardised, flattened window the MLP reads."""
        return self.window * self.n_features

    def packed(self) -> tuple[np.ndarray, np.ndarray]:
        """(layer sizes (L+1,) int64, flat float64 weights+biases) for the kernels."""
        sizes = [self.n_inputs] + [w.shape[0] for w in self.weights]
        flat = np.concatenate([np.concatenate([w.ravel(), b.ravel()])
                               for w, b in zip(self.weights, self.biases)])
        return np.asarray(sizes, dtype=np.int64), np.ascontiguousarray(flat, dtype=float)

    def save(self, path: str | Path) -> None:
        """Write a portable ``.npz`` (arrays and a JSON string; no pickle), atomically."""
        # a weight strictly between 0 and 1 (a blend) is written in format 2, which a reader
        # of format 1 (a bool) refuses instead of reading it as a hybrid
        blend = 0.0 < self.physics < 1.0
        arrays = {'format': np.array(FORMAT_BLEND if blend else FORMAT),
                  'window': np.array(self.window, np.int64), 'dt_s': np.array(self.dt_s, float),
                  'physics': np.array(self.physics if blend else bool(self.physics)),
                  'seed': np.array(self.seed, np.int64), 'n_layers': np.array(len(self.weights)),
                  'x_mean': self.x_mean, 'x_std': self.x_std, 'y_scale': self.y_scale,
                  'features': np.array(self.features),
                  'meta': np.array(json.dumps(self.meta, default=json_default))}
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            arrays[f'W{i}'] = w
            arrays[f'b{i}'] = b
        buf = io.BytesIO()
        np.savez(buf, **arrays)  # type: ignore[arg-type]  # stub: a key may be allow_pickle
        write_atomic(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> 'ResidualNet':
        """Read a file written by :meth:`save`; ConfigError names the file and the bad key."""
        path = Path(path)
        if not path.is_file():
            raise ConfigError(f'residual network file {path} does not exist')
        # only the members the format names, each checked from its header before it is read
        data = read_npz(path, path, 'residual network file', members=_is_member)

        def get(key: str) -> np.ndarray:
            if key not in data:
                raise ConfigError(f'{path}: key {key!r} missing: not a complete residual '
                                  'network file (written by mmg_tuner hybrid training)')
            return data[key]

        fmt = str(get('format'))
        if fmt not in (FORMAT, FORMAT_BLEND):
            raise ConfigError(f"{path}: key 'format' = {fmt!r}, expected {FORMAT!r} or "
                              f'{FORMAT_BLEND!r}')
        feats = tuple(str(f) for f in np.atleast_1d(get('features')))
        base = feats[:N_FEATURES]
        if len(base) != N_FEATURES or base[:3] != FEATURES[:3] or base[-2:] != FEATURES[-2:] \
                or (len(feats) > N_FEATURES and not reads_physics(feats)):
            raise ConfigError(f"{path}: key 'features' = {feats}, this version reads u, v, r, "
                              f'{N_COMMAND_SLOTS} command channels, wind_u, wind_v[, '
                              f'{", ".join(PHYSICS_FEATURES)}]')
        try:
            n = int(get('n_layers'))
            meta = json_loads(str(get('meta')), path, what="key 'meta'", limit=1 << 20)
            net = cls(window=int(get('window')), dt_s=float(get('dt_s')),
                      weights=tuple(np.asarray(get(f'W{i}'), float) for i in range(n)),
                      biases=tuple(np.asarray(get(f'b{i}'), float) for i in range(n)),
                      x_mean=np.asarray(get('x_mean'), float),
                      x_std=np.asarray(get('x_std'), float),
                      y_scale=np.asarray(get('y_scale'), float),
                      physics=float(get('physics')), seed=int(get('seed')), meta=meta,
                      features=feats)
        except ConfigError as exc:
            msg = str(exc).replace('<ResidualNet>', str(path))
            raise ConfigError(msg if msg.startswith(str(path)) else f'{path}: {msg}') from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(f'{path}: malformed residual network file ({exc})') from None
        return net


_MEMBERS = frozenset(('format', 'window', 'dt_s', 'physics', 'seed', 'n_layers', 'x_mean',
                      'x_std', 'y_scale', 'features', 'meta'))


def _is_member(name: str) -> bool:
    """Whether ``name`` is an array a residual network file has (see :meth:`ResidualNet.save`)."""
    return name in _MEMBERS or (name[:1] in ('W', 'b') and name[1:].isdigit()
                                and len(name) < 6)


def model_kind(net: ResidualNet | None) -> str:
    """
    'physics' (no network), 'hybrid', 'pure network' or 'blend' (physics weight in (0, 1)).

    A blend is an ensemble of hybrid and pure networks (``learn.ensemble``).
    """
    if net is None:
        return 'physics'
    return {1.0: 'hybrid', 0.0: 'pure network'}.get(net.physics, 'blend')


def load_residual(params_file: str | Path) -> ResidualNet | None:
    """
    Return the residual network a params.yaml names (``residual: FILE.npz``, relative to it).

    None when the file names none; a missing or corrupt network file is a ConfigError naming
    both files. A model is (ship, parameters, this network): ``load_ship(name, params_file)``
    gives the first two.
    """
    path = Path(params_file)
    doc = load_yaml(path, 'params file')   # size, depth and alias limits (_limits.py)
    name = doc.get('residual') if isinstance(doc, dict) else None
    if name is None:
        return None
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f'{path}: key "residual" = {name!r} must name a .npz file (relative '
                          'to the params file)')
    net_path = Path(name) if Path(name).is_absolute() else path.parent / name
    try:
        return ResidualNet.load(net_path)
    except ConfigError as exc:
        raise ConfigError(f'{path}: key "residual" names {net_path}, which cannot be used: '
                          f'{exc}') from None


def _check_net(net: ResidualNet, where: str) -> None:
    """Refuse inconsistent shapes or non-finite values, naming the key."""
    if not (isinstance(net.window, (int, np.integer)) and net.window >= 1):
        raise ConfigError(f"{where}: key 'window' = {net.window!r} must be an integer >= 1")
    if not (math.isfinite(net.dt_s) and net.dt_s > 0):
        raise ConfigError(f"{where}: key 'dt_s' = {net.dt_s!r} must be positive")
    if len(net.weights) != len(net.biases) or not net.weights:
        raise ConfigError(f'{where}: keys W*/b*: {len(net.weights)} weight and '
                          f'{len(net.biases)} bias arrays (need the same number, >= 1)')
    nf = len(net.features)
    if nf != N_FEATURES and not reads_physics(net.features):
        raise ConfigError(f"{where}: key 'features' holds {nf} names, need {N_FEATURES} "
                          f'(or {N_FEATURES + len(PHYSICS_FEATURES)} ending with '
                          f'{", ".join(PHYSICS_FEATURES)})')
    n_in = net.window * nf
    for i, (w, b) in enumerate(zip(net.weights, net.biases)):
        if w.ndim != 2 or w.shape[1] != n_in or b.shape != (w.shape[0],):
            raise ConfigError(f"{where}: key 'W{i}'/'b{i}' shapes {w.shape}/{b.shape} do "
                              f'not fit an input of {n_in}')
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
            raise ConfigError(f"{where}: key 'W{i}'/'b{i}' holds non-finite values")
        n_in = w.shape[0]
    if n_in != 3:
        raise ConfigError(f"{where}: key 'W{len(net.weights) - 1}' gives {n_in} outputs, "
                          'need 3 (du, dv, dr)')
    for key, a, n in (('x_mean', net.x_mean, nf), ('x_std', net.x_std, nf),
                      ('y_scale', net.y_scale, 3)):
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise ConfigError(f'{where}: key {key!r} must be {n} finite numbers, got shape '
                              f'{a.shape}')
    if not (np.all(net.x_std > 0) and np.all(net.y_scale > 0)):
        raise ConfigError(f"{where}: keys 'x_std', 'y_scale' must be positive")
    weight = net.physics
    if isinstance(weight, (bool, np.bool_)):
        weight = float(weight)
    if not (isinstance(weight, (int, float, np.floating, np.integer))
            and 0.0 <= float(weight) <= 1.0):
        raise ConfigError(f"{where}: key 'physics' = {net.physics!r} must be a weight in "
                          '[0, 1] (1: hybrid, 0: pure network)')


def zero_net(window: int, dt_s: float, hidden: Sequence[int] = (16,), physics: bool = True
             ) -> ResidualNet:
    """Return a network whose output is exactly zero (the hybrid then is its physics)."""
    sizes = [window * N_FEATURES, *hidden, 3]
    rng = np.random.default_rng(0)
    ws = [rng.normal(0, 0.3, (o, i)) for i, o in zip(sizes[:-1], sizes[1:])]
    ws[-1][:] = 0.0
    return ResidualNet(window, float(dt_s), tuple(ws), tuple(np.zeros(o) for o in sizes[1:]),
                       np.zeros(N_FEATURES), np.ones(N_FEATURES), np.ones(3), physics)


# ------------------------------------------------------------------------------- the kernels
@njit(cache=True, fastmath=FASTMATH)
def measured_rows(kind: tuple[int, ...], p_in: FloatArray, states: FloatArray, ctrl: FloatArray,
                  T: int, dt: float, rows: FloatArray, model_states: FloatArray) -> None:
    """
    Fill feature rows (T, N_FEATURES) and model states (T, 6) of a measured history.

    The physics' prediction is not among them (:func:`trial_rows` adds it).

    Each observed state is turned into the model's (antenna to midship, velocities through
    the water), with the inputs and measured wind of its sample.
    """
    p = p_in.copy()
    s = np.empty(6)
    inp = np.empty(ctrl.shape[1] - N_ENV)
    shift = p[_toff] / dt
    measured_wind = has_measured_wind(ctrl)
    for k in range(T):
        if measured_wind:
            use_measured_wind(p, ctrl, k)
        start_state(p, states[k], s)
        input_row(ctrl, k, shift, T, inp)
        feature_row(p, s, inp, rows[k])
        for i in range(6):
            model_states[k, i] = s[i]


@njit(cache=True, fastmath=FASTMATH)
def simulate_hybrid_one(kind: tuple[int, ...], p_in: FloatArray, x0: FloatArray,
                        hist: FloatArray, n_hist: int, ctrl: FloatArray, T: int, dt: float,
                        substeps: int, method: int, window: int, sizes: IntArray,
                        flat: FloatArray, x_mean: FloatArray, x_std: FloatArray,
                        y_scale: FloatArray, physics: float, out: FloatArray,
                        res_out: FloatArray) -> tuple[int, int]:
    """
    One hybrid run over T samples (``integrate.simulate_one`` plus the residual).

    x0: first observed state; hist (>= window-1, n_features): the feature rows before it, of
    which the last n_hist are valid (the rest of the window is padded with the first sample's
    row); res_out (T, 3): the residual held over each interval. Returns (status, k_fail).
    The core's one sample loop (``integrate.drive``) with the network attached.
    """
    start = np.empty((1, 6))
    for i in range(6):
        start[0, i] = x0[i]
    status, k_fail, _ = drive(kind, p_in, start, ctrl, T, dt, substeps, method, 0, RECORD,
                              start[0], np.empty(0, np.int64), out, start[0],
                              (window, sizes, flat, x_mean, x_std, y_scale, physics, hist,
                               n_hist, res_out))
    return status, k_fail


@njit(cache=True, fastmath=FASTMATH)
def steer_hybrid_one(kind: tuple[int, ...], p: FloatArray, x0: FloatArray, ctrl: FloatArray,
                     gear: FloatArray, T: int, dt: float, substeps: int, method: int,
                     window: int, sizes: IntArray, flat: FloatArray, x_mean: FloatArray,
                     x_std: FloatArray, y_scale: FloatArray, physics: float, out: FloatArray,
                     rudder_out: FloatArray, res_out: FloatArray) -> tuple[int, int]:
    """
    Run a manoeuvre of a hybrid with the steering gear in the loop (``integrate.run_maneuver``).

    x0: the midship state; gear: (rudder column, zigzag amplitude, check angle, rate) as
    ``integrate.drive`` reads them in STEERED mode; the residual is held over each sample
    interval (res_out (T, 3)), the steering gear moves each integration step.
    Returns (status, k_fail).
    """
    start = np.empty((1, 6))
    for i in range(6):
        start[0, i] = x0[i]
    status, k_fail, _ = drive(kind, p, start, ctrl, T, dt, substeps, method, 0, STEERED, gear,
                              np.empty(0, np.int64), out, rudder_out,
                              (window, sizes, flat, x_mean, x_std, y_scale, physics,
                               np.zeros((1, x_mean.shape[0])), 0, res_out))
    return status, k_fail


# --------------------------------------------------------------------------- Python entries
def fitted_start(trial: Trial, window_s: float = X0_WINDOW_S) -> np.ndarray:
    """Return the state ``mt.simulate`` starts a recorded trial from (the objective's rule)."""
    return fitted_first_state(trial, window_s)


def trial_rows(ship: ShipConfig, trial: Trial, physics_input: bool = False,
               params: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """
    Feature rows (T, n_features) and model states (T, 6) of a trial's measured states.

    physics_input: the rows end with the physics' accelerations at each measured state, with
    the ship's actuators run over the recorded inputs (``integrate.actuator_outputs``, one step
    per sample) and the sample's wind (:func:`sample_winds`). params: the ship's by default.
    """
    p = np.ascontiguousarray(ship.params if params is None else params, dtype=float)
    ctrl = np.ascontiguousarray(trial.input_array(ship.family.channels))
    T = len(trial)
    rows = np.empty((T, N_FEATURES + (len(PHYSICS_FEATURES) if physics_input else 0)))
    ms = np.empty((T, 6))
    base = np.empty((T, N_FEATURES))
    measured_rows(family_tag(ship.kind), p, np.ascontiguousarray(trial.states), ctrl, T,
                  float(trial.dt), base, ms)
    rows[:, :N_FEATURES] = base
    if physics_input:
        act = np.empty((T, len(ship.family.outputs)))
        actuator_outputs(ship.kind, p, ctrl, T, float(trial.dt), act)
        F = np.empty((T, 6))
        batch_derivative(family_tag(ship.kind), p, ms, act, sample_winds(ship, trial, p), F,
                         np.empty((0, 6, 6)), False)
        rows[:, N_FEATURES:] = F[:, 3:]
    return rows, ms


def sample_winds(ship: ShipConfig, trial: Trial, params: np.ndarray | None = None
                 ) -> np.ndarray:
    """
    Wind (T, 2: speed [m/s], direction it blows from [rad]) at each sample, as kernels apply it.

    The measured wind where recorded, else the last measured one held, else the parameters'.
    """
    p = ship.params if params is None else params
    T = len(trial)
    wind = np.empty((T, 2))
    vw, dw = float(p[_Vw]), float(p[_dirw])
    for k in range(T):
        if trial.wind is not None:
            wn, we = trial.wind[k]
            if wn == wn and we == we:
                vw, dw = math.sqrt(wn * wn + we * we), math.atan2(-we, -wn)
        wind[k] = vw, dw
    return wind


def check_fits(net: ResidualNet, ship: ShipConfig) -> None:
    """
    Refuse a network trained on other channels than ``ship``'s family reads (ConfigError).

    Its feature names against the family's (``core.correction.features_fit``), both named.
    """
    if not features_fit(net.features, ship.family):
        own = feature_names(ship.family)   # (refuses a family no network can read)
        raise ConfigError(f'the residual network reads {", ".join(f for f in net.features if f)}'
                          f'; {ship.name} ({ship.family.name} family) gives '
                          f'{", ".join(f for f in own if f)}: it was trained for another '
                          'kind of ship')


def _check_dt(net: ResidualNet, dt: float, what: str) -> None:
    if abs(dt - net.dt_s) > 1e-6 * net.dt_s:
        raise SimulationError(f'{what}: sample interval {dt:g} s, but the residual network was '
                              f'trained on a window of {net.dt_s:g} s samples; resample the '
                              f'trial to dt = {net.dt_s:g} s')


def simulate_segments(ship: ShipConfig, net: ResidualNet | None, trial: Trial,
                      integrator: str = 'rk4', restart_every_s: float | None = None,
                      substeps: int = 1, params: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, float | None, str]:
    """
    States (T, 6), residual (T, 3), first failure time [s from the trial's start] and reason.

    restart_every_s None: one run from :func:`fitted_start` (``mt.simulate``'s rule);
    a number: restarts from the measured state at t = 0, N, 2N, ... s (0: only at the start)
    as ``tuning.evaluate.predict`` does (raw measured states; the network's window then holds
    the measured history before each restart).
    """
    method = integrator_code(integrator)
    p = np.ascontiguousarray(ship.params if params is None else params, dtype=float)
    T = len(trial)
    dt = float(trial.dt)
    inputs = np.ascontiguousarray(trial.input_array(ship.family.channels))
    res = np.full((T, 3), np.nan)
    if net is not None:
        check_fits(net, ship)
        _check_dt(net, dt, trial.name)
        rows = trial_rows(ship, trial, net.physics_input, p)[0] \
            if restart_every_s is not None else None
        sizes, flat = net.packed()
    if restart_every_s is None:
        segs = [(0, T, fitted_start(trial))]
    else:
        segs = [(a, b, trial.states[a]) for a, b in trial.segments(restart_every_s)]
    out = np.full((T, 6), np.nan)
    fail_t, why = None, ''
    for a, b, x0 in segs:
        if b - a < 2:
            out[a] = trial.states[a]
            continue
        if net is None:
            run = _simulate(ship, x0, inputs[a:b], dt, integrator, substeps,
                            t0=float(trial.t[a]), params=p, check=False)
            seg, ok, k_fail, status = run.states, run.ok, None, run.status
            if not ok:
                k_fail = int(round((run.fail_time_s - trial.t[a]) / dt))
        else:
            seg = np.empty((b - a, 6))
            seg_res = np.empty((b - a, 3))
            if rows is None or a == 0:
                hist, n_hist = np.zeros((max(1, net.window - 1), net.n_features)), 0
            else:
                lo = max(0, a - (net.window - 1))
                hist = np.ascontiguousarray(rows[lo:a]) if a > lo else \
                    np.zeros((1, net.n_features))
                n_hist = a - lo
            st, k_fail = simulate_hybrid_one(
                family_tag(ship.kind), p, np.asarray(x0, float), hist, n_hist, inputs[a:b],
                b - a, dt,
                int(substeps), method, int(net.window), sizes, flat, net.x_mean, net.x_std,
                net.y_scale, float(net.physics), seg, seg_res)
            res[a:b] = seg_res
            ok, status = st == OK, STATUS_TEXT[st]
        out[a:b] = seg
        if not ok and fail_t is None:   # (k_fail is set where a run failed)
            fail_t = float(trial.t[a] - trial.t[0] + dt * min(cast(int, k_fail), b - a - 1))
            why = status
    return out, res, fail_t, why


def simulate_hybrid(ship: ShipConfig, net: ResidualNet | None, trial: Trial, *,
                    integrator: str = 'rk4', restart_every_s: float | None = None,
                    substeps: int = 1) -> Trial:
    """
    Predict a recorded trial with the hybrid model: a :class:`Trial` on the same grid.

    Driven by the recorded inputs, thrusters and measured wind (zero-order hold), starting
    from the fitted first state as ``mt.simulate`` does (restart_every_s None) or restarted
    from the measured state every restart_every_s s as ``evaluate`` does. net None: the plain
    physics (equal to ``mt.simulate``). A run that fails has NaN states from then on and
    ``status``/``fail_time_s`` saying so (the time of the first failure).

    Example::

        net = ResidualNet.load('out/residual.npz')
        run = simulate_hybrid(ship, net, trial)
    """
    states, _, fail_t, why = simulate_segments(ship, net, trial, integrator, restart_every_s,
                                               substeps)
    kind = model_kind(net)
    notes = [f'simulated by mmg_tuner ({ship.name}, {kind}, {integrator})']
    kw: dict[str, Any] = {}
    if fail_t is not None:
        notes.append(f'the simulation stopped at t = {fail_t:.2f} s: {why}')
        kw = {'status': why, 'fail_time_s': float(trial.t[0] + fail_t)}
    return Trial(trial.t.copy(), states, name=trial.name,
                 source=f'simulated: {trial.source or trial.name}', notes=notes,
                 start_s=trial.start_s, inputs=trial.inputs, **kw)


class ResidualStepper:
    """
    The residual one sample at a time (the simulator node's engine).

    A ring buffer holds the window. Call :meth:`accelerations` once per sample interval with
    the model state at its start, the inputs held over it and the apparent wind (and the
    physics' accelerations when the network reads them); hold the result over the interval.
    This reproduces :func:`simulate_hybrid` step by step.
    """

    def __init__(self, net: ResidualNet) -> None:
        self.net = net
        self._sizes, self._flat = net.packed()
        self._ring = np.empty((net.window, net.n_features))
        self._row = np.empty(net.n_features)
        self._z = np.empty(net.n_inputs)
        nb = int(self._sizes.max())
        self._a = np.empty(nb)
        self._b = np.empty(nb)
        self._fresh = True
        self.reset(None)

    def reset(self, state: object = None) -> None:
        """Forget the history: the next call pads the window with its own sample."""
        self._fresh = True

    def accelerations(self, state: np.ndarray | Sequence[float], act: Sequence[float],
                      wind_body: np.ndarray | Sequence[float],
                      physics: Sequence[float] | None = None) -> tuple[float, float, float]:
        """
        Return the residual's (du [m/s^2], dv [m/s^2], dr [rad/s^2]) for this sample.

        state: model state (x, y, psi, u, v_m, r), velocities through the water; act: inputs
        held over the interval (rpm [rev/min], rudder [rad][, bow, stern [rev/s]]);
        wind_body: the apparent wind in body axes [m/s] (:func:`apparent_wind_body`);
        physics: the family's (du, dv, dr) at this sample
        (``core.integrate.physics_accelerations``), needed when the network reads them.
        """
        r = self._row
        if self.net.physics_input:
            if physics is None:
                raise ValueError("this residual network reads the physics' accelerations: "
                                 'pass physics=(du, dv, dr) of the sample')
            r[N_FEATURES:] = physics[:3]
        r[0] = state[3]
        r[1] = state[4]
        r[2] = state[5]
        r[3] = act[0]
        r[4] = act[1]
        r[5] = act[2] if len(act) > 2 else 0.0
        r[6] = act[3] if len(act) > 3 else 0.0
        r[7] = wind_body[0]
        r[8] = wind_body[1]
        ring = self._ring
        if self._fresh:
            ring[:] = r
            self._fresh = False
        else:
            ring[:-1] = ring[1:]
            ring[-1] = r
        net = self.net
        a0, a1, a2 = window_residual(ring, net.window, self._sizes, self._flat, net.x_mean,
                                     net.x_std, net.y_scale, self._z, self._a, self._b)
        return float(a0), float(a1), float(a2)
