"""
Fixed-step integration of the family-blind dynamics, compiled with numba.

``advance`` (one sample interval; the one implementation used by offline simulation, the tuning
objective and the simulator node), whole trajectories (``simulate_one``/``simulate_many``),
manoeuvres with a steering gear in the loop (``run_maneuver``), the tuning cost
(``trajectory_cost``/ ``cost_many``) and its residual vector for least squares
(``residuals_many``: no trajectories kept). The hybrid's runs (``learn/residual.py``) call the same
``advance`` with the network's accelerations.

Every kernel takes the family's tag ``kind`` first and passes it down to
``core/dynamics.py``; nothing here knows a family or an actuator. The whole-run entry points
(``simulate_one``, ``simulate_many``, ``run_maneuver``, ``trajectory_cost``, ``cost_many``) take
the family code (``ShipConfig.kind``) and run the kernel compiled for its family alone.
Batching over candidates and trials is a ``prange`` over independent trajectories, which numba
spreads over cores. Input arrays ``ctrl`` (T, n) hold the family's channels
(``Family.channels``: its actuators' inputs, then the measured wind north/east, NaN where not
measured); the actuators keep their states in a small array ``a``.
The per-sample path (``advance``, the right-hand side ``dynamics.rhs``, the status checks,
``observe_row``) is inlined into the whole-run loops (numba ``inline='always'``) and indexes
rows instead of taking row views: every compiled call or view of an array costs atomic
reference-count updates, which took ~40 % of an Euler step.
The effects that act on observations and on the time base are hooks here (time_offset,
antenna offset, current in the observed velocities); those acting between a command and the
ship belong to the actuators (``core/actuators``).
"""
from __future__ import annotations

import functools
import math
from typing import Any, Callable, TYPE_CHECKING
import warnings

from mmg_tuner.core._jit import FASTMATH
from mmg_tuner.core.correction import feature_row, N_FEATURES, window_residual
from mmg_tuner.core.dynamics import (accelerations, act_tuple, actuate_hold, actuate_output,
                                     actuate_start, astern_surge, family_tag, N_ACT_STATES,
                                     rhs)
from mmg_tuner.core.frames import wrap_pi
from mmg_tuner.core.inputs import value
from mmg_tuner.core.layout import (DIVERGED, EULER, OK, PARAM_INDEX, RPM_NOT_POSITIVE,
                                   SURGE_NOT_POSITIVE)
from numba import njit, prange
from numba.core.errors import NumbaIRAssumptionWarning
import numpy as np

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray, IntArray

N_ENV = 2  # the measured wind north/east: the last two columns of every input array

# Inlining advance (which inlines the family's overload-inlined forces) trips a pedantic
# check of numba's IR inliner about renamed variables; the compiled code is checked
# against the non-inlined kernels by test/core/test_core_dispatch.py.
warnings.filterwarnings('ignore', 'variable .* is not in scope', NumbaIRAssumptionWarning)

_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_ax = PARAM_INDEX['antenna_x']
_ay = PARAM_INDEX['antenna_y']
_toff = PARAM_INDEX['time_offset']
_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']


@njit(cache=True, fastmath=FASTMATH)
def step(kind: tuple[int, ...], p: FloatArray, s: FloatArray, act: tuple[float, ...], h: float,
         method: int, r0: float, r1: float, r2: float, physics: float) -> None:
    """
    Advance s in place by one step h (Euler or classic RK4), inputs held over the step.

    Not inlined: the RK4 path's four right-hand sides stay one compiled function, which keeps
    the Euler hot loop small and the compile time of every whole-run kernel down. The stages
    are tuples (no work arrays: each array a compiled call hands on costs reference counts).
    """
    k1 = rhs(kind, p, s, act, r0, r1, r2, physics)
    if method == EULER:
        for i in range(6):
            s[i] += h * k1[i]
        return
    c = 0.5 * h
    t = (s[0] + c * k1[0], s[1] + c * k1[1], s[2] + c * k1[2], s[3] + c * k1[3],
         s[4] + c * k1[4], s[5] + c * k1[5])
    k2 = rhs(kind, p, t, act, r0, r1, r2, physics)
    t = (s[0] + c * k2[0], s[1] + c * k2[1], s[2] + c * k2[2], s[3] + c * k2[3],
         s[4] + c * k2[4], s[5] + c * k2[5])
    k3 = rhs(kind, p, t, act, r0, r1, r2, physics)
    t = (s[0] + h * k3[0], s[1] + h * k3[1], s[2] + h * k3[2], s[3] + h * k3[3],
         s[4] + h * k3[4], s[5] + h * k3[5])
    k4 = rhs(kind, p, t, act, r0, r1, r2, physics)
    for i in range(6):
        s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, fastmath=FASTMATH, inline='always')
def input_row(ctrl: FloatArray, k: int, frac_shift: float, T: int, inp: FloatArray) -> None:
    """Fill inp with the command channels at sample k (all but the wind), shifted in time."""
    for j in range(inp.shape[0]):
        inp[j] = value(ctrl, k, j, frac_shift, T)


@njit(cache=True, fastmath=FASTMATH)
def has_measured_wind(ctrl: FloatArray) -> bool:
    """Whether the wind columns (the last two) hold any measured value (decided per run)."""
    T, n = ctrl.shape
    for k in range(T):
        if ctrl[k, n - 2] == ctrl[k, n - 2] and ctrl[k, n - 1] == ctrl[k, n - 1]:
            return True
    return False


@njit(cache=True, fastmath=FASTMATH)
def to_water(p: FloatArray, s: FloatArray) -> None:
    """Convert a state with over-ground u, v to u, v through the water (in place)."""
    Vc = p[_Vc]
    if Vc != 0.0:
        rel = p[_dirc] - s[2]
        s[3] -= Vc * math.cos(rel)
        s[4] -= Vc * math.sin(rel)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def observe_row(p: FloatArray, s: FloatArray, out: FloatArray, k: int) -> None:
    """
    Measured quantities from the model state, written to row k of out (n, 6).

    Position at the antenna, velocities over ground (the model integrates velocities through the
    water). The whole-run loops pass a row index, not a row view: a view per sample costs two
    atomic reference-count updates.
    """
    for i in range(6):
        out[k, i] = s[i]
    psi = s[2]
    if p[_ax] != 0.0 or p[_ay] != 0.0:
        c = math.cos(psi)
        sn = math.sin(psi)
        out[k, 0] += p[_ax] * c - p[_ay] * sn
        out[k, 1] += p[_ax] * sn + p[_ay] * c
    if p[_Vc] != 0.0:
        rel = p[_dirc] - psi
        out[k, 3] += p[_Vc] * math.cos(rel)
        out[k, 4] += p[_Vc] * math.sin(rel)


@njit(cache=True, fastmath=FASTMATH)
def observe(p: FloatArray, s: FloatArray, out: FloatArray) -> None:
    """Measured quantities from the model state into out (6,) (as :func:`observe_row`)."""
    for i in range(6):
        out[i] = s[i]
    psi = s[2]
    if p[_ax] != 0.0 or p[_ay] != 0.0:
        c = math.cos(psi)
        sn = math.sin(psi)
        out[0] += p[_ax] * c - p[_ay] * sn
        out[1] += p[_ax] * sn + p[_ay] * c
    if p[_Vc] != 0.0:
        rel = p[_dirc] - psi
        out[3] += p[_Vc] * math.cos(rel)
        out[4] += p[_Vc] * math.sin(rel)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def state_status(kind: tuple[int, ...], s: FloatArray) -> int:
    """
    OK, DIVERGED (non-finite) or SURGE_NOT_POSITIVE (u <= 0 in a family without astern).

    Each element is tested on its own, never a sum: FASTMATH has no 'nnan'/'ninf', so a
    test of a loaded value stays, but with nsz + reassoc LLVM may fold isfinite(a + b) to True.
    """
    for i in range(6):
        if not math.isfinite(s[i]):
            return DIVERGED
    if s[3] <= 0.0 and not astern_surge(kind):
        return SURGE_NOT_POSITIVE
    return OK


@njit(cache=True, fastmath=FASTMATH, inline='always')
def advance(kind: tuple[int, ...], p: FloatArray, s: FloatArray, a: FloatArray,
            ctrl: FloatArray, k: int, shift: float, T: int, dt: float, substeps: int,
            method: int, r0: float = 0.0, r1: float = 0.0, r2: float = 0.0,
            physics: float = 1.0) -> int:
    """
    Advance the model state s (in place) over one sample interval dt: the one step function.

    The commands of sample k of ``ctrl`` (delayed by ``shift`` samples; T samples in all) are
    held over the interval; the actuators turn them into the actuator tuple (advancing their
    states ``a`` each integration step), the family and the shared hooks into accelerations,
    plus the learned residual's (r0, r1, r2) [m/s^2, m/s^2, rad/s^2] held over the interval
    when a network is attached. Returns the status (OK, or why the run stops).
    """
    h = dt / substeps
    st, held = actuate_hold(kind, p, ctrl, k, shift, T, h)
    if st != OK:
        return st
    for _ in range(substeps):
        act = actuate_output(kind, p, held, a)
        if method == EULER:  # the tuning hot path: keep the call chain shallow for inlining
            d = rhs(kind, p, s, act, r0, r1, r2, physics)
            for i in range(6):
                s[i] += h * d[i]
        else:
            step(kind, p, s, act, h, method, r0, r1, r2, physics)
    return state_status(kind, s)


@njit(cache=True, fastmath=FASTMATH)
def start_actuators(kind: tuple[int, ...], p: FloatArray, ctrl: FloatArray, shift: float, T: int,
                    a: FloatArray) -> None:
    """Set the actuator states a from sample 0 of ctrl (Python callers: the node, commands)."""
    actuate_start(kind, p, ctrl, shift, T, a)


@njit(cache=True, fastmath=FASTMATH)
def start_state(p: FloatArray, x0: FloatArray, s: FloatArray) -> None:
    """
    Model state from a first observed state.

    Antenna position moved to midship, velocities over ground turned into velocities through the
    water.
    """
    for i in range(6):
        s[i] = x0[i]
    c = math.cos(s[2])
    sn = math.sin(s[2])
    s[0] -= p[_ax] * c - p[_ay] * sn
    s[1] -= p[_ax] * sn + p[_ay] * c
    to_water(p, s)


@njit(cache=True, fastmath=FASTMATH)
def use_measured_wind(p: FloatArray, ctrl: FloatArray, k: int) -> None:
    """
    Set the wind parameters of p from the measured wind channels at sample k.

    Set the wind parameters of p (a per-trajectory copy) from the measured wind channels (air
    velocity north/east [m/s], the last two columns) at sample k; NaN keeps the parameters.
    """
    n = ctrl.shape[1]
    wn = ctrl[k, n - 2]
    we = ctrl[k, n - 1]
    if wn == wn and we == we:
        p[_Vw] = math.sqrt(wn * wn + we * we)
        p[_dirw] = math.atan2(-we, -wn)  # blows from the opposite of where the air goes


@njit(cache=True, fastmath=FASTMATH)
def physics_accelerations(kind: tuple[int, ...], p: FloatArray, s: FloatArray, a: FloatArray,
                          ctrl: FloatArray, k: int, shift: float, T: int,
                          h: float) -> tuple[float, float, float]:
    """
    Return the family's (du, dv_m, dr) at state s, inputs of sample k: the physics' prediction.

    The actuators advanced over h from their states ``a`` (left untouched), h the *sample*
    interval whatever the integration step, as the training's rows hold them (one actuator
    step per sample, ``actuator_outputs``): the input's definition must not depend on
    ``substeps`` or on the node's step (the actuators' states do, where their response over
    a sample is not exact in steps: a rate-limited azimuth); zeros where the inputs stop the
    run (advance then reports why). A network trained with ``physics_input`` reads it
    (``core.correction.PHYSICS_FEATURES``). Not inlined: the forces compiled once more into
    every whole-run loop would slow the tuning's.
    """
    st, held = actuate_hold(kind, p, ctrl, k, shift, T, h)
    if st != OK:
        return 0.0, 0.0, 0.0
    b = a.copy()
    act = actuate_output(kind, p, held, b)
    d = rhs(kind, p, s, act)
    return d[3], d[4], d[5]


RECORD = 0     # the driver writes the observed states (T, 6)
COST = 1       # it sums the weighted squared errors against a measured trial
RESIDUALS = 2  # it writes those weighted errors, one per (sample, channel)
STEERED = 3    # it writes the observed states, the rudder set by a steering gear in the loop


@njit(cache=True, fastmath=FASTMATH)
def drive(kind: tuple[int, ...], p_in: FloatArray, meas: FloatArray, ctrl: FloatArray, T: int,
          dt: float, substeps: int, method: int, shoot_every: int, mode: int, w: FloatArray,
          chans: IntArray, states: FloatArray, res: FloatArray,
          net: tuple[Any, ...]) -> tuple[int, int, float]:
    """
    Run one trajectory sample by sample: the one sample loop of the whole-run kernels.

    The run starts from the observed state meas[0] (antenna position, velocities over ground)
    and, with shoot_every > 0, restarts from meas[k] every shoot_every samples (multiple
    shooting); ctrl[k] holds the family's channels (commands, then the measured wind) held from
    sample k to k+1 (delayed by time_offset). What it does with each observed sample k+1 is
    ``mode`` (one compiled loop per family for every mode: inlined into each caller it
    compiled 20 % slower; the branch costs about 2 % of a step):
    RECORD writes it to states[k+1] (NaN from the failure on); COST sums
    sum_i w[i] (observed - measured)^2 (heading wrapped; velocities only when weighted);
    RESIDUALS writes w[chans[c]] (observed - measured) to res[k * len(chans) + c] (w the
    square roots of the weights; 1e6, a finite stand-in, from the failure on).
    STEERED generates a manoeuvre (``run_maneuver``): meas[0] is the midship state, no time
    offset, and the rudder column w[0] of ctrl holds the rudder *order* that a steering gear
    of rate w[3] [rad/s] (<= 0: instantaneous) turns, integration step by integration step,
    into the angle the actuators see, written to res[k] (w[1] != 0: the order closed on
    heading as an IMO zigzag of amplitude w[1], check angle w[2]).
    ``net``: a residual network's (window, layer sizes, flat weights, x_mean, x_std, y_scale,
    physics weight, feature rows before the start (the last n_hist valid), n_hist, out (T, 3))
    (``core/correction.py``; :func:`no_net` without one, window 0): its accelerations, from
    the window of feature rows ending at the sample, are held over each sample interval and
    written to out[k] (NaN from the failure on and at T - 1); restarts keep the window. Rows
    longer than N_FEATURES end with the physics' prediction (:func:`physics_accelerations`).
    Returns (status, k_fail, J): k_fail < T when the run failed (diverged or left the model's
    range) at that sample; J covers the samples before it.
    """
    window, sizes, flat, x_mean, x_std, y_scale, physics, hist, n_hist, res3 = net
    hybrid = window > 0
    nf = x_mean.shape[0]
    ring = np.empty((max(window, 1), nf))
    frow = np.empty(nf)
    z = np.empty(max(window, 1) * nf)
    nb = 1
    for i in range(sizes.shape[0]):
        nb = max(nb, sizes[i])
    buf_a = np.empty(nb)
    buf_b = np.empty(nb)
    inp = np.empty(ctrl.shape[1] - N_ENV)
    nh = hist.shape[0]
    p = p_in.copy()  # private: measured wind overwrites its wind slots (one copy per run)
    s = np.empty(6)
    o = np.empty((1, 6))
    a = np.zeros(N_ACT_STATES)
    nc = chans.shape[0]
    steered = mode == STEERED
    row = np.empty((1, ctrl.shape[1]))   # STEERED: this sample's inputs, the gear's rudder
    rc = int(w[0]) if steered else 0
    delta = 0.0  # STEERED: a straight approach, the rudder amidships moving at the gear's rate
    if steered:
        for i in range(6):
            s[i] = meas[0, i]
        to_water(p, s)
        for j in range(ctrl.shape[1]):
            row[0, j] = ctrl[0, j]
        row[0, rc] = delta
        res[0] = delta
        shift = 0.0
        actuate_start(kind, p, row, 0.0, 1, a)
        measured_wind = False
    else:
        start_state(p, meas[0], s)
        shift = p[_toff] / dt
        actuate_start(kind, p, ctrl, shift, T, a)
        measured_wind = has_measured_wind(ctrl)  # decided once per run
    if mode == RECORD or steered:
        observe_row(p, s, states, 0)
    h = dt / substeps
    max_move = w[3] * h if steered and w[3] > 0.0 else 1e9
    src = row if steered else ctrl
    n_inner = substeps if steered else 1
    step_shift = 0.0 if steered else shift
    step_T = 1 if steered else T
    step_dt = h if steered else dt
    step_substeps = 1 if steered else substeps
    cmd = 0.0
    zz_started = False
    zz_cmd = w[1] if steered else 0.0
    psi0 = s[2]
    J = 0.0
    status = OK
    k_fail = T
    for k in range(T - 1):
        if shoot_every > 0 and k > 0 and k % shoot_every == 0:
            start_state(p, meas[k], s)
        if measured_wind:
            use_measured_wind(p, ctrl, k)
        if steered:
            for j in range(ctrl.shape[1]):
                row[0, j] = ctrl[k, j]
            row[0, rc] = delta
        r0 = 0.0
        r1 = 0.0
        r2 = 0.0
        if hybrid:
            if steered:
                for j in range(inp.shape[0]):
                    inp[j] = row[0, j]
            else:
                input_row(ctrl, k, shift, T, inp)
            feature_row(p, s, inp, frow)
            if nf > N_FEATURES:
                ph = physics_accelerations(kind, p, s, a, src, 0 if steered else k,
                                           step_shift, step_T, dt)
                frow[N_FEATURES] = ph[0]
                frow[N_FEATURES + 1] = ph[1]
                frow[N_FEATURES + 2] = ph[2]
            if k == 0:   # the window before the first sample: the history, else padded
                for i in range(window - 1):
                    back = window - 1 - i
                    for f in range(nf):
                        ring[i, f] = hist[nh - back, f] if back <= n_hist else frow[f]
            else:
                for i in range(window - 1):
                    for f in range(nf):
                        ring[i, f] = ring[i + 1, f]
            for f in range(nf):
                ring[window - 1, f] = frow[f]
            r0, r1, r2 = window_residual(ring, window, sizes, flat, x_mean, x_std, y_scale, z,
                                         buf_a, buf_b)
            res3[k, 0] = r0
            res3[k, 1] = r1
            res3[k, 2] = r2
        # one call site of advance (each is a copy of the family's forces in the compiled
        # kernel): a steered run advances one integration step at a time from ``row``,
        # moving its gear in between; any other, one sample of ``ctrl``
        order = ctrl[k, rc] if steered else 0.0
        for _ in range(n_inner):
            if steered:
                cmd = order
                if w[1] != 0.0:
                    if not zz_started and order != 0.0:
                        zz_started = True
                        psi0 = s[2]
                    cmd = 0.0
                    if zz_started:
                        if zz_cmd > 0.0 and s[2] - psi0 >= w[2]:
                            zz_cmd = -abs(w[1])
                        elif zz_cmd < 0.0 and s[2] - psi0 <= -w[2]:
                            zz_cmd = abs(w[1])
                        cmd = zz_cmd
                # the step sees the logged angle at its start (as a zero-order-hold replay of
                # the recorded angle does); the gear then moves toward the order
                row[0, rc] = delta
            status = advance(kind, p, s, a, src, 0 if steered else k, step_shift, step_T,
                             step_dt, step_substeps, method, r0, r1, r2, physics)
            if not steered or status == RPM_NOT_POSITIVE:
                break
            delta += min(max_move, max(-max_move, cmd - delta))
        if steered and status != RPM_NOT_POSITIVE:   # a substep's other failures, per sample
            status = state_status(kind, s)
        if status != OK:
            k_fail = k if status == RPM_NOT_POSITIVE else k + 1
            break
        m = k + 1  # meas[m, i], not a row view (see observe_row)
        if mode == RECORD or steered:
            observe_row(p, s, states, m)
            if steered:
                res[m] = delta
            continue
        observe_row(p, s, o, 0)
        if mode == COST:
            e = o[0, 0] - meas[m, 0]
            J += w[0] * e * e
            e = o[0, 1] - meas[m, 1]
            J += w[1] * e * e
            e = wrap_pi(o[0, 2] - meas[m, 2])
            J += w[2] * e * e
            if w[3] != 0.0 or w[4] != 0.0 or w[5] != 0.0:
                for i in range(3, 6):
                    e = o[0, i] - meas[m, i]
                    J += w[i] * e * e
        else:
            for c in range(nc):
                i = chans[c]
                e = o[0, i] - meas[m, i]
                if i == 2:
                    e = wrap_pi(e)
                res[k * nc + c] = w[i] * e
    if k_fail < T and (mode == RECORD or steered):
        for k in range(k_fail, T):
            if steered:
                res[k] = np.nan
            for i in range(6):
                states[k, i] = np.nan
    elif k_fail < T and mode == RESIDUALS:
        for j in range(max(k_fail - 1, 0) * nc, (T - 1) * nc):
            res[j] = 1e6
    if hybrid:
        for k in range(min(k_fail, T - 1), T):
            for i in range(3):
                res3[k, i] = np.nan
    return status, k_fail, J


@njit(cache=True, inline='always')
def no_net() -> tuple[Any, ...]:
    """Return the ``net`` argument of :func:`drive` for a run without a residual network."""
    return (0, np.zeros(1, np.int64), np.zeros(1), np.zeros(N_FEATURES), np.ones(N_FEATURES),
            np.ones(3), 1.0, np.zeros((1, N_FEATURES)), 0, np.zeros((1, 3)))


@njit(cache=True, fastmath=FASTMATH)
def _simulate_one(kind: tuple[int, ...], p_in: FloatArray, x0: FloatArray, ctrl: FloatArray,
                  T: int, dt: float, substeps: int, method: int,
                  out: FloatArray) -> tuple[int, int]:
    """
    Simulate one trajectory over T samples spaced dt, writing observed states to out[:T].

    x0 is the first observed state (antenna position, velocities over ground); ctrl[k] holds
    the family's channels (commands, then the measured wind) held from sample k to k+1
    (delayed by time_offset if set). Returns (status, sample index of failure). After a
    failure the remaining rows are NaN.
    """
    start = np.empty((1, 6))
    for i in range(6):
        start[0, i] = x0[i]
    status, k_fail, _ = drive(kind, p_in, start, ctrl, T, dt, substeps, method, 0, RECORD,
                              start[0], np.empty(0, np.int64), out, start[0], no_net())
    return status, k_fail


@njit(cache=True, parallel=True)
def _simulate_many(kind: tuple[int, ...], params: FloatArray, x0s: FloatArray,
                   ctrls: FloatArray, lengths: IntArray, dt: float, substeps: int, method: int,
                   out: FloatArray, status: IntArray, k_fail: IntArray) -> None:
    """
    All (candidate, trial) pairs.

    Params (N, P), x0s (M, 6), ctrls (M, T, n_channels), lengths (M,), out (N, M, T, 6). Pairs are
    independent, so they run in parallel over cores.
    """
    N = params.shape[0]
    M = x0s.shape[0]
    for job in prange(N * M):
        i = job // M
        j = job % M
        st, kf = _simulate_one(kind, params[i], x0s[j], ctrls[j], lengths[j], dt, substeps,
                               method, out[i, j])
        status[i, j] = st
        k_fail[i, j] = kf


@njit(cache=True, fastmath=FASTMATH)
def _run_maneuver(kind: tuple[int, ...], p: FloatArray, x0: FloatArray, ctrl: FloatArray,
                  rudder_col: int, zigzag_amp: float, zigzag_check: float, rate: float, T: int,
                  dt: float, substeps: int, method: int, out: FloatArray,
                  rudder_out: FloatArray) -> tuple[int, int]:
    """
    Simulate a manoeuvre with a steering gear in the loop (for generating trials).

    ctrl (T, n): the family's channels at each sample, held per sample; its column
    ``rudder_col`` holds the open-loop rudder *order* [rad], which a steering gear of rate
    ``rate`` [rad/s] (<= 0: instantaneous) turns into the logged rudder angle the actuators
    see (each integration step sees the angle at its start). If zigzag_amp != 0 the order is
    instead closed on heading from the first sample whose order is not 0: it starts at
    zigzag_amp and reverses when the heading change passes +-zigzag_check (IMO zigzag).
    x0 is the midship state (velocities over ground). Writes observed states to out and the
    logged rudder angle at each sample to rudder_out. Returns (status, k_fail).
    """
    start = np.empty((1, 6))
    for i in range(6):
        start[0, i] = x0[i]
    gear = np.array([float(rudder_col), zigzag_amp, zigzag_check, rate])
    status, k_fail, _ = drive(kind, p, start, ctrl, T, dt, substeps, method, 0, STEERED, gear,
                              np.empty(0, np.int64), out, rudder_out, no_net())
    return status, k_fail


@njit(cache=True, fastmath=FASTMATH)
def _trajectory_cost(kind: tuple[int, ...], p_in: FloatArray, meas: FloatArray, ctrl: FloatArray,
                     T: int, dt: float, substeps: int, method: int, weights: FloatArray,
                     shoot_every: int) -> tuple[float, int]:
    """
    Weighted squared error of a simulation against a measured trial (Suyama et al. eq. 43).

    The simulation starts from meas[0] and is driven by ctrl; J = sum_{k>=1} e_k' W e_k with
    e = observed - measured over (x, y, psi (wrapped), u, v, r) and W = diag(weights).
    shoot_every > 0 restarts the simulation from the measured state every shoot_every samples
    (multiple shooting). Returns (J, k_fail): k_fail < T means the run failed at that sample
    (diverged or left the model's range) and J covers only the samples before it.
    """
    _, k_fail, J = drive(kind, p_in, meas, ctrl, T, dt, substeps, method, shoot_every, COST,
                         weights, np.empty(0, np.int64), meas, weights, no_net())
    return J, k_fail


@njit(cache=True, parallel=True)
def _cost_many(kind: tuple[int, ...], params: FloatArray, meas: FloatArray, ctrls: FloatArray,
               lengths: IntArray, dt: float, substeps: int, method: int, weights: FloatArray,
               shoot_every: int, J: FloatArray, k_fail: IntArray) -> None:
    """trajectory_cost for every (candidate, trial) pair, in parallel: J and k_fail (N, M)."""
    N = params.shape[0]
    M = meas.shape[0]
    for job in prange(N * M):
        i = job // M
        j = job % M
        c, kf = _trajectory_cost(kind, params[i], meas[j], ctrls[j], lengths[j], dt, substeps,
                                 method, weights, shoot_every)
        J[i, j] = c
        k_fail[i, j] = kf


@njit(cache=True, fastmath=FASTMATH)
def _trajectory_residuals(kind: tuple[int, ...], p_in: FloatArray, meas: FloatArray,
                          ctrl: FloatArray, T: int, dt: float, substeps: int, method: int,
                          sw: FloatArray, chans: IntArray, shoot_every: int,
                          out: FloatArray) -> int:
    """
    Write the weighted errors whose squares _trajectory_cost sums, one per (sample, channel).

    Samples 1..T-1 in order, for each the channels ``chans`` (those of nonzero weight):
    out[(k - 1) * len(chans) + c] = sw[chans[c]] * (observed - measured) (heading wrapped),
    sw the square roots of the weights. The run starts from meas[0] and, as _trajectory_cost,
    restarts from meas[k] every shoot_every samples (> 0): a least-squares fit of an objective
    with restarts minimises that objective's J, not a free run's. After a failure (diverged
    or left the model's range) the remaining entries are 1e6, a finite stand-in so a
    least-squares solver sees a large, not an undefined, error.
    Returns k_fail (T when the run completed).
    """
    _, k_fail, _ = drive(kind, p_in, meas, ctrl, T, dt, substeps, method, shoot_every,
                         RESIDUALS, sw, chans, meas, out, no_net())
    return k_fail


@njit(cache=True, parallel=True)
def _residuals_many(kind: tuple[int, ...], params: FloatArray, meas: FloatArray,
                    ctrls: FloatArray, lengths: IntArray, dt: float, substeps: int, method: int,
                    sw: FloatArray, chans: IntArray, shoot_every: int, offsets: IntArray,
                    out: FloatArray, k_fail: IntArray) -> None:
    """
    _trajectory_residuals for every (candidate, trial) pair, in parallel.

    sw (M, 6): each trial's square-root weights; trial j fills out[i, offsets[j]:offsets[j + 1]].
    """
    N = params.shape[0]
    M = meas.shape[0]
    for job in prange(N * M):
        i = job // M
        j = job % M
        k_fail[i, j] = _trajectory_residuals(kind, params[i], meas[j], ctrls[j], lengths[j], dt,
                                             substeps, method, sw[j], chans, shoot_every,
                                             out[i, offsets[j]:offsets[j + 1]])


@njit(cache=True, fastmath=FASTMATH)
def _actuator_outputs(kind: tuple[int, ...], p: FloatArray, ctrl: FloatArray, T: int, dt: float,
                      out: FloatArray) -> None:
    """
    Fill out (T, n) with the actuator tuple acting over each sample interval.

    One integration step per sample (as the hybrid's training simulates), the inputs shifted
    by time_offset; what the family's forces read (``Family.outputs``).
    """
    a = np.zeros(N_ACT_STATES)
    shift = p[_toff] / dt
    actuate_start(kind, p, ctrl, shift, T, a)
    for k in range(T):
        _, held = actuate_hold(kind, p, ctrl, k, shift, T, dt)
        act = actuate_output(kind, p, held, a)
        for i in range(len(act)):
            out[k, i] = act[i]


@njit(cache=True, fastmath=FASTMATH)
def _accelerations_many(kind: tuple[int, ...], p: FloatArray, nu: FloatArray, act: FloatArray,
                        out: FloatArray) -> None:
    """
    Fill out (B, 3) with (du/dt, dv_m/dt, dr/dt) of the family (``dynamics.accelerations``).

    nu (B, 3): velocities through the water (u, v_m [m/s], r [rad/s]); act (B, outputs): the
    actuator outputs acting (``Family.outputs``). No wind: the local step of the
    identification (``tuning/lo_go.py``) reads the equations of motion this way.
    """
    for b in range(nu.shape[0]):
        du, dv, dr = accelerations(kind, p, nu[b, 0], nu[b, 1], nu[b, 2],
                                   act_tuple(kind, act, b))
        out[b, 0] = du
        out[b, 1] = dv
        out[b, 2] = dr


def _for_family(kernel: Callable[..., Any]) -> Callable[..., Any]:
    """
    Make the Python entry point of a whole-run kernel.

    Same arguments, ``kind`` the family code; it runs the kernel compiled for that family
    alone (called with the family's tag): ~6 % faster than the run-time branch in the batched
    benchmark (bench/bench_core.py).
    """
    @functools.wraps(kernel)
    def entry(kind: int, *args: Any) -> Any:
        return kernel(family_tag(kind), *args)
    return entry


simulate_one = _for_family(_simulate_one)
simulate_many = _for_family(_simulate_many)
run_maneuver = _for_family(_run_maneuver)
trajectory_cost = _for_family(_trajectory_cost)
cost_many = _for_family(_cost_many)
residuals_many = _for_family(_residuals_many)
actuator_outputs = _for_family(_actuator_outputs)
accelerations_many = _for_family(_accelerations_many)
