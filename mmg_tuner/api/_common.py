"""Checks and helpers the workflows share (option validation, output writing)."""
from __future__ import annotations

from dataclasses import fields, replace
import logging
import math
from pathlib import Path
from typing import Any, cast, Iterable, Mapping, Protocol, Sequence, TYPE_CHECKING, TypeVar

from mmg_tuner._outdir import OutputDir
from mmg_tuner.core.layout import INTEGRATORS
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError
import numpy as np

if TYPE_CHECKING:   # annotations only
    from _typeshed import DataclassInstance


logger = logging.getLogger('mmg_tuner.api')   # one logger for the API, as before the split

MAX_SEED = 2**31 - 1
C = TypeVar('C', bound='DataclassInstance')
"""A workflow's config dataclass."""


class CommonOptions(Protocol):
    """The options the tune and diagnose configs share (read by :func:`_check_common`)."""

    @property
    def a_r(self) -> float | None: ...

    @property
    def integrator(self) -> str: ...

    @property
    def seed(self) -> int: ...

    @property
    def targets(self) -> Sequence[str] | None: ...


def _finite(x: Any) -> bool:   # any value a user gave: not a number is not finite
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def _is_int(x: object) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _check(name: str, value: object, ok: bool, what: str,
           error: type[Exception] = ConfigError) -> None:
    if not ok:
        raise error(f'{name} = {value!r}: must be {what}')


def _check_common(cfg: CommonOptions, error: type[Exception]) -> None:
    _check('a_r', cfg.a_r, cfg.a_r is None or (_finite(cfg.a_r) and cfg.a_r > 0),
           'a finite number > 0 (relative box half-width)', error)
    _check('integrator', cfg.integrator, cfg.integrator in INTEGRATORS,
           f'one of {sorted(INTEGRATORS)}', error)
    _check('seed', cfg.seed, _is_int(cfg.seed) and 0 <= cfg.seed <= MAX_SEED,
           f'a whole number in [0, {MAX_SEED}]', error)
    if cfg.targets is not None:
        _check('targets', cfg.targets, len(cfg.targets) > 0 and all(
            isinstance(t, str) for t in cfg.targets), 'a non-empty list of parameter names',
            error)


def _write_all(out: str | Path | OutputDir, docs: Iterable[tuple[str, str]],
               images: Mapping[str, bytes], last: tuple[str, str]) -> list[Path]:
    own = not isinstance(out, OutputDir)
    # (own: out is a path, else the open OutputDir; mypy does not narrow through own)
    od = OutputDir.open(cast('str | Path', out)) if own else cast(OutputDir, out)
    try:
        paths = [od.write_text(n, t) for n, t in docs]
        paths += [od.write_bytes(n, b) for n, b in images.items()]
        paths.append(od.write_text(*last))
    finally:
        if own:
            od.close()
    return paths


def _as_list(trials: Trial | Iterable[Trial] | None) -> list[Trial]:
    if trials is None:
        return []
    if isinstance(trials, Trial):
        return [trials]
    return list(trials)


def _config(cls: type[C], config: C | None, options: dict[str, Any]) -> C:
    if config is None:
        return cls(**options)
    if not isinstance(config, cls):
        raise TypeError(f'config must be a {cls.__name__}, got {type(config).__name__}')
    return replace(config, **options) if options else config


def config_fields(cls: type[DataclassInstance]) -> list[str]:
    """Field names of a config dataclass (for the CLIs)."""
    return [f.name for f in fields(cls)]
