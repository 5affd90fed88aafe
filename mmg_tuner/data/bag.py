"""
rosbag2 (sqlite3 or MCAP storage) and bare MCAP files to and from :class:`Trial`.

Reading is two layers, as in rosbags: :func:`read_series` pulls the raw time series of the
mapped topics (stamps in ns, values as arrays) out of any container; :mod:`.assemble` turns
those into validated, framed, resampled trials. No ROS install is needed.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
import os
from pathlib import Path
import sqlite3
import struct
from typing import Any, Callable, cast, Iterator, TYPE_CHECKING

from mmg_tuner.core import frames
from mmg_tuner.core.channels import TABLE
from mmg_tuner.data.cdr import decode_columns
from mmg_tuner.data.files import _why, check_regular_file, display_text
from mmg_tuner.data.topics import (CLOCK, IMU, NAVSATFIX, per_channel_actuators,
                                   POSE_TYPES, THRUSTER_ROLES, TopicMap)
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import OutputError, TrialDataError
import numpy as np

if TYPE_CHECKING:   # annotations only: geodesy is imported where a sensor bag is written
    from mmg_tuner.core.geodesy import Datum
    from rosbags.interfaces import Connection
    from rosbags.typesys.store import MsgType

try:  # rosbags >= 0.10
    from rosbags.typesys import Stores, get_typestore
    TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
except ImportError:  # pragma: no cover
    # an older rosbags (requirements.txt asks for >= 0.10): reading or writing a bag then fails
    TYPESTORE = None  # type: ignore[assignment]

# an item of a container's reader: ('connections', [(topic, type, message count)]),
# ('note', text) or a message (topic, type, receive time [ns], raw CDR bytes)
_Item = tuple[Any, ...]


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
    # frame_ids the messages carried: {'frame_id': {id: count}, 'child_frame_id': {...}};
    # empty when not known (a CSV, a series built in code): then nothing is checked
    frame_ids: dict[str, dict[str, int]] = field(default_factory=dict)
    base: str = ''  # time base: 'header' (header.stamp) or 'receive'; '' = not known
    lag_s: float | None = None  # median receive time - header stamp [s] (header base only)


@dataclass
class RawRecording:
    path: str
    series: dict[str, Series]
    topics_found: dict[str, tuple[str, int]]  # topic -> (type, message count)
    start_ns: int = 0
    end_ns: int = 0
    notes: list[str] = field(default_factory=list)  # about the container (e.g. recovered)
    topic_map: TopicMap | None = None  # the map as resolved against this recording
    reading: list[str] = field(default_factory=list)  # how it was read (for inspect)


NS = 1_000_000_000
MCAP_MAGIC = b'\x89MCAP0\r\n'


class IncompleteMcapError(TrialDataError):
    """
    An MCAP file holding at most its 8-byte magic (a recorder stopped before writing anything).

    A folder of recordings skips such a file with a warning (:func:`.load.load_trials`).
    """


def check_mcap_size(path: Path, size: int) -> None:
    """
    Refuse an MCAP file of ``size`` bytes that cannot hold a record.

    rosbags fails on one holding just the magic with a bare TypeError; anything longer is
    handled (and fuzzed) by the readers.
    """
    if size <= len(MCAP_MAGIC):
        raise IncompleteMcapError(
            f'{display_text(str(path))}: not a complete MCAP file: {size} bytes, at most the '
            f'{len(MCAP_MAGIC)}-byte magic that starts one (a recorder stopped before writing '
            'anything?); record it again or remove it')


# a rosbags message (deserialize_cdr's object) is a dataclass generated per type: Any here
def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * NS + int(header.stamp.nanosec)


def _yaw_from_quat(q: Any) -> float:
    return float(frames.yaw_from_quaternion(q.x, q.y, q.z, q.w))


def _quat_ok(q: Any) -> float:
    """1.0 for a unit quaternion (within 10 %), 0.0 for none (all zeros) or garbage."""
    n = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w
    return 1.0 if 0.81 <= n <= 1.21 else 0.0


# a JointState gives a shaft's speed (a channel in these units) as its velocity, the rest as its
# position
SPEED_UNITS = ('rev/min', 'rev/s')


def _decode(msg: Any, msgtype: str, joint: str, role: str, topic: str, path: str
            ) -> tuple[int | None, tuple[float, ...]]:
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
    if msgtype == NAVSATFIX:  # WGS84 deg, ellipsoidal height m; status -1 = no fix
        return _stamp_ns(msg.header), (msg.latitude, msg.longitude, msg.altitude,
                                       float(msg.status.status))
    if msgtype == IMU:  # ENU yaw, angular_velocity.z (FLU, counter-clockwise), orientation valid
        ok = _quat_ok(msg.orientation) if msg.orientation_covariance[0] != -1.0 else 0.0
        # (an invalid orientation reads as yaw 0 flagged 0: its yaw rate stays usable)
        return _stamp_ns(msg.header), (_yaw_from_quat(msg.orientation) if ok else 0.0,
                                       msg.angular_velocity.z, ok)
    if msgtype == 'geometry_msgs/msg/QuaternionStamped':
        ok = _quat_ok(msg.quaternion)
        return _stamp_ns(msg.header), (_yaw_from_quat(msg.quaternion) if ok else 0.0, ok)
    if msgtype == 'geometry_msgs/msg/Vector3Stamped':
        return _stamp_ns(msg.header), (msg.vector.x, msg.vector.y)
    if msgtype in ('std_msgs/msg/Float64', 'std_msgs/msg/Float32'):
        return None, (float(msg.data),)
    if msgtype == CLOCK:
        return None, (float(int(msg.clock.sec) * NS + int(msg.clock.nanosec)),)
    if msgtype == 'sensor_msgs/msg/JointState':
        names = list(msg.name)
        if joint not in names:
            raise TrialDataError(f'{path}: topic {topic}: joint {joint!r} not in {names}')
        i = names.index(joint)
        # a shaft's speed (propeller, thruster) is the joint velocity, the rudder's angle
        # its position
        speed = role in TABLE and TABLE[role].unit in SPEED_UNITS
        arr = msg.velocity if speed else msg.position
        if len(arr) <= i:
            raise TrialDataError(f'{path}: topic {topic}: joint {joint!r} has no '
                                 f'{"velocity" if speed else "position"}')
        return _stamp_ns(msg.header), (float(arr[i]),)
    raise TrialDataError(f'{path}: topic {topic}: unsupported type {msgtype}')


def _decode_topic(raws: list[bytes], recv: list[int], msgtype: str, joint: str, role: str,
                  topic: str, path: str
                  ) -> tuple[np.ndarray | None, np.ndarray | list[tuple[float, ...]],
                             dict[str, dict[str, int]]]:
    """
    Decode one topic's messages: header stamps, values and frame_ids.

    Returns (header stamps [ns], or None for a type without a header; values; frame_id counts),
    decoded column-wise when the message layout allows, else one message at a time.
    """
    cols = decode_columns(raws, msgtype)
    if cols is not None:
        hdr, vals, fids = cols
        return hdr, vals, {k: {v: len(raws)} for k, v in fids.items()}
    stamps: list[int | None] = []
    values: list[tuple[float, ...]] = []
    frames: dict[str, dict[str, int]] = {}
    for raw, ts in zip(raws, recv):
        try:
            msg = TYPESTORE.deserialize_cdr(raw, msgtype)
        except READER_ERRORS as exc:  # corrupt CDR
            raise TrialDataError(f'{path}: topic {topic} at t = {ts * 1e-9:.3f} s: cannot '
                                 f'decode message ({type(exc).__name__})') from None
        st, v = _decode(msg, msgtype, joint, role, topic, path)
        stamps.append(st)
        values.append(v)
        for key, obj in (('frame_id', getattr(msg, 'header', None)), ('child_frame_id', msg)):
            fid = getattr(obj, key if key == 'child_frame_id' else 'frame_id', None)
            if isinstance(fid, str):
                d = frames.setdefault(key, {})
                d[fid] = d.get(fid, 0) + 1
    return (None if stamps and stamps[0] is None else np.asarray(stamps, dtype=np.int64),
            values, frames)


def _roles(tm: TopicMap) -> dict[str, tuple[str, str, str]]:
    """
    Map each role to (topic, expected type, joint).

    role (odom, twist, heading, imu, rudder, rpm, wind, bow_thruster, stern_thruster) -> (topic,
    expected type, joint). One topic may serve several roles (a JointState carrying rudder and
    propeller, an Imu giving heading and yaw rate).
    """
    roles = {'odom': (tm.odom_topic, tm.odom_type, '')}
    for role in ('rudder', 'rpm'):   # a screw and rudder's, looked for in every recording
        c = tm.channel(role)
        roles[role] = (c.topic, c.msgtype, c.joint)
    if tm.odom_type != 'nav_msgs/msg/Odometry' and tm.twist_topic:
        roles['twist'] = (tm.twist_topic, tm.twist_type, '')
    if tm.imu_topic:
        roles['imu'] = (tm.imu_topic, tm.imu_type, '')
    if tm.odom_type == NAVSATFIX and tm.heading_topic:
        roles['heading'] = (tm.heading_topic, tm.heading_type, '')
    if tm.wind_topic:
        roles['wind'] = (tm.wind_topic, tm.wind_type, '')
    for role, c in tm.channels.items():  # the others: read when the recording has them
        if role not in roles and c.topic:
            roles[role] = (c.topic, c.msgtype, c.joint)
    types: dict[str, str] = {}
    for topic, typ, _ in roles.values():
        if types.setdefault(topic, typ) != typ:
            raise TrialDataError(f'topic map: {topic} is mapped with two types '
                                 f'({types[topic]}, {typ})')
    return roles


def _is_auto(tm: TopicMap, key: str) -> bool:
    """Return a key the user's map did not set and that still holds its default: found by type."""
    return key not in tm.given and getattr(tm, key) == getattr(TopicMap, key)


def resolve_topic_map(tm: TopicMap, found: dict[str, tuple[str, int]], path: str
                      ) -> tuple[TopicMap, list[str]]:
    """
    Return the topic map with its open topics found by message type, where unambiguous.

    The pose source (/odom, else the one Odometry or NavSatFix topic), and for a NavSatFix the one
    Imu (yaw rate, and heading), the one QuaternionStamped (heading, before the Imu's orientation)
    and the one TwistStamped. Ambiguity is an error listing the candidates; a topic the user's map
    names is never replaced.
    """
    by_type: dict[str, list[str]] = {}
    for topic, (msgtype, n) in sorted(found.items()):
        if n > 0:
            by_type.setdefault(msgtype, []).append(topic)
    notes: list[str] = []
    kw: dict[str, str] = {}

    def pick(what: str, key: str, types: tuple[str, ...], hint: str) -> str | None:
        cands = [(t, ty) for ty in types for t in by_type.get(ty, [])]
        if len(cands) > 1:
            listed = ', '.join(f'{t} ({ty})' for t, ty in cands)
            raise TrialDataError(f'{path}: {what} is ambiguous: {len(cands)} candidate topics '
                                 f'{listed}; choose one with {hint} in a topic map (--topics)')
        if not cands:
            return None
        kw[key] = cands[0][0]
        notes.append(f'{what}: {cands[0][0]} ({cands[0][1]}), the only one of its type '
                     '(no topic map entry)')
        return cands[0][1]

    pose_type = tm.odom_type
    if _is_auto(tm, 'odom_topic') and found.get(tm.odom_topic, ('', 0))[0] not in POSE_TYPES:
        types = (tm.odom_type,) if 'odom_type' in tm.given else \
            ('nav_msgs/msg/Odometry', NAVSATFIX)
        typ = pick('pose source', 'odom_topic', types, 'odom.topic and odom.type')
        if typ is not None:
            kw['odom_type'] = pose_type = typ
    elif _is_auto(tm, 'odom_type') and found.get(tm.odom_topic, ('', 0))[0] in POSE_TYPES:
        pose_type = kw['odom_type'] = found[tm.odom_topic][0]  # /odom as recorded
    if pose_type == NAVSATFIX:
        if _is_auto(tm, 'imu_topic'):
            pick('IMU (heading and yaw rate)', 'imu_topic', (IMU,), 'imu.topic')
        if _is_auto(tm, 'heading_topic') and _is_auto(tm, 'heading_type'):
            # a dedicated heading (a GNSS compass) before the Imu's orientation
            typ = pick('heading', 'heading_topic', ('geometry_msgs/msg/QuaternionStamped',),
                       'heading.topic and heading.type')
            if typ is not None:
                kw['heading_type'] = typ
        if _is_auto(tm, 'twist_topic'):
            pick('velocity (TwistStamped)', 'twist_topic', ('geometry_msgs/msg/TwistStamped',),
                 "twist.topic (or twist.topic: '' to derive velocities from the fixes)")
    # kw holds topic and type fields only (str), not every field's type
    return (replace(tm, **kw) if kw else tm), notes  # type: ignore[arg-type]


def _reader_errors() -> tuple[type[BaseException], ...]:
    """
    Return what the readers raise on a corrupt, truncated or unreadable file.

    Found by fuzzing real bags (test_data_io.py flips and cuts bytes) -- so that only those become
    TrialDataError and a bug of ours still surfaces as itself.
    """
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
    """Return the storage files of a rosbag2 folder, every file checked to be regular."""
    check_regular_file(bag / 'metadata.yaml', 'rosbag2 metadata.yaml', MAX_METADATA_BYTES)
    files = sorted(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3', '.zstd'))
    for f in files:
        size = check_regular_file(f, 'rosbag2 storage file')
        if f.suffix == '.mcap':
            check_mcap_size(f, size)
    return files


def _iter_rosbag2(path: Path) -> Iterator[_Item]:
    """
    Items of a rosbag2 folder.

    One whose MCAP storage rosbags cannot open (a recorder killed before writing the footer) is
    recovered by a streaming read of its .mcap files.
    """
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


def _iter_bare_mcap(path: Path) -> Iterator[_Item]:
    """
    Rosbags reads a bare ROS 2 MCAP fastest.

    Other MCAP files (another profile, a missing summary or footer, corruption) are read record by
    record with the mcap library.
    """
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


def _iter_mcap_stream(path: Path) -> Iterator[_Item]:
    """
    Every intact message of an MCAP file, read front to back without its summary.

    A file cut short (a recorder killed before writing the footer) or corrupt part-way gives the
    messages before the break, and a note saying how many and where it broke.
    """
    from mcap.records import Channel, Footer, Message, Schema
    from mcap.stream_reader import StreamReader
    size = check_regular_file(path, 'MCAP file')
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    counts: dict[int, int] = {}
    n = orphans = 0
    first_ns: int | None = None
    last_ns: int | None = None
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
        span = cast(int, last_ns) - cast(int, first_ns)   # set with the first of n > 0 messages
        yield 'note', (f'{display_text(str(path))}: {why}; recovered the {n} intact '
                       f'message(s) before the break, up to {span * 1e-9:.1f} s '
                       'after the first; anything after it is lost'
                       + (f'; {orphans} message(s) of unknown channels skipped' if orphans
                          else ''))


# every type a topic map may map (and /clock): their messages are kept until the topics are
# resolved; anything else (images, point clouds) is skipped unread
READ_TYPES = frozenset(POSE_TYPES + ('geometry_msgs/msg/TwistStamped', IMU,
                                     'geometry_msgs/msg/QuaternionStamped',
                                     'geometry_msgs/msg/Vector3Stamped', 'std_msgs/msg/Float64',
                                     'std_msgs/msg/Float32', 'sensor_msgs/msg/JointState', CLOCK))
SIM_TIME_MAX_NS = 100_000_000 * NS  # header stamps before 1973: a simulation's clock from 0
WALL_TIME_MIN_NS = 1_000_000_000 * NS  # receive times after 2001: the wall clock


def read_series(path: str | Path, tm: TopicMap) -> RawRecording:
    """
    Raw series of the mapped topics from a rosbag2 directory or a bare .mcap file.

    Topics the map leaves open are found by type (:func:`resolve_topic_map`); each series is
    timed as the map says (header stamp or receive time, plus offset_s), receive times on
    another clock than the header stamps (a simulation on /clock) mapped onto it.
    """
    path = Path(path)
    if path.is_dir() or path.name == 'metadata.yaml':
        bag = path if path.is_dir() else path.parent
        if not (bag / 'metadata.yaml').is_file():
            raise TrialDataError(f'{bag}: not a rosbag2 directory (no metadata.yaml)')
        it = _iter_rosbag2(bag)
    elif path.suffix == '.mcap':
        check_mcap_size(path, check_regular_file(path, 'MCAP file'))
        it = _iter_bare_mcap(path)
    else:
        raise TrialDataError(f'{path}: not a rosbag2 directory or .mcap file')
    given_types = {topic: typ for role, (topic, typ, _) in _roles(tm).items()
                   if f'{role}_topic' in tm.given}
    recv: dict[str, list[int]] = {}
    raws: dict[str, list[bytes]] = {}
    found: dict[str, tuple[str, int]] = {}
    first = last = None
    notes: list[str] = []

    def check_type(topic: str, msgtype: str) -> None:
        if topic in given_types and msgtype != given_types[topic]:
            raise TrialDataError(f'{path}: topic {topic} has type {msgtype}, the topic map '
                                 f'expects {given_types[topic]}')
    for item in it:
        if item[0] == 'note':
            notes.append(item[1])
            continue
        if item[0] == 'connections':
            for topic, msgtype, count in item[1] or []:
                found[topic] = (msgtype, int(count))
                check_type(topic, msgtype)
            continue
        topic, msgtype, ts, raw = item
        first = ts if first is None else min(first, ts)
        last = ts if last is None else max(last, ts)
        if msgtype not in READ_TYPES:
            continue
        check_type(topic, msgtype)
        recv.setdefault(topic, []).append(ts)
        raws.setdefault(topic, []).append(bytes(raw))
    for topic in found:
        if not raws.get(topic) and found[topic][0] in READ_TYPES:
            found[topic] = (found[topic][0], 0)
    tm, reading = resolve_topic_map(tm, found, str(path))
    roles = _roles(tm)
    for role, (topic, msgtype, _) in roles.items():
        if topic in found and found[topic][0] != msgtype:
            raise TrialDataError(f'{path}: topic {topic} has type {found[topic][0]}, the topic '
                                 f'map expects {msgtype}')
    series = {}
    headers: dict[str, np.ndarray | None] = {}
    for role, (topic, msgtype, joint) in roles.items():
        if not raws.get(topic):
            continue
        try:
            hdr, values, frames = _decode_topic(raws[topic], recv[topic], msgtype, joint, role,
                                                topic, str(path))
            rec_ns = np.asarray(recv[topic], dtype=np.int64)
            series[role] = Series(topic, msgtype, rec_ns, np.asarray(values, dtype=float),
                                  rec_ns, frame_ids=frames, base='receive')
            headers[role] = hdr
        except (OverflowError, ValueError) as exc:
            raise TrialDataError(f'{path}: topic {topic}: corrupt stamps or values '
                                 f'({exc})') from None
    clock = None
    for topic, (typ, _) in found.items():
        if typ == CLOCK and raws.get(topic):
            _, vals, _ = _decode_topic(raws[topic], recv[topic], CLOCK, '', 'clock', topic,
                                       str(path))
            clock = (topic, np.asarray(recv[topic], dtype=np.int64),
                     np.asarray(vals, dtype=float)[:, 0])
    reading += _time_bases(series, headers, tm, clock)
    return RawRecording(str(path), series, found, first or 0, last or 0, notes, tm, reading)


def _identity(ns: np.ndarray) -> np.ndarray:
    return ns


def _through_clock(c_recv: np.ndarray, c_val: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Receive time [ns] -> simulated time by the /clock messages' (receive, value) pairs."""
    def to_sim(ns: np.ndarray) -> np.ndarray:
        sim: np.ndarray = np.interp(ns.astype(float), c_recv, c_val).astype(np.int64)
        return sim
    return to_sim


def _linear_map(r0: int, h0: int, a: float, b: float) -> Callable[[np.ndarray], np.ndarray]:
    """Receive time [ns] -> header clock: h0 + a + b (t - r0), a and b in seconds."""
    def to_hdr(ns: np.ndarray) -> np.ndarray:
        return h0 + np.round((a + b * (ns - r0) * 1e-9) * 1e9).astype(np.int64)
    return to_hdr


def _time_bases(series: dict[str, Series], headers: dict[str, np.ndarray | None], tm: TopicMap,
                clock: tuple[str, np.ndarray, np.ndarray] | None) -> list[str]:
    """
    Time each series as the map says.

    header.stamp (a zero stamp falls back to the receive time) or receive time, plus the role's
    offset_s. Receive times on another clock than the header stamps (a simulation: stamps from
    /clock near 0, the recorder on the wall clock) are mapped onto the header clock through /clock,
    else by a linear fit to the stamps. Sets each header-timed series' lag_s (median receive -
    stamp) for the clock check.
    """
    notes: list[str] = []
    for role, s in series.items():
        hdr = headers.get(role)
        if tm.stamp(role) == 'header' and hdr is not None \
                and np.any(hdr != 0):
            # a zero stamp among wall-clock ones was never set: its receive time stands in;
            # on a simulated clock 0 is the first instant
            unset = (hdr == 0) & (np.median(hdr[hdr != 0]) > SIM_TIME_MAX_NS)
            s.stamps_ns = np.where(unset, s.receive_ns, hdr)
            s.base = 'header'
    hdr_series = [s for s in series.values() if s.base == 'header']

    to_hdr: Callable[[np.ndarray], np.ndarray] = _identity
    if hdr_series:
        ref = max(hdr_series, key=lambda s: s.stamps_ns.size)
        sim = (np.median(ref.stamps_ns) < SIM_TIME_MAX_NS
               and np.median(ref.receive_ns) > WALL_TIME_MIN_NS)
        if clock is not None and clock[1].size >= 2 and \
                abs(np.median(clock[1] - clock[2])) > NS:
            to_hdr = _through_clock(clock[1].astype(float), clock[2])
            notes.append(f'time: receive times mapped onto simulated time through {clock[0]} '
                         f'({clock[1].size} messages; the recorder ran on the wall clock)')
        elif sim:
            rx = (ref.receive_ns - ref.receive_ns[0]).astype(float) * 1e-9
            b, a = np.polyfit(rx, (ref.stamps_ns - ref.stamps_ns[0]) * 1e-9, 1)
            to_hdr = _linear_map(int(ref.receive_ns[0]), int(ref.stamps_ns[0]), a, b)
            notes.append(f'time: header stamps of {ref.topic} are on a simulated clock (near 0) '
                         'and there is no /clock: receive times mapped onto it by a linear fit '
                         f'to its stamps (rate {b:.4f} of the wall clock)')
    for role, s in series.items():
        if s.base == 'receive':
            s.stamps_ns = to_hdr(s.receive_ns)
        off = tm.offset_s(role)
        if off:
            s.stamps_ns = s.stamps_ns + int(round(off * 1e9))
            s.notes.append(f'{s.topic}: {off:+g} s added to its times ({role}.offset_s)')
        if s.base == 'header':
            s.lag_s = float(np.median(to_hdr(s.receive_ns) - s.stamps_ns)) * 1e-9
    return notes


def write_trial_bag(trial: Trial, path: str | Path, storage: str = 'mcap',
                    tm: TopicMap | None = None, start_ns: int = 1_700_000_000_000_000_000
                    ) -> None:
    """
    Write a trial as a rosbag2 (storage 'mcap' or 'sqlite3') with the default topics.

    Odometry in map/base_link (REP-103/105) and Float64 commands. The trial's own samples are
    written; each message is stamped at its sample time (ns since start_ns). A trial with measured
    wind also gets the wind topic (Vector3Stamped, true wind in ENU), one with thrusters the two
    thruster topics (Float64 in the map's unit and sign). A trial of a craft commanded per
    thruster (no rpm and rudder: a twin-azimuth tug) gets odometry and a Float64 topic per
    channel it has among the map's n_port, n_stbd, azimuth_port, azimuth_stbd (and the
    commanded angles where the map names a topic for them).
    """
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
            screw = 'rpm' in trial.inputs and 'rudder' in trial.inputs
            if screw:
                c_rud = w.add_connection(tm.topic('rudder'), Float64.__msgtype__, typestore=ts)
                c_rpm = w.add_connection(tm.topic('rpm'), Float64.__msgtype__, typestore=ts)
            own = [r for ins in per_channel_actuators(trial.inputs).values() for r in ins]
            c_chan = [(w.add_connection(tm.topic(r), Float64.__msgtype__,
                                        typestore=ts), trial.inputs[r], tm.factor(r))
                      for r in own if r in trial.inputs and tm.topic(r) and not screw]
            V3S = ts.types['geometry_msgs/msg/Vector3Stamped']
            c_wind = None
            if trial.wind is not None:
                c_wind = w.add_connection(tm.wind_topic or '/wind', V3S.__msgtype__,
                                          typestore=ts)
            c_thr = []
            if trial.thrusters is not None:
                for role in THRUSTER_ROLES:
                    topic = tm.topic(role) or TABLE[role].topic
                    c_thr.append((w.add_connection(topic, Float64.__msgtype__, typestore=ts),
                                  tm.factor(role)))
            for k in range(len(trial)):
                stamp = start_ns + int(round(trial.t[k] * 1e9))
                w.write(c_odom, stamp, ts.serialize_cdr(odometry_msg(trial.states[k], stamp),
                                                        Odometry.__msgtype__))
                if screw:
                    w.write(c_rud, stamp, ts.serialize_cdr(
                        Float64(data=float(trial.controls[k, 1] / tm.factor('rudder'))),
                        Float64.__msgtype__))
                    w.write(c_rpm, stamp, ts.serialize_cdr(
                        Float64(data=float(trial.controls[k, 0] / tm.factor('rpm'))),
                        Float64.__msgtype__))
                for c, values, factor in c_chan:
                    w.write(c, stamp, ts.serialize_cdr(Float64(data=float(values[k] / factor)),
                                                       Float64.__msgtype__))
                for j, (c, factor) in enumerate(c_thr):
                    w.write(c, stamp, ts.serialize_cdr(
                        # c_thr has a topic per thruster only when the trial has thrusters
                        Float64(data=float(cast(np.ndarray, trial.thrusters)[k, j] / factor)),
                        Float64.__msgtype__))
                if c_wind is not None:  # true wind, ENU: x east, y north
                    wind = cast(np.ndarray, trial.wind)   # c_wind: the trial has wind
                    w.write(c_wind, stamp, ts.serialize_cdr(V3S(
                        header=_header(stamp, 'map'),
                        vector=ts.types['geometry_msgs/msg/Vector3'](
                            x=float(wind[k, 1]), y=float(wind[k, 0]), z=0.0)),
                        V3S.__msgtype__))
    except (WriterError, OSError) as exc:
        raise OutputError(f'{path}: cannot write rosbag2 ({_why(exc)})') from None


def _header(stamp_ns: int, frame_id: str) -> MsgType:
    ts = TYPESTORE.types
    return ts['std_msgs/msg/Header'](
        stamp=ts['builtin_interfaces/msg/Time'](sec=stamp_ns // 1_000_000_000,
                                                nanosec=stamp_ns % 1_000_000_000),
        frame_id=frame_id)


def odometry_msg(state: np.ndarray, stamp_ns: int) -> MsgType:
    """nav_msgs/Odometry (rosbags type) of a model-frame state: ENU pose, FLU twist."""
    ts = TYPESTORE.types
    x, y, psi, u, v, r = (float(s) for s in state)
    yaw = frames.psi_to_enu_yaw(psi)
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
                     storage: str = 'mcap', model_topic: str = '/model/odom') -> None:
    """
    Write recorded and simulated odometry and the recorded commands as a rosbag2.

    Recorded odometry on /odom (so that ``inspect`` and ``tune`` read the measurement, as
    from the recording), the model's odometry on model_topic (never /odom) and the recorded
    commands, stamped in trial time, as a rosbag2 (MCAP: Foxglove opens the .mcap inside).
    """
    if model_topic.strip('/') == 'odom':
        raise OutputError(f'model odometry topic {model_topic!r}: /odom holds the recorded '
                          'odometry (the measurement); choose another, e.g. /model/odom')
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
            c_sim = w.add_connection('/' + model_topic.lstrip('/'), Odometry, typestore=ts)
            c_rec = w.add_connection('/odom', Odometry, typestore=ts)
            screw = 'rpm' in trial.inputs and 'rudder' in trial.inputs
            if screw:
                c_rud = w.add_connection(TABLE['rudder'].topic, Float64.__msgtype__,
                                         typestore=ts)
                c_rpm = w.add_connection(TABLE['rpm'].topic, Float64.__msgtype__, typestore=ts)
            # a craft commanded per thruster: its channels on the default map's topics
            c_chan = [] if screw else [
                (w.add_connection(TABLE[r].topic, Float64.__msgtype__, typestore=ts),
                 trial.inputs[r])
                for ins in per_channel_actuators(trial.inputs).values() for r in ins
                if r in trial.inputs and TABLE[r].topic]
            for k in range(len(trial)):
                stamp = int(round((trial.t[k] - trial.t[0]) * 1e9)) + 1
                w.write(c_rec, stamp, ts.serialize_cdr(odometry_msg(trial.states[k], stamp),
                                                       Odometry))
                if np.all(np.isfinite(simulated[k])):
                    w.write(c_sim, stamp, ts.serialize_cdr(odometry_msg(simulated[k], stamp),
                                                           Odometry))
                for c, values in c_chan:
                    w.write(c, stamp, ts.serialize_cdr(Float64(data=float(values[k])),
                                                       Float64.__msgtype__))
                if not screw:
                    continue
                w.write(c_rud, stamp, ts.serialize_cdr(Float64(data=float(trial.controls[k, 1])),
                                                       Float64.__msgtype__))
                w.write(c_rpm, stamp, ts.serialize_cdr(Float64(data=float(trial.controls[k, 0])),
                                                       Float64.__msgtype__))
    except (WriterError, OSError) as exc:
        raise OutputError(f'{path}: cannot write rosbag2 ({_why(exc)})') from None


def write_sensor_bag(trial: Trial, path: str | Path, datum: Datum | None = None, *,
                     lever_arm_m: tuple[float, float] = (0.0, 0.0), heading: str = 'imu',
                     twist_frame: str = '', gnss_frame: str = 'gps', imu_frame: str = 'imu_link',
                     state_stamp_offset_s: float = 0.0, sim_time: bool = False,
                     write_clock: bool = True, storage: str = 'mcap',
                     start_ns: int = 1_700_000_000_000_000_000) -> None:
    """
    Write a trial as a ship's sensors record it.

    sensor_msgs/NavSatFix on /fix (the antenna at lever_arm_m (forward, left) in base_link, about
    ``datum``, a core.geodesy.Datum), sensor_msgs/Imu on /imu/data (ENU yaw, angular_velocity.z =
    -r), and Float64 commands.

    heading: 'imu' (the Imu's orientation), 'quaternion' (geometry_msgs/QuaternionStamped on
    /heading in ``map``; the Imu then has no orientation), 'north_deg' (Float64 compass
    heading, degrees clockwise from north, on /heading). twist_frame: '' = no velocity topic;
    an earth frame ('map') = the antenna's ENU velocity over ground on /vel, as
    nmea_navsat_driver publishes it; a body frame ('base_link') = body velocities (FLU).
    state_stamp_offset_s: header stamps of /fix, /imu/data, /heading and /vel run this much
    ahead of their receive times (a GPS-time clock). sim_time: header stamps count from 0
    (a simulation's /clock, recorded on /clock unless write_clock is False) while receive
    times stay on the wall clock. Test and demonstration tool: the samples are the trial's own.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.errors import WriterError

    from mmg_tuner.core.geodesy import Datum, enu_to_geodetic
    datum = datum or Datum(35.0, 139.0, 0.0)
    if heading not in ('imu', 'quaternion', 'north_deg'):
        raise ValueError(f'heading {heading!r}: one of imu, quaternion, north_deg')
    ts = TYPESTORE.types
    path = Path(path)
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    x, y, psi, u, v, r = trial.states.T
    yaw = frames.psi_to_enu_yaw(psi)
    lx, ly = lever_arm_m
    east = y + lx * np.cos(yaw) - ly * np.sin(yaw)
    north = x + lx * np.sin(yaw) + ly * np.cos(yaw)
    lat, lon, alt = enu_to_geodetic(east, north, np.zeros_like(east), datum)
    wz = -r
    # the antenna's velocity: base velocity (FLU) + omega x lever, then turned into ENU
    ua, va = u - wz * ly, -v + wz * lx
    ve, vn = ua * np.cos(yaw) - va * np.sin(yaw), ua * np.sin(yaw) + va * np.cos(yaw)
    Q, V3 = ts['geometry_msgs/msg/Quaternion'], ts['geometry_msgs/msg/Vector3']
    names = {'fix': NAVSATFIX, 'imu': IMU, 'cmd': 'std_msgs/msg/Float64',
             'tw': 'geometry_msgs/msg/TwistStamped', 'q': 'geometry_msgs/msg/QuaternionStamped',
             'clock': CLOCK}
    hdr_off = int(round(state_stamp_offset_s * 1e9))
    try:
        with Writer(path, version=9, storage_plugin=plugin) as w:
            def conn(topic: str, key: str) -> Connection:
                return w.add_connection(topic, names[key], typestore=TYPESTORE)
            c = {'fix': conn('/fix', 'fix'), 'imu': conn('/imu/data', 'imu'),
                 'rud': conn(TABLE['rudder'].topic, 'cmd'), 'rpm': conn(TABLE['rpm'].topic, 'cmd')}
            if twist_frame:
                c['tw'] = conn('/vel', 'tw')
            if heading == 'quaternion':
                c['hd'] = conn('/heading', 'q')
            elif heading == 'north_deg':
                c['hd'] = conn('/heading', 'cmd')
            if sim_time and write_clock:
                c['clock'] = conn('/clock', 'clock')

            def put(key: str, stamp: int, msg: MsgType) -> None:
                w.write(c[key], stamp, TYPESTORE.serialize_cdr(msg, msg.__msgtype__))
            for k in range(len(trial)):
                t_ns = int(round(trial.t[k] * 1e9))
                recv = start_ns + t_ns
                st = (t_ns if sim_time else recv) + hdr_off
                q = Q(x=0.0, y=0.0, z=math.sin(yaw[k] / 2), w=math.cos(yaw[k] / 2))
                if 'clock' in c:
                    put('clock', recv, ts[CLOCK](clock=ts['builtin_interfaces/msg/Time'](
                        sec=t_ns // NS, nanosec=t_ns % NS)))
                cov = np.zeros(9)
                put('fix', recv, ts[NAVSATFIX](
                    header=_header(st, gnss_frame),
                    status=ts['sensor_msgs/msg/NavSatStatus'](status=0, service=1),
                    latitude=float(lat[k]), longitude=float(lon[k]), altitude=float(alt[k]),
                    position_covariance=cov, position_covariance_type=0))
                ocov = np.zeros(9)
                if heading != 'imu':
                    ocov[0] = -1.0  # REP-145: no orientation
                put('imu', recv, ts[IMU](
                    header=_header(st, imu_frame),
                    orientation=q if heading == 'imu' else Q(x=0.0, y=0.0, z=0.0, w=0.0),
                    orientation_covariance=ocov,
                    angular_velocity=V3(x=0.0, y=0.0, z=float(wz[k])),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=V3(x=0.0, y=0.0, z=9.81),
                    linear_acceleration_covariance=np.zeros(9)))
                if heading == 'quaternion':
                    put('hd', recv, ts[names['q']](header=_header(st, 'map'), quaternion=q))
                elif heading == 'north_deg':
                    put('hd', recv, ts['std_msgs/msg/Float64'](
                        data=float(np.degrees(psi[k]) % 360.0)))
                if twist_frame:
                    earth = twist_frame.rsplit('/', 1)[-1] in ('map', 'odom', 'world', 'enu')
                    lin = V3(x=float(ve[k]), y=float(vn[k]), z=0.0) if earth else \
                        V3(x=float(u[k]), y=float(-v[k]), z=0.0)
                    put('tw', recv, ts[names['tw']](
                        header=_header(st, twist_frame),
                        twist=ts['geometry_msgs/msg/Twist'](
                            linear=lin, angular=V3(x=0.0, y=0.0,
                                                   z=0.0 if earth else float(wz[k])))))
                put('rud', recv, ts['std_msgs/msg/Float64'](data=float(trial.controls[k, 1])))
                put('rpm', recv, ts['std_msgs/msg/Float64'](data=float(trial.controls[k, 0])))
    except (WriterError, OSError) as exc:
        raise OutputError(f'{path}: cannot write rosbag2 ({_why(exc)})') from None
