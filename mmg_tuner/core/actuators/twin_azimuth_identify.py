"""
What ``tune --method lo-go`` fits of ``twin_azimuth`` before the hull: the azimuth drive.

The actuator declares this module (``IDENTIFY`` in ``twin_azimuth.py``); ``tuning/lo_go.py``
calls :func:`fit` through that declaration (the protocol is in ``core/actuators/__init__.py``),
so the identification names no craft. :func:`fit` returns an :class:`AzimuthFit` (its
``params``, ``report()`` for identify.json, ``describe()`` for people) or None.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Sequence

from mmg_tuner.core.actuators.twin_azimuth import thrust
from mmg_tuner.core.integrate import actuator_outputs
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import steps_per_sample
from mmg_tuner.core.trial import Trial
import numpy as np

NAME = 'azimuth'
"""The key of the fit in identify.json."""


def bollard_curve(p: np.ndarray, n: float) -> float:
    """Return one thruster's thrust [N] at shaft speed n [rev/s] (a bollard table's unit check)."""
    return float(thrust(p, n))


_AZ_BOUNDS = (np.log([1e-2, 1e-2, 1e-2]), np.log([1e4, 1e2, 10.0]))
"""Bounds of log(k1 [1/s^2], k2 [1/s], rate limit [rad/s]) in the azimuth fit: a drive from
minutes to milliseconds, a slew rate from 0.6 deg/s to 570 deg/s."""
_AZ_RESOLUTION_RAD = 1e-4
"""An angle error no azimuth sensor resolves (0.006 deg): a drive with more constants must
lower the angle error by more than this, per sample, to be kept (on noise-free angles 1 % of
almost nothing is not evidence)."""


@dataclass(frozen=True)
class AzimuthFit:
    """alpha'' = k1 (alpha_c - alpha) - k2 alpha': k1 [1/s^2], k2 [1/s]; R^2 of the angles."""

    k1: float
    k2: float
    r2: float
    rmse_rad: float
    samples: int
    rate_max: float | None = None
    """The drive's rate limit [rad/s] the data determine (None: the ship's kept; 0: none)."""

    @property
    def params(self) -> dict[str, float]:
        """Return the parameters the fit sets."""
        out = {'azimuth_k1': self.k1, 'azimuth_k2': self.k2}
        if self.rate_max is not None:
            out['azimuth_rate_max'] = self.rate_max
        return out

    def report(self) -> dict[str, Any]:
        """Return identify.json's entry."""
        return {'k1': self.k1, 'k2': self.k2, 'r2': self.r2, 'rmse_rad': self.rmse_rad,
                'samples': self.samples}

    def describe(self) -> str:
        """Return one line for people (the command's output, identify.md)."""
        return (f'azimuth dynamics: k1 = {self.k1:.4g} 1/s^2, k2 = {self.k2:.4g} 1/s, '
                f'R^2 {self.r2:.5f} over {self.samples} angles')


def _has_commands(trial: Trial, cmd_channels: Sequence[str]) -> bool:
    """Whether the trial recorded every command channel somewhere."""
    return all(c in trial.inputs and np.any(np.isfinite(trial.inputs[c]))
               for c in cmd_channels)


def _azimuth_channels(ship: ShipConfig) -> tuple[list[str], list[str], list[int]]:
    """(measured angle channels, command channels, their columns in the actuator outputs)."""
    ins = ship.family.inputs
    cmds = [c for c in ins if c.startswith('azimuth_cmd_')]
    meas = [c.replace('azimuth_cmd_', 'azimuth_') for c in cmds]
    outs = [ship.family.outputs.index('alpha_' + c.split('_')[-1]) for c in cmds]
    return meas, cmds, outs


def fit(ship: ShipConfig, trials: Sequence[Trial],
        substeps: int | None = None) -> AzimuthFit | None:
    """
    Fit k1, k2 to the trials that recorded commanded and measured angles (None: none did).

    The actuator kernel replays each command from the first measured angle in the steps the
    simulation takes (``substeps`` per sample; None: steps of at most 0.1 s, as GO and
    ``evaluate`` integrate); the mean of the angles acting over sample interval k is compared
    with the angle recorded at sample k (the angle acting over its interval: the repository's
    convention, doc/guides/tug.md). One step per sample instead fitted a slower drive at a
    low rate (it compared the angle at the interval's end, half a sample ahead). Three nested
    drives are fitted: the ship's (with its rate limit, if any), eq. 9 without a limit, and
    with a limit fitted too; each of the last two wins only where it explains the angles
    better by 1 % (the fitted limit then replaces the ship's; 0: the drive outran the ship's
    limit). Samples whose angle was not recorded (NaN) are left out.
    """
    from scipy.optimize import least_squares

    meas_ch, cmd_ch, cols = _azimuth_channels(ship)
    if not cmd_ch:
        return None
    used = [t for t in trials if _has_commands(t, cmd_ch)]
    if not used:
        return None
    fam = ship.family
    base = ship.params.copy()
    for k in ('azimuth_offset_port', 'azimuth_offset_stbd'):
        if k in PARAM_INDEX:
            base[PARAM_INDEX[k]] = 0.0
    data = []
    for tr in used:
        sub = substeps or steps_per_sample(tr.dt)
        ctrl = np.repeat(np.asarray(tr.input_array(fam.channels)), sub, axis=0)
        data.append((np.ascontiguousarray(ctrl), sub,
                     np.column_stack([tr.inputs[c] for c in meas_ch])[1:], tr.dt / sub))
        # row 0 is where the replay starts: compared from row 1 on
    i1, i2 = PARAM_INDEX['azimuth_k1'], PARAM_INDEX['azimuth_k2']
    i3 = PARAM_INDEX['azimuth_rate_max']

    def resid(z: np.ndarray, limit: float) -> np.ndarray:
        p = base.copy()
        p[i1], p[i2] = math.exp(z[0]), math.exp(z[1])
        p[i3] = math.exp(z[2]) if len(z) > 2 else limit
        out: list[np.ndarray] = []
        for ctrl, sub, m, h in data:
            T = len(ctrl)
            a = np.zeros((T, len(fam.outputs)))
            actuator_outputs(ship.kind, p, ctrl, T, h, a)
            out.append(a[:, cols].reshape(T // sub, sub, len(cols)).mean(axis=1)[1:] - m)
        e = np.concatenate([x.ravel() for x in out])[seen]   # a sensor dropout: no residual
        return np.where(np.isfinite(e), e, 10.0)   # a diverging drive: far off, not NaN

    def fit(z0: np.ndarray, limit: float = 0.0) -> tuple[np.ndarray, float]:
        lo, hi = _AZ_BOUNDS[0][:len(z0)], _AZ_BOUNDS[1][:len(z0)]
        z0 = np.clip(z0, lo + 1e-6, hi - 1e-6)
        sol = least_squares(resid, z0, args=(limit,), method='trf', bounds=(lo, hi),
                            x_scale=1.0, diff_step=1e-4)
        return sol.x, float(sol.fun @ sol.fun)

    m = np.concatenate([d[2].ravel() for d in data])
    seen = np.isfinite(m)
    if seen.sum() < 10:
        return None
    # three drives, nested: the ship's (with its limit, if it declares one), eq. 9 without a
    # limit (wins by 1 % of the angle error: data that never saturate the loop cannot show
    # the ship's limit wrong), a fitted limit (wins by 1 %)
    k1, k2 = (ship['azimuth_k1'], ship['azimuth_k2'])
    z0 = np.log([k1 if k1 > 0 else 4.0, k2 if k2 > 0 else 3.0])

    def better(new: float, old: float) -> bool:   # by 1 % and more than sensors resolve
        return bool(new < 0.99 * old) and old - new > _AZ_RESOLUTION_RAD ** 2 * seen.sum()

    (z, sse), rate = fit(z0, base[i3]), base[i3]
    if base[i3] > 0:
        zu, sseu = fit(z0)
        if better(sseu, sse):
            z, sse, rate = zu, sseu, 0.0
    # the fitted limit from several starts (where the loop never saturates, a limit has no
    # gradient): the ship's limit and the fastest move recorded (interval means: a lower
    # bound), from the best constants so far and from the ship's
    moves = [np.abs(np.diff(d[2], axis=0)) / (d[3] * d[1]) for d in data]
    fastest = max((float(np.nanmax(x)) for x in moves if np.isfinite(x).any()), default=0.0)
    tops = {t for t in (base[i3], fastest, 0.5 * fastest) if t > 1e-3}
    if tops:
        z3, sse3 = min((fit(np.append(zk, math.log(t))) for zk in (z, z0) for t in tops),
                       key=lambda f: f[1])
        if better(sse3, sse):
            z, sse, rate = z3[:2], sse3, float(math.exp(z3[2]))
    e = resid(z, rate)
    mm = m[seen]
    ss = float(np.sum((mm - mm.mean()) ** 2))
    return AzimuthFit(float(math.exp(z[0])), float(math.exp(z[1])),
                      1.0 - float(np.sum(e ** 2)) / ss if ss > 0 else 1.0,
                      float(np.sqrt(np.mean(e ** 2))), int(e.size),
                      None if rate == base[i3] else rate)
