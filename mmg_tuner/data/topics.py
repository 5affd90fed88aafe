"""Topic maps: which topics, message types, units and signs a recording uses (YAML)."""
from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import yaml

from mmg_tuner.errors import ConfigError

POSE_TYPES = ('nav_msgs/msg/Odometry', 'geometry_msgs/msg/PoseStamped')
SCALAR_TYPES = ('std_msgs/msg/Float64', 'std_msgs/msg/Float32', 'sensor_msgs/msg/JointState')
RUDDER_UNITS = {'rad': 1.0, 'deg': math.pi / 180.0}
RPM_UNITS = {'rpm': 1.0, 'rps': 60.0, 'rad_s': 60.0 / (2.0 * math.pi)}
WIND_TYPES = ('geometry_msgs/msg/Vector3Stamped',)
# true_enu: the air's velocity over ground in the map frame (ENU, m/s);
# apparent_flu: the air's velocity relative to the ship in base_link (FLU, m/s), as an
# anemometer on the ship measures it (converted to true wind with the recorded motion)
WIND_FRAMES = ('true_enu', 'apparent_flu')
SECTIONS = ('odom', 'twist', 'rudder', 'rpm', 'wind', 'resample')
MAX_MAP_BYTES = 1 << 20  # a topic map is a few hundred bytes


@dataclass(frozen=True)
class TopicMap:
    odom_topic: str = '/odom'
    odom_type: str = 'nav_msgs/msg/Odometry'
    twist_topic: str = ''
    twist_type: str = 'geometry_msgs/msg/TwistStamped'
    rudder_topic: str = '/rudder_angle'
    rudder_type: str = 'std_msgs/msg/Float64'
    rudder_joint: str = ''
    rudder_unit: str = 'rad'
    rudder_sign: float = 1.0
    rpm_topic: str = '/propeller_rpm'
    rpm_type: str = 'std_msgs/msg/Float64'
    rpm_joint: str = ''
    rpm_unit: str = 'rpm'
    wind_topic: str = '/wind'   # optional: used when the recording has it; '' = never
    wind_type: str = 'geometry_msgs/msg/Vector3Stamped'
    wind_frame: str = 'true_enu'
    dt: float = 1.0
    max_gap_s: float = 5.0

    @property
    def rudder_to_rad(self) -> float:
        return RUDDER_UNITS[self.rudder_unit] * self.rudder_sign

    @property
    def rpm_factor(self) -> float:
        return RPM_UNITS[self.rpm_unit]


def default_topic_map_path() -> Path | None:
    here = Path(__file__).resolve()
    for parent in here.parents:
        for cand in (parent / 'config' / 'topics.yaml',
                     parent / 'share' / 'mmg_tuner' / 'config' / 'topics.yaml'):
            if cand.is_file():
                return cand
    return None


def load_topic_map(path: str | Path | None = None) -> TopicMap:
    """Read a topic map YAML; keys left out keep the defaults of conventions.md."""
    if path is None:
        return TopicMap()
    path = Path(path)
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_MAP_BYTES:
            raise ConfigError(f'topic map {path}: not a regular YAML file of at most '
                              f'{MAX_MAP_BYTES >> 20} MB')
        doc = yaml.safe_load(path.read_bytes().decode('utf-8-sig'))
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        raise ConfigError(f'topic map {path}: not valid YAML '
                          f'({getattr(exc, "problem", None) or exc}{where})') from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f'topic map {path}: not UTF-8 text (byte {exc.start})') from None
    except OSError as exc:
        raise ConfigError(f'topic map {path}: {exc.strerror or exc}') from None
    return topic_map_from_dict({} if doc is None else doc, str(path))


def _typed(source: str, key: str, v: Any, default: Any) -> Any:
    """v as the type of the field's default: a string for topics, types, joints, units and
    frames, a finite number for sign, dt and max_gap_s."""
    if isinstance(default, str):
        if not isinstance(v, str):
            raise ConfigError(f'{source}: {key} = {v!r} must be a string')
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError(f'{source}: {key} = {v!r} must be a finite number')
    return float(v)


def topic_map_from_dict(doc: Mapping[str, Any], source: str = '<dict>') -> TopicMap:
    if not isinstance(doc, Mapping):
        raise ConfigError(f'{source}: a topic map is a mapping of sections (odom, rudder, rpm, '
                          f'...), not {type(doc).__name__}')
    unknown = sorted(str(k) for k in doc if k not in SECTIONS)
    if unknown:
        raise ConfigError(f'{source}: unknown section(s) {unknown}; known: {list(SECTIONS)}')
    kw: dict[str, Any] = {}
    fields = TopicMap.__dataclass_fields__
    for sec in SECTIONS:
        block = doc.get(sec)
        if block is None:
            continue
        if not isinstance(block, Mapping):
            raise ConfigError(f'{source}: section {sec} must be a mapping of keys, not '
                              f'{type(block).__name__}')
        for k, v in block.items():
            key = f'{sec}_{k}' if sec != 'resample' else str(k)
            if sec == 'resample' and key not in ('dt', 'max_gap_s') or key not in fields:
                raise ConfigError(f'{source}: unknown key {sec}.{k}')
            kw[key] = _typed(source, f'{sec}.{k}', v, fields[key].default)
    tm = TopicMap(**kw)
    if tm.odom_type not in POSE_TYPES:
        raise ConfigError(f'{source}: odom.type {tm.odom_type!r} not one of {POSE_TYPES}')
    for name, typ in (('rudder', tm.rudder_type), ('rpm', tm.rpm_type)):
        if typ not in SCALAR_TYPES:
            raise ConfigError(f'{source}: {name}.type {typ!r} not one of {SCALAR_TYPES}')
    if tm.rudder_unit not in RUDDER_UNITS or tm.rpm_unit not in RPM_UNITS:
        raise ConfigError(f'{source}: units must be rudder {list(RUDDER_UNITS)}, '
                          f'rpm {list(RPM_UNITS)}')
    if tm.wind_type not in WIND_TYPES or tm.wind_frame not in WIND_FRAMES:
        raise ConfigError(f'{source}: wind.type must be one of {WIND_TYPES} and wind.frame one '
                          f'of {WIND_FRAMES}')
    if tm.rudder_sign not in (1, -1):
        raise ConfigError(f'{source}: rudder.sign must be 1 or -1')
    if not 1e-3 <= tm.dt <= 3600 or not 0 < tm.max_gap_s <= 1e6:
        raise ConfigError(f'{source}: resample.dt must be within [0.001, 3600] s and '
                          f'max_gap_s within (0, 1e6] s (got {tm.dt:g}, {tm.max_gap_s:g})')
    return tm
