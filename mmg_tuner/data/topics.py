"""Topic maps: which topics, message types, units and signs a recording uses (YAML)."""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
import math
import os
from pathlib import Path
import stat
from typing import Any, Iterable, Mapping

from mmg_tuner._limits import yaml_loads
from mmg_tuner.core.actuators import declared_inputs, REGISTRY as ACTUATORS
from mmg_tuner.core.channels import ENVIRONMENT, TABLE
from mmg_tuner.core.geodesy import Datum
from mmg_tuner.errors import ConfigError

NAVSATFIX = 'sensor_msgs/msg/NavSatFix'
IMU = 'sensor_msgs/msg/Imu'
CLOCK = 'rosgraph_msgs/msg/Clock'
POSE_TYPES = ('nav_msgs/msg/Odometry', 'geometry_msgs/msg/PoseStamped', NAVSATFIX)
TWIST_TYPES = ('geometry_msgs/msg/TwistStamped',)
# heading of a GNSS pose: an IMU's or a GNSS compass's orientation, or a plain number
HEADING_TYPES = (IMU, 'geometry_msgs/msg/QuaternionStamped', 'std_msgs/msg/Float64',
                 'std_msgs/msg/Float32')
HEADING_UNITS = {'rad': 1.0, 'deg': math.pi / 180.0}
# a number's convention: enu = yaw counter-clockwise from east (REP-103);
# north_cw = compass heading, clockwise from true north (NMEA HDT, a gyrocompass)
HEADING_CONVENTIONS = ('enu', 'north_cw')
STAMP_SOURCES = ('header', 'receive')  # header: the message's header.stamp (when it has one)
# frame_ids accepted per kind of frame (the last path element, so ship2/base_link is
# base_link): earth = ENU-aligned world frames (REP-105), body = frames fixed to the hull
# that share base_link's axes (FLU). Anything else is refused, never guessed.
EARTH_FRAMES = ('map', 'odom', 'world', 'earth', 'enu')
BODY_FRAMES = ('base_link', 'base_footprint', 'imu', 'imu_link', 'gps', 'gnss', 'gps_link',
               'gnss_link', 'navsat_link', 'antenna', 'gnss_antenna')
SCALAR_TYPES = ('std_msgs/msg/Float64', 'std_msgs/msg/Float32', 'sensor_msgs/msg/JointState')
WIND_TYPES = ('geometry_msgs/msg/Vector3Stamped',)
# true_enu: the air's velocity over ground in the map frame (ENU, m/s);
# apparent_flu: the air's velocity relative to the ship in base_link (FLU, m/s), as an
# anemometer on the ship measures it (converted to true wind with the recorded motion)
WIND_FRAMES = ('true_enu', 'apparent_flu')
# A recorded command's unit -> the factor to its channel's unit (core/channels.py), per channel
# unit; the first is the channel's own unit (the default). A channel of another unit is read in
# that unit only.
RECORDED_UNITS: dict[str, dict[str, float]] = {
    'rad': {'rad': 1.0, 'deg': math.pi / 180.0},
    'rev/s': {'rps': 1.0, 'rpm': 1.0 / 60.0, 'rad_s': 1.0 / (2.0 * math.pi)},
    'rev/min': {'rpm': 1.0, 'rps': 60.0, 'rad_s': 60.0 / (2.0 * math.pi)},
}
# a screw and rudder's channels (Trial.controls) and the tunnel thrusters' (Trial.thrusters),
# which the readers assemble apart; every other actuator's channels (a craft commanded per
# thruster, a water jet) go to Trial.inputs by name (per_channel_actuators)
SCREW_ROLES = ('rudder', 'rpm')
THRUSTER_ROLES = tuple(declared_inputs('tunnel_thrusters'))
FLAT_SECTIONS = ('odom', 'twist', 'heading', 'imu', 'gnss', 'wind', 'frames', 'time',
                 'resample', 'replay')
FLAT_STAMPED = ('odom', 'twist', 'heading', 'imu', 'wind')
CHANNEL_KEYS = ('topic', 'type', 'joint', 'unit', 'sign', 'stamp', 'offset_s')


def command_channels() -> tuple[str, ...]:
    """Return the channels a topic map has a section for: every channel but the environment."""
    return tuple(c for c in TABLE if c not in ENVIRONMENT)


def per_channel_actuators(recorded: Iterable[str]) -> dict[str, tuple[str, ...]]:
    """
    Return the actuators (name -> their input channels) a recording commanded channel by channel.

    Those whose inputs include a recorded channel other than a screw and rudder's and the tunnel
    thrusters' (a twin-azimuth tug's n_port ..., a plugin's). A recording of one of them needs
    every input without a default (core/channels.py); the others are read when recorded.
    """
    seen = set(recorded) - set(SCREW_ROLES) - set(THRUSTER_ROLES)
    out: dict[str, tuple[str, ...]] = {}
    for name in ACTUATORS:
        ins = declared_inputs(name)
        if seen & set(ins):
            out[name] = ins
    return out


def recorded_units(channel: str) -> dict[str, float]:
    """Return the units a channel may be recorded in, with the factor to the channel's unit."""
    unit = TABLE[channel].unit
    return RECORDED_UNITS.get(unit, {unit: 1.0})


@dataclass(frozen=True)
class ChannelTopic:
    """
    How one command channel is recorded: a scalar topic (or a JointState's joint).

    unit: one of :func:`recorded_units`; sign: +1, or -1 when the recording's sense is the
    channel's opposite; stamp: ``header`` or ``receive``; offset_s: added to the topic's times.
    """

    topic: str
    msgtype: str = 'std_msgs/msg/Float64'   # the section's key ``type``
    joint: str = ''
    unit: str = ''
    sign: float = 1.0
    stamp: str = 'header'
    offset_s: float = 0.0


def default_channels() -> dict[str, ChannelTopic]:
    """Each command channel's defaults: its declared topic, its own unit ('': never read)."""
    return {c: ChannelTopic(TABLE[c].topic, unit=next(iter(recorded_units(c))))
            for c in command_channels()}


MAX_MAP_BYTES = 1 << 20  # a topic map is a few hundred bytes


@dataclass(frozen=True)
class TopicMap:
    """
    Which topics a recording uses and how to read them (see config/topics.yaml).

    ``given`` holds the keys a user's map set: a topic not given may be found by message type
    when that is unambiguous (one NavSatFix, one Imu, ...); a given one never is.
    """

    odom_topic: str = '/odom'
    odom_type: str = 'nav_msgs/msg/Odometry'
    odom_stamp: str = 'header'
    odom_offset_s: float = 0.0     # added to this topic's times [s] (e.g. -18 for GPS time)
    twist_topic: str = ''
    twist_type: str = 'geometry_msgs/msg/TwistStamped'
    twist_stamp: str = 'header'
    twist_offset_s: float = 0.0
    heading_topic: str = ''        # '' = the imu topic's orientation
    heading_type: str = IMU
    heading_unit: str = 'rad'      # a Float64/Float32 heading only
    heading_convention: str = 'enu'
    heading_stamp: str = 'header'
    heading_offset_s: float = 0.0
    imu_topic: str = ''            # yaw rate (angular_velocity.z) and by default the heading
    imu_type: str = IMU
    imu_stamp: str = 'header'
    imu_offset_s: float = 0.0
    gnss_datum_lat_deg: float = math.nan  # NaN: the first fix is the datum
    gnss_datum_lon_deg: float = math.nan
    gnss_datum_alt_m: float = math.nan
    gnss_lever_x_m: float = 0.0    # GNSS antenna in base_link (FLU: forward, left, up) [m]
    gnss_lever_y_m: float = 0.0
    gnss_lever_z_m: float = 0.0
    wind_topic: str = '/wind'   # optional: used when the recording has it; '' = never
    wind_type: str = 'geometry_msgs/msg/Vector3Stamped'
    wind_frame: str = 'true_enu'
    wind_stamp: str = 'header'
    wind_offset_s: float = 0.0
    # the command channels' sections (rudder, rpm, thrusters, azimuths, ...): one per channel
    # of the channel table (core/channels.py, which the actuators extend), generated from it
    channels: Mapping[str, ChannelTopic] = field(default_factory=default_channels)
    frames_earth: tuple[str, ...] = EARTH_FRAMES
    frames_body: tuple[str, ...] = BODY_FRAMES
    # two streams whose header-vs-receive offsets differ by more than this are on two clocks
    # (GPS time is 18 s ahead of UTC): refused, never read silently shifted
    time_max_offset_s: float = 1.0
    # the rudder -> yaw acceleration cross-correlation peaking further off than this is
    # reported as a suspected command/state time offset
    time_max_lag_s: float = 8.0
    dt: float = 1.0
    max_gap_s: float = 5.0
    smooth_s: float = 10.0  # window of the local linear fit that derives velocities [s]
    # replay_node's outputs: the model's odometry never on the recording's odometry topic,
    # where inspect would read it as the measurement
    replay_model_odom_topic: str = 'model/odom'
    replay_recorded_odom_topic: str = 'recorded/odom'
    given: frozenset[str] = frozenset()

    @property
    def datum_given(self) -> bool:
        return math.isfinite(self.gnss_datum_lat_deg)

    @property
    def lever_arm_m(self) -> tuple[float, float]:
        return self.gnss_lever_x_m, self.gnss_lever_y_m

    @property
    def heading_to_rad(self) -> float:
        return HEADING_UNITS[self.heading_unit]

    def channel(self, name: str) -> ChannelTopic:
        """Return how command channel ``name`` is recorded (ConfigError naming the known)."""
        try:
            return self.channels[name]
        except KeyError:
            raise ConfigError(f'topic map: no channel {name!r}; the map has '
                              f'{", ".join(self.channels)}') from None

    def factor(self, name: str) -> float:
        """Return the factor from a recorded value of channel ``name`` to the channel's unit."""
        c = self.channel(name)
        return recorded_units(name)[c.unit] * c.sign

    def topic(self, role: str) -> str:
        """Return the topic of a role: a section (odom, imu, wind, ...) or a command channel."""
        return self.channels[role].topic if role in self.channels else \
            str(getattr(self, f'{role}_topic'))

    def stamp(self, role: str) -> str:
        """Return a role's time source (``header`` or ``receive``); roles without one: header."""
        return self.channels[role].stamp if role in self.channels else \
            str(getattr(self, f'{role}_stamp', 'header'))

    def offset_s(self, role: str) -> float:
        """Return the offset added to a role's times [s] (0 for roles without one)."""
        return self.channels[role].offset_s if role in self.channels else \
            float(getattr(self, f'{role}_offset_s', 0.0))


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
        # depth and alias-expansion limits; invalid YAML is a ConfigError naming the line
        doc = yaml_loads(path.read_bytes().decode('utf-8-sig'), f'topic map {path}')
    except UnicodeDecodeError as exc:
        raise ConfigError(f'topic map {path}: not UTF-8 text (byte {exc.start})') from None
    except OSError as exc:
        raise ConfigError(f'topic map {path}: {exc.strerror or exc}') from None
    return topic_map_from_dict({} if doc is None else doc, str(path))


def _typed(source: str, key: str, v: Any, default: Any) -> Any:
    """
    V as the type of the field's default.

    A string for topics, types, joints, units and frames, a list of strings for frame tables, a
    finite number for sign, dt and max_gap_s.
    """
    if isinstance(default, tuple):
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise ConfigError(f'{source}: {key} = {v!r} must be a list of frame_id strings')
        return tuple(x.strip('/').rsplit('/', 1)[-1] for x in v)
    if isinstance(default, str):
        if not isinstance(v, str):
            raise ConfigError(f'{source}: {key} = {v!r} must be a string')
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError(f'{source}: {key} = {v!r} must be a finite number')
    return float(v)


def _channel_section(source: str, name: str, block: Mapping[str, Any]) -> ChannelTopic:
    """Check a command channel's section (keys, types, unit, sign, stamp) and return it."""
    fields_ = ChannelTopic.__dataclass_fields__
    kw: dict[str, Any] = {}
    for k, v in block.items():
        if k not in CHANNEL_KEYS:
            raise ConfigError(f'{source}: unknown key {name}.{k}; known: {list(CHANNEL_KEYS)}')
        field_ = 'msgtype' if k == 'type' else str(k)
        kw[field_] = _typed(source, f'{name}.{k}', v, fields_[field_].default
                            if k != 'topic' else '')
    c = replace(default_channels()[name], **kw)
    if c.msgtype not in SCALAR_TYPES:
        raise ConfigError(f'{source}: {name}.type {c.msgtype!r} not one of {SCALAR_TYPES}')
    units = recorded_units(name)
    if c.unit not in units:
        raise ConfigError(f'{source}: {name}.unit {c.unit!r} not one of {list(units)} (the '
                          f'channel is in {TABLE[name].unit}, core/channels.py)')
    if c.sign not in (1, -1):
        raise ConfigError(f'{source}: {name}.sign must be 1 (the sense of the channel, '
                          'core/channels.py) or -1')
    if c.stamp not in STAMP_SOURCES:
        raise ConfigError(f'{source}: {name}.stamp {c.stamp!r} not one of '
                          f'{list(STAMP_SOURCES)}')
    if abs(c.offset_s) > 1e6:
        raise ConfigError(f'{source}: {name}.offset_s must be within +-1e6 s')
    return c


def topic_map_from_dict(doc: Mapping[str, Any], source: str = '<dict>') -> TopicMap:
    """Check a topic map's sections (a YAML document's mapping) and return the map."""
    if not isinstance(doc, Mapping):
        raise ConfigError(f'{source}: a topic map is a mapping of sections (odom, rudder, rpm, '
                          f'...), not {type(doc).__name__}')
    channel_names = command_channels()
    sections = FLAT_SECTIONS + channel_names
    unknown = sorted(str(k) for k in doc if k not in sections)
    if unknown:
        raise ConfigError(f'{source}: unknown section(s) {unknown}; known: {list(sections)}')
    kw: dict[str, Any] = {}
    given: set[str] = set()
    flat = {f.name: f for f in fields(TopicMap)}
    channels = default_channels()
    for sec in sections:
        block = doc.get(sec)
        if block is None:
            continue
        if not isinstance(block, Mapping):
            raise ConfigError(f'{source}: section {sec} must be a mapping of keys, not '
                              f'{type(block).__name__}')
        if sec in channel_names:
            channels[sec] = _channel_section(source, sec, block)
            given.update(f'{sec}_{k}' for k in block)
            continue
        for k, v in block.items():
            key = f'{sec}_{k}' if sec != 'resample' else str(k)
            if sec == 'resample' and key not in ('dt', 'max_gap_s', 'smooth_s') or \
                    key not in flat or key in ('given', 'channels'):
                raise ConfigError(f'{source}: unknown key {sec}.{k}')
            kw[key] = _typed(source, f'{sec}.{k}', v, flat[key].default)
    tm = TopicMap(**kw, channels=channels, given=frozenset(given | set(kw)))
    if tm.odom_type not in POSE_TYPES:
        raise ConfigError(f'{source}: odom.type {tm.odom_type!r} not one of {POSE_TYPES}')
    if tm.wind_type not in WIND_TYPES or tm.wind_frame not in WIND_FRAMES:
        raise ConfigError(f'{source}: wind.type must be one of {WIND_TYPES} and wind.frame one '
                          f'of {WIND_FRAMES}')
    for name, typ, ok in (('twist', tm.twist_type, TWIST_TYPES), ('imu', tm.imu_type, (IMU,)),
                          ('heading', tm.heading_type, HEADING_TYPES)):
        if typ not in ok:
            raise ConfigError(f'{source}: {name}.type {typ!r} not one of {ok}')
    if tm.heading_unit not in HEADING_UNITS or tm.heading_convention not in HEADING_CONVENTIONS:
        raise ConfigError(f'{source}: heading.unit must be one of {list(HEADING_UNITS)} and '
                          f'heading.convention one of {list(HEADING_CONVENTIONS)}')
    for role in FLAT_STAMPED:
        if getattr(tm, f'{role}_stamp') not in STAMP_SOURCES:
            raise ConfigError(f'{source}: {role}.stamp {getattr(tm, role + "_stamp")!r} not one '
                              f'of {list(STAMP_SOURCES)}')
        if abs(getattr(tm, f'{role}_offset_s')) > 1e6:
            raise ConfigError(f'{source}: {role}.offset_s must be within +-1e6 s')
    datum = [k for k in ('gnss_datum_lat_deg', 'gnss_datum_lon_deg', 'gnss_datum_alt_m')
             if k in tm.given]
    if datum and len(datum) != 3:
        raise ConfigError(f'{source}: gnss.datum_lat_deg, datum_lon_deg and datum_alt_m go '
                          'together (a datum needs all three; none = the first fix)')
    if datum:
        try:
            Datum(tm.gnss_datum_lat_deg, tm.gnss_datum_lon_deg, tm.gnss_datum_alt_m)
        except ConfigError as exc:
            raise ConfigError(f'{source}: gnss.{exc}') from None
    if max(abs(tm.gnss_lever_x_m), abs(tm.gnss_lever_y_m), abs(tm.gnss_lever_z_m)) > 1e3:
        raise ConfigError(f'{source}: gnss.lever_*_m must be within +-1000 m (the antenna '
                          'is on the ship)')
    overlap = set(tm.frames_earth) & set(tm.frames_body)
    if overlap:
        raise ConfigError(f'{source}: frames {sorted(overlap)} listed as both earth and body')
    if not 0 < tm.time_max_offset_s <= 1e6 or not 0 < tm.time_max_lag_s <= 1e6 or \
            not 0 < tm.smooth_s <= 3600:
        raise ConfigError(f'{source}: time.max_offset_s, time.max_lag_s must be in (0, 1e6] s '
                          f'and resample.smooth_s in (0, 3600] s')
    if not 1e-3 <= tm.dt <= 3600 or not 0 < tm.max_gap_s <= 1e6:
        raise ConfigError(f'{source}: resample.dt must be within [0.001, 3600] s and '
                          f'max_gap_s within (0, 1e6] s (got {tm.dt:g}, {tm.max_gap_s:g})')
    return tm
