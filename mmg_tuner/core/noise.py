"""
Sensor noise models: 1-sigma white-noise levels that turn a true trial into a recorded one.

A noise model is a frozen dataclass of sigmas (SI units, radians) with an ``apply(trial, rng)``
method; ``data/generate.py`` holds the usual trial sensors', an actuator's own catalogue module
(``core/actuators/__init__.py``: ``TRIALS``) holds the sensors of the craft it drives.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
import math
from typing import Self

from mmg_tuner.errors import ConfigError


@dataclass(frozen=True)
class Sigmas:
    """1-sigma noise levels, each a finite number >= 0: the fields of a noise model."""

    def __post_init__(self) -> None:
        for k, v in self.__dict__.items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f'sensor noise {k} = {v!r}: must be a finite number >= 0')

    @classmethod
    def none(cls) -> Self:
        """Return the noise model with every sigma 0 (exact measurements)."""
        return cls(*(0.0 for _ in fields(cls)))

    def describe(self) -> str:
        """Return the sigmas as ``name=value`` pairs (a trial's note)."""
        return ', '.join(f'{k}={v:.4g}' for k, v in self.__dict__.items())
