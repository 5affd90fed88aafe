"""
Fixed-step integration of the family-blind dynamics, compiled with numba.

``advance`` (one sample interval; the one implementation used by offline simulation, the tuning
objective and the simulator node), whole trajectories (``simulate_one``/``simulate_many``),
manoeuvres with a steering gear in the loop (``run_maneuver``) and the tuning cost
(``trajectory_cost``/ ``cost_many``).

Every kernel takes the family ``kind`` first and passes it down to
:func:`~mmg_tuner.core.dynamics.derivative`; nothing here knows a family. ``kind`` is the
family code (``ShipConfig.kind``, branched on at run time) or its tag
(``dynamics.FAMILY_TAGS``: the kernel is compiled for that family alone). The whole-run entry
points (``simulate_one``, ``simulate_many``, ``run_maneuver``, ``trajectory_cost``,
``cost_many``) take the code and run the kernel compiled for its family. Batching over
candidates and trials is a ``prange`` over independent trajectories, which numba spreads over
cores. Input arrays ``ctrl`` (T, n) hold the channels of ``core/channels.py`` in order.
The per-sample path (``advance``, the right-hand side ``dynamics.rhs``, the status checks,
``observe_row``) is inlined into the whole-run loops (numba ``inline='always'``) and indexes
rows instead of taking row views: every compiled call or view of an array costs atomic
reference-count updates, which took ~40 % of an Euler step.
The effects that act on inputs and observations are hooks here (rpm_scale, rudder_offset,
rudder_lag_tau, time_offset, antenna offset, current in the observed velocities).
"""
from __future__ import annotations

import functools
import math
import warnings

from mmg_tuner.core._jit import FASTMATH
from mmg_tuner.core.channels import BOW_THRUSTER, RPM, RUDDER, STERN_THRUSTER, WIND_E, WIND_N
from mmg_tuner.core.dynamics import astern_rpm, astern_surge, family_tag, rhs
from mmg_tuner.core.frames import wrap_pi
from mmg_tuner.core.layout import (DIVERGED, EULER, OK, PARAM_INDEX, RPM_NOT_POSITIVE,
                                   SURGE_NOT_POSITIVE)
from numba import njit, prange
from numba.core.errors import NumbaIRAssumptionWarning
import numpy as np

# Inlining advance (which inlines the family's overload-inlined forces) trips a pedantic
# check of numba's IR inliner about renamed variables; the compiled code is checked
# against the non-inlined kernels by test/test_core_dispatch.py.
warnings.filterwarnings('ignore', 'variable .* is not in scope', NumbaIRAssumptionWarning)

_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_doff = PARAM_INDEX['rudder_offset']
_tau = PARAM_INDEX['rudder_lag_tau']
_nscale = PARAM_INDEX['rpm_scale']
_ax = PARAM_INDEX['antenna_x']
_ay = PARAM_INDEX['antenna_y']
_toff = PARAM_INDEX['time_offset']
_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']


@njit(cache=True, fastmath=FASTMATH)
def step(kind, p, s, act, h, method, k1, k2, k3, k4, tmp):
    """Advance s in place by one step h (Euler or classic RK4), inputs held over the step."""
    rhs(kind, p, s, act, k1)
    if method == EULER:
        for i in range(6):
            s[i] += h * k1[i]
        return
    for i in range(6):
        tmp[i] = s[i] + 0.5 * h * k1[i]
    rhs(kind, p, tmp, act, k2)
    for i in range(6):
        tmp[i] = s[i] + 0.5 * h * k2[i]
    rhs(kind, p, tmp, act, k3)
    for i in range(6):
        tmp[i] = s[i] + h * k3[i]
    rhs(kind, p, tmp, act, k4)
    for i in range(6):
        s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, fastmath=FASTMATH, inline='always')
def _control_at(ctrl, k, j, frac_shift, T):
    """Control channel j at sample k delayed by frac_shift samples (linear interpolation)."""
    if frac_shift == 0.0:
        return ctrl[k, j]
    t = k - frac_shift
    if t <= 0.0:
        return ctrl[0, j]
    if t >= T - 1:
        return ctrl[T - 1, j]
    i = int(t)
    w = t - i
    return (1.0 - w) * ctrl[i, j] + w * ctrl[i + 1, j]


@njit(cache=True, fastmath=FASTMATH)
def to_water(p, s):
    """Convert a state with over-ground u, v to u, v through the water (in place)."""
    Vc = p[_Vc]
    if Vc != 0.0:
        rel = p[_dirc] - s[2]
        s[3] -= Vc * math.cos(rel)
        s[4] -= Vc * math.sin(rel)


@njit(cache=True, fastmath=FASTMATH, inline='always')
def observe_row(p, s, out, k):
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
def observe(p, s, out):
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
def rpm_status(kind, n_rps):
    """OK or RPM_NOT_POSITIVE: n_P <= 0 (or NaN) is refused unless the family covers astern."""
    if n_rps > 0.0 or (astern_rpm(kind) and n_rps == n_rps):
        return OK
    return RPM_NOT_POSITIVE


@njit(cache=True, fastmath=FASTMATH, inline='always')
def state_status(kind, s):
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
def advance(kind, p, s, delta_act, rpm, rudder, dt, substeps, method, k1, k2, k3, k4, tmp,
            bow=0.0, stern=0.0):
    """
    Advance the model state s (in place) over one sample interval dt.

    With the recorded or commanded rpm, rudder [rad] and thrusters [rev/s] held.

    delta_act is the actual rudder angle (the steering-gear lag state); the input effects act
    here: rpm_scale, rudder_offset, rudder_lag_tau. Returns (status, new delta_act).
    """
    n_rps = rpm * p[_nscale] / 60.0
    st = rpm_status(kind, n_rps)
    if st != OK:
        return st, delta_act
    delta_cmd = rudder + p[_doff]
    h = dt / substeps
    tau = p[_tau]
    decay = math.exp(-h / tau) if tau > 0.0 else 0.0
    for _ in range(substeps):
        # steering gear: exact first-order response to the held command
        delta_act = delta_cmd + (delta_act - delta_cmd) * decay
        act = (n_rps, delta_act, bow, stern)
        if method == EULER:  # the tuning hot path: keep the call chain shallow for inlining
            rhs(kind, p, s, act, k1)
            for i in range(6):
                s[i] += h * k1[i]
        else:
            step(kind, p, s, act, h, method, k1, k2, k3, k4, tmp)
    return state_status(kind, s), delta_act


@njit(cache=True, fastmath=FASTMATH)
def start_state(p, x0, s):
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
def _use_measured_wind(p, ctrl, k):
    """
    Set the wind parameters of p from the measured wind channels at sample k.

    Set the wind parameters of p (a per-trajectory copy) from the measured wind channels (air
    velocity north/east [m/s]) at sample k; NaN keeps the parameters.
    """
    wn = ctrl[k, WIND_N]
    we = ctrl[k, WIND_E]
    if wn == wn and we == we:
        p[_Vw] = math.sqrt(wn * wn + we * we)
        p[_dirw] = math.atan2(-we, -wn)  # blows from the opposite of where the air goes


@njit(cache=True, fastmath=FASTMATH)
def _simulate_one(kind, p_in, x0, ctrl, T, dt, substeps, method, out):
    """
    Simulate one trajectory over T samples spaced dt, writing observed states to out[:T].

    x0 is the first observed state (antenna position, velocities over ground); ctrl[k] holds
    the input channels (rpm, rudder_rad[, wind_n, wind_e[, bow, stern]]) held from sample k to
    k+1 (delayed by time_offset if set). Returns (status, sample index of failure). After a
    failure the remaining rows are NaN.
    """
    p = p_in.copy()  # private: measured wind overwrites its wind slots (one copy per run)
    s = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    start_state(p, x0, s)
    observe_row(p, s, out, 0)
    shift = p[_toff] / dt
    delta_act = _control_at(ctrl, 0, RUDDER, shift, T) + p[_doff]
    # optional channels, decided once per run (a per-sample wrapper costs ~30 % in Euler)
    measured_wind = ctrl.shape[1] > WIND_E
    thrusters = ctrl.shape[1] > STERN_THRUSTER
    status = OK
    k_fail = T
    for k in range(T - 1):
        if measured_wind:
            _use_measured_wind(p, ctrl, k)
        rpm = _control_at(ctrl, k, RPM, shift, T)
        rudder = _control_at(ctrl, k, RUDDER, shift, T)
        bow = 0.0
        stern = 0.0
        if thrusters:
            bow = _control_at(ctrl, k, BOW_THRUSTER, shift, T)
            stern = _control_at(ctrl, k, STERN_THRUSTER, shift, T)
        status, delta_act = advance(kind, p, s, delta_act, rpm, rudder, dt, substeps,
                                    method, k1, k2, k3, k4, tmp, bow, stern)
        if status != OK:
            k_fail = k if status == RPM_NOT_POSITIVE else k + 1
            break
        observe_row(p, s, out, k + 1)
    if status != OK:
        for k in range(k_fail, T):
            for i in range(6):
                out[k, i] = np.nan
    return status, k_fail


@njit(cache=True, parallel=True)
def _simulate_many(kind, params, x0s, ctrls, lengths, dt, substeps, method, out, status,
                   k_fail):
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
def _run_maneuver(kind, p, x0, rpm, rudder_cmd, zigzag_amp, zigzag_check, rate, T, dt,
                  substeps, method, out, rudder_out):
    """
    Simulate a manoeuvre with a steering gear in the loop (for generating trials).

    rudder_cmd[k] is the open-loop rudder order at sample k (rad); if zigzag_amp != 0 the order
    is instead closed on heading from the first sample where rudder_cmd[k] != 0: it starts at
    zigzag_amp and reverses when the heading change passes +-zigzag_check (IMO zigzag).
    rate: steering-gear rate limit [rad/s] (<= 0: instantaneous). rpm[k] is held per sample.
    Writes observed states to out and the actual rudder angle at each sample to rudder_out.
    Returns (status, k_fail).
    """
    s = np.empty(6)
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    for i in range(6):
        s[i] = x0[i]
    to_water(p, s)
    observe(p, s, out[0])
    h = dt / substeps
    max_move = rate * h if rate > 0.0 else 1e9
    delta = 0.0  # straight approach: the rudder starts amidships and moves at the gear's rate
    rudder_out[0] = delta
    # effects between the recorded (indicated) rudder/rpm and what acts on the ship
    tau = p[_tau]
    decay = math.exp(-h / tau) if tau > 0.0 else 0.0
    delta_act = delta + p[_doff]
    zz_started = False
    zz_cmd = zigzag_amp
    psi0 = s[2]
    status = OK
    k_fail = T
    for k in range(T - 1):
        n_rps = rpm[k] * p[_nscale] / 60.0
        status = rpm_status(kind, n_rps)
        if status != OK:
            k_fail = k
            break
        for _ in range(substeps):
            if zigzag_amp != 0.0:
                if not zz_started and rudder_cmd[k] != 0.0:
                    zz_started = True
                    psi0 = s[2]
                if zz_started:
                    dpsi = s[2] - psi0
                    if zz_cmd > 0.0 and dpsi >= zigzag_check:
                        zz_cmd = -abs(zigzag_amp)
                    elif zz_cmd < 0.0 and dpsi <= -zigzag_check:
                        zz_cmd = abs(zigzag_amp)
                    cmd = zz_cmd
                else:
                    cmd = 0.0
            else:
                cmd = rudder_cmd[k]
            # the step sees the angle at its start (as a zero-order-hold replay of the
            # recorded angle does); the gear then moves toward the order
            delta_act = delta + p[_doff] + (delta_act - delta - p[_doff]) * decay
            step(kind, p, s, (n_rps, delta_act, 0.0, 0.0), h, method, k1, k2, k3, k4, tmp)
            diff = cmd - delta
            if diff > max_move:
                diff = max_move
            elif diff < -max_move:
                diff = -max_move
            delta += diff
        ok = True
        for i in range(6):
            if not math.isfinite(s[i]):
                ok = False
        if not ok:
            status = DIVERGED
            k_fail = k + 1
            break
        if s[3] <= 0.0 and not astern_surge(kind):
            status = SURGE_NOT_POSITIVE
            k_fail = k + 1
            break
        observe(p, s, out[k + 1])
        rudder_out[k + 1] = delta
    if status != OK:
        for k in range(k_fail, T):
            rudder_out[k] = np.nan
            for i in range(6):
                out[k, i] = np.nan
    return status, k_fail


@njit(cache=True, fastmath=FASTMATH)
def _trajectory_cost(kind, p_in, meas, ctrl, T, dt, substeps, method, weights, shoot_every):
    """
    Weighted squared error of a simulation against a measured trial (Suyama et al. eq. 43).

    The simulation starts from meas[0] and is driven by ctrl; J = sum_{k>=1} e_k' W e_k with
    e = observed - measured over (x, y, psi (wrapped), u, v, r) and W = diag(weights).
    shoot_every > 0 restarts the simulation from the measured state every shoot_every samples
    (multiple shooting). Returns (J, k_fail): k_fail < T means the run failed at that sample
    (diverged or left the model's range) and J covers only the samples before it.
    """
    p = p_in.copy()  # private: measured wind overwrites its wind slots (one copy per run)
    s = np.empty(6)
    o = np.empty((1, 6))
    k1 = np.empty(6)
    k2 = np.empty(6)
    k3 = np.empty(6)
    k4 = np.empty(6)
    tmp = np.empty(6)
    shift = p[_toff] / dt
    delta_act = _control_at(ctrl, 0, RUDDER, shift, T) + p[_doff]
    # optional channels, decided once per run (a per-sample wrapper costs ~30 % in Euler)
    measured_wind = ctrl.shape[1] > WIND_E
    thrusters = ctrl.shape[1] > STERN_THRUSTER
    J = 0.0
    for k in range(T - 1):
        if k == 0 or (shoot_every > 0 and k % shoot_every == 0):
            start_state(p, meas[k], s)
        if measured_wind:
            _use_measured_wind(p, ctrl, k)
        rpm = _control_at(ctrl, k, RPM, shift, T)
        rudder = _control_at(ctrl, k, RUDDER, shift, T)
        bow = 0.0
        stern = 0.0
        if thrusters:
            bow = _control_at(ctrl, k, BOW_THRUSTER, shift, T)
            stern = _control_at(ctrl, k, STERN_THRUSTER, shift, T)
        status, delta_act = advance(kind, p, s, delta_act, rpm, rudder, dt, substeps,
                                    method, k1, k2, k3, k4, tmp, bow, stern)
        if status != OK:
            return J, (k if status == RPM_NOT_POSITIVE else k + 1)
        observe_row(p, s, o, 0)
        m = k + 1  # meas[m, i], not a row view (see observe_row)
        e = o[0, 0] - meas[m, 0]
        J += weights[0] * e * e
        e = o[0, 1] - meas[m, 1]
        J += weights[1] * e * e
        e = wrap_pi(o[0, 2] - meas[m, 2])
        J += weights[2] * e * e
        if weights[3] != 0.0 or weights[4] != 0.0 or weights[5] != 0.0:
            for i in range(3, 6):
                e = o[0, i] - meas[m, i]
                J += weights[i] * e * e
    return J, T


@njit(cache=True, parallel=True)
def _cost_many(kind, params, meas, ctrls, lengths, dt, substeps, method, weights, shoot_every,
               J, k_fail):
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


def _for_family(kernel):
    """
    Make the Python entry point of a whole-run kernel.

    Same arguments, ``kind`` the family code; it runs the kernel compiled for that family
    alone (called with the family's tag): ~6 % faster than the run-time branch in the batched
    benchmark (bench/bench_core.py).
    """
    @functools.wraps(kernel)
    def entry(kind, *args):
        return kernel(family_tag(kind), *args)
    return entry


simulate_one = _for_family(_simulate_one)
simulate_many = _for_family(_simulate_many)
run_maneuver = _for_family(_run_maneuver)
trajectory_cost = _for_family(_trajectory_cost)
cost_many = _for_family(_cost_many)
