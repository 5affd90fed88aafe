"""Topic maps: which topics, message types, units and signs a recording uses (YAML)."""
from __future__ import annotations

import math
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
        doc = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f'topic map {path}: {exc}') from None
    return topic_map_from_dict(doc, str(path))


def topic_map_from_dict(doc: Mapping[str, Any], source: str = '<dict>') -> TopicMap:
    kw: dict[str, Any] = {}
    for sec in ('odom', 'twist', 'rudder', 'rpm', 'wind'):
        block = doc.get(sec) or {}
        for k, v in block.items():
            key = f'{sec}_{k}'
            if key not in TopicMap.__dataclass_fields__:
                raise ConfigError(f'{source}: unknown key {sec}.{k}')
            kw[key] = v
    for k, v in (doc.get('resample') or {}).items():
        if k not in ('dt', 'max_gap_s'):
            raise ConfigError(f'{source}: unknown key resample.{k}')
        kw[k] = float(v)
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
    if not tm.dt > 0 or not tm.max_gap_s > 0:
        raise ConfigError(f'{source}: resample.dt and max_gap_s must be positive')
    return tm
