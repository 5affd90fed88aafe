"""
Measured coefficients as priors of the diagnosis.

A coefficient measured outside the trials (a resistance test's R_0, a self-propulsion test's
wake fraction w_P0, a rudder-angle feedback's offset) enters every tuning of the search as a
Gaussian prior with its stated standard error, not as a fixed value: fixing it at a value that
is itself uncertain forces the other parameters to absorb the measurement's error, and an
effect that needs a little of that coefficient's room (an antenna offset, a propeller side
force) is then lost. A tight error holds the coefficient; a loose one lets the trials move it.

The prior's unit is the one the diagnosis' standard errors use
(:func:`~mmg_tuner.tuning.identifiability.standard_errors`: cov = s^2 (J'J + s^2 / BOX_VARIANCE
I)^-1 with s^2 = SSR / (n - p)): penalty = s^2 * sum(((theta - value) / se)^2), s^2 from the
model's tuning J over its n weighted residuals. With it the tuned estimate is the usual
combination of the measurement and what the trials say, each weighed by its inverse variance.

File format (YAML, SI units and radians, as params.yaml)::

    measured:
      R_0: {value: 0.0224, se: 0.0005, source: resistance test, 2024-03}
      rudder_offset: {value: 0.0, se: 0.005, source: rudder-angle feedback}
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Mapping

from mmg_tuner._limits import clip, load_yaml
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import ConfigError
from mmg_tuner.tuning.objective import Objective, Prior
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np


@dataclass(frozen=True)
class Measurement:
    """One measured coefficient: its value and standard error (SI units, radians)."""

    value: float
    se: float
    source: str = ''


def check(measured: Mapping[str, Measurement], where: str = 'measured') -> dict[str, Measurement]:
    """Return ``measured`` checked: known parameter names, finite values, errors > 0."""
    out = {}
    for name, m in dict(measured or {}).items():
        if not isinstance(m, Measurement):
            m = Measurement(*m) if isinstance(m, (tuple, list)) else m
        if name not in PARAM_INDEX:
            raise ConfigError(f'{where}: no parameter {name!r} (a measurement names a model '
                              'coefficient, e.g. R_0, w_P0, rudder_offset)')
        if not (isinstance(m, Measurement) and math.isfinite(m.value)
                and math.isfinite(m.se) and m.se > 0):
            raise ConfigError(f'{where}: {name}: needs a finite value and a standard error se '
                              f'> 0, got {m!r}')
        out[name] = m
    return out


def load(path: str | Path) -> dict[str, Measurement]:
    """Read a measurements file (module docstring); errors name the file and the field."""
    p = Path(path)
    doc = load_yaml(p, 'measurements file')   # size, depth and alias limits
    if not isinstance(doc, dict) or not isinstance(doc.get('measured'), dict):
        raise ConfigError(f"{p}: no 'measured:' mapping of coefficient -> {{value, se}}")
    out = {}
    for name, entry in doc['measured'].items():
        if not isinstance(entry, dict) or set(entry) - {'value', 'se', 'source'} \
                or 'value' not in entry or 'se' not in entry:
            raise ConfigError(f'{p}: measured.{name}: must be {{value: V, se: S[, source: '
                              f'text]}}, got {clip(repr(entry))}')
        try:
            out[name] = Measurement(float(entry['value']), float(entry['se']),
                                    str(entry.get('source', '')))
        except (TypeError, ValueError):
            raise ConfigError(f'{p}: measured.{name}: value and se must be numbers, got '
                              f'{entry!r}') from None
    return check(out, str(p))


def residual_count(obj: Objective) -> int:
    """Return the number of weighted residuals n of an objective (samples x weighted states)."""
    b = obj.batch
    return int(np.sum(np.maximum(b.lengths - 1, 0)) * np.count_nonzero(obj.weights > 0))


def prior(measured: Mapping[str, Measurement], s2: float) -> Prior | None:
    """Return the prior of the measurements in J units (s2: J per residual), None if none."""
    if not measured:
        return None
    names = list(measured)
    return Prior(np.array([PARAM_INDEX[n] for n in names]),
                 np.array([measured[n].value for n in names]),
                 np.array([measured[n].se for n in names]), float(s2))


def with_prior(obj: Objective, pr: Prior | None) -> Objective:
    """Return the same tuning objective with the prior ``pr`` (unchanged when None)."""
    if pr is None:
        return obj
    return Objective(obj.ship, obj.batch, obj.weights, obj.shoot_every_s,
                     {0: 'euler', 1: 'rk4'}[obj.method],
                     obj.substeps, obj.trial_weights, pr)


def s2_of(obj: Objective, ship: ShipConfig, space: ParameterSpace, theta: np.ndarray) -> float:
    """Return J per residual, SSR / (n - p), of the model ``theta`` on ``obj`` (no prior)."""
    J, _ = obj.per_trial(space.full_params(ship.params, theta))
    n = residual_count(obj)
    return float(J[0].sum()) / max(n - space.dim, 1)
