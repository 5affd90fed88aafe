"""
Identification local -> global of a control-oriented model (MBPE-LOGO, arXiv 2312.05644).

The whole ship, in the paper's order (doc/reference/mbpe_logo_tug.md):

1. **Thrust** (:func:`fit_thrust`): the polynomial F(n) = p0 + p1 n + ... + p5 n^5 per
   thruster (eq. 20) fitted to a bollard-pull table (columns ``n,thrust``: rev/s, N per
   thruster; :func:`read_bollard_table` refuses a table that is too short or not monotone,
   saying why). Its degree is chosen by leave-one-out error among 1 ... min(5, points - 3).
2. **The actuators' own fits** (:func:`actuator_fits`): what an actuator declares it can fit
   of itself (``IDENTIFY``), e.g. the azimuth dynamics alpha'' = k1 (alpha_c - alpha) - k2
   alpha' (eq. 9) from the commanded and the measured angles, when a trial recorded both
   (``core/actuators/twin_azimuth_identify.py``: the core's actuator kernel replays the
   commands and SciPy's least squares matches its angles to the measured ones).
3. **LO** (:func:`lo_fit`): given measured accelerations, M nu_dot + C(nu) nu + D(nu) nu = tau
   is linear in the hull coefficients, so the local step is *one* linear least-squares
   problem. Its regressor is read from the family's own compiled equations (the core's
   accelerations and the family's ``mass_solve``): the equation error is evaluated for the
   coefficients and for each one moved by a step, and linearity (checked) turns the
   differences into the columns; what no coefficient scales (a mass matrix or a thrust kept
   at known values) is the right-hand side. No equation is written twice, and any family
   linear in its coefficients (the 22 of ``surge_decoupled``, the 6 of ``simplified6``,
   either Coriolis form; an actuator whose tau is linear in its own coefficients,
   ``screw_rudder_tau``, identified with the hull's) works. Accelerations
   come from the (Savitzky-Golay smoothed) velocities over each sample interval, the hull's
   forces averaged over its two ends (trapezoid), the thrust held as the kernels hold it.
4. **GO** (:func:`go_fit`): the multi-step simulation error of u, v, r (each over its pooled
   standard deviation) minimised from the LO solution with a ridge pull toward it
   (``GO_RIDGE``), by SciPy's
   trust-region least squares; the residuals of all candidates of a finite-difference
   Jacobian are simulated in one batched call of the core's kernel
   (``core.simulate.simulate_batch``). Multiple shooting at the data level: the trials are
   cut into pieces of ``segment_s`` seconds, each started from its measured state
   (``tuning/segments.py``; 0: single shooting, the paper's). ``grow``: manoeuvres are added
   one by one, each stage started from the previous one's solution (the paper's Algorithm 1;
   the LO step needs no repetition, being exact and global on each set).

:func:`identify` runs them in that order and returns an :class:`IdentifyResult` whose
:meth:`~IdentifyResult.write` gives ``params.yaml`` (loaded by ``load_ship(name, params)``),
``identify.json`` and ``identify.md``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import importlib
import logging
import math
from pathlib import Path
import time
from typing import Any, Callable, cast, Sequence, TYPE_CHECKING, TypedDict

from mmg_tuner._outdir import OutputDir
from mmg_tuner.core.actuators import actuator, load_companion
from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.integrate import accelerations_many, actuator_outputs
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.models import module_of
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import simulate_batch, steps_per_sample
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TuningError
from mmg_tuner.tuning.gate import check_before_writing, mark_note
from mmg_tuner.tuning.gate import markdown as gate_markdown
from mmg_tuner.tuning.objective import TrialBatch
from mmg_tuner.tuning.report import json_text, params_yaml_text, unique_names
from mmg_tuner.tuning.segments import split_trials
import numpy as np

if TYPE_CHECKING:   # annotations only
    from numpy.typing import ArrayLike

logger = logging.getLogger(__name__)
BOLLARD_SCATTER = 0.05   # a bollard row's scatter allowed, share of the largest pull
GO_RIDGE = 1e-3
"""GO's pull toward its start (LO, or the ship's values) per squared relative change: a
coefficient moves by its own size only where that lowers the simulation error by 0.1 % of
the velocities' variance. A prior that weak still keeps the terms twelve manoeuvres barely
excite (N_rrr, Y_absr_r) near their start; at 1e-6 (no prior) they drifted tenfold and a
2 Hz twin's held-out yaw rate error was 5.6 % (tug_random development seeds 0-9: every
twin better or equal at 1e-3 in v and r but two, by at most 0.25 points)."""

METHODS = ('lo', 'go', 'lo-go')
"""lo: the local step alone; go: the global step from the ship's values; lo-go: both."""
MIN_BOLLARD_POINTS = 4
"""A bollard table needs this many rows (n, thrust): a curve from fewer is a guess."""
MAX_THRUST_DEGREE = 5
THRUST_PARAMS = tuple(f'thrust_p{k}' for k in range(MAX_THRUST_DEGREE + 1))
LO_WINDOW_S = 4.0
"""LO fits velocity increments over windows this long [s] (0: accelerations per interval)."""
_VEL = (3, 4, 5)   # u, v, r in the state


# ------------------------------------------------------------------------------- thrust
@dataclass(frozen=True)
class BollardTable:
    """A bollard-pull test: shaft speed n [rev/s] and thrust [N] per thruster, n ascending."""

    n: np.ndarray
    thrust: np.ndarray
    source: str = ''
    astern_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The astern rows (n < 0) as measured: shaft speed [rev/s] and thrust [N], |n| ascending."""
    astern_thrust: np.ndarray = field(default_factory=lambda: np.zeros(0))


def read_bollard_table(path: str | Path) -> BollardTable:
    """Read a CSV with a header ``n,thrust`` (rev/s, N per thruster) and check it."""
    path = Path(path)
    from mmg_tuner._limits import check_lines, read_text   # size and line-length limits
    text = read_text(path, 'bollard-pull table', limit=1 << 20, error=TuningError)
    check_lines(text, path, 'bollard-pull table', error=TuningError)
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith('#')]
    if not lines:
        raise TuningError(f'bollard-pull table {path}: empty; expected a header n,thrust '
                          '(rev/s, N per thruster) and one row per shaft speed')
    header = [h.strip() for h in lines[0].split(',')]
    if 'n' not in header or 'thrust' not in header:
        raise TuningError(f'bollard-pull table {path}: header {",".join(header)!r} lacks '
                          'column n (rev/s) or thrust (N per thruster)')
    jn, jt = header.index('n'), header.index('thrust')
    n, F = [], []
    for i, ln in enumerate(lines[1:], start=2):
        cells = [c.strip() for c in ln.split(',')]
        try:
            n.append(float(cells[jn]))
            F.append(float(cells[jt]))
        except (IndexError, ValueError):
            raise TuningError(f'bollard-pull table {path}, row {i}: {ln!r} is not two '
                              'numbers n, thrust') from None
    return check_bollard_table(np.array(n), np.array(F), str(path))


def _by_speed(n: np.ndarray, F: np.ndarray, source: str,
              astern: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Return the rows sorted by shaft speed n (astern: its magnitude); one thrust per speed."""
    order = np.argsort(n, kind='stable')
    n, F = n[order], F[order]
    twice = np.diff(n) <= 0
    if np.any(twice):
        k = int(np.argmax(twice))
        what = 'an astern shaft speed' if astern else f'shaft speed n = {n[k]:g} rev/s'
        raise TuningError(f'{source}: {what} appears twice; one thrust per speed')
    return n, F


def check_bollard_table(n: ArrayLike, thrust: ArrayLike, source: str = 'bollard-pull table'
                        ) -> BollardTable:
    """Return the table, or a TuningError naming what makes it unusable."""
    n = np.asarray(n, dtype=float)
    F = np.asarray(thrust, dtype=float)
    if n.shape != F.shape or n.ndim != 1:
        raise TuningError(f'{source}: n and thrust must be two columns of equal length')
    if len(n) < MIN_BOLLARD_POINTS:
        raise TuningError(f'{source}: too short: {len(n)} rows; a thrust curve needs at least '
                          f'{MIN_BOLLARD_POINTS} shaft speeds (n, thrust)')
    if not (np.all(np.isfinite(n)) and np.all(np.isfinite(F))):
        k = int(np.argmax(~(np.isfinite(n) & np.isfinite(F))))
        raise TuningError(f'{source}: row {k + 1} has a non-finite value (n = {n[k]}, '
                          f'thrust = {F[k]})')
    # a load cell's scatter: near n = 0 the pull is smaller than the noise, so a row may dip
    # below the one before it or an astern row read a little positive; what exceeds this share
    # of the largest pull is a wrong row or unit, not scatter, and is refused
    tol = BOLLARD_SCATTER * float(np.max(np.abs(F)))
    astern = n < 0
    an, aF = -n[astern], F[astern]
    n, F = n[~astern], F[~astern]
    if an.size:
        if np.all(aF >= -tol) and np.any(aF > tol):   # magnitudes: the astern pull as positive
            aF = -aF
        if np.any(aF > tol):
            k = int(np.argmax(aF > tol))
            raise TuningError(f'{source}: astern row n = {-an[k]:g} rev/s has thrust '
                              f'{aF[k]:g} N: astern rows give the thrust astern (negative, or '
                              'every astern row positive as a magnitude), not a mix of signs')
        an, aF = _by_speed(an, aF, source, astern=True)
    if len(n) < MIN_BOLLARD_POINTS:
        raise TuningError(f'{source}: {len(n)} ahead rows (n >= 0); the ahead curve needs at '
                          f'least {MIN_BOLLARD_POINTS} shaft speeds (astern rows give the '
                          'astern ratio only)')
    n, F = _by_speed(n, F, source)
    if np.any(np.diff(F) < -tol):
        k = int(np.argmax(np.diff(F) < -tol))
        raise TuningError(f'{source}: not monotone: thrust falls from {F[k]:g} N at n = '
                          f'{n[k]:g} to {F[k + 1]:g} N at n = {n[k + 1]:g} rev/s, more than '
                          f'the {BOLLARD_SCATTER:.0%} of the largest pull a load cell scatters; '
                          'a bollard pull grows with shaft speed (check the units and the rows)')
    if np.any(np.diff(F) < 0):
        k = int(np.argmax(np.diff(F) < 0))
        logger.info('%s: thrust dips by %.3g N between n = %g and %g rev/s, within the load '
                    "cell's scatter: fitted through", source, F[k] - F[k + 1], n[k], n[k + 1])
    if not F[-1] > 0:
        raise TuningError(f'{source}: no positive thrust at any shaft speed')
    return BollardTable(n, F, source, an, aF)


@dataclass(frozen=True)
class ThrustFit:
    """Thrust polynomial coefficients p0..p5 [N / (rev/s)^k], its degree and fit quality."""

    coefficients: tuple[float, ...]
    degree: int
    rmse_N: float
    r2: float
    points: int
    astern_ratio: float | None = None
    """|thrust astern| / thrust ahead at the same |n|, from the astern rows (None: none)."""
    astern_points: int = 0

    @property
    def params(self) -> dict[str, float]:
        out = dict(zip(THRUST_PARAMS, self.coefficients))
        if self.astern_ratio is not None:
            out['thrust_astern_ratio'] = self.astern_ratio
        return out


def fit_thrust(table: BollardTable, degree: int | None = None) -> ThrustFit:
    """
    Fit F(n) = sum_k p_k n^k (eq. 20) to a bollard table, degree <= 5.

    ``degree`` None: the degree 1 ... min(5, points - 3) with the least leave-one-out error
    whose curve grows over the table's speeds (dips within ``BOLLARD_SCATTER`` of the
    largest pull allowed, as :func:`check_bollard_table` allows them in the rows).
    """
    n, F = table.n, table.thrust
    top = min(MAX_THRUST_DEGREE, len(n) - 3)
    # degree + 2 points at least: with degree + 1 the curve passes through every point and
    # leaves no residual to judge it (or the table) by
    if degree is not None and not 1 <= degree <= MAX_THRUST_DEGREE:
        raise TuningError(f'{table.source}: thrust degree {degree}: must be 1 ... '
                          f'{MAX_THRUST_DEGREE}')
    if degree is not None and len(n) < degree + 2:
        raise TuningError(f'{table.source}: too short for degree {degree}: {len(n)} rows; a '
                          f'polynomial of degree {degree} needs at least {degree + 2} shaft '
                          'speeds (one more than its coefficients, so that it is checked '
                          'against the table, not merely passed through it)')
    grid = np.linspace(n[0], n[-1], 200)
    tol = BOLLARD_SCATTER * float(np.max(np.abs(F)))
    best = None
    for d in ([degree] if degree is not None else range(1, max(1, top) + 1)):
        A = np.vander(n, d + 1, increasing=True)
        c, *_ = np.linalg.lstsq(A, F, rcond=None)
        H = A @ np.linalg.pinv(A)
        e = F - A @ c
        loo = float(np.mean((e / np.maximum(1e-12, 1 - np.diag(H))) ** 2))
        curve = np.vander(grid, d + 1, increasing=True) @ c
        # grows with n, up to the load cell's scatter: a dip of a few tenths of a newton near
        # n = 0 is noise (refusing it left a straight line for a curve like n^2.17)
        monotone = bool(np.max(np.maximum.accumulate(curve) - curve) <= tol)
        if degree is None and not monotone:
            continue
        if best is None or loo < best[0]:
            best = (loo, d, c, e)
    if best is None:
        raise TuningError(f'{table.source}: no polynomial of degree <= {top} grows with n '
                          'over the table; check the rows')
    _, d, c, e = best
    coef = tuple(float(x) for x in c) + (0.0,) * (MAX_THRUST_DEGREE - d)
    ss = float(np.sum((F - F.mean()) ** 2))
    ratio = None
    an, aF = table.astern_n, table.astern_thrust
    if an.size:   # astern: the ahead curve times one ratio, least squares over the astern rows
        ahead = np.vander(an, len(coef), increasing=True) @ np.array(coef)
        if float(ahead @ ahead) > 0:
            ratio = float(-aF @ ahead / (ahead @ ahead))
        if ratio is None or not 0.05 <= ratio <= 2.0:
            raise TuningError(f'{table.source}: the astern rows give {abs(aF).max():g} N at '
                              f'most, an astern/ahead ratio of {ratio if ratio else math.nan:.3g}'
                              ': outside 0.05 ... 2 (check the astern rows, their sign and units)')
    return ThrustFit(coef, d, float(np.sqrt(np.mean(e ** 2))),
                     1.0 - float(np.sum(e ** 2)) / ss if ss > 0 else 1.0, len(n), ratio,
                     int(an.size))


# ------------------------------------------------------------------ the actuators' own fits
def actuator_fits(ship: ShipConfig, trials: Sequence[Trial], substeps: int | None = None
                  ) -> dict[str, Any]:
    """
    Return what the ship's actuators fit of themselves from the trials, by name.

    An actuator may declare a fit of its own (``IDENTIFY``, core/actuators/__init__.py: a
    drive's constants from recorded commands and feedback); each returns an object with
    ``params``, ``report()`` and ``describe()``, or None (nothing to fit from these trials).
    """
    out: dict[str, Any] = {}
    for name in ship.family.actuators:
        kit = load_companion(name, 'IDENTIFY')
        if kit is None:
            continue
        fit = kit.fit(ship, trials, substeps)
        if fit is not None:
            out[str(kit.NAME)] = fit
    return out


# ----------------------------------------------------------------------------------- LO
def coefficient_names(ship: ShipConfig) -> tuple[str, ...]:
    """Return the family's model coefficients (its ``COEFFICIENTS``), else the ship's targets."""
    mod = importlib.import_module(module_of(ship.model))
    names = tuple(getattr(mod, 'COEFFICIENTS', ()) or ship.tuning_targets)
    if not names:
        raise TuningError(f'{ship.name}: the family {ship.model!r} declares no COEFFICIENTS '
                          'and the ship no tuning targets: nothing to identify')
    return names


def _check_family(ship: ShipConfig) -> None:
    fam = ship.family
    if fam.motion is None or fam.mass_solve is None:
        raise TuningError(f'{ship.name}: LO/GO identification needs a control-oriented family '
                          f'(its own M, C(nu), D(nu): surge_decoupled, simplified6); '
                          f'{ship.model!r} uses the MMG equations: tune it with CMA-ES '
                          '(no --method, no --bollard-pull)')


def _smooth(x: np.ndarray, dt: float, smooth_s: float) -> np.ndarray:
    """Savitzky-Golay (cubic) smoothing over ``smooth_s`` seconds (0 or too short: as is)."""
    w = int(round(smooth_s / dt)) | 1
    if smooth_s <= 0 or w < 5 or len(x) < w:
        return x
    from scipy.signal import savgol_filter
    return cast(np.ndarray, savgol_filter(x, w, 3, axis=0))   # (SciPy has no annotations)


def actuator_outputs_of(ship: ShipConfig, trial: Trial, params: np.ndarray | None = None,
                        commands: bool = False) -> np.ndarray:
    """
    Return the actuator outputs (T, outputs) acting over each sample interval.

    Through the core's actuator kernel from the recorded inputs. ``commands`` False: recorded
    commands are ignored, so the measured angles act, held over the interval (the local step's
    view); True: the actuator dynamics replay them.
    """
    fam = ship.family
    p = ship.params if params is None else params
    ctrl = np.array(trial.input_array(fam.channels))
    if not commands:
        for j, c in enumerate(fam.channels):
            if TABLE[c].default is not None and TABLE[c].default != TABLE[c].default:
                ctrl[:, j] = np.nan   # an optional command: "not recorded"
    T = len(trial)
    act = np.zeros((T, len(fam.outputs)))
    actuator_outputs(ship.kind, p, np.ascontiguousarray(ctrl), T, trial.dt, act)
    return act


def _tau(ship: ShipConfig, p: np.ndarray, nu: np.ndarray, act: np.ndarray) -> np.ndarray:
    """Return tau (len(nu), 3): the actuators' own ``forces`` at velocities nu, outputs act."""
    tau = np.zeros((len(nu), 3))
    k = 0
    for name in ship.family.actuators:
        a = actuator(name)
        if a.forces is not None:
            for i in range(len(nu)):
                u, v, r = nu[i]
                tau[i] += a.forces(p, u, v, r, tuple(act[i]), k)
        k += len(a.outputs)
    return tau


def actuator_forces(ship: ShipConfig, trial: Trial, params: np.ndarray | None = None,
                    commands: bool = False) -> np.ndarray:
    """
    Return tau (T, 3) [N, N, N m] of each sample interval from the recorded inputs.

    Through the core's actuator kernel (:func:`actuator_outputs_of`, ``commands`` as there)
    and the actuators' own ``forces``, at the measured velocities of each sample (an actuator
    whose force depends on the ship's speed, ``screw_rudder_tau``, reads them).
    """
    p = ship.params if params is None else params
    act = actuator_outputs_of(ship, trial, p, commands)
    return _tau(ship, p, trial.states[:, _VEL], act)


def mass_matrix(ship: ShipConfig, p: np.ndarray) -> np.ndarray:
    """Return M (3, 3) of a control-oriented family (mass_solve's response to unit forces)^-1."""
    # (a control-oriented family's mass_solve: _check_family refuses a family without one)
    mass_solve = cast(Callable[..., Any], ship.family.mass_solve)
    return np.linalg.inv(np.column_stack([mass_solve(p, *e) for e in np.eye(3)]))


@dataclass(frozen=True)
class Intervals:
    """Hold one trial's local-step data: nu (T, 3), dnu/dt (T-1, 3), actuator outputs (T-1, k)."""

    nu: np.ndarray
    dnu: np.ndarray
    act: np.ndarray


def interval_data(ship: ShipConfig, trial: Trial, smooth_s: float) -> Intervals:
    """
    Return the smoothed velocities, their differences and each interval's actuator outputs.

    The outputs from the recorded shaft speeds, rudder and measured azimuth angles, held over
    the interval as the kernels hold them: a recorded angle is the one acting over its sample
    interval (the repository's convention, doc/guides/tug.md), so a simulation driven by the
    recorded inputs reproduces the run.
    """
    nu = _smooth(trial.states[:, _VEL], trial.dt, smooth_s)
    dnu = np.diff(nu, axis=0) / trial.dt
    return Intervals(nu, dnu, actuator_outputs_of(ship, trial)[:-1])


def equation_error(ship: ShipConfig, p: np.ndarray, data: Intervals) -> np.ndarray:
    """
    M (dnu - the mean of the model's accelerations at both interval ends) (T-1, 3) [N, N, N m].

    That is M nu_dot + C nu + D nu - tau - F: the family's equations of motion read through
    the core's compiled accelerations (``core.integrate.accelerations_many``: hull, actuators'
    tau, the family's other forces such as tunnel thrusters, effects; no wind), each
    interval's actuator outputs held over it, evaluated at the velocities of both of its ends
    (trapezoid).
    """
    acc = np.empty((2 * len(data.dnu), 3))
    nu = np.ascontiguousarray(np.concatenate([data.nu[:-1], data.nu[1:]]))
    act = np.ascontiguousarray(np.concatenate([data.act, data.act]))
    accelerations_many(ship.kind, p, nu, act, acc)
    n = len(data.dnu)
    e: np.ndarray = (data.dnu - 0.5 * (acc[:n] + acc[n:])) @ mass_matrix(ship, p).T
    return e


def regressor(ship: ShipConfig, names: Sequence[str], data: Intervals
              ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return A (T-1, 3, d) and c (T-1, 3) with equation_error = A theta + c.

    Columns by differences of the family's and the actuators' terms around the ship's values
    (c: the part no named coefficient scales: the inertia of a fixed mass matrix, a fixed
    thrust); a model not linear in these coefficients (checked by a second, combined step) is
    refused.
    """
    p0 = ship.params.copy()
    idx = [PARAM_INDEX[n] for n in names]
    base = equation_error(ship, p0, data)
    steps = np.array([max(abs(p0[j]), 1.0) for j in idx])
    cols = []
    for j, step in zip(idx, steps):
        p = p0.copy()
        p[j] += step
        cols.append((equation_error(ship, p, data) - base) / step)
    A = np.stack(cols, axis=-1)
    # linearity: all coefficients moved at once by half their steps, predicted by A
    p = p0.copy()
    p[idx] += 0.5 * steps
    probe = equation_error(ship, p, data)
    scale = max(float(np.max(np.abs(base))), float(np.max(np.abs(probe))), 1e-9)
    if float(np.max(np.abs(probe - base - A @ (0.5 * steps)))) > 1e-6 * scale:
        raise TuningError(f'{ship.name}: the family {ship.model!r} is not linear in '
                          f'{", ".join(names)} (with the switches as set: e.g. '
                          'simplified6 needs tau_v = 1); the local step needs a model linear '
                          'in its coefficients')
    return A, base - A @ p0[idx]


@dataclass
class LoResult:
    """The local step: coefficients, the equation-error RMS per DOF, the regressor's cond."""

    names: tuple[str, ...]
    theta: np.ndarray
    residual_rms: tuple[float, float, float]   # [N, N, N m]
    condition: float
    samples: int
    wall_s: float
    window_s: float = 0.0
    constraints: tuple[str, ...] = ()
    """The physical constraints active at the solution (empty: the least-squares optimum)."""


def _window_sums(A: np.ndarray, c: np.ndarray, dt: float, K: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """
    Sum the interval rows A (n, 3, d), c (n, 3) over windows of K intervals, times dt.

    The sum of M dnu dt over K intervals is M (nu_end - nu_start); that of the trapezoid
    forces, their integral: the windowed rows are M delta-nu = integral (tau - C nu - D nu) dt,
    linear in the coefficients as the interval rows are, with the velocity noise entering
    through two samples per window instead of being divided by dt. Windows start every K / 2
    intervals; K <= 1: the interval rows as they are (the derivative form).
    """
    n = len(A)
    K = min(K, n)
    if K <= 1:
        return A, c
    cA = np.concatenate([np.zeros((1,) + A.shape[1:]), np.cumsum(A, axis=0)])
    cc = np.concatenate([np.zeros((1,) + c.shape[1:]), np.cumsum(c, axis=0)])
    starts = np.arange(0, n - K + 1, max(1, K // 2))
    return (cA[starts + K] - cA[starts]) * dt, (cc[starts + K] - cc[starts]) * dt


@dataclass(frozen=True)
class Physics:
    """
    The family's physics, linear in the coefficients: M(theta) and the hull's power.

    mass(theta) = mass0 + sum_j theta_j mass_cols[j] (None: the coefficients do not move M, or
    M is not linear in them); power rows P theta + p0 >= 0: nu^T D(nu) nu (the power the hull's
    damping takes out; the Coriolis terms do none) at sampled velocities, for the whole nu,
    for surge alone and for sway-yaw alone (None: an actuator coefficient is among the
    names, so the hull's power cannot be told from the actuator's).
    """

    names: tuple[str, ...]
    mass0: np.ndarray | None
    mass_cols: np.ndarray | None
    power: np.ndarray | None
    power0: np.ndarray | None
    diag_floor: np.ndarray | None

    def mass(self, theta: np.ndarray) -> np.ndarray | None:
        if self.mass0 is None:
            return None
        # (mass_cols are set with mass0)
        return self.mass0 + np.tensordot(theta, cast(np.ndarray, self.mass_cols), axes=1)

    def mass_minors(self, theta: np.ndarray) -> np.ndarray:
        """
        (diagonal of sym M - floor, 1 - c12^2, det C): each >= 0 for a positive definite M.

        C = D^-1/2 sym(M) D^-1/2 (D its diagonal): the minors of the normalised matrix, so
        the margin is the same whatever the units.
        """
        S = cast(np.ndarray, self.mass(theta))   # (called only where mass0 is set)
        S = 0.5 * (S + S.T)
        d = np.diag(S)
        if np.any(d <= 0):
            return np.concatenate([d - self.diag_floor, [-1.0, -1.0]])
        q = 1.0 / np.sqrt(d)
        C = S * q[:, None] * q[None, :]
        return np.concatenate([d - self.diag_floor, [1.0 - C[0, 1] ** 2, np.linalg.det(C)]])

    def mass_ok(self, theta: np.ndarray, margin: float = 0.0) -> bool:
        """Whether M(theta) is positive definite (its normalised minors above ``margin``)."""
        if self.mass0 is None:
            return True
        m = self.mass_minors(theta)
        return bool(np.all(m[:3] > 0) and np.all(m[3:] > margin))

    def dissipative(self, theta: np.ndarray, tol: float = 0.0) -> bool:
        """Whether the hull takes power out at every sampled velocity (within tol x scale)."""
        if self.power is None:
            return True
        pw = self.power @ theta + self.power0
        return bool(np.all(pw >= -tol * self.power_scale))

    @property
    def power_scale(self) -> float:
        return float(np.max(np.abs(self.power0))) if self.power0 is not None and len(
            self.power0) else 1.0


MASS_MARGIN = 0.1
"""LO keeps the normalised mass matrix's minors (1 - c12^2, det) at least this far from 0."""


def physics(ship: ShipConfig, names: Sequence[str], velocities: np.ndarray) -> Physics:
    """Return :class:`Physics` of ``ship`` for ``names``, its power sampled at ``velocities``."""
    names = tuple(names)
    p0 = ship.params.copy()
    idx = [PARAM_INDEX[n] for n in names]
    steps = np.array([max(abs(p0[j]), 1.0) for j in idx])
    mass0 = mass_cols = floor = None
    try:
        M0 = mass_matrix(ship, p0)
        cols = []
        for j, h in zip(idx, steps):
            p = p0.copy()
            p[j] += h
            cols.append((mass_matrix(ship, p) - M0) / h)
        Mc = np.array(cols)
        p = p0.copy()
        p[idx] += 0.5 * steps
        linear = np.allclose(mass_matrix(ship, p), M0 + np.tensordot(0.5 * steps, Mc, axes=1),
                             rtol=1e-8, atol=1e-8 * float(np.max(np.abs(M0))))
        if linear and np.any(np.abs(Mc) > 0) and np.all(np.isfinite(M0)):
            mass_cols = Mc
            mass0 = M0 - np.tensordot(p0[idx], Mc, axes=1)
            d0 = np.abs(np.diag(M0))
            floor = 1e-3 * np.where(d0 > 0, d0, max(float(np.max(d0)), 1.0))
    except (np.linalg.LinAlgError, ZeroDivisionError, FloatingPointError):
        pass
    power = power0 = None
    own = set(_actuator_params(ship))
    if not own & set(names) and len(velocities):
        nu = np.asarray(velocities, dtype=float)
        sets = [nu, nu * np.array([1.0, 0.0, 0.0]), nu * np.array([0.0, 1.0, 1.0])]
        nu = np.ascontiguousarray(np.concatenate(sets))
        act = np.zeros((len(nu), len(ship.family.outputs)))

        def pw(p: np.ndarray) -> np.ndarray:
            acc = np.empty((len(nu), 3))
            accelerations_many(ship.kind, p, nu, act, acc)
            f = -(acc @ mass_matrix(ship, p).T)    # C nu + D nu (tau = 0)
            s: np.ndarray = np.sum(f * nu, axis=1)
            return s
        try:
            base = pw(p0)
            cols = []
            for j, h in zip(idx, steps):
                p = p0.copy()
                p[j] += h
                cols.append((pw(p) - base) / h)
            P = np.column_stack(cols)
            if np.all(np.isfinite(P)) and np.all(np.isfinite(base)):
                power, power0 = P, base - P @ p0[idx]
        except (np.linalg.LinAlgError, ZeroDivisionError, FloatingPointError):
            pass
    return Physics(names, mass0, mass_cols, power, power0, floor)


def _sample_velocities(trials: Sequence[Trial], smooth_s: float, most: int = 300
                       ) -> np.ndarray:
    """Return up to ``most`` measured (smoothed) velocities of the trials, spread over them."""
    nu = np.concatenate([_smooth(t.states[:, _VEL], t.dt, max(smooth_s, 1.0)) for t in trials])
    nu = nu[np.all(np.isfinite(nu), axis=1)]
    if len(nu) > most:
        nu = nu[np.linspace(0, len(nu) - 1, most).astype(int)]
    return nu


def _constrained(B: np.ndarray, y: np.ndarray, cn: np.ndarray, phys: Physics,
                 x0: np.ndarray) -> tuple[np.ndarray, tuple[str, ...]]:
    """
    Minimise ||B x - y||^2 (theta = x / cn), M positive definite, the hull dissipative.

    SciPy's SLSQP on the normal equations (d unknowns): the power rows are linear
    inequalities, the mass matrix's normalised minors smooth ones (margin
    :data:`MASS_MARGIN`). Returns (x, the constraints active at the solution).
    """
    from scipy.optimize import minimize

    H = B.T @ B
    g = B.T @ y
    scale = max(float(np.max(np.abs(np.diag(H)))), 1e-300)
    cons = []
    if phys.power is not None:
        G = phys.power / cn[None, :]
        gs = np.maximum(np.linalg.norm(G, axis=1), 1e-300)
        cons.append({'type': 'ineq', 'fun': lambda x: (G @ x + phys.power0) / gs,
                     'jac': lambda x: G / gs[:, None]})
    if phys.mass0 is not None:
        def minors(x: np.ndarray) -> np.ndarray:
            m = phys.mass_minors(x / cn)
            m[3:] -= MASS_MARGIN
            # (mass0 checked not None above, diag_floor set with it; mypy does not narrow
            # an attribute inside a nested function)
            m[:3] /= np.maximum(np.abs(np.diag(cast(np.ndarray, phys.mass0)))
                                + cast(np.ndarray, phys.diag_floor) * 1e3, 1e-300)
            return m
        cons.append({'type': 'ineq', 'fun': minors})
    sol = minimize(lambda x: (x @ H @ x - 2 * g @ x) / scale, x0,
                   jac=lambda x: 2 * (H @ x - g) / scale, method='SLSQP', constraints=cons,
                   options={'maxiter': 300, 'ftol': 1e-12})
    x = sol.x
    active = []
    if phys.power is not None and np.min(phys.power @ (x / cn) + phys.power0) \
            < 1e-6 * phys.power_scale:
        active.append('dissipative damping')
    if phys.mass0 is not None and np.min(phys.mass_minors(x / cn)[3:]) < MASS_MARGIN + 1e-6:
        active.append('positive definite mass matrix')
    return x, tuple(active)


def lo_fit(ship: ShipConfig, trials: Sequence[Trial], names: Sequence[str] | None = None,
           smooth_s: float = 2.0, window_s: float | None = None,
           constrain: bool = True) -> LoResult:
    """
    Solve the local step: one (constrained) linear least-squares problem over all trials.

    A theta = -c (:func:`regressor`): with the hull's coefficients alone, c is minus the
    thrust and this is M nu_dot + C nu + D nu = tau; with the actuator's coefficients among
    them (``screw_rudder_tau``), their columns come from tau and c holds what stays fixed (a
    mass matrix kept at its published values).

    Errors in variables: measured velocities carry noise, and a derivative of them divides it
    by the sample interval. So the rows are integrated, not differentiated: over windows of
    ``window_s`` seconds (None: :data:`LO_WINDOW_S`; 0: every interval on its own, the
    derivative form) M (nu(t + w) - nu(t)) = integral of (tau - C nu - D nu) dt, the forces
    by trapezoid over the samples (:func:`_window_sums`). Rows: the three equations of every
    window, each DOF scaled by the RMS of its right-hand side (N and N m made comparable);
    columns scaled to unit norm (conditioning). ``constrain``: when the least-squares optimum
    is not physical (a mass matrix that is not positive definite, a hull that puts power in
    at a sampled velocity), the same problem under those constraints (:func:`_constrained`,
    SciPy SLSQP). ``residual_rms``: the equation error per sample interval [N, N, N m].
    """
    t0 = time.perf_counter()
    _check_family(ship)
    names = tuple(names or coefficient_names(ship))
    window_s = LO_WINDOW_S if window_s is None else float(window_s)
    As, bs, Ai, bi = [], [], [], []
    for tr in trials:
        if len(tr) < 3:
            raise TuningError(f'trial {tr.name}: fewer than 3 samples, no acceleration to fit')
        A, c = regressor(ship, names, interval_data(ship, tr, smooth_s))
        Ai.append(A)
        bi.append(-c)
        K = int(round(window_s / tr.dt)) if window_s > 0 else 1
        A, c = _window_sums(A, c, tr.dt, K)
        As.append(A)
        bs.append(-c)
    A = np.concatenate(As)
    b = np.concatenate(bs)
    if not float(np.max(np.abs(b))) > 1e-9 * max(float(np.max(np.abs(A))), 1e-300):
        raise TuningError(f'{ship.name}: the local step is homogeneous in '
                          f'{", ".join(names)} (the mass matrix, the damping and the thrust '
                          'all free: only their ratios are determined); keep the mass matrix '
                          'or a thrust coefficient at a known value (leave it out of the '
                          'tuning targets) or give a bollard-pull table')
    w = np.sqrt(np.mean(b ** 2, axis=0))
    w[~(w > 0)] = 1.0
    Aw = (A / w[None, :, None]).reshape(-1, len(names))
    bw = (b / w[None, :]).ravel()
    cn = np.linalg.norm(Aw, axis=0)
    cn[~(cn > 0)] = 1.0
    sol, *_ = np.linalg.lstsq(Aw / cn, bw, rcond=None)
    theta = sol / cn
    active: tuple[str, ...] = ()
    if constrain:
        phys = physics(ship, names, _sample_velocities(trials, smooth_s))
        if not (phys.mass_ok(theta, MASS_MARGIN) and phys.dissipative(theta)):
            start = np.array([ship[n] for n in names])
            ok = phys.mass_ok(start, MASS_MARGIN) and phys.dissipative(start)
            x, active = _constrained(Aw / cn, bw, cn, phys, start * cn if ok else sol)
            theta = x / cn
    s = np.linalg.svd(Aw / cn, compute_uv=False)
    A1, b1 = np.concatenate(Ai), np.concatenate(bi)
    res = (A1 @ theta) - b1
    # (the residuals' three columns: u, v, r)
    rms = cast(tuple[float, float, float],
               tuple(float(x) for x in np.sqrt(np.mean(res ** 2, axis=0))))
    return LoResult(names, theta, rms,
                    float(s[0] / s[-1]) if s[-1] > 0 else math.inf, len(b),
                    time.perf_counter() - t0, window_s, active)


# ----------------------------------------------------------------------------------- GO
@dataclass
class GoResult:
    """The global step: coefficients, its cost before and after, evaluations, stages."""

    names: tuple[str, ...]
    theta: np.ndarray
    cost_start: float
    cost: float
    evaluations: int
    stages: int
    wall_s: float
    success: bool
    message: str
    data_cost: float = math.nan
    """The simulation error alone (no pull toward the prior): what candidates are compared on."""
    start: str = ''
    """Where the winning GO started: 'LO' or "the ship's values"."""
    candidates: dict[str, float] = field(default_factory=dict)
    """Each start's data_cost (lo-go: GO from LO and GO from the ship's values)."""


def go_start_line(g: GoResult) -> str:
    """Say which GO start won and by how much (the simulation error alone, lower wins)."""
    if not g.candidates:
        return ''
    others = {k: v for k, v in g.candidates.items() if k != g.start}
    text = f'from {g.start} won, simulation error {g.data_cost:.4g}'
    for k, v in others.items():
        w = g.data_cost
        pc = 100.0 * (v - w) / w if math.isfinite(v) and math.isfinite(w) and w > 0 \
            else math.nan
        note = ('' if not math.isfinite(pc) else
                f' ({pc:.1f} % higher than the winner)' if pc >= 0 else
                ' (not physical: set aside)')
        text += f'; from {k}: {v:.4g}{note}'
    return text


class _Simulator:
    """u, v, r residuals of the (segmented) trials for a batch of coefficient vectors."""

    def __init__(self, ship: ShipConfig, trials: Sequence[Trial], names: Sequence[str],
                 segment_s: float, integrator: str, substeps: int, sigma: np.ndarray) -> None:
        named = [replace(t, name=n) for t, n in zip(trials, unique_names(trials))]
        segs = split_trials(named, segment_s)
        batch = TrialBatch.from_trials([s.trial for s in segs], x0_window_s=0.0)
        self.ship, self.idx = ship, [PARAM_INDEX[n] for n in names]
        self.meas = batch.meas
        self.ctrls = batch.inputs_for(ship.family.channels, ship.name)
        self.lengths = batch.lengths
        self.dt = batch.dt
        self.integrator, self.substeps = integrator, substeps
        T = self.meas.shape[1]
        self.mask = (np.arange(T)[None, :] < self.lengths[:, None])
        self.mask[:, 0] = False
        self.n = int(self.mask.sum())
        self.sigma = sigma
        self.target = (self.meas[..., _VEL] / sigma)[self.mask]

    def residuals(self, thetas: np.ndarray) -> np.ndarray:
        """(N, n * 3) residuals / sqrt(n) of coefficient vectors (N, d), each within +-10 sigma."""
        P = np.repeat(self.ship.params[None, :], len(thetas), axis=0)
        P[:, self.idx] = thetas
        out, _, _ = simulate_batch(self.ship.kind, P, self.meas[:, 0], self.ctrls, self.dt,
                                   self.lengths, self.integrator, self.substeps)
        sim = (out[..., _VEL] / self.sigma)[:, self.mask]
        r = sim - self.target[None]
        # a diverging candidate: bounded residuals keep the step finite and the cost comparable
        r[~np.isfinite(r)] = 10.0
        np.clip(r, -10.0, 10.0, out=r)
        rs: np.ndarray = r.reshape(len(thetas), -1) / math.sqrt(self.n)
        return rs

    def diverges(self, theta: np.ndarray) -> bool:
        """Whether the model leaves the measured velocities' range tenfold or turns non-finite."""
        P = self.ship.params[None, :].copy()
        P[:, self.idx] = theta
        out, _, _ = simulate_batch(self.ship.kind, P, self.meas[:, 0], self.ctrls, self.dt,
                                   self.lengths, self.integrator, self.substeps)
        sim = out[0][..., _VEL][self.mask]
        top = np.max(np.abs(self.meas[..., _VEL][self.mask]), axis=0)
        return bool(not np.all(np.isfinite(sim))
                    or np.any(np.max(np.abs(sim), axis=0) > 10 * np.maximum(top, 1e-3)))


def pooled_velocity_sigma(trials: Sequence[Trial]) -> np.ndarray:
    """Return the std of u, v, r over all samples (a floor keeps a flat one usable)."""
    st = np.concatenate([t.states[:, _VEL] for t in trials])
    s = np.std(st, axis=0)
    floored: np.ndarray = np.maximum(s, 1e-3 * max(float(np.max(s)), 1e-9))
    return floored


ResidualsAndJacobian = Callable[[np.ndarray, bool], tuple[np.ndarray, np.ndarray | None]]
"""(z, jacobian) -> (r(z), J(z) when ``jacobian``, else None)."""


def levenberg_marquardt(residuals_and_jacobian: ResidualsAndJacobian, z0: np.ndarray,
                        max_iter: int = 40, rtol: float = 1e-9
                        ) -> tuple[np.ndarray, float, int, int, str]:
    """
    Minimise ||r(z)||^2 by Levenberg-Marquardt on the normal equations (Marquardt scaling).

    ``residuals_and_jacobian(z, jacobian)`` returns r (and J when ``jacobian``). The normal
    equations are d x d, so no factorisation of the tall Jacobian is needed (SciPy's
    ``least_squares`` spends most of its time there: an SVD of the (n, d) matrix per step, slow
    when other jobs share the cores). Returns (z, cost, residual evaluations, Jacobians, why
    it stopped).
    """
    z = np.asarray(z0, dtype=float).copy()
    # (asked for, the Jacobian is returned)
    r, J = cast(tuple[np.ndarray, np.ndarray], residuals_and_jacobian(z, True))
    cost = float(r @ r)
    mu, nfev, njev = 1e-3, 1, 1
    why = f'{max_iter} iterations'
    for _ in range(max_iter):
        H = J.T @ J
        g = J.T @ r
        d = np.maximum(np.diag(H), 1e-12 * max(float(np.max(np.diag(H))), 1e-300))
        while True:
            step = np.linalg.solve(H + mu * np.diag(d), -g)
            r_new = residuals_and_jacobian(z + step, False)[0]
            nfev += 1
            c_new = float(r_new @ r_new)
            if c_new < cost:
                break
            mu *= 4.0
            if mu > 1e12:
                return z, cost, nfev, njev, 'no step lowers the cost (converged)'
        gain = cost - c_new
        z = z + step
        mu = max(mu / 3.0, 1e-12)
        cost = c_new
        if gain <= rtol * cost or np.linalg.norm(step) <= 1e-10 * (1 + np.linalg.norm(z)):
            why = 'converged (relative cost decrease below tolerance)'
            break
        r, J = cast(tuple[np.ndarray, np.ndarray], residuals_and_jacobian(z, True))
        njev += 1
    return z, cost, nfev, njev, why


def go_fit(ship: ShipConfig, trials: Sequence[Trial], theta0: np.ndarray,
           names: Sequence[str] | None = None, prior: np.ndarray | None = None,
           ridge: float = GO_RIDGE, segment_s: float = 20.0, integrator: str = 'rk4',
           substeps: int = 1, max_nfev: int = 40, grow: bool = False,
           phys: Physics | None = None) -> GoResult:
    """
    Minimise the simulation error of u, v, r from theta0, pulled toward ``prior`` (LO).

    cost = mean over samples of sum_{u,v,r} ((sim - meas) / sigma)^2
    + ridge * sum_j ((theta_j - prior_j) / s_j)^2, s_j = max(|prior_j|, a floor): a
    coefficient the data do not determine stays at its local value. Levenberg-Marquardt
    (:func:`levenberg_marquardt`), at most ``max_nfev`` iterations; each Jacobian is one batched
    simulation of the d + 1 candidates. ``grow``: the trials are added one by one
    (Algorithm 1), each stage from the last one's solution or from LO, whichever fits that
    stage's trials better (the paper's "from LO if GO fails"), earlier stages a quarter of the
    iterations. ``phys`` (:func:`physics`): a step to a mass matrix that is not positive
    definite is refused (its cost taken as the largest), so GO stays where M is physical.
    """
    t0 = time.perf_counter()
    _check_family(ship)
    names = tuple(names or coefficient_names(ship))
    theta0 = np.asarray(theta0, dtype=float)
    prior = theta0.copy() if prior is None else np.asarray(prior, dtype=float)
    scale = np.maximum(np.abs(prior), 0.02 * max(float(np.median(np.abs(prior))), 1e-6))
    sigma = pooled_velocity_sigma(trials)
    trials = list(trials)
    stages = ([trials[:j] for j in range(1, len(trials) + 1)] if grow and len(trials) > 1
              else [trials])
    theta = theta0.copy()
    evals = 0
    cost_start = cost = math.nan
    why = ''
    rw = math.sqrt(ridge)
    h = 1e-6
    for si, subset in enumerate(stages):
        sim = _Simulator(ship, subset, names, segment_s, integrator, substeps, sigma)

        def rj(z: np.ndarray, jacobian: bool, sim: _Simulator = sim
               ) -> tuple[np.ndarray, np.ndarray | None]:
            th = prior + z * scale
            cand = np.vstack([th[None], th[None] + np.diag(h * scale)]) if jacobian \
                else th[None]
            R = sim.residuals(cand)
            if not jacobian and phys is not None and not phys.mass_ok(th):
                R[0] = 10.0 / math.sqrt(sim.n)   # no ship: the worst cost there is
            r = np.concatenate([R[0], rw * z])
            if not jacobian:
                return r, None
            J = np.vstack([((R[1:] - R[0]) / h).T, rw * np.eye(len(z))])
            return r, J

        z0 = (theta - prior) / scale
        if si > 0:   # Algorithm 1: from the last stage's GO, or from LO where that fits worse
            r_go, r_lo = rj(z0, False)[0], rj(np.zeros_like(z0), False)[0]
            if not float(r_go @ r_go) <= float(r_lo @ r_lo):
                z0 = np.zeros_like(z0)
        last = si == len(stages) - 1
        if last:
            r0 = rj(z0, False)[0]
            cost_start = float(r0 @ r0)
        z, cost, nfev, njev, why = levenberg_marquardt(
            rj, z0, max_nfev if last else max(3, max_nfev // 4))
        evals += nfev + njev * (len(names) + 1)
        theta = prior + z * scale
    r_end = sim.residuals(theta[None])[0]
    return GoResult(names, theta, cost_start, cost, evals, len(stages),
                    time.perf_counter() - t0, True, why, float(r_end @ r_end))


# ------------------------------------------------------------------------------ identify
@dataclass
class IdentifyResult:
    """Everything :func:`identify` found; ``params`` the values written to params.yaml."""

    ship: ShipConfig = field(repr=False)
    method: str
    params: dict[str, float]
    thrust: ThrustFit | None
    actuators: dict[str, Any]
    """What the actuators fitted of themselves (:func:`actuator_fits`), by name."""
    lo: LoResult | None
    go: GoResult | None
    wall_s: float
    trials: list[str] = field(default_factory=list)

    @property
    def identified_ship(self) -> ShipConfig:
        return self.ship.with_params(self.params, 'identified parameters')

    def report(self) -> dict[str, Any]:
        """identify.json's content."""
        d: dict[str, Any] = {
            'ship': self.ship.name, 'model': self.ship.model, 'method': self.method,
            'trials': list(self.trials), 'wall_s': self.wall_s,
            'params': {n: {'pre': float(self.ship[n]), 'identified': float(v)}
                       for n, v in self.params.items()}}
        if self.thrust is not None:
            t = self.thrust
            d['thrust'] = {'coefficients': list(t.coefficients), 'degree': t.degree,
                           'rmse_N': t.rmse_N, 'r2': t.r2, 'points': t.points}
        for name, fit in self.actuators.items():
            d[name] = fit.report()
        if self.lo is not None:
            d['lo'] = {'residual_rms': list(self.lo.residual_rms),
                       'condition': self.lo.condition, 'samples': self.lo.samples,
                       'wall_s': self.lo.wall_s, 'window_s': self.lo.window_s,
                       'constraints_active': list(self.lo.constraints)}
        if self.go is not None:
            g = self.go
            d['go'] = {'cost_start': g.cost_start, 'cost': g.cost, 'evaluations': g.evaluations,
                       'stages': g.stages, 'wall_s': g.wall_s, 'success': g.success,
                       'message': g.message, 'data_cost': g.data_cost, 'start': g.start,
                       'candidates': dict(g.candidates), 'start_line': go_start_line(g)}
        return d

    def markdown(self) -> str:
        r = self.report()
        lines = [f'# identify: {self.ship.name} ({self.ship.model}), method {self.method}', '',
                 f'{len(self.trials)} trial(s), {self.wall_s:.1f} s.', '']
        if self.thrust is not None:
            t = self.thrust
            lines.append(f'- thrust polynomial, degree {t.degree} from {t.points} bollard '
                         f'points: RMSE {t.rmse_N:.3g} N, R^2 {t.r2:.5f}')
        lines += [f'- {fit.describe()}' for fit in self.actuators.values()]
        if self.lo is not None:
            lo = self.lo
            lines.append(f'- LO: one least-squares problem over {lo.samples} '
                         + (f'windows of {lo.window_s:g} s (velocity increments)'
                            if lo.window_s > 0 else 'intervals')
                         + f', condition {lo.condition:.3g}, equation error RMS '
                         + ', '.join(f'{x:.3g}' for x in lo.residual_rms)
                         + ' [N, N, N m]; constraints active: '
                         + (', '.join(lo.constraints) or 'none'))
        if self.go is not None:
            g = self.go
            lines.append(f'- GO: cost {g.cost_start:.4g} -> {g.cost:.4g} in {g.evaluations} '
                         f'simulations ({g.stages} stage(s)), {g.wall_s:.1f} s; {g.message}')
            if g.candidates:
                lines.append(f'- GO start: {go_start_line(g)}')
        lines += ['', '| parameter | pre-determined | identified |', '|---|---|---|']
        for n, v in r['params'].items():
            lines.append(f'| {n} | {v["pre"]:.6g} | {v["identified"]:.6g} |')
        return '\n'.join(lines) + '\n'

    def write(self, out: str | Path | OutputDir, write_unphysical: bool = False,
              trials: Sequence[Trial] = ()) -> list[Path]:
        """
        params.yaml, identify.md, then identify.json (its presence: the set is complete).

        The model is checked first (``tuning/gate.py``: plausibility, and a simulation of
        ``trials``, the identification's): a failure is a TuningError unless
        ``write_unphysical`` (then marked in identify.md and params.yaml's note).
        """
        marks = check_before_writing(self.ship, self.params, trials, 'identified parameters',
                                     write_unphysical)
        own = not isinstance(out, OutputDir)
        # (own: out is a path, else the open OutputDir; mypy does not narrow through own)
        od = OutputDir.open(cast('str | Path', out)) if own else cast(OutputDir, out)
        try:
            note = mark_note(f'identified by mmg_tuner ({self.method}) on '
                             + (', '.join(self.trials) or 'the trials'), marks)
            paths = [od.write_text('params.yaml', params_yaml_text(self.ship, self.params,
                                                                   note)),
                     od.write_text('identify.md', self.markdown() + gate_markdown(marks)),
                     od.write_text('identify.json', json_text(self.report()))]
        finally:
            if own:
                od.close()
        return paths


class _GoOptions(TypedDict):
    """The keyword arguments :func:`identify` passes to each start's :func:`go_fit`."""

    ridge: float
    segment_s: float
    integrator: str
    substeps: int
    max_nfev: int
    grow: bool
    phys: Physics | None


def identify(ship: ShipConfig, trials: Sequence[Trial], method: str = 'lo-go',
             bollard: BollardTable | None = None, thrust_degree: int | None = None,
             names: Sequence[str] | None = None, smooth_s: float = 2.0,
             ridge: float = GO_RIDGE, segment_s: float = 20.0, integrator: str = 'rk4',
             substeps: int | None = None, max_nfev: int = 40, grow: bool = False
             ) -> IdentifyResult:
    """
    Identify the whole ship: thrust curve, the actuators' own fits, hull coefficients (LO, GO).

    ``method``: 'lo', 'go' (from the ship's values) or 'lo-go' (GO from LO, pulled toward
    it; GO from the ship's values runs too and the physical one that fits the trials better
    wins, :func:`_best_go`). ``bollard``: the bollard-pull table (None: the ship's thrust
    curve is kept). ``substeps`` None: GO integrates in steps of at most 0.1 s.
    """
    t0 = time.perf_counter()
    if method not in METHODS:
        raise TuningError(f'method {method!r}: use one of {", ".join(METHODS)}')
    _check_family(ship)
    trials = list(trials)
    if not trials:
        raise TuningError('identify: no trials given')
    names = tuple(names or coefficient_names(ship))
    params: dict[str, float] = {}
    thrust = None
    if bollard is not None:
        from mmg_tuner.data.channel_units import bollard_unit_warnings, warn_all
        warn_all(bollard_unit_warnings(ship, np.concatenate([-bollard.astern_n, bollard.n]),
                                       np.concatenate([bollard.astern_thrust, bollard.thrust]),
                                       bollard.source or 'bollard-pull table'), logger)
        thrust = fit_thrust(bollard, thrust_degree)
        params.update(thrust.params)
        logger.info('thrust: degree %d, RMSE %.3g N over %d bollard points', thrust.degree,
                    thrust.rmse_N, thrust.points)
    if substeps is None:
        substeps = steps_per_sample(max(t.dt for t in trials))
    fits = actuator_fits(ship.with_params(params), trials, substeps)
    for fit in fits.values():
        params.update(fit.params)
        logger.info('%s', fit.describe())
    work = ship.with_params(params)
    lo = go = None
    theta = np.array([work[n] for n in names])
    if method in ('lo', 'lo-go'):
        lo = lo_fit(work, trials, names, smooth_s)
        theta = lo.theta
        logger.info('LO: %d intervals, %.2f s', lo.samples, lo.wall_s)
    if method in ('go', 'lo-go'):
        phys = physics(work, names, _sample_velocities(trials, smooth_s))
        opts: _GoOptions = {'ridge': ridge, 'segment_s': segment_s, 'integrator': integrator,
                            'substeps': substeps, 'max_nfev': max_nfev, 'grow': grow,
                            'phys': phys}
        starts = [('LO', theta)] if method == 'lo-go' else []
        starts.append(("the ship's values", np.array([work[n] for n in names])))
        runs = [(label, go_fit(work, trials, th0, names, prior=th0, **opts))
                for label, th0 in starts]
        go = _best_go(work, trials, names, runs, phys, integrator, substeps)
        theta = go.theta
        logger.info('GO: cost %.4g -> %.4g, %.1f s, from %s', go.cost_start, go.cost,
                    go.wall_s, go.start)
    params.update({n: float(v) for n, v in zip(names, theta)})
    return IdentifyResult(ship, method, params, thrust, fits, lo, go, time.perf_counter() - t0,
                          unique_names(trials))


def _best_go(ship: ShipConfig, trials: Sequence[Trial], names: tuple[str, ...],
             runs: list[tuple[str, GoResult]], phys: Physics, integrator: str,
             substeps: int) -> GoResult:
    """
    Return the GO run with the least simulation error among the physical ones.

    Physical: a positive definite mass matrix and a free run of every identification trial
    that stays finite and within ten times the measured velocities. When none is, the least
    error (the model check before writing names what is wrong). The winner carries every
    start's error (``candidates``) and where it started (``start``).
    """
    full = _Simulator(ship, trials, names, 0.0, integrator, substeps,
                      pooled_velocity_sigma(trials)) if len(runs) else None
    scored = []
    for label, g in runs:
        # (full exists when there are runs)
        ok = phys.mass_ok(g.theta) and not cast(_Simulator, full).diverges(g.theta)
        scored.append((not ok, g.data_cost, label, g))
        if not ok:
            logger.warning('GO from %s: %s', label, 'mass matrix not positive definite'
                           if not phys.mass_ok(g.theta) else 'diverges on its own trials')
    scored.sort(key=lambda x: (x[0], x[1] if math.isfinite(x[1]) else math.inf))
    best = scored[0][3]
    best.start = scored[0][2]
    best.candidates = {label: g.data_cost for label, g in runs}
    best.wall_s = sum(g.wall_s for _, g in runs)
    best.evaluations = sum(g.evaluations for _, g in runs)
    return best


def _actuator_params(ship: ShipConfig) -> tuple[str, ...]:
    """Return the parameters of the ship's actuators (not the hull's)."""
    return tuple(q for a in ship.family.actuators for q in actuator(a).params)


__all__ = ['BollardTable', 'GO_RIDGE', 'GoResult', 'IdentifyResult', 'LoResult', 'METHODS',
           'ThrustFit', 'actuator_fits', 'check_bollard_table', 'fit_thrust', 'go_fit', 'identify',
           'lo_fit', 'read_bollard_table', 'steps_per_sample']
