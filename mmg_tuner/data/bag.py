"""rosbag2 (sqlite3 or MCAP storage) and bare MCAP files to and from :class:`Trial`.

Reading is two layers, as in rosbags: :func:`read_series` pulls the raw time series of the
mapped topics (stamps in ns, values as arrays) out of any container; :mod:`.assemble` turns
those into validated, framed, resampled trials. No ROS install is needed.
"""
from __future__ import annotations

import math
import os
import sqlite3
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmg_tuner.data.cdr import decode_columns
from mmg_tuner.data.files import _why, check_regular_file, display_text
from mmg_tuner.data.topics import TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import OutputError, TrialDataError

try:  # rosbags >= 0.10
    from rosbags.typesys import Stores, get_typestore
    TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
except ImportError:  # pragma: no cover
    TYPESTORE = None


@dataclass
class Series:
    """One topic's samples: stamps [ns] and values (n, k), plus what was done to them."""

    topic: str
    msgtype: str
    stamps_ns: np.ndarray
    values: np.ndarray
    receive_ns: np.ndarray
    notes: list[str] = field(default_factory=list)
    frame: str = ''  # for wind: 'true_enu' or 'apparent_flu' (empty: the topic map's)


@dataclass
class RawRecording:
    path: str
    series: dict[str, Series]
    topics_found: dict[str, tuple[str, int]]  # topic -> (type, message count)
    start_ns: int = 0
    end_ns: int = 0
    notes: list[str] = field(default_factory=list)  # about the container (e.g. recovered)


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _yaw_from_quat(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _decode(msg, msgtype: str, joint: str, role: str, topic: str, path: str
            ) -> tuple[int | None, tuple]:
    """(header stamp or None, values) of one message, by type."""
    if msgtype == 'nav_msgs/msg/Odometry':
        p, tw = msg.pose.pose, msg.twist.twist
        return _stamp_ns(msg.header), (p.position.x, p.position.y, _yaw_from_quat(p.orientation),
                                       tw.linear.x, tw.linear.y, tw.angular.z)
    if msgtype == 'geometry_msgs/msg/PoseStamped':
        p = msg.pose
        return _stamp_ns(msg.header), (p.position.x, p.position.y,
                                       _yaw_from_quat(p.orientation))
    if msgtype == 'geometry_msgs/msg/TwistStamped':
        tw = msg.twist
        return _stamp_ns(msg.header), (tw.linear.x, tw.linear.y, tw.angular.z)
    if msgtype == 'geometry_msgs/msg/Vector3Stamped':
        return _stamp_ns(msg.header), (msg.vector.x, msg.vector.y)
    if msgtype in ('std_msgs/msg/Float64', 'std_msgs/msg/Float32'):
        return None, (float(msg.data),)
    if msgtype == 'sensor_msgs/msg/JointState':
        names = list(msg.name)
        if joint not in names:
            raise TrialDataError(f'{path}: topic {topic}: joint {joint!r} not in {names}')
        i = names.index(joint)
        # the propeller's shaft speed is the joint velocity, the rudder's angle its position
        arr = msg.velocity if role == 'rpm' else msg.position
        if len(arr) <= i:
            raise TrialDataError(f'{path}: topic {topic}: joint {joint!r} has no '
                                 f'{"velocity" if role == "rpm" else "position"}')
        return _stamp_ns(msg.header), (float(arr[i]),)
    raise TrialDataError(f'{path}: topic {topic}: unsupported type {msgtype}')


def _decode_topic(raws: list[bytes], recv: list[int], msgtype: str, joint: str, role: str,
                  topic: str, path: str) -> tuple[list | np.ndarray, list | np.ndarray]:
    """(stamps [ns], values) of one topic: column-wise when the layout allows, else one by one.
    Header stamps are preferred; a zero stamp falls back to the receive time."""
    cols = decode_columns(raws, msgtype)
    if cols is not None:
        st, values = cols
        rec = np.asarray(recv, dtype=np.int64)
        stamps = rec if st is None else np.where(st == 0, rec, st)
        return stamps, values
    stamps, values = [], []
    for raw, ts in zip(raws, recv):
        try:
            msg = TYPESTORE.deserialize_cdr(raw, msgtype)
        except READER_ERRORS as exc:  # corrupt CDR
            raise TrialDataError(f'{path}: topic {topic} at t = {ts * 1e-9:.3f} s: cannot '
                                 f'decode message ({type(exc).__name__})') from None
        st, v = _decode(msg, msgtype, joint, role, topic, path)
        stamps.append(ts if st is None or st == 0 else st)
        values.append(v)
    return stamps, values


def _roles(tm: TopicMap) -> dict[str, tuple[str, str, str]]:
    """role (odom, twist, rudder, rpm, wind) -> (topic, expected type, joint). One topic may serve
    several roles (a JointState carrying rudder and propeller)."""
    roles = {'odom': (tm.odom_topic, tm.odom_type, ''),
             'rudder': (tm.rudder_topic, tm.rudder_type, tm.rudder_joint),
             'rpm': (tm.rpm_topic, tm.rpm_type, tm.rpm_joint)}
    if tm.odom_type == 'geometry_msgs/msg/PoseStamped' and tm.twist_topic:
        roles['twist'] = (tm.twist_topic, tm.twist_type, '')
    if tm.wind_topic:
        roles['wind'] = (tm.wind_topic, tm.wind_type, '')
    types: dict[str, str] = {}
    for topic, typ, _ in roles.values():
        if types.setdefault(topic, typ) != typ:
            raise TrialDataError(f'topic map: {topic} is mapped with two types '
                                 f'({types[topic]}, {typ})')
    return roles


def _reader_errors() -> tuple[type[BaseException], ...]:
    """What the readers raise on a corrupt, truncated or unreadable file -- found by fuzzing
    real bags (test_data_io.py flips and cuts bytes) -- so that only those become
    TrialDataError and a bug of ours still surfaces as itself."""
    from mcap.exceptions import McapError
    from rosbags.rosbag2.errors import ReaderError
    from rosbags.serde import SerdeError
    errs: list[type[BaseException]] = [
        ReaderError, McapError, SerdeError, sqlite3.Error, struct.error, OSError, EOFError,
        UnicodeDecodeError,   # corrupt strings (topic names, YAML, CDR strings)
        OverflowError, MemoryError,  # corrupt length fields: the readers try to allocate them
        KeyError, IndexError,  # corrupt ids: a channel or schema that is not there
        RuntimeError]         # lz4.frame's decompression error
    try:
        import apsw  # rosbags' sqlite3 driver
        errs.append(apsw.Error)
    except ImportError:  # pragma: no cover
        pass
    for mod in ('backports.zstd', 'compression.zstd', 'zstandard'):
        try:
            errs.append(__import__(mod, fromlist=['ZstdError']).ZstdError)
        except (ImportError, AttributeError):
            pass
    return tuple(errs)


READER_ERRORS = _reader_errors()
MAX_METADATA_BYTES = 64 << 20  # a rosbag2 metadata.yaml is kilobytes; more is not one


def _check_bag_files(bag: Path) -> list[Path]:
    """The storage files of a rosbag2 folder, every file checked to be regular."""
    check_regular_file(bag / 'metadata.yaml', 'rosbag2 metadata.yaml', MAX_METADATA_BYTES)
    files = sorted(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3', '.zstd'))
    for f in files:
        check_regular_file(f, 'rosbag2 storage file')
    return files


def _iter_rosbag2(path: Path):
    """Items of a rosbag2 folder; one whose MCAP storage rosbags cannot open (a recorder
    killed before writing the footer) is recovered by a streaming read of its .mcap files."""
    from rosbags.rosbag2 import Reader
    files = _check_bag_files(path)
    started = False
    try:
        with Reader(path) as reader:
            conns = list(reader.connections)
            items = [(c.topic, c.msgtype, c.msgcount) for c in conns]
            started = True
            yield 'connections', items
            yield from ((c.topic, c.msgtype, ts, raw) for c, ts, raw in reader.messages())
    except READER_ERRORS as exc:
        mcaps = [f for f in files if f.suffix == '.mcap']
        if started or not mcaps:
            raise TrialDataError(f'{path}: cannot read rosbag2 ({type(exc).__name__}: '
                                 f'{exc})') from None
        yield 'note', (f'{path}: rosbags cannot open it ({type(exc).__name__}: {exc}); read '
                       'its MCAP file(s) record by record instead')
        for f in mcaps:
            yield from _iter_mcap_stream(f)


def _iter_bare_mcap(path: Path):
    """rosbags reads a bare ROS 2 MCAP fastest; other MCAP files (another profile, a missing
    summary or footer, corruption) are read record by record with the mcap library."""
    from rosbags.rosbag2 import Reader
    try:
        reader = Reader(path)
        reader.open()
    except READER_ERRORS:
        yield from _iter_mcap_stream(path)
        return
    try:
        yield 'connections', [(c.topic, c.msgtype, c.msgcount) for c in reader.connections]
        yield from ((c.topic, c.msgtype, ts, raw) for c, ts, raw in reader.messages())
    except READER_ERRORS as exc:
        raise TrialDataError(f'{path}: cannot read MCAP ({type(exc).__name__}: {exc})') \
            from None
    finally:
        reader.close()


def _iter_mcap_stream(path: Path):
    """Every intact message of an MCAP file, read front to back without its summary: a file
    cut short (a recorder killed before writing the footer) or corrupt part-way gives the
    messages before the break, and a note saying how many and where it broke."""
    from mcap.records import Channel, Footer, Message, Schema
    from mcap.stream_reader import StreamReader
    size = check_regular_file(path, 'MCAP file')
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    counts: dict[int, int] = {}
    n = orphans = 0
    first_ns = last_ns = None
    complete = False
    problem = None
    with open(path, 'rb') as f:
        try:
            reader = StreamReader(f, skip_magic=False, record_size_limit=max(size, 1 << 16))
            for rec in reader.records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    channels[rec.id] = (rec.topic, schemas.get(rec.schema_id, ''))
                elif isinstance(rec, Message):
                    ch = channels.get(rec.channel_id)
                    if ch is None:
                        orphans += 1
                        continue
                    counts[rec.channel_id] = counts.get(rec.channel_id, 0) + 1
                    n += 1
                    first_ns = rec.log_time if first_ns is None else first_ns
                    last_ns = rec.log_time
                    yield ch[0], ch[1], rec.log_time, rec.data
                elif isinstance(rec, Footer):
                    complete = True
        except READER_ERRORS as exc:
            problem = (f'{type(exc).__name__}{": " + str(exc) if str(exc) else ""} near byte '
                       f'{f.tell()} of {size}')
    if n == 0:
        raise TrialDataError(f'{path}: cannot read MCAP: no intact message'
                             f'{" (" + problem + ")" if problem else ""}')
    yield 'connections', [(channels[c][0], channels[c][1], k) for c, k in counts.items()]
    if problem or not complete:
        ends = problem is None or problem.startswith('EndOfFile')
        why = ('the file ends before its footer (a recorder stopped without closing it?)'
               if ends else f'the file is corrupt ({problem})')
        yield 'note', (f'{display_text(str(path))}: {why}; recovered the {n} intact '
                       f'message(s) before the break, up to {(last_ns - first_ns) * 1e-9:.1f} s '
                       'after the first; anything after it is lost'
                       + (f'; {orphans} message(s) of unknown channels skipped' if orphans
                          else ''))


def read_series(path: str | Path, tm: TopicMap) -> RawRecording:
    """Raw series of the mapped topics from a rosbag2 directory or a bare .mcap file."""
    path = Path(path)
    if path.is_dir() or path.name == 'metadata.yaml':
        bag = path if path.is_dir() else path.parent
        if not (bag / 'metadata.yaml').is_file():
            raise TrialDataError(f'{bag}: not a rosbag2 directory (no metadata.yaml)')
        it = _iter_rosbag2(bag)
    elif path.suffix == '.mcap':
        check_regular_file(path, 'MCAP file')
        it = _iter_bare_mcap(path)
    else:
        raise TrialDataError(f'{path}: not a rosbag2 directory or .mcap file')
    roles = _roles(tm)
    types = {topic: typ for topic, typ, _ in roles.values()}
    recv: dict[str, list] = {t: [] for t in types}
    raws: dict[str, list] = {t: [] for t in types}
    found: dict[str, tuple[str, int]] = {}
    first = last = None
    notes: list[str] = []
    for item in it:
        if item[0] == 'note':
            notes.append(item[1])
            continue
        if item[0] == 'connections':
            for topic, msgtype, count in item[1] or []:
                found[topic] = (msgtype, int(count))
                if topic in types and msgtype != types[topic]:
                    raise TrialDataError(f'{path}: topic {topic} has type {msgtype}, the topic '
                                         f'map expects {types[topic]}')
            continue
        topic, msgtype, ts, raw = item
        first = ts if first is None else min(first, ts)
        last = ts if last is None else max(last, ts)
        if topic not in types:
            continue
        if msgtype != types[topic]:
            raise TrialDataError(f'{path}: topic {topic} has type {msgtype}, the topic map '
                                 f'expects {types[topic]}')
        recv[topic].append(ts)
        raws[topic].append(bytes(raw))
    series = {}
    for role, (topic, msgtype, joint) in roles.items():
        if not raws[topic]:
            continue
        try:
            stamps, values = _decode_topic(raws[topic], recv[topic], msgtype, joint, role,
                                           topic, str(path))
            series[role] = Series(topic, msgtype, np.asarray(stamps, dtype=np.int64),
                                  np.asarray(values, dtype=float),
                                  np.asarray(recv[topic], dtype=np.int64))
        except (OverflowError, ValueError) as exc:
            raise TrialDataError(f'{path}: topic {topic}: corrupt stamps or values '
                                 f'({exc})') from None
    for topic in found:
        if topic in raws and not raws[topic]:
            found[topic] = (found[topic][0], 0)
    return RawRecording(str(path), series, found, first or 0, last or 0, notes)


def write_trial_bag(trial: Trial, path: str | Path, storage: str = 'mcap',
                    tm: TopicMap | None = None, start_ns: int = 1_700_000_000_000_000_000
                    ) -> None:
    """Write a trial as a rosbag2 (storage 'mcap' or 'sqlite3') with the default topics:
    Odometry in map/base_link (REP-103/105) and Float64 commands. The trial's own samples are
    written; each message is stamped at its sample time (ns since start_ns). A trial with
    measured wind also gets the wind topic (Vector3Stamped, true wind in ENU)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.errors import WriterError

    tm = tm or TopicMap()
    path = Path(path)
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    ts = TYPESTORE
    Odometry = ts.types['nav_msgs/msg/Odometry']
    Float64 = ts.types['std_msgs/msg/Float64']
    try:
        with Writer(path, version=9, storage_plugin=plugin) as w:
            c_odom = w.add_connection(tm.odom_topic, Odometry.__msgtype__, typestore=ts)
            c_rud = w.add_connection(tm.rudder_topic, Float64.__msgtype__, typestore=ts)
            c_rpm = w.add_connection(tm.rpm_topic, Float64.__msgtype__, typestore=ts)
            V3S = ts.types['geometry_msgs/msg/Vector3Stamped']
            c_wind = None
            if trial.wind is not None:
                c_wind = w.add_connection(tm.wind_topic or '/wind', V3S.__msgtype__,
                                          typestore=ts)
            for k in range(len(trial)):
                stamp = start_ns + int(round(trial.t[k] * 1e9))
                w.write(c_odom, stamp, ts.serialize_cdr(odometry_msg(trial.states[k], stamp),
                                                        Odometry.__msgtype__))
                w.write(c_rud, stamp, ts.serialize_cdr(
                    Float64(data=float(trial.controls[k, 1] / tm.rudder_to_rad)),
                    Float64.__msgtype__))
                w.write(c_rpm, stamp, ts.serialize_cdr(
                    Float64(data=float(trial.controls[k, 0] / tm.rpm_factor)),
                    Float64.__msgtype__))
                if c_wind is not None:  # true wind, ENU: x east, y north
                    w.write(c_wind, stamp, ts.serialize_cdr(V3S(
                        header=_header(stamp, 'map'),
                        vector=ts.types['geometry_msgs/msg/Vector3'](
                            x=float(trial.wind[k, 1]), y=float(trial.wind[k, 0]), z=0.0)),
                        V3S.__msgtype__))
    except (WriterError, OSError) as exc:
        raise OutputError(f'{path}: cannot write rosbag2 ({_why(exc)})') from None


def _header(stamp_ns: int, frame_id: str):
    ts = TYPESTORE.types
    return ts['std_msgs/msg/Header'](
        stamp=ts['builtin_interfaces/msg/Time'](sec=stamp_ns // 1_000_000_000,
                                                nanosec=stamp_ns % 1_000_000_000),
        frame_id=frame_id)


def odometry_msg(state: np.ndarray, stamp_ns: int):
    """nav_msgs/Odometry (rosbags type) of a model-frame state: ENU pose, FLU twist."""
    ts = TYPESTORE.types
    x, y, psi, u, v, r = (float(s) for s in state)
    yaw = math.pi / 2 - psi
    Header = ts['std_msgs/msg/Header']
    Time = ts['builtin_interfaces/msg/Time']
    P = ts['geometry_msgs/msg/Point']
    Q = ts['geometry_msgs/msg/Quaternion']
    V = ts['geometry_msgs/msg/Vector3']
    cov = np.zeros(36)
    return ts['nav_msgs/msg/Odometry'](
        header=Header(stamp=Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000),
                      frame_id='map'),
        child_frame_id='base_link',
        pose=ts['geometry_msgs/msg/PoseWithCovariance'](
            pose=ts['geometry_msgs/msg/Pose'](position=P(x=y, y=x, z=0.0),
                                              orientation=Q(x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                            w=math.cos(yaw / 2))),
            covariance=cov),
        twist=ts['geometry_msgs/msg/TwistWithCovariance'](
            twist=ts['geometry_msgs/msg/Twist'](linear=V(x=u, y=-v, z=0.0),
                                                angular=V(x=0.0, y=0.0, z=-r)),
            covariance=cov))


def write_replay_bag(trial: Trial, simulated: np.ndarray, path: str | Path,
                     storage: str = 'mcap') -> None:
    """Recorded odometry (/recorded/odom), simulated odometry (/odom) and the recorded
    commands, stamped in trial time, as a rosbag2 (MCAP: Foxglove opens the .mcap inside)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.errors import WriterError

    ts = TYPESTORE
    Odometry = ts.types['nav_msgs/msg/Odometry'].__msgtype__
    Float64 = ts.types['std_msgs/msg/Float64']
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    path = Path(path)
    if os.path.lexists(path):  # never replace what is there (a recording, a user's folder)
        raise OutputError(f'{path} exists; nothing is overwritten: choose a new path')
    try:
        with Writer(path, version=9, storage_plugin=plugin) as w:
            c_sim = w.add_connection('/odom', Odometry, typestore=ts)
            c_rec = w.add_connection('/recorded/odom', Odometry, typestore=ts)
            c_rud = w.add_connection('/rudder_angle', Float64.__msgtype__, typestore=ts)
            c_rpm = w.add_connection('/propeller_rpm', Float64.__msgtype__, typestore=ts)
            for k in range(len(trial)):
                stamp = int(round((trial.t[k] - trial.t[0]) * 1e9)) + 1
                w.write(c_rec, stamp, ts.serialize_cdr(odometry_msg(trial.states[k], stamp),
                                                       Odometry))
                if np.all(np.isfinite(simulated[k])):
                    w.write(c_sim, stamp, ts.serialize_cdr(odometry_msg(simulated[k], stamp),
                                                           Odometry))
                w.write(c_rud, stamp, ts.serialize_cdr(Float64(data=float(trial.controls[k, 1])),
                                                       Float64.__msgtype__))
                w.write(c_rpm, stamp, ts.serialize_cdr(Float64(data=float(trial.controls[k, 0])),
                                                       Float64.__msgtype__))
    except (WriterError, OSError) as exc:
        raise OutputError(f'{path}: cannot write rosbag2 ({_why(exc)})') from None
