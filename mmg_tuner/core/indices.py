"""
Manoeuvring indices (IMO MSC.137(76) definitions) from a trajectory in the model frame.

Heading changes are measured from the heading at rudder execution; positions relative to the
position there, along (advance) and across (transfer, tactical diameter) the initial heading.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from mmg_tuner.core.frames import unwrap
import numpy as np


@dataclass(frozen=True)
class TurningIndices:
    advance_m: float
    transfer_m: float
    tactical_diameter_m: float
    direction: str  # 'starboard' or 'port'

    def in_lengths(self, L: float) -> dict[str, float]:
        return {'advance_L': self.advance_m / L, 'transfer_L': self.transfer_m / L,
                'tactical_diameter_L': self.tactical_diameter_m / L}


@dataclass(frozen=True)
class ZigzagIndices:
    first_overshoot_deg: float
    second_overshoot_deg: float
    direction: str  # first rudder to 'starboard' or 'port'


def execution_index(rudder_rad: np.ndarray, threshold_rad: float = math.radians(1.0)) -> int:
    """First sample where the rudder has moved by more than threshold from its initial angle."""
    moved = np.abs(rudder_rad - rudder_rad[0]) > threshold_rad
    return int(np.argmax(moved)) if moved.any() else 0


def _crossing(values: np.ndarray, level: float) -> float | None:
    """Fractional index where values first reach level (linear interpolation)."""
    above = np.nonzero(values >= level)[0]
    if above.size == 0:
        return None
    k = int(above[0])
    if k == 0:
        return 0.0
    v0, v1 = values[k - 1], values[k]
    return float(k - 1 + (level - v0) / (v1 - v0))


def _interp(a: np.ndarray, fidx: float) -> float:
    k = int(math.floor(fidx))
    if k >= a.size - 1:
        return float(a[-1])
    w = fidx - k
    return float((1 - w) * a[k] + w * a[k + 1])


def turning_indices(x: np.ndarray, y: np.ndarray, psi: np.ndarray, k_exec: int = 0
                    ) -> TurningIndices:
    """
    Return advance, transfer and tactical diameter of a turn.

    Advance and transfer at 90 deg, tactical diameter at 180 deg heading change (NaN if the turn
    does not get that far).
    """
    psi = unwrap(psi)
    dpsi = psi[k_exec:] - psi[k_exec]
    sign = 1.0 if dpsi[np.argmax(np.abs(dpsi))] >= 0 else -1.0
    dpsi = sign * dpsi
    c, s = math.cos(psi[k_exec]), math.sin(psi[k_exec])
    dx, dy = x[k_exec:] - x[k_exec], y[k_exec:] - y[k_exec]
    along = dx * c + dy * s
    across = sign * (-dx * s + dy * c)
    k90 = _crossing(dpsi, math.pi / 2)
    k180 = _crossing(dpsi, math.pi)
    nan = float('nan')
    return TurningIndices(
        advance_m=_interp(along, k90) if k90 is not None else nan,
        transfer_m=_interp(across, k90) if k90 is not None else nan,
        tactical_diameter_m=_interp(across, k180) if k180 is not None else nan,
        direction='starboard' if sign > 0 else 'port')


def zigzag_indices(psi: np.ndarray, rudder_rad: np.ndarray, check_rad: float,
                   k_exec: int | None = None) -> ZigzagIndices:
    """
    First and second overshoot angles [deg] of a zigzag (NaN where not reached).

    The first overshoot is the largest heading excursion beyond the check angle after the
    heading first passes it, until it passes the opposite check angle; the second likewise.
    """
    if k_exec is None:
        k_exec = execution_index(rudder_rad)
    psi = unwrap(psi)
    dpsi = psi[k_exec:] - psi[k_exec]
    after = rudder_rad[k_exec:] - rudder_rad[0]
    first = after[np.argmax(np.abs(after) > math.radians(1.0))] if after.size else 1.0
    sign = 1.0 if first >= 0 else -1.0
    h = sign * dpsi
    nan = float('nan')
    k1 = _crossing(h, check_rad)
    if k1 is None:
        return ZigzagIndices(nan, nan, 'starboard' if sign > 0 else 'port')
    k1 = int(math.ceil(k1))
    k2 = _crossing(-h[k1:], check_rad)
    seg1 = h[k1:] if k2 is None else h[k1:k1 + int(math.ceil(k2)) + 1]
    os1 = math.degrees(float(seg1.max()) - check_rad)
    os2 = nan
    if k2 is not None:
        k2 = k1 + int(math.ceil(k2))
        k3 = _crossing(h[k2:], check_rad)
        seg2 = -h[k2:] if k3 is None else -h[k2:k2 + int(math.ceil(k3)) + 1]
        # complete once the heading turned back (a peak before the record ends)
        if k3 is not None or int(np.argmax(seg2)) < seg2.size - 1:
            os2 = math.degrees(float(seg2.max()) - check_rad)
    return ZigzagIndices(os1, os2, 'starboard' if sign > 0 else 'port')
