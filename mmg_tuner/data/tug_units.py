"""
Units on the twin-thruster path: shaft speeds, azimuth angles, the bollard table.

A shaft speed in rpm, an azimuth in degrees, a bollard table's n in rpm or thrust in kgf.

Each finding is one ``WARNING:`` sentence naming the column and the likely unit, with the
ship's own limit it was judged by (``steering.max_thruster_rps``, ``steering.max_azimuth_deg``,
the ship's thrust curve ``thrust_p0..p5``): the readers log it (``--strict`` makes it an error)
and read the data as they stand.
"""
from __future__ import annotations

import logging
import math
from typing import Sequence

from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
import numpy as np

G = 9.80665   # N per kgf
RPM_PER_RPS = 60.0


def _steering(ship: ShipConfig) -> tuple[float, float]:
    """(max shaft speed [rev/s], max azimuth [rad]) of the ship's YAML (0: not given)."""
    st = ship.extra.get('steering') or {}
    if not isinstance(st, dict):
        return 0.0, 0.0
    try:
        rps = float(st.get('max_thruster_rps', 0.0) or 0.0)
        az = math.radians(float(st.get('max_azimuth_deg', 0.0) or 0.0))
    except (TypeError, ValueError):
        return 0.0, 0.0
    return rps, az


def shaft_speed_warning(column: str, values: np.ndarray, max_rps: float) -> str:
    """Name a shaft speed column [rev/s] beyond twice the limit that fits it as rpm ('': no)."""
    v = np.abs(values[np.isfinite(values)])
    if not max_rps > 0 or not v.size:
        return ''
    top = float(np.max(v))
    if top > 2 * max_rps and top / RPM_PER_RPS <= 2 * max_rps:
        return (f"column '{column}': up to {top:g}, beyond twice the ship's "
                f'{max_rps:g} rev/s (steering.max_thruster_rps); as rpm it is '
                f'{top / RPM_PER_RPS:.3g} rev/s: it looks like rpm; the format wants rev/s '
                '(divide by 60)')
    return ''


def azimuth_warning(column: str, values: np.ndarray, max_az: float) -> str:
    """Name an azimuth column [rad] beyond twice the limit that fits it as degrees ('': no)."""
    v = np.abs(values[np.isfinite(values)])
    if not v.size:
        return ''
    top = float(np.max(v))
    lim = max_az if max_az > 0 else math.pi
    if top > max(2 * lim, 1.2) and math.radians(top) <= max(2 * lim, 0.1) + 1e-9 \
            or top > 2 * math.pi and top <= 360.0:
        return (f"column '{column}': up to {top:g}, beyond the ship's +-{math.degrees(lim):g} "
                'deg (steering.max_azimuth_deg) read as radians: it looks like degrees; the '
                'format wants radians (multiply by pi/180)')
    return ''


def channel_unit_warnings(trial: Trial, ship: ShipConfig) -> list[str]:
    """Return the unit findings of a twin-thruster trial's shaft speed and azimuth columns."""
    max_rps, max_az = _steering(ship)
    out = []
    for c, v in sorted(trial.inputs.items()):
        ch = TABLE.get(c)
        if ch is None or c not in ship.family.inputs:
            continue
        w = (shaft_speed_warning(c, np.asarray(v, float), max_rps) if ch.unit == 'rev/s' else
             azimuth_warning(c, np.asarray(v, float), max_az)
             if ch.unit == 'rad' and c.startswith('azimuth') else '')
        if w:
            out.append(f'{trial.name}: {w}')
    return out


def bollard_unit_warnings(ship: ShipConfig, n: np.ndarray, thrust: np.ndarray,
                          source: str = 'bollard-pull table') -> list[str]:
    """
    Return the unit findings of a bollard table: n in rpm, thrust in kgf.

    n: beyond twice ``steering.max_thruster_rps`` and within it as rpm. thrust: the median
    ratio of the table's thrust to the ship's own curve (``thrust_p0..p5``) at the same speeds
    between 1/15 and 1/6 (1/9.81: kgf read as N); judged only where the curve gives thrust.
    """
    from mmg_tuner.core.actuators.twin_azimuth import thrust as curve
    max_rps, _ = _steering(ship)
    out = []
    w = shaft_speed_warning('n', np.asarray(n, float), max_rps)
    if w:
        out.append(f'{source}: {w}')
    n = np.asarray(n, float)
    if w:
        n = n / RPM_PER_RPS
    F = np.asarray(thrust, float)
    ref = np.array([curve(ship.params, float(x)) for x in n]) if \
        'thrust_p0' in ship.family.params else np.zeros_like(n)
    ok = (n > 0) & (np.abs(ref) > 1e-9) & np.isfinite(F)
    if ok.sum() >= 2:
        q = float(np.median(F[ok] / ref[ok]))
        if 1 / 15 <= q <= 1 / 6:
            out.append(f"{source}: column 'thrust': {1 / q:.3g} times less than the ship's "
                       'thrust curve (thrust_p0..p5) at the same shaft speeds: it looks like '
                       'kgf; the format wants N (multiply by 9.80665)')
    return out


def warn_all(lines: Sequence[str], logger: logging.Logger) -> list[str]:
    """Log each finding as its ``WARNING:`` line; return them."""
    for w in lines:
        logger.warning('WARNING: %s', w)
    return list(lines)
