"""
Frame conventions and conversions, in one place.

ROS (REP-103/105) world frames are ENU: x east, y north, z up, yaw counter-clockwise from east;
``base_link`` is x forward, y port (left), z up. The MMG earth frame (the model state) is
x_E north, y_E east, psi clockwise from north; body axes x forward, y starboard. So

* position:    x_E = y_enu,  y_E = x_enu;
* heading:     psi = pi/2 - yaw_enu;
* body velocity: u = vx_flu, v = -vy_flu, r = -wz_flu;
* a world vector (north, east) = (y_enu, x_enu).

Headings: :func:`wrap_pi` to (-pi, pi] (compiled, usable in kernels), :func:`unwrap` for
continuous histories. Functions take floats or NumPy arrays alike.
"""
from __future__ import annotations

import math
from typing import TypeVar

from mmg_tuner.core._jit import FASTMATH
from numba import njit
import numpy as np
import numpy.typing as npt

FloatOrArray = TypeVar('FloatOrArray', float, npt.NDArray[np.float64])
"""A float, or a float64 array of them: the conversions work element-wise on either."""

TWO_PI = 2.0 * math.pi


@njit(cache=True, fastmath=FASTMATH)
def wrap_pi(a: float) -> float:
    """
    Return an angle [rad] wrapped into [-pi, pi).

    An angle [rad] wrapped into [-pi, pi) (a value already inside (-pi, pi] is returned unchanged:
    heading errors almost always are, so the costly modulo is skipped).
    """
    if -math.pi < a <= math.pi:
        return a
    return (a + math.pi) % TWO_PI - math.pi


def wrap_angle(a: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Wrap array angles into [-pi, pi) (the NumPy version of :func:`wrap_pi`)."""
    return (np.asarray(a, dtype=float) + math.pi) % TWO_PI - math.pi


def unwrap(psi: npt.ArrayLike) -> np.ndarray:
    """Return a continuous heading history [rad] from a wrapped one (jumps over pi removed)."""
    return np.unwrap(np.asarray(psi, dtype=float))


def yaw_from_quaternion(x: FloatOrArray, y: FloatOrArray, z: FloatOrArray,
                        w: FloatOrArray) -> FloatOrArray:
    """Yaw [rad] (rotation about z, counter-clockwise) of a quaternion (x, y, z, w)."""
    return np.arctan2(  # type: ignore[no-any-return]  # numpy's ufuncs return Any
        2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], ...]:
    """(x, y, z, w) of a pure rotation by yaw [rad] about z."""
    yaw = np.asarray(yaw, dtype=float)
    return 0.0 * yaw, 0.0 * yaw, np.sin(0.5 * yaw), np.cos(0.5 * yaw)


def enu_yaw_to_psi(yaw: FloatOrArray) -> FloatOrArray:
    """ENU yaw (counter-clockwise from east) -> MMG heading psi (clockwise from north)."""
    return 0.5 * math.pi - yaw


def psi_to_enu_yaw(psi: FloatOrArray) -> FloatOrArray:
    """MMG heading psi (clockwise from north) -> ENU yaw (counter-clockwise from east)."""
    return 0.5 * math.pi - psi


def enu_to_mmg_position(x_enu: FloatOrArray,
                        y_enu: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray]:
    """ENU (east, north) [m] -> MMG earth frame (x_E north, y_E east)."""
    return y_enu, x_enu


def mmg_to_enu_position(x_e: FloatOrArray, y_e: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray]:
    """MMG earth frame (x_E north, y_E east) -> ENU (x east, y north)."""
    return y_e, x_e


def flu_to_mmg_body(vx: FloatOrArray, vy: FloatOrArray,
                    wz: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """Turn base_link (forward, left, up) velocities into MMG body (u fwd, v stbd, r cw)."""
    return vx, -vy, -wz


def mmg_body_to_flu(u: FloatOrArray, v: FloatOrArray,
                    r: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """MMG body (u, v starboard, r clockwise) -> base_link (vx, vy left, wz counter-clockwise)."""
    return u, -v, -r


def enu_vector_to_ne(vx_enu: FloatOrArray,
                     vy_enu: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray]:
    """Return a world vector in ENU (east, north) -> (north, east) components."""
    return vy_enu, vx_enu


def body_to_ne(psi: FloatOrArray, fwd: FloatOrArray,
               stbd: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray]:
    """Turn a body-axis vector (forward, starboard) into (north, east) at heading psi."""
    c, s = np.cos(psi), np.sin(psi)
    return fwd * c - stbd * s, fwd * s + stbd * c


def ne_to_body(psi: FloatOrArray, north: FloatOrArray,
               east: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray]:
    """Return a (north, east) vector -> body axes (forward, starboard) at heading psi."""
    c, s = np.cos(psi), np.sin(psi)
    return north * c + east * s, -north * s + east * c
