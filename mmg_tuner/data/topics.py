"""Topic maps: which topics, message types, units and signs a recording uses (YAML)."""
from __future__ import annotations

from dataclasses import dataclass
import math
import os
from pathlib import Path
import stat
from typing import Any, Mapping

from mmg_tuner._limits import yaml_loads
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
RUDDER_UNITS = {'rad': 1.0, 'deg': math.pi / 180.0}
RPM_UNITS = {'rpm': 1.0, 'rps': 60.0, 'rad_s': 60.0 / (2.0 * math.pi)}
WIND_TYPES = ('geometry_msgs/msg/Vector3Stamped',)
# true_enu: the air's velocity over ground in the map frame (ENU, m/s);
# apparent_flu: the air's velocity relative to the ship in base_link (FLU, m/s), as an
# anemometer on the ship measures it (converted to true wind with the recorded motion)
WIND_FRAMES = ('true_enu', 'apparent_flu')
# thruster revolutions -> rev/s (the input channels' unit, core/channels.py)
THRUSTER_UNITS = {'rps': 1.0, 'rpm': 1.0 / 60.0, 'rad_s': 1.0 / (2.0 * math.pi)}
THRUSTER_ROLES = ('bow_thruster', 'stern_thruster')
# a craft commanded per thruster (twin azimuths, core/actuators/twin_azimuth.py): its channels,
# one Float64 topic each, named as VRX names its thruster topics (osrf/vrx,
# vrx_urdf/wamv_gazebo/urdf/thruster_layouts/wamv_gazebo_thruster_config.xacro:
# thrusters/<name>/thrust, thrusters/<name>/pos); the first four are what such a recording
# needs, the commanded angles are read only when mapped
AZIMUTH_REQUIRED = ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd')
AZIMUTH_ROLES = AZIMUTH_REQUIRED + ('azimuth_cmd_port', 'azimuth_cmd_stbd')
ANGLE_UNITS = {'rad': 1.0, 'deg': math.pi / 180.0}
SECTIONS = ('odom', 'twist', 'heading', 'imu', 'gnss', 'rudder', 'rpm', 'wind') + \
    THRUSTER_ROLES + AZIMUTH_ROLES + ('frames', 'time', 'resample', 'replay')
STAMPED_ROLES = ('odom', 'twist', 'heading', 'imu', 'rudder', 'rpm', 'wind') + \
    THRUSTER_ROLES + AZIMUTH_ROLES
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
    rudder_topic: str = '/rudder_angle'
    rudder_type: str = 'std_msgs/msg/Float64'
    rudder_joint: str = ''
    rudder_unit: str = 'rad'
    rudder_sign: float = 1.0
    rudder_stamp: str = 'header'
    rudder_offset_s: float = 0.0
    rpm_topic: str = '/propeller_rpm'
    rpm_type: str = 'std_msgs/msg/Float64'
    rpm_joint: str = ''
    rpm_unit: str = 'rpm'
    rpm_stamp: str = 'header'
    rpm_offset_s: float = 0.0
    wind_topic: str = '/wind'   # optional: used when the recording has it; '' = never
    wind_type: str = 'geometry_msgs/msg/Vector3Stamped'
    wind_frame: str = 'true_enu'
    wind_stamp: str = 'header'
    wind_offset_s: float = 0.0
    # optional thrusters (rev/s after unit and sign; + pushes the ship to starboard, as
    # core/channels.py): read when the recording has them; '' = never
    bow_thruster_topic: str = '/bow_thruster'
    bow_thruster_type: str = 'std_msgs/msg/Float64'
    bow_thruster_joint: str = ''
    bow_thruster_unit: str = 'rps'
    bow_thruster_sign: float = 1.0
    bow_thruster_stamp: str = 'header'
    bow_thruster_offset_s: float = 0.0
    stern_thruster_topic: str = '/stern_thruster'
    stern_thruster_type: str = 'std_msgs/msg/Float64'
    stern_thruster_joint: str = ''
    stern_thruster_unit: str = 'rps'
    stern_thruster_sign: float = 1.0
    stern_thruster_stamp: str = 'header'
    stern_thruster_offset_s: float = 0.0
    # a craft commanded per thruster (rev/s, + ahead; rad, 0 = thrust ahead, + = thrust
    # toward starboard, after unit and sign): read when the recording has them
    n_port_topic: str = '/thrusters/port/thrust'
    n_port_type: str = 'std_msgs/msg/Float64'
    n_port_joint: str = ''
    n_port_unit: str = 'rps'
    n_port_sign: float = 1.0
    n_port_stamp: str = 'header'
    n_port_offset_s: float = 0.0
    n_stbd_topic: str = '/thrusters/stbd/thrust'
    n_stbd_type: str = 'std_msgs/msg/Float64'
    n_stbd_joint: str = ''
    n_stbd_unit: str = 'rps'
    n_stbd_sign: float = 1.0
    n_stbd_stamp: str = 'header'
    n_stbd_offset_s: float = 0.0
    azimuth_port_topic: str = '/thrusters/port/pos'
    azimuth_port_type: str = 'std_msgs/msg/Float64'
    azimuth_port_joint: str = ''
    azimuth_port_unit: str = 'rad'
    azimuth_port_sign: float = 1.0
    azimuth_port_stamp: str = 'header'
    azimuth_port_offset_s: float = 0.0
    azimuth_stbd_topic: str = '/thrusters/stbd/pos'
    azimuth_stbd_type: str = 'std_msgs/msg/Float64'
    azimuth_stbd_joint: str = ''
    azimuth_stbd_unit: str = 'rad'
    azimuth_stbd_sign: float = 1.0
    azimuth_stbd_stamp: str = 'header'
    azimuth_stbd_offset_s: float = 0.0
    azimuth_cmd_port_topic: str = ''
    azimuth_cmd_port_type: str = 'std_msgs/msg/Float64'
    azimuth_cmd_port_joint: str = ''
    azimuth_cmd_port_unit: str = 'rad'
    azimuth_cmd_port_sign: float = 1.0
    azimuth_cmd_port_stamp: str = 'header'
    azimuth_cmd_port_offset_s: float = 0.0
    azimuth_cmd_stbd_topic: str = ''
    azimuth_cmd_stbd_type: str = 'std_msgs/msg/Float64'
    azimuth_cmd_stbd_joint: str = ''
    azimuth_cmd_stbd_unit: str = 'rad'
    azimuth_cmd_stbd_sign: float = 1.0
    azimuth_cmd_stbd_stamp: str = 'header'
    azimuth_cmd_stbd_offset_s: float = 0.0
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
    given: frozenset = frozenset()

    @property
    def datum_given(self) -> bool:
        return math.isfinite(self.gnss_datum_lat_deg)

    @property
    def lever_arm_m(self) -> tuple[float, float]:
        return self.gnss_lever_x_m, self.gnss_lever_y_m

    @property
    def heading_to_rad(self) -> float:
        return HEADING_UNITS[self.heading_unit]

    @property
    def rudder_to_rad(self) -> float:
        return RUDDER_UNITS[self.rudder_unit] * self.rudder_sign

    @property
    def rpm_factor(self) -> float:
        return RPM_UNITS[self.rpm_unit]

    def thruster_factor(self, role: str) -> float:
        """Return the factor from a recorded value to rev/s (+ to starboard) of a thruster."""
        return THRUSTER_UNITS[getattr(self, f'{role}_unit')] * getattr(self, f'{role}_sign')

    def channel_factor(self, role: str) -> float:
        """Return the factor from a recorded value to its channel's unit (AZIMUTH_ROLES)."""
        units = THRUSTER_UNITS if role.startswith('n_') else ANGLE_UNITS
        return units[getattr(self, f'{role}_unit')] * getattr(self, f'{role}_sign')


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
            if sec == 'resample' and key not in ('dt', 'max_gap_s', 'smooth_s') or \
                    key not in fields or key == 'given':
                raise ConfigError(f'{source}: unknown key {sec}.{k}')
            kw[key] = _typed(source, f'{sec}.{k}', v, fields[key].default)
    tm = TopicMap(**kw, given=frozenset(kw))
    if tm.odom_type not in POSE_TYPES:
        raise ConfigError(f'{source}: odom.type {tm.odom_type!r} not one of {POSE_TYPES}')
    for name, typ in (('rudder', tm.rudder_type), ('rpm', tm.rpm_type),
                      ('bow_thruster', tm.bow_thruster_type),
                      ('stern_thruster', tm.stern_thruster_type),
                      *((r, getattr(tm, f'{r}_type')) for r in AZIMUTH_ROLES)):
        if typ not in SCALAR_TYPES:
            raise ConfigError(f'{source}: {name}.type {typ!r} not one of {SCALAR_TYPES}')
    if tm.rudder_unit not in RUDDER_UNITS or tm.rpm_unit not in RPM_UNITS:
        raise ConfigError(f'{source}: units must be rudder {list(RUDDER_UNITS)}, '
                          f'rpm {list(RPM_UNITS)}')
    for role in THRUSTER_ROLES:
        if getattr(tm, f'{role}_unit') not in THRUSTER_UNITS:
            raise ConfigError(f'{source}: {role}.unit {getattr(tm, role + "_unit")!r} not one '
                              f'of {list(THRUSTER_UNITS)}')
        if getattr(tm, f'{role}_sign') not in (1, -1):
            raise ConfigError(f'{source}: {role}.sign must be 1 (+ pushes the ship to '
                              'starboard) or -1')
    for role in AZIMUTH_ROLES:
        units = THRUSTER_UNITS if role.startswith('n_') else ANGLE_UNITS
        if getattr(tm, f'{role}_unit') not in units:
            raise ConfigError(f'{source}: {role}.unit {getattr(tm, role + "_unit")!r} not one '
                              f'of {list(units)}')
        if getattr(tm, f'{role}_sign') not in (1, -1):
            raise ConfigError(f'{source}: {role}.sign must be 1 (the sense of the channel, '
                              'core/channels.py) or -1')
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
    for role in STAMPED_ROLES:
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
    if tm.rudder_sign not in (1, -1):
        raise ConfigError(f'{source}: rudder.sign must be 1 or -1')
    if not 1e-3 <= tm.dt <= 3600 or not 0 < tm.max_gap_s <= 1e6:
        raise ConfigError(f'{source}: resample.dt must be within [0.001, 3600] s and '
                          f'max_gap_s within (0, 1e6] s (got {tm.dt:g}, {tm.max_gap_s:g})')
    return tm
