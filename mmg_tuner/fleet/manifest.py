"""
The fleet manifest: which ships, which trials, which options.

Validated once, here, before any work starts (like SciPy's ``check_arguments``): every error names
the manifest, the ship and the key. A missing or unreadable trial is *not* a manifest error: it
fails that ship alone, with its reason, when the ship's task loads it.

Example (relative paths are relative to the manifest's folder)::

    defaults:                    # optional: options for every ship
      budget: quick
    ships:
      - name: ship_a             # unique; results go to OUT/ship_a/
        ship: suzaku             # a config name or a YAML path
        tune: [trials/a/turning_p35, {path: trials/a/zigzag_p20_10, date: 2024-03-01}]
        test: [trials/a/zigzag_m20_20, trials/a/random_p30]
        effects: [current, rudder_offset]
        diagnose_options: {integrator: rk4}

Per-ship keys (all optional but name, ship, tune): ``test``, ``params`` (overlay YAML),
``topics`` (topic map YAML), ``dt`` [s] (default 1.0; both steps load the trials at it),
``trial_scale`` ('ship' | 'full'), ``steps`` (default [tune, diagnose]), ``plots`` (default
true), ``trend_parameter`` (default R_0: fitted per trial date to see a model degrade), every
field of :class:`mmg_tuner.api.TuneConfig` and :class:`mmg_tuner.api.DiagnoseConfig` (a
field both have, e.g. ``seed`` or ``targets``, applies to both), and ``tune_options`` /
``diagnose_options`` mappings for a value one step alone should take (e.g. ``integrator``,
whose defaults differ: euler for tune, rk4 for diagnose, as the commands have them).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
import datetime as _dt
import difflib
import json
import math
import os
from pathlib import Path
import re
from typing import Any, cast, Iterable, Mapping, Sequence

from mmg_tuner import api
from mmg_tuner._limits import load_yaml
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.errors import ConfigError, MmgTunerError

STEPS = ('tune', 'diagnose')
_TUNE_FIELDS = tuple(f.name for f in fields(api.TuneConfig))
_DIAG_FIELDS = tuple(f.name for f in fields(api.DiagnoseConfig))
_OWN = ('name', 'ship', 'tune', 'test', 'params', 'topics', 'dt', 'trial_scale', 'steps',
        'plots', 'trend_parameter', 'tune_options', 'diagnose_options')
KNOWN_KEYS = tuple(dict.fromkeys(_OWN + _TUNE_FIELDS + _DIAG_FIELDS))
# a ship's name is a folder name under --out: no separators, no hidden or special names
_NAME = re.compile(r'^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$')
RESERVED = ('fleet.json', 'fleet.md', 'fleet.png')


@dataclass(frozen=True)
class TrialSource:
    """
    One trial input (a bag folder, .mcap, .csv, .dat or a folder of them).

    With the date it was recorded when the manifest gives one (dated groups reveal a model that
    degrades).
    """

    path: Path
    date: _dt.date | None = None

    def to_dict(self) -> dict[str, Any]:
        return {'path': str(self.path), 'date': self.date.isoformat() if self.date else None}


@dataclass(frozen=True)
class ShipJob:
    """Everything one ship's work needs; picklable, sent to the Dask workers."""

    name: str
    ship: str                          # config name, or an absolute YAML path
    tune: tuple[TrialSource, ...]
    test: tuple[TrialSource, ...]
    tune_config: api.TuneConfig
    diagnose_config: api.DiagnoseConfig
    params: Path | None = None
    topics: Path | None = None
    dt: float = 1.0
    trial_scale: str = 'ship'
    steps: tuple[str, ...] = STEPS
    plots: bool = True
    trend_parameter: str = 'R_0'

    def options_doc(self) -> dict[str, Any]:
        """Every option as plain JSON data (the resume hash covers it)."""
        def conf(c: api.TuneConfig | api.DiagnoseConfig) -> dict[str, Any]:
            return {f.name: _plain(getattr(c, f.name)) for f in fields(c)}
        return {'name': self.name, 'ship': self.ship,
                'tune': [s.to_dict() for s in self.tune],
                'test': [s.to_dict() for s in self.test],
                'params': str(self.params) if self.params else None,
                'topics': str(self.topics) if self.topics else None, 'dt': self.dt,
                'trial_scale': self.trial_scale, 'steps': list(self.steps),
                'plots': self.plots, 'trend_parameter': self.trend_parameter,
                'tune_config': conf(self.tune_config),
                'diagnose_config': conf(self.diagnose_config)}

    @property
    def dated(self) -> bool:
        return len({s.date for s in self.tune + self.test if s.date is not None}) >= 2


@dataclass(frozen=True)
class Manifest:
    path: Path | None
    ships: tuple[ShipJob, ...]

    def __len__(self) -> int:
        return len(self.ships)


def _plain(v: Any) -> Any:
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in sorted(v.items())}
    return v


def load_manifest(path: str | Path) -> Manifest:
    """Read and validate a manifest YAML (see the module docstring)."""
    path = Path(path)
    doc = load_yaml(path, 'manifest')   # size, depth and alias limits (_limits.py)
    return manifest_from_dict(doc, path)


def manifest_from_dict(doc: Any, path: str | Path | None = None) -> Manifest:
    """
    Validate a manifest given as data.

    Relative paths are taken from ``path``'s folder (the working directory when None).
    """
    where = f'manifest {path}' if path else 'manifest'
    base = Path(path).resolve().parent if path else Path.cwd()
    if not isinstance(doc, Mapping):
        raise ConfigError(f'{where}: expected a mapping with a "ships" list, got '
                          f'{type(doc).__name__}')
    extra = sorted(set(doc) - {'ships', 'defaults'})
    if extra:
        raise ConfigError(f'{where}: unknown top-level key(s) {extra}; use "ships" and '
                          'optionally "defaults"')
    defaults = doc.get('defaults') or {}
    if not isinstance(defaults, Mapping):
        raise ConfigError(f'{where}: "defaults" must be a mapping of per-ship options')
    for bad in ('name', 'tune', 'test'):
        if bad in defaults:
            raise ConfigError(f'{where}: defaults.{bad} is per ship; give it in each ship')
    ships = doc.get('ships')
    if not isinstance(ships, list) or not ships:
        raise ConfigError(f'{where}: "ships" must be a non-empty list')
    jobs: list[ShipJob] = []
    seen: dict[str, int] = {}
    for i, entry in enumerate(ships):
        if not isinstance(entry, Mapping):
            raise ConfigError(f'{where}: ships[{i}] must be a mapping, got '
                              f'{type(entry).__name__}')
        label = f'{where}: ships[{i}]' + (f' ({entry["name"]})' if 'name' in entry else '')
        merged = {**defaults, **entry}
        for key in ('tune_options', 'diagnose_options'):  # nested defaults merge too
            if isinstance(defaults.get(key), Mapping) and isinstance(entry.get(key), Mapping):
                merged[key] = {**defaults[key], **entry[key]}
        job = _ship_job(merged, label, base)
        if job.name in seen:
            raise ConfigError(f'{label}: name {job.name!r} is already used by ships['
                              f'{seen[job.name]}]; names must be unique (one folder each)')
        seen[job.name] = i
        jobs.append(job)
    return Manifest(Path(path) if path else None, tuple(jobs))


def _unknown(keys: Iterable[Any], known: Sequence[str], label: str) -> None:
    for k in keys:
        if k not in known:
            close = difflib.get_close_matches(str(k), known, n=1)
            raise ConfigError(f'{label}: unknown key {k!r}' +
                              (f' (did you mean {close[0]!r}?)' if close else
                               f'; known: {", ".join(known)}'))


def _path(v: Any, label: str, key: str, base: Path) -> Path:
    if not isinstance(v, (str, Path)) or not str(v).strip():
        raise ConfigError(f'{label}: {key} must be a path, got {v!r}')
    p = Path(str(v)).expanduser()
    return Path(os.path.normpath(p if p.is_absolute() else base / p))


def _date(v: Any, label: str, key: str) -> _dt.date:
    if isinstance(v, _dt.datetime):
        return v.date()
    if isinstance(v, _dt.date):
        return v
    try:
        return _dt.date.fromisoformat(str(v))
    except ValueError:
        raise ConfigError(f'{label}: {key} {v!r} is not a date (YYYY-MM-DD)') from None


def _sources(v: Any, label: str, key: str, base: Path, required: bool
             ) -> tuple[TrialSource, ...]:
    if v is None:
        if required:
            raise ConfigError(f'{label}: "{key}" is required: a list of trial files or folders')
        return ()
    if isinstance(v, (str, Mapping)):
        v = [v]
    if not isinstance(v, list) or (required and not v):
        raise ConfigError(f'{label}: {key} must be a non-empty list of trial files or folders')
    out = []
    for j, item in enumerate(v):
        k = f'{key}[{j}]'
        if isinstance(item, Mapping):
            _unknown(item, ('path', 'date'), f'{label}: {k}')
            if 'path' not in item:
                raise ConfigError(f'{label}: {k} needs a "path"')
            out.append(TrialSource(_path(item['path'], label, k + '.path', base),
                                   _date(item['date'], label, k + '.date')
                                   if item.get('date') is not None else None))
        else:
            out.append(TrialSource(_path(item, label, k, base)))
    return tuple(out)


def _config_kwargs(src: Mapping[str, Any], names: tuple[str, ...]) -> dict[str, Any]:
    kw = {}
    for k in names:
        if k in src:
            v = src[k]
            if k == 'bounds' and isinstance(v, Mapping):
                v = {n: tuple(b) if isinstance(b, list) else b for n, b in v.items()}
            elif isinstance(v, list):
                v = tuple(v)
            kw[k] = v
    return kw


def _ship_job(e: Mapping[str, Any], label: str, base: Path) -> ShipJob:
    _unknown(e, KNOWN_KEYS, label)
    name = e.get('name')
    if not isinstance(name, str) or not _NAME.match(name) or name in RESERVED:
        raise ConfigError(f'{label}: name {name!r} must be 1-100 letters, digits, "_", "-" or '
                          '"." starting with a letter or digit (it is the folder OUT/<name>/), '
                          f'and not one of {list(RESERVED)}')
    ship = e.get('ship')
    if not isinstance(ship, str) or not ship.strip():
        raise ConfigError(f'{label}: "ship" is required: a config name (suzaku, kvlcc2) or a '
                          'YAML path')
    if ship.endswith(('.yaml', '.yml')) or '/' in ship:
        ship = str(_path(ship, label, 'ship', base))
    tune = _sources(e.get('tune'), label, 'tune', base, True)
    test = _sources(e.get('test'), label, 'test', base, False)
    dt = e.get('dt', 1.0)
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (
            math.isfinite(dt) and 1e-3 <= dt <= 600):
        raise ConfigError(f'{label}: dt {dt!r} must be a step in [0.001, 600] s')
    scale = e.get('trial_scale', 'ship')
    if scale not in ('ship', 'full'):
        raise ConfigError(f"{label}: trial_scale {scale!r} must be 'ship' or 'full'")
    steps = e.get('steps', list(STEPS))
    if isinstance(steps, str):
        steps = [steps]
    if not isinstance(steps, list) or not steps or any(s not in STEPS for s in steps):
        raise ConfigError(f'{label}: steps {steps!r} must be a non-empty list of {list(STEPS)}')
    plots = e.get('plots', True)
    if not isinstance(plots, bool):
        raise ConfigError(f'{label}: plots {plots!r} must be true or false')
    trend = e.get('trend_parameter', 'R_0')
    if trend not in PARAM_INDEX:
        raise ConfigError(f'{label}: trend_parameter {trend!r} is not a model parameter')
    configs = {}
    for step, cls, names in (('tune', api.TuneConfig, _TUNE_FIELDS),
                             ('diagnose', api.DiagnoseConfig, _DIAG_FIELDS)):
        own = e.get(f'{step}_options') or {}
        if not isinstance(own, Mapping):
            raise ConfigError(f'{label}: {step}_options must be a mapping of '
                              f'{cls.__name__} fields')
        _unknown(own, names, f'{label}: {step}_options')
        kw = {**_config_kwargs(e, names), **_config_kwargs(own, names)}
        try:
            configs[step] = cls(**kw)
        except MmgTunerError as exc:
            raise ConfigError(f'{label}: {exc}') from None
        except TypeError as exc:
            raise ConfigError(f'{label}: {step} options: {exc}') from None
    # (each step's config of its own class, made above)
    return ShipJob(name, ship, tune, test, cast(api.TuneConfig, configs['tune']),
                   cast(api.DiagnoseConfig, configs['diagnose']),
                   _path(e['params'], label, 'params', base) if e.get('params') else None,
                   _path(e['topics'], label, 'topics', base) if e.get('topics') else None,
                   float(dt), scale, tuple(dict.fromkeys(steps)), plots, trend)


def manifest_json(m: Manifest) -> str:
    return json.dumps([j.options_doc() for j in m.ships], indent=1)
