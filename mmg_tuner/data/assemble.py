"""
Raw topic series -> validated trials on a uniform grid in the model frame.

The motion comes from an Odometry, a PoseStamped (+ TwistStamped) or a GNSS recording:
NavSatFix on a local ENU plane at a datum (core.geodesy), heading from an Imu, a
QuaternionStamped or a number, yaw rate from the Imu (r = -omega_z), velocities from a
TwistStamped read in its frame or derived by a local least-squares fit, the antenna's lever
arm removed. Every frame_id is checked against its role; streams on two clocks are refused;
a rudder leading the yaw response by more than time.max_lag_s is reported.

Repairs are documented in each trial's notes: non-finite samples dropped, unsorted stamps
sorted, duplicate stamps dropped, gaps longer than max_gap_s split the trial, samples outside
the model's range (rpm <= 0, u <= 0) split it too unless keep_astern (a family that covers
them). Optional thruster topics become Trial.thrusters [rev/s] (a missing one is 0). A
recording of a craft commanded per thruster (any of the topic map's n_port, n_stbd,
azimuth_port, azimuth_stbd topics present: a twin-azimuth tug) needs odometry and all four
instead of rudder and rpm, and becomes a trial of those channels (plus azimuth_cmd_port,
azimuth_cmd_stbd when mapped); nothing is split for astern (its models cover it). Anything
unrepairable raises TrialDataError naming the file, topic and time.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import cast, Sequence

from mmg_tuner.core import frames
from mmg_tuner.core.channels import ENVIRONMENT, TABLE
from mmg_tuner.core.geodesy import ALT_MAX_M, Datum, datum_from_fixes, geodetic_to_enu
from mmg_tuner.core.limits import GENERIC_LIMITS, InputLimits
from mmg_tuner.data.bag import RawRecording, Series
from mmg_tuner.data.consistency import (check_motion, clock_resets, cuts, Motion,
                                        reset_findings, split_at, unusable_reason,
                                        UnusableRecordingError, warn)
from mmg_tuner.data.files import brief
from mmg_tuner.data.topics import (IMU, NAVSATFIX, per_channel_actuators,
                                   THRUSTER_ROLES, TopicMap)
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np

MIN_SAMPLES = 10
MAX_SAMPLES = 20_000_000  # ~230 days at 1 s: more means corrupt stamps
LAG_MIN_R2 = 0.5  # below it the yaw model explains too little to date the commands
MAX_WIND_MS = 100.0  # no anemometer reading beyond it is wind (the strongest gusts ~110 m/s)


# the readers' plausibility: an input channel's ``recorded`` cap (core/limits.py), the ship's own
# with one (load_trials(..., limits=input_limits(ship))), else GENERIC_LIMITS
def _implausible(s: Series, role: str, tm: TopicMap, lim: InputLimits) -> tuple[np.ndarray, str]:
    """(mask of samples no ship of these limits can show, what is wrong with them)."""
    v = s.values
    none = np.zeros(len(v), dtype=bool)
    if role == 'odom' and s.msgtype == NAVSATFIX:  # lat, lon [deg], alt [m], status
        return ((np.abs(v[:, 0]) > 90) | (np.abs(v[:, 1]) > 180) | (v[:, 3] < 0)
                | (np.abs(v[:, 2]) > ALT_MAX_M),
                'no fix (status < 0), latitude/longitude out of range or |altitude| > '
                f'{ALT_MAX_M:g} m')
    if role == 'imu':
        return (np.abs(v[:, 1]) > lim.yaw_rate_max_rad_s,
                f'|angular_velocity.z| > {math.degrees(lim.yaw_rate_max_rad_s):.0f} deg/s')
    if role in ('odom', 'twist'):
        bad = none.copy()
        if role == 'odom':
            bad |= np.any(np.abs(v[:, :2]) > lim.position_max_m, axis=1)
        vel = v[:, 3:6] if role == 'odom' and v.shape[1] == 6 else v if role == 'twist' else None
        if vel is not None:
            bad |= np.hypot(vel[:, 0], vel[:, 1]) > lim.speed_max_ms
            bad |= np.abs(vel[:, 2]) > lim.yaw_rate_max_rad_s
        return bad, (f'position beyond {lim.position_max_m:.0e} m, speed > '
                     f'{lim.speed_max_ms:.1f} m/s or |yaw rate| > '
                     f'{math.degrees(lim.yaw_rate_max_rad_s):.0f} deg/s')
    if role == 'wind':
        return np.hypot(v[:, 0], v[:, 1]) > MAX_WIND_MS, f'wind > {MAX_WIND_MS:g} m/s'
    if role in TABLE and role not in ENVIRONMENT:   # an input channel: its recording cap
        c = lim.channel(role)
        if math.isfinite(c.recorded):
            cap = f'{math.degrees(c.recorded):.0f} deg' if c.unit == 'rad' else \
                f'{c.recorded:.6g} {c.unit}'
            why = f' ({c.basis})' if c.recorded == c.limit else ''
            return np.abs(v[:, 0] * tm.factor(role)) > c.recorded, f'|{role}| > {cap}{why}'
    return none, ''


def clean_series(s: Series, path: str, t0_ns: int, role: str = '', tm: TopicMap | None = None,
                 limits: InputLimits | None = None) -> Series:
    """
    Drop non-finite, implausible and duplicate samples and sort the stamps.

    Drop non-finite, implausible (outside limits, see core/limits.py) and duplicate samples, sort
    unsorted stamps; say what was done.
    """
    def t(ns: int) -> float:
        return (ns - t0_ns) * 1e-9
    ok = np.all(np.isfinite(s.values), axis=1)
    if not ok.all():
        bad = np.nonzero(~ok)[0]
        s.notes.append(f'{s.topic}: dropped {bad.size} non-finite sample(s), first at '
                       f't = {t(s.stamps_ns[bad[0]]):.3f} s')
        s.stamps_ns, s.values = s.stamps_ns[ok], s.values[ok]
    if role and s.values.size:
        mask, what = _implausible(s, role, tm or TopicMap(), limits or GENERIC_LIMITS)
        if mask.any():
            bad = np.nonzero(mask)[0]
            # an odometry vector is ENU/FLU whatever was read (a CSV's x is north): say so
            axes = ' (ENU x, y, yaw; FLU u, v, r)' if s.msgtype == 'nav_msgs/msg/Odometry' \
                else ''
            s.notes.append(f'{s.topic}: dropped {bad.size} implausible sample(s) ({what}), '
                           f'first at t = {t(s.stamps_ns[bad[0]]):.3f} s, value{axes} '
                           f'{s.values[bad[0]].tolist()}')
            s.stamps_ns, s.values = s.stamps_ns[~mask], s.values[~mask]
    if s.stamps_ns.size and np.any(np.diff(s.stamps_ns) < 0):
        k = int(np.argmax(np.diff(s.stamps_ns) < 0))
        s.notes.append(f'{s.topic}: stamps not sorted (first at t = {t(s.stamps_ns[k]):.3f} s); '
                       'sorted by stamp')
        order = np.argsort(s.stamps_ns, kind='stable')
        s.stamps_ns, s.values = s.stamps_ns[order], s.values[order]
    if s.stamps_ns.size > 1:
        dup = np.concatenate([[False], np.diff(s.stamps_ns) == 0])
        if dup.any():
            s.notes.append(f'{s.topic}: dropped {int(dup.sum())} duplicate stamp(s), first at '
                           f't = {t(s.stamps_ns[np.argmax(dup)]):.3f} s')
            s.stamps_ns, s.values = s.stamps_ns[~dup], s.values[~dup]
    if s.stamps_ns.size < 2:
        raise TrialDataError(f'{path}: topic {s.topic} has fewer than 2 usable samples'
                             + (f' ({brief(s.notes)})' if s.notes else ''))
    return s


def _segments(rec: RawRecording, series: list[Series], tm: TopicMap, t0_ns: int, notes: list[str],
              faults: Sequence[tuple[float, float]] = ()) -> list[tuple[float, float]]:
    """
    Time ranges [s] covered by every topic without a gap longer than max_gap_s.

    faults: open ranges (last good sample, first good sample) [s] the consistency checks cut
    out; they split the ranges as a gap does.
    """
    start = max(float((s.stamps_ns[0] - t0_ns) * 1e-9) for s in series)
    end = min(float((s.stamps_ns[-1] - t0_ns) * 1e-9) for s in series)
    if end <= start:
        raise TrialDataError(f'{rec.path}: the topics do not overlap in time')
    cuts = []
    for s in series:
        t = (s.stamps_ns - t0_ns) * 1e-9
        gaps = np.nonzero(np.diff(t) > tm.max_gap_s)[0]
        for g in gaps:
            cuts.append((t[g], t[g + 1]))
            notes.append(f'{s.topic}: gap of {t[g + 1] - t[g]:.1f} s at t = {t[g]:.1f} s '
                         f'(> {tm.max_gap_s:g} s): trial split there')
    cuts.extend(faults)
    segs = [(start, end)]
    for a, b in sorted(cuts):
        new = []
        for lo, hi in segs:
            if b <= lo or a >= hi:
                new.append((lo, hi))
                continue
            if a > lo:
                new.append((lo, a))
            if b < hi:
                new.append((b, hi))
        segs = new
    return segs


def assemble_trials(rec: RawRecording, tm: TopicMap, name: str = 'trial',
                    limits: InputLimits | None = None, keep_astern: bool = False
                    ) -> list[Trial]:
    """
    Frame, resample and split one recording into trials (see module docstring).

    limits: plausibility ranges of the ship (core.limits.input_limits); default generic.
    keep_astern: keep astern propeller (rpm <= 0) and u <= 0 samples (for a family that covers
    them); by default they split the trial and are left out with a note. How the recording was read
    (pose source, datum, frames, time bases, a suspected time offset) is added to rec.reading and
    to every trial's notes.
    """
    tm = rec.topic_map or tm
    resets = {r: clock_resets(s.stamps_ns * 1e-9) for r, s in rec.series.items()}
    if any(v.size for v in resets.values()):
        return _split_at_clock_resets(rec, tm, name, limits, keep_astern, resets)
    # a craft commanded channel by channel (twin azimuths, a plugin's actuator): its channels
    # in place of rudder and rpm
    own = per_channel_actuators(rec.series)
    per_thruster = bool(own)
    own_roles = [c for ins in own.values() for c in ins]
    required = [c for c in own_roles if TABLE[c].default is None]
    needed = ['odom', *required] if per_thruster else ['odom', 'rudder', 'rpm']
    for role in needed:
        if role not in rec.series:
            topic = tm.topic(role) or f'(none mapped: {role}.topic)'
            found = ', '.join(f'{t} ({ty}, {n} msgs)' for t, (ty, n) in sorted(
                rec.topics_found.items())) or 'nothing'
            channel = f' for channel {role!r} ({TABLE[role].description}, ' \
                f'{TABLE[role].unit}); a recording of {" and ".join(own)} needs ' \
                f'{", ".join(tm.topic(r) or r for r in required)}' \
                if per_thruster else ''
            raise TrialDataError(f'{rec.path}: topic {topic} missing or empty{channel}; found: '
                                 f'{found}. Use --topics MAP.yaml to map other names.')
    kinds = check_frames(rec, tm)
    t0_ns = int(min(s.stamps_ns.min() for s in rec.series.values()))
    optional = [r for r in ('twist', 'imu', 'heading') if r in rec.series]
    cleaned = {r: clean_series(rec.series[r], rec.path, t0_ns, r, tm, limits)
               for r in needed + optional}
    series = [cleaned[r] for r in needed + optional]
    wind = None
    if 'wind' in rec.series:
        wind = clean_series(rec.series['wind'], rec.path, t0_ns, 'wind', tm, limits)
        if not wind.frame:
            wind.frame = tm.wind_frame
    thr = {r: clean_series(rec.series[r], rec.path, t0_ns, r, tm, limits)
           for r in THRUSTER_ROLES if r in rec.series}
    # the per-thruster channels (required ones cleaned above; commanded angles when mapped)
    chan = {r: cleaned[r] if r in cleaned else
            clean_series(rec.series[r], rec.path, t0_ns, r, tm, limits)
            for r in own_roles if r in rec.series} if per_thruster else {}
    check_clocks(rec.path, {**cleaned, **({'wind': wind} if wind is not None else {}), **thr,
                            **chan}, tm)
    notes = list(rec.notes) + list(rec.reading) + [n for s in series for n in s.notes] + \
        (wind.notes if wind is not None else []) + [n for s in thr.values() for n in s.notes] + \
        [n for r, s in chan.items() if r not in cleaned for n in s.notes]
    for r in THRUSTER_ROLES:
        if thr and r not in thr:
            notes.append(f'{tm.topic(r) or r}: not recorded, {r} taken as '
                         '0 rev/s')
    if series[0].base == 'header':  # a CSV has neither: its one time column
        notes.append(f'{cleaned["odom"].topic}: header stamps used (not receive time)')
    kin, how = _kinematics(cleaned, kinds, tm, t0_ns, rec.path)
    how += _describe_times({**cleaned, **thr, **chan}, wind)
    rec.reading.extend(h for h in how if h not in rec.reading)
    notes.extend(how)
    # the channels against each other, at the recording's own times (before resampling)
    findings = check_motion(name, _motion(kin, cleaned.get('rpm'), tm, t0_ns),
                            limits.length_m if limits is not None else 0.0)
    warn(findings)
    notes.extend(f.note() for f in findings)
    if any(f.long for f in findings):
        raise UnusableRecordingError(f'{rec.path}: not used: {unusable_reason(findings)}')
    trials = []
    for lo, hi in _segments(rec, series, tm, t0_ns, notes, cuts(findings)):
        n = int(math.floor((hi - lo) / tm.dt + 1e-9)) + 1
        if n > MAX_SAMPLES:
            raise TrialDataError(f'{rec.path}: segment {lo:.1f}-{hi:.1f} s would need {n} '
                                 f'samples at dt = {tm.dt:g} s: corrupt stamps?')
        if n < MIN_SAMPLES:
            notes.append(f'segment {lo:.1f}-{hi:.1f} s shorter than {MIN_SAMPLES} samples: '
                         'dropped')
            continue
        grid = lo + tm.dt * np.arange(n)
        trials.extend(_resample(kin, cleaned.get('rudder'), cleaned.get('rpm'), tm, t0_ns,
                                grid, rec.path, name, notes, wind, thr,
                                keep_astern or per_thruster, chan))
    if not trials:
        raise TrialDataError(f'{rec.path}: no usable trial ({brief(notes) or "too short"})')
    for tr in trials if not per_thruster else ():   # the lag is dated by the rudder
        lag = command_lag_s(tr, window_s=tm.smooth_s)
        if lag is not None:
            tr.notes.append(_lag_note(lag, tm, cleaned['rudder'].topic))
    if len(trials) > 1:  # one recording split into several: number them in time order
        for i, tr in enumerate(trials, 1):
            tr.name = f'{name}_{i}'
    return trials


def _split_at_clock_resets(rec: RawRecording, tm: TopicMap, name: str,
                           limits: InputLimits | None, keep_astern: bool,
                           resets: dict[str, np.ndarray]) -> list[Trial]:
    """
    Assemble each stretch between clock resets on its own (never sorted into one splice).

    Every topic must go back as often as the others (one clock for all); otherwise which
    samples belong together cannot be told, and the recording is refused naming the topics.
    """
    counts = {rec.series[r].topic: int(v.size) for r, v in resets.items()}
    if len(set(counts.values())) > 1:
        raise TrialDataError(f'{rec.path}: the time goes backwards (a clock reset) a different '
                             f'number of times per topic ({counts}): which samples belong '
                             'together cannot be told; split the recording at the reset')
    lead = 'odom' if 'odom' in rec.series else next(iter(rec.series))
    stamps = rec.series[lead].stamps_ns
    found = reset_findings(name, stamps * 1e-9, resets[lead], stamps[0] * 1e-9)
    warn(found)
    n_parts = int(resets[lead].size) + 1
    trials: list[Trial] = []
    why: list[str] = []
    for i in range(n_parts):
        series = {}
        for r, s in rec.series.items():
            sl = split_at(s.stamps_ns.size, resets[r])[i]
            series[r] = Series(s.topic, s.msgtype, s.stamps_ns[sl], s.values[sl],
                               s.receive_ns[sl], list(s.notes), s.frame, s.frame_ids, s.base,
                               s.lag_s)
        part = RawRecording(rec.path, series, rec.topics_found, rec.start_ns, rec.end_ns,
                            list(rec.notes) + [f.note() for f in found], rec.topic_map,
                            rec.reading)
        try:
            got = assemble_trials(part, tm, f'{name}_part{i + 1}', limits, keep_astern)
        except TrialDataError as exc:   # one stretch too short or faulty: the others count
            why.append(f'stretch {i + 1} of {n_parts}: {exc}')
            continue
        for tr in got:
            tr.notes.extend(why)
        trials.extend(got)
    if not trials:
        raise TrialDataError(f'{rec.path}: no usable trial ({brief(why)})')
    if len(trials) > 1:
        for i, tr in enumerate(trials, 1):
            tr.name = f'{name}_{i}'
    else:
        trials[0].name = name
    return trials


def _motion(kin: 'Kinematics', rpm: Series | None, tm: TopicMap, t0_ns: int) -> Motion:
    """
    Return the motion at the pose's own times in the model frame (consistency checks).

    rpm None (a craft commanded per thruster): NaN, so no check reads a propeller.
    """
    t = kin.t_pos
    yaw = np.interp(t, kin.t_yaw, kin.yaw)
    n = np.full(t.size, np.nan) if rpm is None else _interp(rpm, t0_ns, t, 0) * tm.factor('rpm')
    return Motion(t, kin.north, kin.east, frames.enu_yaw_to_psi(yaw),
                  np.interp(t, kin.t_vel, kin.u_flu), -np.interp(t, kin.t_vel, kin.v_flu),
                  -np.interp(t, kin.t_rate, kin.wz), n)


# ------------------------------------------------------------------------------------ frames

# what each role's frame_id must be: 'earth' (ENU-aligned world frame), 'body' (on the hull,
# base_link's axes) or 'either' (a twist: its frame says how to read it)
_FRAME_RULES = {
    ('odom', 'nav_msgs/msg/Odometry'): {'frame_id': 'earth', 'child_frame_id': 'body'},
    ('odom', 'geometry_msgs/msg/PoseStamped'): {'frame_id': 'earth'},
    ('odom', NAVSATFIX): {'frame_id': 'body'},
    ('twist', 'geometry_msgs/msg/TwistStamped'): {'frame_id': 'either'},
    ('imu', IMU): {'frame_id': 'body'},
    ('heading', IMU): {'frame_id': 'body'},
    ('heading', 'geometry_msgs/msg/QuaternionStamped'): {'frame_id': 'earth'},
}
_WHY = {'earth': 'an earth (ENU, REP-103/105) frame', 'body': "a body frame (base_link's axes)"}


def frame_kind(frame_id: str, tm: TopicMap) -> str | None:
    """'earth', 'body' or None (unknown) of a frame_id; ship2/base_link counts as base_link."""
    last = frame_id.strip('/').rsplit('/', 1)[-1]
    if last in tm.frames_earth:
        return 'earth'
    return 'body' if last in tm.frames_body else None


def check_frames(rec: RawRecording, tm: TopicMap) -> dict[str, str]:
    """
    Check every mapped topic's frame_id(s) against what its role needs.

    Returns the frame kind per role ('earth' or 'body': a twist's decides how it is read). A topic
    whose frame is unknown, contradicts its role or changes is an error naming topic and frame.
    """
    kinds: dict[str, str] = {}
    for role, s in rec.series.items():
        rules = dict(_FRAME_RULES.get((role, s.msgtype), {}))
        if role == 'wind':
            rules = {'frame_id': 'earth' if (s.frame or tm.wind_frame) == 'true_enu' else 'body'}
        for key, need in rules.items():
            ids = s.frame_ids.get(key)
            if not ids:  # not known (a CSV, a series built in code): nothing to check
                continue
            if len(ids) > 1:
                raise TrialDataError(f'{rec.path}: topic {s.topic}: {key} changes within the '
                                     f'recording ({sorted(ids)}): one frame per topic')
            (fid,) = ids
            kind = frame_kind(fid, tm)
            what = f'{s.msgtype} {key}' + (f' ({role})' if role != 'odom' else '')
            if kind is None:
                raise TrialDataError(
                    f'{rec.path}: topic {s.topic}: {key} {fid!r} is not a known frame; a '
                    f'{what} must be '
                    + ('an earth or a body frame' if need == 'either' else _WHY[need])
                    + f'. Known: earth {list(tm.frames_earth)}, body {list(tm.frames_body)}; '
                    'add it to frames.earth or frames.body in the topic map if it is one')
            if need != 'either' and kind != need:
                raise TrialDataError(f'{rec.path}: topic {s.topic}: {key} {fid!r} is '
                                     f'{_WHY[kind]}, but a {what} must be {_WHY[need]}')
            if key == 'frame_id':
                kinds[role] = kind
    return kinds


# -------------------------------------------------------------------------------------- time

def check_clocks(path: str, series: dict[str, Series], tm: TopicMap) -> None:
    """
    Refuse streams on two clocks.

    Each header-timed series' receive times lag its stamps by lag_s (transport, milliseconds); a
    receive-timed one by 0. Lags differing by more than time.max_offset_s mean a constant offset
    between streams (GPS time is 18 s ahead of UTC) that would shift the commands against the
    states: an error naming topic and field.
    """
    # a header-timed series is kept only with its lag (not None)
    lags = {r: (cast(float, s.lag_s) if s.base == 'header' else 0.0) for r, s in series.items()
            if s.base and (s.base == 'receive' or s.lag_s is not None)}
    if len(lags) < 2:
        return
    hi = max(lags, key=lambda r: lags[r])
    lo = min(lags, key=lambda r: lags[r])
    if lags[hi] - lags[lo] <= tm.time_max_offset_s:
        return
    # the odd one out is the header-timed series furthest from its receive times
    odd = max((r for r in lags if series[r].base == 'header'), key=lambda r: abs(lags[r]))
    other = lo if odd == hi else hi
    so, sb = series[odd], series[other]
    field_b = 'header.stamp' if sb.base == 'header' else 'receive time'
    raise TrialDataError(
        f'{path}: topic {so.topic} header.stamp runs {-lags[odd]:+.3f} s from its receive '
        f'times, topic {sb.topic} ({field_b}) {-lags[other]:+.3f} s: the streams are on two '
        f'clocks {abs(lags[odd] - lags[other]):.3f} s apart (> time.max_offset_s = '
        f'{tm.time_max_offset_s:g} s; GPS time runs 18 s ahead of UTC), which would shift '
        f'commands against states. Set {odd}.offset_s: {lags[odd] - lags[other]:.3f} in the '
        f'topic map to correct it, or {odd}.stamp: receive to use receive times')


def _describe_times(series: dict[str, Series], wind: Series | None) -> list[str]:
    parts = []
    for role, s in list(series.items()) + ([('wind', wind)] if wind is not None else []):
        if not s.base:
            continue
        lag = (f', receive - stamp {s.lag_s * 1e3:+.0f} ms' if s.base == 'header'
               and s.lag_s is not None else '')
        parts.append(f'{s.topic} {"header.stamp" if s.base == "header" else "receive time"}'
                     f'{lag}')
    return ['time bases: ' + '; '.join(parts)] if parts else []


def command_lag_s(trial: Trial, max_lag_s: float = 30.0, window_s: float = 10.0
                  ) -> tuple[float, float] | None:
    """
    (lag [s], fit R^2) at which the rudder best explains the yaw acceleration.

    For each lag L within +-max_lag_s the first-order Nomoto model r' = a delta(t - L) + b r + c is
    fitted by least squares (the b r term takes the yaw damping, which biases a plain cross-
    correlation of delta and r' by several seconds); the best L is refined by a parabola. Positive:
    the recorded rudder leads the motion (commands stamped early). About 0 (a second or two) in a
    consistent recording. window_s: the local quadratic fit that gives r'. Every lag is fitted
    on the same samples of r' (all but max_lag_s at either end): a window that moved with the
    lag dropped the yaw transient of a turn put over in the first seconds and made a clean
    200 s turning trial "follow the rudder by +20 s". None when the rudder hardly moves within
    those samples or the trial is too short to tell.
    """
    dt = trial.dt
    n = len(trial)
    k_max = int(min(max_lag_s, trial.duration_s / 4) / dt)
    rud = trial['rudder']
    if k_max < 2 or np.std(rud[k_max:n - k_max]) < math.radians(1.0):
        return None
    r = trial['r']
    _, rdot = local_poly_fit(trial.t, r, max(3 * dt, window_s))  # symmetric: no shift
    lags = np.arange(-k_max, k_max + 1)
    r2 = np.empty(lags.size)
    j = np.arange(k_max, n - k_max)  # the same r' samples for every lag
    for i, k in enumerate(lags):  # pairs r'(t_j) with delta(t_j - k dt)
        A = np.column_stack([rud[j - k], r[j], np.ones(j.size)])
        y = rdot[j]
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        ss = float(np.sum((y - y.mean()) ** 2))
        r2[i] = 1.0 - float(np.sum((y - A @ coef) ** 2)) / ss if ss > 0 else 0.0
    i = int(np.argmax(r2))
    frac = 0.0
    if 0 < i < r2.size - 1:
        den = r2[i - 1] - 2 * r2[i] + r2[i + 1]
        frac = 0.5 * (r2[i - 1] - r2[i + 1]) / den if den < 0 else 0.0
    return float((lags[i] + frac) * dt), float(r2[i])


def _lag_note(lag: tuple[float, float], tm: TopicMap, rudder_topic: str) -> str:
    """
    Say what the rudder-to-yaw lag tells about the command clock.

    Within time.max_lag_s the best lag is no finding: the first-order yaw model's lag also
    takes the steering gear and the dynamics it lacks (a clean 20/20 zigzag of SUZAKU fits best
    at -3.8 s, within 0.01 of R^2 from -6 s to -2 s), so only a lag beyond it is reported as a
    suspected offset.
    """
    s, c = lag
    fit = f'best-fit lag {s:+.1f} s of a first-order yaw model, R^2 {c:.2f}'
    if c < LAG_MIN_R2:
        return ('time: the rudder explains too little of the yaw motion to date the commands '
                f'({fit})')
    if abs(s) > tm.time_max_lag_s:
        return (f'time: the yaw acceleration follows the rudder by {s:+.1f} s ({fit}) -- beyond '
                f'time.max_lag_s = {tm.time_max_lag_s:g} s: a constant offset between '
                f'{rudder_topic} and the state streams? (rudder.offset_s in the topic map '
                'corrects one)')
    return (f'time: commands and motion agree within time.max_lag_s = {tm.time_max_lag_s:g} s '
            f'({fit}; inside that range the lag is not a clock offset)')


# -------------------------------------------------------------------------------- kinematics

def local_poly_fit(t: np.ndarray, y: np.ndarray, window_s: float, order: int = 2,
                   chunk: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the local polynomial fit of y and its first derivative at each t.

    (fitted value, first derivative) of y at each t from a least-squares polynomial of the given
    order (1 or 2) over the samples within +-window_s/2 (Savitzky-Golay for irregular stamps);
    within window_s/2 of either end the window keeps its full width, shifted inward (savgol's
    mode='interp'); at a gap it is one-sided. On a symmetric window both orders give the same
    slope; at the ends order 1 has a far smaller variance (the derivative of an off-centre
    quadratic is an extrapolation), at a bias of about acceleration x window/2, so the velocities
    use order 1. A point with fewer than order + 2 neighbours uses a straight line, with one only
    its neighbour difference.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = t.size
    val, der = y.copy(), np.zeros(n)
    if n < 2:
        return val, der
    half = 0.5 * window_s
    # near the ends the window keeps its width, shifted inward (savgol's mode='interp')
    centre = np.clip(t, t[0] + half, max(t[-1] - half, t[0] + half))
    lo_idx = np.searchsorted(t, centre - half, side='left')
    hi_idx = np.searchsorted(t, centre + half, side='right')
    width = int(np.max(hi_idx - lo_idx))
    for c0 in range(0, n, chunk):
        rows = np.arange(c0, min(n, c0 + chunk))
        idx = lo_idx[rows, None] + np.arange(width)[None, :]
        mask = idx < hi_idx[rows, None]
        idx = np.minimum(idx, n - 1)
        x = np.where(mask, (t[idx] - t[rows, None]) / half, 0.0)  # scaled to [-1, 1]
        w = mask.astype(float)
        yy = np.where(mask, y[idx], 0.0)
        m = [np.sum(w * x ** k, axis=1) for k in range(2 * order + 1)]
        b = [np.sum(w * yy * x ** k, axis=1) for k in range(order + 1)]
        cnt = m[0]
        A = np.stack([np.stack([m[i + j] for j in range(order + 1)], -1)
                      for i in range(order + 1)], -2)
        B = np.stack(b, -1)
        quad = (cnt >= order + 2) & (np.abs(np.linalg.det(A)) > 1e-9 * cnt ** (order + 1))
        coef = np.zeros((rows.size, order + 1))
        if quad.any():
            coef[quad] = np.linalg.solve(A[quad], B[quad][..., None])[..., 0]
        lin = ~quad
        if lin.any():  # a straight line where the quadratic is not determined
            det = m[0][lin] * m[2][lin] - m[1][lin] ** 2
            ok = det > 1e-12
            c1 = np.where(ok, (m[0][lin] * b[1][lin] - m[1][lin] * b[0][lin])
                          / np.where(ok, det, 1.0), np.nan)
            c0_ = np.where(ok, (b[0][lin] - c1 * m[1][lin])
                           / np.where(cnt[lin] > 0, cnt[lin], 1.0), np.nan)
            coef[lin, 0], coef[lin, 1] = c0_, c1
        val[rows], der[rows] = coef[:, 0], coef[:, 1] / half
    bad = ~np.isfinite(der)
    if bad.any():  # isolated samples: the neighbour difference
        g = np.gradient(y, t) if n > 1 else np.zeros(n)
        der[bad], val[bad] = g[bad], y[bad]
    return val, der


@dataclass
class Kinematics:
    """
    The ship's motion at the recording's own sample times, REP-103/105 frames.

    base_link position east/north in the local ENU frame [m], ENU yaw (unwrapped) [rad], body
    velocity forward/left (FLU) [m/s] and yaw rate about z up [rad/s]; times [s] from t0.
    """

    t_pos: np.ndarray
    east: np.ndarray
    north: np.ndarray
    t_yaw: np.ndarray
    yaw: np.ndarray
    t_vel: np.ndarray
    u_flu: np.ndarray
    v_flu: np.ndarray
    t_rate: np.ndarray
    wz: np.ndarray


def _t(s: Series, t0_ns: int) -> np.ndarray:
    return (s.stamps_ns - t0_ns) * 1e-9


def _heading(s: Series, role: str, tm: TopicMap, path: str, notes: list[str]
             ) -> tuple[np.ndarray, np.ndarray]:
    """(kept-sample mask, ENU yaw [rad]) of a heading source."""
    if s.msgtype in (IMU, 'geometry_msgs/msg/QuaternionStamped'):
        ok = s.values[:, 2 if s.msgtype == IMU else 1] > 0
        field_ = 'orientation' if s.msgtype == IMU else 'quaternion'
        if not ok.any():
            raise TrialDataError(
                f'{path}: topic {s.topic}: {field_} is not given (orientation_covariance[0] = '
                f'-1 or not a unit quaternion) in any message: no heading for the NavSatFix '
                'pose; map heading.topic (QuaternionStamped, or Float64 with heading.unit and '
                'heading.convention)')
        if not ok.all():
            notes.append(f'{s.topic}: dropped {int((~ok).sum())} sample(s) without a valid '
                         f'{field_} for the heading')
        return ok, s.values[:, 0]
    val = s.values[:, 0] * tm.heading_to_rad
    if tm.heading_convention == 'north_cw':
        val = frames.psi_to_enu_yaw(val)  # clockwise from north -> ENU yaw
    return np.ones(len(val), dtype=bool), val


def _kinematics(ser: dict[str, Series], kinds: dict[str, str], tm: TopicMap, t0_ns: int,
                path: str) -> tuple[Kinematics, list[str]]:
    """
    Return the motion from the sources the map gives, plus how it was read (notes, inspect).

    Pose and heading, velocities (recorded, turned by the heading when in an earth frame, or
    derived by a local linear fit over resample.smooth_s), yaw rate (IMU, a body twist, or derived
    from the heading likewise), the GNSS lever arm removed.
    """
    od = ser['odom']
    t_od = _t(od, t0_ns)
    how: list[str] = []
    frame_text = ', '.join(
        f'{s.topic} ' + ' -> '.join(next(iter(s.frame_ids[k]))
                                    for k in ('frame_id', 'child_frame_id')
                                    if s.frame_ids.get(k))
        for s in ser.values() if s.frame_ids.get('frame_id'))
    win = f'local linear least-squares fit over {tm.smooth_s:g} s'
    imu = ser.get('imu')
    vel_src = rate_src = None
    if od.msgtype == 'nav_msgs/msg/Odometry':
        k = Kinematics(t_od, od.values[:, 0], od.values[:, 1],
                       t_od, frames.unwrap(od.values[:, 2]),
                       t_od, od.values[:, 3], od.values[:, 4], t_od, od.values[:, 5])
        how.append(f'pose source: {od.topic} (Odometry: pose, body twist)')
    else:
        if od.msgtype == NAVSATFIX:
            lat, lon, alt = od.values[:, 0], od.values[:, 1], od.values[:, 2]
            if tm.datum_given:
                datum, which = Datum(tm.gnss_datum_lat_deg, tm.gnss_datum_lon_deg,
                                     tm.gnss_datum_alt_m), 'topic map'
            else:
                datum, which = datum_from_fixes(lat, lon, alt, f'{path}: topic {od.topic}'), \
                    'first fix'
            east, north, _ = geodetic_to_enu(lat, lon, alt, datum)
            hs = ser.get('heading') or imu
            if hs is None:
                raise TrialDataError(
                    f'{path}: topic {od.topic} (NavSatFix) gives no heading and there is no '
                    'heading source: map imu.topic (sensor_msgs/Imu orientation) or '
                    'heading.topic (QuaternionStamped, or Float64 with unit and convention)')
            keep, yaw = _heading(hs, 'heading', tm, path, how)
            t_yaw, yaw = _t(hs, t0_ns)[keep], frames.unwrap(yaw[keep])
            conv = ('' if hs.msgtype in (IMU, 'geometry_msgs/msg/QuaternionStamped') else
                    f' [{tm.heading_unit}, {tm.heading_convention}]')
            how.append(f'pose source: {od.topic} (NavSatFix) on the local ENU plane at datum '
                       f'{datum.lat_deg:.7f} deg N, {datum.lon_deg:.7f} deg E, '
                       f'{datum.alt_m:.2f} m ({which}; WGS84 via pymap3d); heading from '
                       f'{hs.topic} ({hs.msgtype.rsplit("/", 1)[-1]}{conv})')
            lx, ly = tm.lever_arm_m
            if lx or ly:  # the antenna sits at (lx, ly) in base_link: base = antenna - R(yaw) l
                yf = np.interp(t_od, t_yaw, yaw)
                east = east - (lx * np.cos(yf) - ly * np.sin(yf))
                north = north - (lx * np.sin(yf) + ly * np.cos(yf))
                how.append(f'GNSS lever arm ({lx:g}, {ly:g}) m in base_link (FLU) removed '
                           'with the heading')
        else:
            east, north = od.values[:, 0], od.values[:, 1]
            t_yaw, yaw = t_od, frames.unwrap(od.values[:, 2])
            how.append(f'pose source: {od.topic} (PoseStamped)')
        # the velocities and the yaw rate are filled in below, before k is returned
        k = Kinematics(t_od, east, north, t_yaw, yaw, t_od,
                       None, None, None, None)  # type: ignore[arg-type]
        tw = ser.get('twist')
        if imu is not None:
            k.t_rate, k.wz = _t(imu, t0_ns), imu.values[:, 1]
            rate_src = f'{imu.topic} angular_velocity.z (r = -omega_z, REP-103)'
        if tw is not None:
            t_tw = _t(tw, t0_ns)
            vx, vy, wz = tw.values[:, 0], tw.values[:, 1], tw.values[:, 2]
            if kinds.get('twist', 'body') == 'earth':  # ENU over ground -> FLU by the heading
                yt = np.interp(t_tw, t_yaw, yaw)
                c, sn = np.cos(yt), np.sin(yt)
                u, v = vx * c + vy * sn, -vx * sn + vy * c
                lx, ly = tm.lever_arm_m if od.msgtype == NAVSATFIX else (0.0, 0.0)
                lever = ''
                if (lx or ly) and k.wz is not None:  # antenna velocity = base + omega x l
                    w = np.interp(t_tw, k.t_rate, k.wz)
                    u, v = u + w * ly, v - w * lx
                    lever = ', lever arm removed'
                vel_src = (f'{tw.topic} (TwistStamped in earth frame '
                           f'{next(iter(tw.frame_ids.get("frame_id", {"?": 0})))}: ENU velocity '
                           f'turned into the body by the heading{lever})')
            else:
                u, v = vx, vy
                vel_src = f'{tw.topic} (TwistStamped in body frame)'
                if k.wz is None:
                    k.t_rate, k.wz = t_tw, wz
                    rate_src = f'{tw.topic} angular.z'
            k.t_vel, k.u_flu, k.v_flu = t_tw, u, v
        if k.u_flu is None:
            _, ve = local_poly_fit(t_od, east, tm.smooth_s, order=1)
            _, vn = local_poly_fit(t_od, north, tm.smooth_s, order=1)
            yp = np.interp(t_od, t_yaw, yaw)
            c, sn = np.cos(yp), np.sin(yp)
            k.u_flu, k.v_flu = ve * c + vn * sn, -ve * sn + vn * c
            vel_src = f'derived from positions and heading ({win})'
        if k.wz is None:
            _, k.wz = local_poly_fit(t_yaw, yaw, tm.smooth_s, order=1)
            k.t_rate = t_yaw
            rate_src = f'derived from the heading ({win})'
        how.append(f'velocities: {vel_src}; yaw rate: {rate_src}')
    if frame_text:
        how.append(f'frames: {frame_text}')
    return k, how


def _resample(kin: Kinematics, rud: Series | None, rpm: Series | None, tm: TopicMap, t0_ns: int,
              grid: np.ndarray, path: str, name: str, notes: list[str],
              wind: Series | None = None, thr: dict[str, Series] | None = None,
              keep_astern: bool = False, chan: dict[str, Series] | None = None
              ) -> list[Trial]:
    """
    Return the trials of one segment on ``grid``, split where it leaves the model's range.

    rud and rpm are None for a craft commanded per thruster, whose channels come in ``chan``
    (role = channel name, in the channel's unit after the map's unit and sign).
    """
    # ENU map / FLU base_link (REP-103/105) -> MMG: x_E = y_map, y_E = x_map, psi = pi/2 - yaw
    x = np.interp(grid, kin.t_pos, kin.north)
    y = np.interp(grid, kin.t_pos, kin.east)
    psi = frames.enu_yaw_to_psi(np.interp(grid, kin.t_yaw, kin.yaw))
    u = np.interp(grid, kin.t_vel, kin.u_flu)
    v = -np.interp(grid, kin.t_vel, kin.v_flu)
    r = -np.interp(grid, kin.t_rate, kin.wz)
    states = np.column_stack([x, y, psi, u, v, r])
    if rpm is None:   # per thruster: no propeller to split astern by (keep_astern is set)
        rpm_v = np.full(grid.size, np.nan)
        controls = None
    else:
        # rudder and rpm are both mapped (both None only per thruster)
        rudder = _interp(cast(Series, rud), t0_ns, grid, 0) * tm.factor('rudder')
        rpm_v = _interp(rpm, t0_ns, grid, 0) * tm.factor('rpm')
        controls = np.column_stack([rpm_v, rudder])
    channels = {ch: _interp(s, t0_ns, grid, 0) * tm.factor(ch)
                for ch, s in (chan or {}).items()}
    wind_ne = None if wind is None else _true_wind(wind, t0_ns, grid, psi, u, v)
    thrusters = None
    if thr:  # rev/s, + to starboard; a thruster not recorded is 0
        thrusters = np.column_stack([
            _interp(thr[r], t0_ns, grid, 0) * tm.factor(r) if r in thr
            else np.zeros(grid.size) for r in THRUSTER_ROLES])
    good = np.ones(grid.size, dtype=bool) if keep_astern else (rpm_v > 0) & (u > 0)
    if keep_astern:
        astern = float(np.mean((rpm_v <= 0) | (u <= 0)))
        if astern > 0:
            notes = notes + [f'astern propeller or u <= 0 kept ({100 * astern:.0f} % of '
                             'samples)']
    out = []
    k = 0
    while k < grid.size:
        if not good[k]:
            j = k
            while j < grid.size and not good[j]:
                j += 1
            what = 'rpm <= 0 (reverse or stopped propeller)' if np.any(rpm_v[k:j] <= 0) \
                else 'u <= 0 (going astern or stopped)'
            notes.append(f'{what} from t = {grid[k]:.1f} to {grid[j - 1]:.1f} s: outside the '
                         'MMG model range, left out (kept for a ship whose family covers it, '
                         'e.g. lowspeed)')
            k = j
            continue
        j = k
        while j < grid.size and good[j]:
            j += 1
        if j - k >= MIN_SAMPLES:
            out.append(Trial(grid[k:j] - grid[k], states[k:j],
                             None if controls is None else controls[k:j], name=name,
                             inputs={ch: a[k:j] for ch, a in channels.items()},
                             source=str(path), start_s=float(grid[k]),
                             wind=None if wind_ne is None else wind_ne[k:j],
                             thrusters=None if thrusters is None else thrusters[k:j],
                             notes=list(notes) + [f'resampled on dt = {tm.dt:g} s, linear '
                                                  f'interpolation; starts at {grid[k]:.2f} s '
                                                  'of the recording']))
        else:
            notes.append(f'segment {grid[k]:.1f}-{grid[j - 1]:.1f} s between the parts left '
                         f'out is shorter than {MIN_SAMPLES} samples: dropped')
        k = j
    for tr in out:  # what was left out after a trial began is said in every trial too
        tr.notes.extend(n for n in notes if n not in tr.notes)
    return out


def _interp(s: Series, t0_ns: int, grid: np.ndarray, col: int) -> np.ndarray:
    out: np.ndarray = np.interp(grid, (s.stamps_ns - t0_ns) * 1e-9, s.values[:, col])
    return out


def _true_wind(wind: Series, t0_ns: int, grid: np.ndarray, psi: np.ndarray, u: np.ndarray,
               v: np.ndarray) -> np.ndarray:
    """Measured wind on the grid as the true air velocity (north, east) [m/s]."""
    a = _interp(wind, t0_ns, grid, 0)
    b = _interp(wind, t0_ns, grid, 1)
    if wind.frame == 'true_enu':
        return np.column_stack([b, a])
    # apparent wind in FLU -> MMG body axes (y to starboard), plus the ship's velocity over
    # ground, turned to north/east
    ub = a + u
    vb = -b + v
    c, s = np.cos(psi), np.sin(psi)
    return np.column_stack([ub * c - vb * s, ub * s + vb * c])


def body_velocities_from_poses(t: np.ndarray, x: np.ndarray, y: np.ndarray, psi: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-frame u, v and yaw rate r from earth positions and heading (central differences)."""
    dx, dy, dpsi = np.gradient(x, t), np.gradient(y, t), np.gradient(psi, t)
    c, s = np.cos(psi), np.sin(psi)
    return dx * c + dy * s, -dx * s + dy * c, dpsi
