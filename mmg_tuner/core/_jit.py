"""Compilation settings shared by every kernel module."""
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    FloatArray = npt.NDArray[np.float64]
    """A float64 array: the parameter vector p, states, inputs (kernel annotations only)."""
    IntArray = npt.NDArray[np.int64]
    """An int64 array: trial lengths, statuses, failure samples, channel indices."""

# Fast-math without 'nnan'/'ninf': divergence checks rely on isfinite.
FASTMATH = {'nsz', 'arcp', 'contract', 'afn', 'reassoc'}
U_MIN = 1e-6  # m/s, keeps r' = r L / U finite at rest
