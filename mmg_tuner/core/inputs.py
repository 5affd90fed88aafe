"""
Reading an input array in the kernels: one channel at one sample, shifted in time.

The kernels' input array ``ctrl`` (T, n) holds a family's channels (``Family.channels``).
The plant reads each actuator's columns once per sample (``where`` then ``commands``) and
hands the actuator a tuple of floats: no array passes through the actuator models, whose every
inlined layer would otherwise cost an atomic reference count per array on the hot path.
"""
from __future__ import annotations

from typing import Any, Callable, TYPE_CHECKING

from mmg_tuner.core._jit import FASTMATH
from numba import njit

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray


@njit(cache=True, fastmath=FASTMATH, inline='always')
def value(ctrl: FloatArray, k: int, j: int, frac_shift: float, T: int) -> float:
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


@njit(cache=True, fastmath=FASTMATH, inline='always')
def where(k: int, frac_shift: float, T: int) -> tuple[int, int, float]:
    """
    Rows and weight (i0, i1, w) of sample k delayed by frac_shift samples.

    The value of a channel there is ``(1 - w) * ctrl[i0, j] + w * ctrl[i1, j]`` (as ``value``).
    """
    if frac_shift == 0.0:
        return k, k, 0.0
    t = k - frac_shift
    if t <= 0.0:
        return 0, 0, 0.0
    if t >= T - 1:
        return T - 1, T - 1, 0.0
    i = int(t)
    return i, i + 1, t - i


def _reader(n: int) -> Callable[..., Any]:
    """Compiled reader of n consecutive channels from column j as a tuple (numba, inlined)."""
    cols = ', '.join(f'(1.0 - w) * ctrl[i0, j + {c}] + w * ctrl[i1, j + {c}]' for c in range(n))
    src = f'def read(ctrl, i0, i1, w, j):\n    return ({cols},)\n'
    ns: dict[str, Any] = {}
    exec(src, ns)  # noqa: S102 - a fixed template: numba needs a literal tuple per width
    return njit(cache=False, fastmath=FASTMATH, inline='always')(ns['read'])


_READERS = {n: _reader(n) for n in range(1, 9)}


def commands(n: int) -> Callable[..., Any]:
    """Return the compiled reader of an actuator's n input channels (n <= 8)."""
    if n not in _READERS:
        raise TypeError(f'an actuator reads at most {max(_READERS)} channels, not {n}')
    return _READERS[n]
