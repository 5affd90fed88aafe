"""
Reading an input array in the kernels: one channel at one sample, shifted in time.

The kernels' input array ``ctrl`` (T, n) holds a family's channels (``Family.channels``);
actuator models read their columns straight from it (``value(ctrl, k, j, shift, T)``), so a
sample's inputs never pass through an intermediate array on the hot path.
"""
from __future__ import annotations

from mmg_tuner.core._jit import FASTMATH
from numba import njit


@njit(cache=True, fastmath=FASTMATH, inline='always')
def value(ctrl, k, j, frac_shift, T):
    """Channel j at sample k delayed by frac_shift samples (linear interpolation)."""
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
