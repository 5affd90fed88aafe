"""
Units of the channels a craft is commanded by, one by one: shaft speeds, angles, bollard tables.

A shaft speed [rev/s] in rpm, an angle [rad] in degrees, a bollard table's n in rpm or thrust
in kgf. Each channel is judged by its unit against the ship's command limit for it
(``core/limits.command_limits``: ``steering.max_thruster_rps``, ``steering.max_azimuth_deg``),
a bollard table against the thrust curve its actuator declares (``IDENTIFY``'s
``bollard_curve``). Each finding is one ``WARNING:`` sentence naming the column, the likely
unit and the limit it was judged by: the readers log it (``--strict`` makes it an error) and
read the data as they stand. The rpm and rudder of a screw-and-rudder ship have their own
checks (``data/consistency.py``, ``core/limits.InputLimits``).
"""
from __future__ import annotations

import logging
import math
from typing import Callable, Sequence

from mmg_tuner.core.actuators import load_companion
from mmg_tuner.core.channels import CONTROL_NAMES, TABLE
from mmg_tuner.core.limits import command_limits, CommandLimit
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError
import numpy as np

G = 9.80665   # N per kgf
RPM_PER_RPS = 60.0


def _limit(ship: ShipConfig, channel: str) -> CommandLimit | None:
    """Return the ship's command limit of ``channel`` (None: the YAML gives none to judge by)."""
    try:
        lim = command_limits(ship, (channel,))[channel]
    except ConfigError:   # a bad YAML value: the loaders say so; nothing to judge by here
        return None
    # (a shaft speed without steering.max_thruster_rps has no limit: nothing to judge by)
    return lim if math.isfinite(lim.limit) else None


def shaft_speed_warning(column: str, values: np.ndarray, max_rps: float,
                        basis: str = 'steering.max_thruster_rps') -> str:
    """Name a shaft speed column [rev/s] beyond twice the limit that fits it as rpm ('': no)."""
    v = np.abs(values[np.isfinite(values)])
    if not max_rps > 0 or not v.size:
        return ''
    top = float(np.max(v))
    if top > 2 * max_rps and top / RPM_PER_RPS <= 2 * max_rps:
        return (f"column '{column}': up to {top:g}, beyond twice the ship's "
                f'{max_rps:g} rev/s ({basis}); as rpm it is '
                f'{top / RPM_PER_RPS:.3g} rev/s: it looks like rpm; the format wants rev/s '
                '(divide by 60)')
    return ''


def angle_warning(column: str, values: np.ndarray, max_rad: float,
                  basis: str = 'the angle limit') -> str:
    """Name an angle column [rad] beyond twice the limit that fits it as degrees ('': no)."""
    v = np.abs(values[np.isfinite(values)])
    if not v.size:
        return ''
    top = float(np.max(v))
    lim = max_rad if max_rad > 0 else math.pi
    if top > max(2 * lim, 1.2) and math.radians(top) <= max(2 * lim, 0.1) + 1e-9 \
            or top > 2 * math.pi and top <= 360.0:
        return (f"column '{column}': up to {top:g}, beyond the ship's +-{math.degrees(lim):g} "
                f'deg ({basis}) read as radians: it looks like degrees; the '
                'format wants radians (multiply by pi/180)')
    return ''


def channel_unit_warnings(trial: Trial, ship: ShipConfig) -> list[str]:
    """Return the unit findings of a trial's shaft speed [rev/s] and angle [rad] columns."""
    judge: dict[str, Callable[[str, np.ndarray, float, str], str]] = {
        'rev/s': shaft_speed_warning, 'rad': angle_warning}
    out = []
    for c, v in sorted(trial.inputs.items()):
        ch = TABLE.get(c)
        if ch is None or ch.unit not in judge or c not in ship.family.inputs \
                or c in CONTROL_NAMES:
            continue
        lim = _limit(ship, c)
        values = np.asarray(v, float)
        w = '' if lim is None else judge[ch.unit](c, values, lim.limit, lim.basis)
        if w:
            out.append(f'{trial.name}: {w}')
    return out


def bollard_unit_warnings(ship: ShipConfig, n: np.ndarray, thrust: np.ndarray,
                          source: str = 'bollard-pull table') -> list[str]:
    """
    Return the unit findings of a bollard table: n in rpm, thrust in kgf.

    n: beyond twice ``steering.max_thruster_rps`` and within it as rpm. thrust: the median
    ratio of the table's thrust to the ship's own curve (its actuator's ``bollard_curve``) at
    the same speeds between 1/15 and 1/6 (1/9.81: kgf read as N); judged only where the curve
    gives thrust.
    """
    curve = _bollard_curve(ship)
    shaft = next((c for c in ship.family.inputs if c in TABLE and TABLE[c].unit == 'rev/s'), None)
    lim = _limit(ship, shaft) if shaft is not None else None
    max_rps = lim.limit if lim is not None else 0.0
    out = []
    w = shaft_speed_warning('n', np.asarray(n, float), max_rps)
    if w:
        out.append(f'{source}: {w}')
    n = np.asarray(n, float)
    if w:
        n = n / RPM_PER_RPS
    F = np.asarray(thrust, float)
    ref = np.array([curve(ship.params, float(x)) for x in n]) if curve is not None else \
        np.zeros_like(n)
    ok = (n > 0) & (np.abs(ref) > 1e-9) & np.isfinite(F)
    if ok.sum() >= 2:
        q = float(np.median(F[ok] / ref[ok]))
        if 1 / 15 <= q <= 1 / 6:
            out.append(f"{source}: column 'thrust': {1 / q:.3g} times less than the ship's "
                       'thrust curve (thrust_p0..p5) at the same shaft speeds: it looks like '
                       'kgf; the format wants N (multiply by 9.80665)')
    return out


def _bollard_curve(ship: ShipConfig) -> Callable[[np.ndarray, float], float] | None:
    """Return the thrust curve F(params, n) [N] an actuator of the ship declares, or None."""
    for name in ship.family.actuators:
        module = load_companion(name, 'IDENTIFY')
        if module is not None:
            curve = getattr(module, 'bollard_curve', None)
            if curve is not None:
                return curve   # type: ignore[no-any-return]  # a module attribute
    return None


def warn_all(lines: Sequence[str], logger: logging.Logger) -> list[str]:
    """Log each finding as its ``WARNING:`` line; return them."""
    for w in lines:
        logger.warning('WARNING: %s', w)
    return list(lines)
