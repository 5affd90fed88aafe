"""
Compiled helpers of the training: the physics over a batch with its state Jacobian.

The differentiable simulation calls the *same* compiled ``core.dynamics.derivative`` as every
other simulation (one source of the force equations): :func:`batch_derivative` evaluates it
for a batch of states, and its Jacobian with respect to the state by central differences in
float64 (the families have branches and table look-ups; a finite difference of the compiled
kernel needs no second implementation). JAX sees it through ``jax.pure_callback`` with a
custom VJP (``_engine.physics_fn``). NumPy and numba only.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from mmg_tuner.core.correction import window_residual
from mmg_tuner.core.dynamics import act_tuple, derivative
from mmg_tuner.core.layout import PARAM_INDEX
from numba import njit
import numpy as np

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray, IntArray

_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']
FD_REL_STEP = 1e-6
"""Central-difference step, relative to max(1, |state|): truncation ~1e-12, rounding ~1e-10."""


@njit(cache=True)
def batch_derivative(kind: tuple[int, ...], p_in: FloatArray, S: FloatArray, A: FloatArray,
                     Wd: FloatArray, F: FloatArray, J: FloatArray, with_jac: bool) -> None:
    """
    Fill ds/dt F (B, 6) of the family for states, actuator tuples and winds.

    ``kind``: the family's tag; S (B, 6) states, A (B, n_outputs) actuator tuples, Wd (B, 2)
    winds.

    Wd holds (wind_speed [m/s], wind_dir [rad]) per row (the measured wind of the sample, or
    the ship's parameters). with_jac: also J (B, 6, 6) = dF/dS by central differences (x, y
    do not enter the dynamics: their columns are exactly 0).
    """
    p = p_in.copy()
    s = np.empty(6)
    out = np.empty(6)
    fp = np.empty(6)
    fm = np.empty(6)
    for b in range(S.shape[0]):
        p[_Vw] = Wd[b, 0]
        p[_dirw] = Wd[b, 1]
        act = act_tuple(kind, A, b)
        for i in range(6):
            s[i] = S[b, i]
        derivative(kind, p, s, act, out)
        for i in range(6):
            F[b, i] = out[i]
        if not with_jac:
            continue
        for i in range(6):
            J[b, i, 0] = 0.0
            J[b, i, 1] = 0.0
        for j in range(2, 6):
            h = FD_REL_STEP * max(1.0, abs(S[b, j]))
            s[j] = S[b, j] + h
            derivative(kind, p, s, act, fp)
            s[j] = S[b, j] - h
            derivative(kind, p, s, act, fm)
            s[j] = S[b, j]
            for i in range(6):
                J[b, i, j] = (fp[i] - fm[i]) / (2.0 * h)


@njit(cache=True)
def teacher_residuals(rows: FloatArray, window: int, sizes: IntArray, flat: FloatArray,
                      x_mean: FloatArray, x_std: FloatArray, y_scale: FloatArray,
                      out: FloatArray) -> None:
    """
    Fill out (T, 3) with the residual on a measured history.

    At each sample the window of measured rows (padded with the first at the start), as a
    one-step prediction sees it.
    """
    T = rows.shape[0]
    nf = rows.shape[1]
    ring = np.empty((window, nf))
    z = np.empty(window * nf)
    nb = 0
    for i in range(sizes.shape[0]):
        nb = max(nb, sizes[i])
    buf_a = np.empty(nb)
    buf_b = np.empty(nb)
    for k in range(T):
        for i in range(window):
            kk = k - (window - 1) + i
            if kk < 0:
                kk = 0
            for f in range(nf):
                ring[i, f] = rows[kk, f]
        a0, a1, a2 = window_residual(ring, window, sizes, flat, x_mean, x_std, y_scale, z,
                                     buf_a, buf_b)
        out[k, 0] = a0
        out[k, 1] = a1
        out[k, 2] = a2
