"""
Ship configs: YAML files into a frozen :class:`ShipConfig` holding the flat parameter vector.

A ship is data, never code: ``config/<name>.yaml`` holds particulars, added masses, hull
derivatives, propeller and rudder models (each value citing its source). ``load_ship('suzaku')``
finds the installed or in-tree config by name; a path to any YAML works too.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import difflib
import math
from pathlib import Path
import re
from typing import Any, Collection, Mapping

from mmg_tuner._limits import clip, load_yaml
from mmg_tuner.core.layout import EFFECT_NEUTRAL, MODEL_KINDS, N_PARAMS, PARAM_INDEX, PARAM_NAMES
from mmg_tuner.core.models import Family, family
from mmg_tuner.core.plausibility import refuse_impossible
from mmg_tuner.errors import ConfigError
import numpy as np

_SECTIONS = ('particulars', 'added_mass', 'hull', 'propeller', 'rudder', 'thrusters', 'windage')


def config_dirs() -> list[Path]:
    """Where ship configs are looked up by name: the source tree, then the colcon share dir."""
    here = Path(__file__).resolve()
    dirs = []
    for parent in here.parents:
        for cand in (parent / 'config', parent / 'share' / 'mmg_tuner' / 'config'):
            if (cand / 'suzaku.yaml').is_file() and cand not in dirs:
                dirs.append(cand)
    return dirs


def resolve_config_path(name_or_path: str | Path) -> Path:
    """Return a ship name (``suzaku``) or a path to a YAML file -> the file's path."""
    p = Path(name_or_path)
    if p.suffix in ('.yaml', '.yml') or p.is_file():
        if not p.is_file():
            raise ConfigError(f'ship config {p} does not exist')
        return p
    for d in config_dirs():
        cand = d / f'{name_or_path}.yaml'
        if cand.is_file():
            return cand
    known = sorted({f.stem for f in embedded_ship_files()})
    raise ConfigError(f'unknown ship {name_or_path!r}: give a YAML path or one of {known}')


def embedded_ship_files() -> list[Path]:
    """
    Return the ship YAMLs in the config folders, by folder then name.

    Only ship files (they declare a model family), not the node, topic or demo configs.
    """
    return [f for d in config_dirs() for f in sorted(d.glob('*.yaml'))
            if re.search(r'^model:', f.read_text(encoding='utf-8'), re.M)]


@dataclass(frozen=True)
class ShipConfig:
    """
    One ship: its model structure and the full flat parameter vector.

    Attributes
    ----------
    name: ship name.
    model: the model family (``core/models``): ``'container'`` (fine-tuning paper),
        ``'standard'`` (MMG standard method) or ``'lowspeed'`` (four-quadrant, low speed).
    params: float64 vector in :data:`~mmg_tuner.core.layout.PARAM_NAMES` order.
    rudder_rate_rad_s: steering-gear rate limit.
    max_rudder_rad: rudder angle limit.
    tuning_targets: default names to tune.
    a_r: default relative half-width of the tuning box.
    scale_ratio: Froude scale ratio to full scale (1 for a real ship).
    source: the YAML file this came from.
    tuning_bounds: absolute search boxes {name: (lower, upper)} from the YAML's
        ``tuning.bounds`` (they replace +-a_r for those names).

    """

    name: str
    model: str
    params: np.ndarray
    rudder_rate_rad_s: float
    max_rudder_rad: float
    tuning_targets: tuple[str, ...]
    a_r: float = 0.5
    scale_ratio: float = 1.0
    source: str = ''
    extra: Mapping[str, Any] = field(default_factory=dict)
    tuning_bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def kind(self) -> int:
        """Return the family's integer code: what the compiled kernels take first."""
        return MODEL_KINDS[self.model]

    @property
    def family(self) -> Family:
        """Return the model family: its inputs and capabilities (astern rpm, u <= 0)."""
        return family(self.model)

    @property
    def L_pp(self) -> float:
        return float(self.params[PARAM_INDEX['L_pp']])

    @property
    def has_windage(self) -> bool:
        """
        Whether the config describes the above-water ship (needed by the wind effect).

        Blendermann's areas and coefficients, or those a family's own wind model reads.
        """
        keys = ('rho_air', 'A_F', 'A_L') if self.family.wind is not None else (
            'rho_air', 'A_F', 'A_L', 'L_OA', 'CD_t')
        return all(self[k] > 0 for k in keys)

    def __getitem__(self, name: str) -> float:
        return float(self.params[_index(name, self.source)])

    def as_dict(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(PARAM_NAMES, self.params)}

    def with_params(self, values: Mapping[str, float], source: str = '') -> 'ShipConfig':
        """
        Return a copy with some parameters replaced (e.g. tuned), validated like a ship file.

        ``source`` names where the values came from in errors.
        """
        where = source or 'parameters'
        p = self.params.copy()
        for k, v in values.items():
            p[_index(k, where)] = _number(v, k, where)
        _check_physical(p, where, set(values), self.family.required)
        p.setflags(write=False)
        return ShipConfig(self.name, self.model, p, self.rudder_rate_rad_s, self.max_rudder_rad,
                          self.tuning_targets, self.a_r, self.scale_ratio, self.source, self.extra,
                          self.tuning_bounds)


# Physical plausibility, checked for ship files and overlays alike.
_POSITIVE = ('rho', 'L_pp', 'B', 'd', 'm', 'I_zG')
_POSITIVE_IF_REQUIRED = ('D_P', 'H_R', 'A_R')   # a propeller and rudder, where the family has them
_NON_NEGATIVE = ('m_x', 'm_y', 'J_z', 'rho_air', 'A_F', 'A_L', 'L_OA', 'current_speed',
                 'wind_speed', 'rudder_lag_tau', 'rpm_scale')
MAX_MAGNITUDE = 1e15
"""No parameter of a ship is this large in SI units or as a coefficient (a 500 000 t ship of
400 m has m = 5e8 kg, I_zG ~ 5e12 kg m^2): larger values are typing errors or divergent fits
(R_0: 1e300)."""


def _number(v: Any, key: str, source: str) -> float:
    """Return a finite float from a YAML value, or a ConfigError naming the key and value."""
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise ConfigError(f'{source}: {key} = {v!r} is not a number')
    try:
        x = float(v)
    except ValueError:
        raise ConfigError(f'{source}: {key} = {v!r} is not a number') from None
    if not math.isfinite(x):
        raise ConfigError(f'{source}: {key} = {v!r} is not finite')
    if abs(x) > MAX_MAGNITUDE:
        raise ConfigError(f'{source}: {key} = {v!r} is absurdly large (|value| > '
                          f'{MAX_MAGNITUDE:g})')
    return x


def _check_physical(p: np.ndarray, source: str, keys: Collection[str] | None = None,
                    required: Collection[str] = _POSITIVE_IF_REQUIRED) -> None:
    """
    Refuse physically impossible values (keys: only report these, e.g. an overlay's).

    required: the family's required keys (a propeller's and rudder's sizes must be positive
    only for a family that has them).
    """
    for k in _POSITIVE + tuple(k for k in _POSITIVE_IF_REQUIRED if k in required):
        if not p[PARAM_INDEX[k]] > 0 and (keys is None or k in keys):
            raise ConfigError(f'{source}: {k} must be positive, got {k} = '
                              f'{p[PARAM_INDEX[k]]:g}')
    for k in _NON_NEGATIVE:
        if p[PARAM_INDEX[k]] < 0 and (keys is None or k in keys):
            raise ConfigError(f'{source}: {k} must not be negative, got {k} = '
                              f'{p[PARAM_INDEX[k]]:g}')
    # the centre of gravity lies in the hull: x_G [m] from midships, |x_G| <= L_pp / 2
    xg, half = p[PARAM_INDEX['x_G']], p[PARAM_INDEX['L_pp']] / 2
    if not abs(xg) <= half and (keys is None or {'x_G', 'L_pp'} & set(keys)):
        raise ConfigError(f'{source}: x_G = {xg:g} m puts the centre of gravity outside the '
                          f'hull (|x_G| <= L_pp / 2 = {half:g} m); x_G is in metres from '
                          'midships, + forward')
    # the ship file only: a tuned overlay's R_0 comes from a box the user chose, and refusing
    # it would lose a finished run (ParameterSpace keeps the pre-determined value's box)
    r0 = p[PARAM_INDEX['R_0']]
    if keys is None and r0 < 0:
        raise ConfigError(f'{source}: R_0 = {r0:g} is negative: the straight-ahead '
                          'resistance coefficient (R_0 >= 0) opposes the motion')


# every top-level key a ship file may have (anything else is a typing error, refused)
_TOP_LEVEL = _SECTIONS + ('name', 'model', 'scale', 'scale_ratio', 'setting', 'steering',
                          'tuning')


def _check_top_level(doc: Mapping[str, Any], source: str) -> None:
    """Refuse a key the loader would ignore (``tunning:``), listing the known ones."""
    unknown = [k for k in doc if k not in _TOP_LEVEL]
    if unknown:
        k = unknown[0]
        close = difflib.get_close_matches(str(k), _TOP_LEVEL, n=1)
        raise ConfigError(f'{source}: unknown top-level key {clip(repr(k), 60)}'
                          + (f" (did you mean '{close[0]}'?)" if close else '')
                          + f"; the known keys are {', '.join(_TOP_LEVEL)}")


def _index(name: str, source: str) -> int:
    try:
        return PARAM_INDEX[name]
    except KeyError:
        raise ConfigError(f'{source or "parameters"}: unknown parameter {name!r}') from None


def load_ship(name_or_path: str | Path = 'suzaku', params_file: str | Path | None = None
              ) -> ShipConfig:
    """
    Load a ship config by name or path; ``params_file`` overlays tuned values.

    Examples
    --------
    >>> ship = load_ship('suzaku')
    >>> ship['t_P']
    0.08

    """
    path = resolve_config_path(name_or_path)
    ship = ship_from_dict(_read_yaml(path, 'ship config'), str(path))
    refuse_impossible(ship, str(path))   # a model that cannot be a ship: core/plausibility.py
    if params_file is not None:
        ship = ship.with_params(load_params_file(params_file), source=str(params_file))
        refuse_impossible(ship, str(params_file))
    return ship


def _read_yaml(path: Path, what: str) -> Any:
    """Return a YAML document from a text file, or a ConfigError saying why not."""
    if not path.is_file():
        raise ConfigError(f'{what} {path} is not a file')
    return load_yaml(path, what)   # size, depth and alias-expansion limits (_limits.py)


def ship_from_dict(doc: Mapping[str, Any], source: str = '<dict>') -> ShipConfig:
    if not isinstance(doc, Mapping):
        raise ConfigError(f'{source}: a ship config must be a mapping')
    _check_top_level(doc, source)
    model = doc.get('model')
    if not isinstance(model, str) or model not in MODEL_KINDS:
        raise ConfigError(f'{source}: key "model" must be one of {sorted(MODEL_KINDS)}, '
                          f'got {model!r}')
    fam = family(model)
    values: dict[str, Any] = {**fam.defaults, **EFFECT_NEUTRAL}
    for sec in _SECTIONS:
        block = _section(doc, sec, source)
        for k, v in block.items():
            if k in ('C_b', 'displacement'):
                values[k] = v
                continue
            if k not in PARAM_INDEX:
                raise ConfigError(f'{source}: {sec}.{k} is not a known parameter')
            values[k] = v
    missing = [k for k in fam.required if k not in values]
    if missing:
        raise ConfigError(f'{source}: missing required keys {missing}')
    for k, v in values.items():
        if not (v == 'derived' and k in ('m', 'I_zG')):
            values[k] = _number(v, k, source)
    _derive_mass(values, source)
    p = np.zeros(N_PARAMS)
    for k, v in values.items():
        if k in ('C_b', 'displacement'):
            continue
        p[PARAM_INDEX[k]] = _number(v, k, source)
    _check_physical(p, source, required=fam.required)
    p.setflags(write=False)
    steering = _section(doc, 'steering', source)
    tuning = _section(doc, 'tuning', source)
    targets = tuning.get('targets', ())
    if not isinstance(targets, (list, tuple)) or not all(isinstance(t, str) for t in targets):
        raise ConfigError(f'{source}: tuning.targets = {targets!r} must be a list of names')
    targets = tuple(targets)
    for t in targets:
        _index(t, source)
    rate = _number(steering.get('rate_deg_s', 2.32), 'steering.rate_deg_s', source)
    max_rudder = _number(steering.get('max_rudder_deg', 35.0), 'steering.max_rudder_deg', source)
    a_r = _number(tuning.get('a_r', 0.5), 'tuning.a_r', source)
    scale = _number(doc.get('scale_ratio', 1.0), 'scale_ratio', source)
    for key, v, ok in (('steering.rate_deg_s', rate, rate > 0),
                       ('steering.max_rudder_deg', max_rudder, 0 < max_rudder <= 90),
                       ('tuning.a_r', a_r, 0 < a_r <= 10), ('scale_ratio', scale, scale > 0)):
        if not ok:
            raise ConfigError(f'{source}: {key} = {v:g} is out of range')
    return ShipConfig(
        name=str(doc.get('name', Path(source).stem)), model=model, params=p,
        rudder_rate_rad_s=math.radians(rate), max_rudder_rad=math.radians(max_rudder),
        tuning_targets=targets, a_r=a_r, scale_ratio=scale, source=source,
        extra={k: v for k, v in doc.items() if k not in _SECTIONS},
        tuning_bounds=_tuning_bounds(tuning, source))


def _tuning_bounds(tuning: Mapping[str, Any], source: str) -> dict[str, tuple[float, float]]:
    """``tuning.bounds``: {name: [lower, upper]} with known names and finite lower < upper."""
    block = tuning.get('bounds')
    if block is None:
        return {}
    if not isinstance(block, Mapping):
        raise ConfigError(f'{source}: tuning.bounds must be a mapping name: [lower, upper]')
    out = {}
    for k, v in block.items():
        key = f'tuning.bounds.{k}'
        if not isinstance(k, str) or k not in PARAM_INDEX:
            raise ConfigError(f'{source}: {key}: unknown parameter {k!r}')
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise ConfigError(f'{source}: {key} = {v!r} must be [lower, upper]')
        lo, hi = _number(v[0], key, source), _number(v[1], key, source)
        if not lo < hi:
            raise ConfigError(f'{source}: {key} = [{lo:g}, {hi:g}]: lower must be < upper')
        out[k] = (lo, hi)
    return out


def _section(doc: Mapping[str, Any], sec: str, source: str) -> Mapping[str, Any]:
    block = doc.get(sec)
    if block is None:
        return {}
    if not isinstance(block, Mapping):
        raise ConfigError(f'{source}: section {sec!r} must be a mapping of key: value, got '
                          f'{type(block).__name__} {block!r:.60}')
    return block


def _derive_mass(values: dict[str, Any], source: str) -> None:
    """
    Fill in m and I_zG given as 'derived'.

    m = rho C_b L B d (or rho * displacement), I_zG = m (L/4)^2.
    """
    rho, L = float(values['rho']), float(values['L_pp'])
    if values.get('m', 'derived') == 'derived':
        if 'displacement' in values:
            values['m'] = rho * float(values['displacement'])
        elif 'C_b' in values:
            values['m'] = rho * float(values['C_b']) * L * float(values['B']) * float(values['d'])
        else:
            raise ConfigError(f'{source}: m is "derived" but neither C_b nor displacement given')
    if values.get('I_zG', 'derived') == 'derived':
        values['I_zG'] = float(values['m']) * (0.25 * L) ** 2


# the top-level keys of a params overlay (tune/diagnose write the first four; residual names a
# network, provenance is the benchmarks' record of their inputs)
PARAMS_FILE_KEYS = ('ship', 'ship_config', 'note', 'params', 'residual', 'provenance')


def load_params_file(path: str | Path) -> dict[str, float]:
    """Read a params.yaml written by ``tune``/``diagnose``: ``{params: {name: value}}``."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f'params file {path} does not exist')
    doc = _read_yaml(path, 'params file')
    params = doc.get('params') if isinstance(doc, Mapping) else None
    if not isinstance(params, Mapping):
        raise ConfigError(f'{path}: expected a mapping under key "params"')
    unknown = [str(k) for k in doc if k not in PARAMS_FILE_KEYS]
    if unknown:   # a typo (residul:) would drop what it names in silence
        shown = ', '.join(repr(clip(k, 40)) for k in unknown[:3])
        raise ConfigError(f'{path}: unknown top-level key(s) {shown}'
                          + (f' and {len(unknown) - 3} more' if len(unknown) > 3 else '')
                          + f"; a params file has only {', '.join(PARAMS_FILE_KEYS)}")
    out = {}
    for k, v in params.items():
        if not isinstance(k, str) or k not in PARAM_INDEX:
            raise ConfigError(f'{path}: unknown parameter {k!r}')
        out[k] = _number(v, f'params.{k}', str(path))
    return out
