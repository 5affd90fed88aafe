"""
A learned correction of the accelerations: the hybrid's residual network, evaluated in the loop.

The one sample loop (``integrate.drive``) adds a small MLP's (du, dv_m, dr) to the family's
accelerations when a network is attached (``learn/residual.py`` trains, stores and loads it).
The network sees a window of the most recent samples (the current one included) of its
family's features (:func:`feature_names`: the state, the family's first channels by name, the
apparent wind and, when it was trained so, the physics' own accelerations at that sample),
each standardised and ordered oldest first, and its output is held over the sample interval,
as the recorded inputs are. Only NumPy and numba: a ROS install without JAX
runs trained hybrids.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from mmg_tuner.core._jit import FASTMATH
from mmg_tuner.core.dynamics import apparent_wind
from numba import njit

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from typing import Sequence

    from mmg_tuner.core._jit import FloatArray, IntArray
    from mmg_tuner.core.models import Family

N_COMMAND_SLOTS = 4   # command channels a feature row holds (zero where a family has fewer)
FEATURES: tuple[str, ...] = ('u', 'v', 'r', 'rpm', 'rudder', 'bow_thruster', 'stern_thruster',
                             'wind_u', 'wind_v')
"""Per-sample inputs of a screw-and-rudder ship's network (:func:`feature_names`): the model
state through the water (u, v_m [m/s], r [rad/s]), rpm [rev/min], rudder [rad] (recorded), bow
and stern thrusters [rev/s] (zero when the ship has none) and the apparent wind (the air's
velocity relative to the ship) in body axes [m/s]."""
N_FEATURES = len(FEATURES)
PHYSICS_FEATURES: tuple[str, ...] = ('phys_du', 'phys_dv', 'phys_dr')
"""Optional last features: the family's accelerations (du, dv_m [m/s^2], dr [rad/s^2]) at the
sample's state and inputs, without the network (the physics' prediction the network then
corrects; ``ResidualConfig.physics_input``)."""
FEATURE_PARAMS = ('current_speed', 'current_dir', 'antenna_x', 'antenna_y', 'wind_speed',
                  'wind_dir')
"""Parameters the features (and the kinematics) read: never trained with the network."""


def feature_names(family: Family, physics_input: bool = False) -> tuple[str, ...]:
    """
    Return the names of a family's feature row: u, v, r, its commands, wind_u, wind_v.

    physics_input: then the physics' accelerations (:data:`PHYSICS_FEATURES`).

    The command slots hold the family's first N_COMMAND_SLOTS input channels in kernel order
    (the kernel reads them by position), then empty names (zero) when it has fewer. Each must
    be always recorded and none beyond the slots may be: a channel that may be NaN (a
    commanded angle recorded only sometimes) comes after them. Another family has no network
    (ConfigError naming its channels).
    """
    from mmg_tuner.core.channels import TABLE
    from mmg_tuner.errors import ConfigError

    def always(c: str) -> bool:
        d = TABLE[c].default
        return d is None or d == d
    inputs = family.inputs
    n = min(N_COMMAND_SLOTS, len(inputs))
    if not all(always(c) for c in inputs[:n]) or any(always(c) for c in inputs[n:]):
        raise ConfigError(f'the {family.name!r} family reads {", ".join(inputs)}: a residual '
                          f'network reads its first {N_COMMAND_SLOTS} channels, each always '
                          'recorded (the ones that may be NaN after them)')
    return ('u', 'v', 'r') + inputs[:n] + ('',) * (N_COMMAND_SLOTS - n) + \
        ('wind_u', 'wind_v') + (PHYSICS_FEATURES if physics_input else ())


def reads_physics(names: Sequence[str]) -> bool:
    """Whether a network of feature ``names`` reads the physics' accelerations too."""
    return len(names) == N_FEATURES + len(PHYSICS_FEATURES) and \
        tuple(names[N_FEATURES:]) == PHYSICS_FEATURES


def features_fit(names: Sequence[str], family: Family) -> bool:
    """
    Whether a network of feature ``names`` reads ``family``'s channels as it was trained to.

    Equal to :func:`feature_names` but for the padding: a slot beyond the family's commands
    may carry any name the family lacks (networks saved before the names were per family
    call SUZAKU's empty slots bow_thruster and stern_thruster; zero either way).
    """
    own = feature_names(family, reads_physics(names))
    if len(names) != len(own):
        return False
    return all(a == b or (b == '' and a not in family.inputs) for a, b in zip(names, own))


@njit(cache=True, fastmath=FASTMATH)
def mlp_forward(sizes: IntArray, flat: FloatArray, x: FloatArray, buf_a: FloatArray,
                buf_b: FloatArray) -> FloatArray:
    """
    Evaluate the MLP on x (sizes[0],): tanh hidden layers, linear output.

    Returns the buffer holding the output. buf_a, buf_b: work buffers of length >=
    max(sizes). Weights are (out, in) row-major then the biases, layer after layer, as
    ``ResidualNet.packed`` lays them out.
    """
    n_layers = sizes.shape[0] - 1
    src = x
    off = 0
    for li in range(n_layers):
        n_in = sizes[li]
        n_out = sizes[li + 1]
        dst = buf_a if li % 2 == 0 else buf_b
        boff = off + n_in * n_out
        for j in range(n_out):
            acc = flat[boff + j]
            row = off + j * n_in
            for i in range(n_in):
                acc += flat[row + i] * src[i]
            dst[j] = math.tanh(acc) if li < n_layers - 1 else acc
        off = boff + n_out
        src = dst
    return src


@njit(cache=True, fastmath=FASTMATH)
def feature_row(p: FloatArray, s: FloatArray, inp: FloatArray, row: FloatArray) -> None:
    """Fill row (N_FEATURES,) for model state s and the command row held at this sample."""
    row[0] = s[3]
    row[1] = s[4]
    row[2] = s[5]
    row[3] = inp[0]
    row[4] = inp[1]
    row[5] = inp[2] if inp.shape[0] > 2 else 0.0
    row[6] = inp[3] if inp.shape[0] > 3 else 0.0
    wu, wv = apparent_wind(p, s[2], s[3], s[4])
    row[7] = wu
    row[8] = wv


@njit(cache=True, fastmath=FASTMATH)
def window_residual(ring: FloatArray, window: int, sizes: IntArray, flat: FloatArray,
                    x_mean: FloatArray, x_std: FloatArray, y_scale: FloatArray, z: FloatArray,
                    buf_a: FloatArray, buf_b: FloatArray) -> tuple[float, float, float]:
    """(du, dv, dr) of the network for the window ring (window, n_features), oldest first."""
    nf = ring.shape[1]
    for i in range(window):
        for f in range(nf):
            z[i * nf + f] = (ring[i, f] - x_mean[f]) / x_std[f]
    o = mlp_forward(sizes, flat, z, buf_a, buf_b)
    return o[0] * y_scale[0], o[1] * y_scale[1], o[2] * y_scale[2]
