"""What is in a recording: topics and rates, trials, detected manoeuvres, ranges, problems."""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path

from mmg_tuner.core import frames
from mmg_tuner.core.channels import TABLE
from mmg_tuner.core.limits import InputLimits
from mmg_tuner.data.assemble import assemble_trials
from mmg_tuner.data.bag import read_series
from mmg_tuner.data.files import display_text, safe_name, unique_names
from mmg_tuner.data.load import cut_at_event, find_inputs, load_one
from mmg_tuner.data.topics import TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np


def detect_maneuver(trial: Trial) -> str:
    """
    'straight', 'turning', 'pull-out', 'zigzag' or 'mixed' (e.g. random manoeuvres).

    From the rudder history and the heading change; a craft steered by azimuth thrusters (no
    rudder channel): their mean azimuth order stands for the rudder, their mean shaft speed
    for the rpm.
    """
    rud, rpm = _steer_and_speed(trial)
    psi = np.degrees(frames.unwrap(trial['psi']))
    if rud is None:   # no steering channel to read: say only whether it turned
        return 'straight' if np.ptp(psi) < 10.0 else 'mixed'
    if np.abs(rud).max() < 3.0:   # a tug turning on differential thrust is no straight run
        return 'straight' if 'rudder' in trial.inputs or np.ptp(psi) < 10.0 else 'mixed'
    on = np.abs(rud) >= 3.0
    big = rud[on]
    amp = float(np.percentile(np.abs(big), 95))   # a spike of the sensor is not an order
    # most of the time the rudder is held at one magnitude (turning, zigzag, pull-out orders).
    # Samples where the gear slews between orders count for neither side: a 35 deg zigzag at
    # 2.3 deg/s spends a third of its time slewing, a random run holds many magnitudes
    held = on & ~_slewing(trial.t, rud)
    steady = (np.count_nonzero(held) > 0
              and np.mean(np.abs(np.abs(rud[held]) - amp) < 0.15 * amp) > 0.7)
    reversals = int(np.count_nonzero(np.diff(np.sign(big)) != 0))
    if steady and reversals == 0 and abs(psi[-1] - psi[0]) >= 90.0:
        last_on = int(np.nonzero(on)[0][-1])
        if last_on < trial.t.size - 10 and abs(rud[-1]) < 3.0:
            return 'pull-out'
        return 'turning'
    # one reversal is a zigzag cut short (its first overshoot recorded); the propeller keeps
    # one ahead speed through a zigzag (berthing and random runs change it)
    mid = float(np.median(rpm))   # most of the run at one rpm: a start from rest is allowed
    one_rpm = mid > 0 and np.mean(np.abs(rpm - mid) <= 0.05 * mid) >= 0.7
    if steady and reversals >= 1 and np.ptp(psi) < 120.0 and one_rpm:
        return 'zigzag'
    return 'mixed'


def _steer_and_speed(trial: Trial) -> tuple[np.ndarray | None, np.ndarray]:
    """Return (the steering angle [deg] or None, the propulsion speed) of a trial."""
    if 'rudder' in trial.inputs and 'rpm' in trial.inputs:
        return np.degrees(trial['rudder']), trial['rpm']

    # a craft commanded channel by channel: its angles (the orders where recorded) and its
    # shaft speeds, each the mean over the actuator's channels
    from mmg_tuner.core.actuators import commanded_channels

    def mean_of(unit: str, ordered: bool) -> np.ndarray | None:
        cols = [a for n, a in trial.inputs.items() if n in TABLE and TABLE[n].unit == unit
                and (n in commanded_channels()) == ordered]
        return np.mean(cols, axis=0) if cols else None
    steer = mean_of('rad', True)
    if steer is None or not np.all(np.isfinite(steer)):
        steer = mean_of('rad', False)
    speed = mean_of('rev/s', False)
    return (None if steer is None else np.degrees(steer),
            np.zeros(len(trial)) if speed is None else speed)


def _slewing(t: np.ndarray, rud_deg: np.ndarray) -> np.ndarray:
    """Return where the rudder moves at more than half its fastest rate (1 s smoothed)."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    k = max(1, int(round(1.0 / dt)))
    # edge-padded: zeros beyond the record would read as a jump off a rudder held over
    smooth = np.convolve(np.pad(rud_deg, (k // 2, k - 1 - k // 2), mode='edge'),
                         np.ones(k) / k, mode='valid') if k > 1 else rud_deg
    rate = np.abs(np.gradient(smooth, t)) if t.size > 1 else np.zeros_like(t)
    fastest = float(np.percentile(rate, 99))
    return rate > 0.5 * fastest if fastest > 0.5 else np.zeros(t.size, bool)


@dataclass
class TrialSummary:
    name: str
    duration_s: float
    dt: float
    maneuver: str
    speed_range_ms: tuple[float, float]
    rpm_range: tuple[float, float]
    rudder_range_deg: tuple[float, float]
    notes: list[str]
    # a craft commanded per thruster: each input channel's (min, max, unit), angles in deg
    channels: dict[str, tuple[float, float, str]] = field(default_factory=dict)


@dataclass
class RecordingSummary:
    path: str
    duration_s: float = 0.0
    topics: dict[str, tuple[str, int, float]] = field(default_factory=dict)  # type, count, Hz
    trials: list[TrialSummary] = field(default_factory=list)
    error: str = ''
    # how it was read: topics found by type, pose source, datum, frames, time bases
    reading: list[str] = field(default_factory=list)


def summarize_trial(tr: Trial) -> TrialSummary:
    notes = list(tr.notes)
    if tr.wind is not None:  # the air's mean velocity -> speed and where it blows from
        n, e = tr.wind.mean(axis=0)
        notes.append(f'measured wind: mean {math.hypot(n, e):.1f} m/s from '
                     f'{math.degrees(math.atan2(-e, -n)) % 360:.0f} deg (used by the model)')
    if tr.thrusters is not None:
        lo, hi = tr.thrusters.min(axis=0), tr.thrusters.max(axis=0)
        notes.append(f'thrusters [rev/s]: bow {lo[0]:+.1f}..{hi[0]:+.1f}, stern '
                     f'{lo[1]:+.1f}..{hi[1]:+.1f} (used by a family that reads them)')
    if 'rpm' not in tr.inputs or 'rudder' not in tr.inputs:
        return TrialSummary(tr.name, tr.duration_s, tr.dt, detect_maneuver(tr),
                            (float(tr['u'].min()), float(tr['u'].max())), (math.nan,) * 2,
                            (math.nan,) * 2, notes, _channel_ranges(tr))
    return TrialSummary(
        tr.name, tr.duration_s, tr.dt, detect_maneuver(tr),
        (float(tr['u'].min()), float(tr['u'].max())),
        (float(tr['rpm'].min()), float(tr['rpm'].max())),
        (math.degrees(float(tr['rudder'].min())), math.degrees(float(tr['rudder'].max()))),
        notes)


def _channel_ranges(tr: Trial) -> dict[str, tuple[float, float, str]]:
    """Return each input channel's (min, max, unit) over the trial (radians shown in deg)."""
    out = {}
    for name, a in tr.inputs.items():
        a = a[np.isfinite(a)]
        if not a.size:
            continue
        unit = TABLE[name].unit if name in TABLE else ''
        lo, hi = float(a.min()), float(a.max())
        if unit == 'rad':
            lo, hi, unit = math.degrees(lo), math.degrees(hi), 'deg'
        out[name] = (lo, hi, unit)
    return out


def summarize(path: str | Path, tm: TopicMap, limits: InputLimits | None = None,
              keep_astern: bool = False) -> tuple[list[RecordingSummary], list[Trial]]:
    """Return what each recording in path holds (see summarize_many)."""
    return summarize_many([path], tm, limits, keep_astern)


def summarize_many(paths: list[str | Path], tm: TopicMap, limits: InputLimits | None = None,
                   keep_astern: bool = False, cut: tuple[str, float] | None = None
                   ) -> tuple[list[RecordingSummary], list[Trial]]:
    """
    Return what each recording in paths holds and the usable trials.

    What each recording in paths holds (one RecordingSummary each, a problem as its error) and the
    usable trials, read as load_trials reads them, with names unique across all. keep_astern: keep
    astern propeller and u <= 0 samples (a ship whose family covers them); cut: (event, seconds
    before it) cuts each trial there (:func:`.load.cut_at_event`).
    """
    out: list[RecordingSummary] = []
    per: list[list[Trial]] = []
    for path in paths:
        path = Path(path)
        if not path.exists():
            out.append(RecordingSummary(display_text(str(path)),
                                        error='no such file or directory'))
            per.append([])
            continue
        try:
            inputs = find_inputs(path)
        except TrialDataError as exc:
            out.append(RecordingSummary(display_text(str(path)), error=str(exc)))
            per.append([])
            continue
        for p in inputs:
            rs, found = _summarize_one(p, tm, limits, keep_astern)
            if cut is not None:
                found = cut_at_event(found, *cut)
            out.append(rs)
            per.append(found)
    trials = unique_names([t for found in per for t in found])
    for rs, found in zip(out, per):
        rs.trials = [summarize_trial(t) for t in found]
    return out, trials


def _summarize_one(p: Path, tm: TopicMap, limits: InputLimits | None,
                   keep_astern: bool = False) -> tuple[RecordingSummary, list[Trial]]:
    rs = RecordingSummary(display_text(str(p)))
    found: list[Trial] = []
    try:
        if p.is_dir() or p.suffix == '.mcap':
            rec = read_series(p, tm)
            rs.duration_s = (rec.end_ns - rec.start_ns) * 1e-9
            for topic, (typ, n) in sorted(rec.topics_found.items()):
                rate = (n - 1) / rs.duration_s if rs.duration_s > 0 and n > 1 else 0.0
                rs.topics[display_text(topic)] = (display_text(typ), n, rate)
            rs.reading = rec.reading
            found = assemble_trials(rec, tm, name=safe_name(p.name if p.is_dir() else p.stem),
                                    limits=limits, keep_astern=keep_astern)
            rs.reading = [display_text(r) for r in rec.reading]
            for tr in found:
                tr.source = display_text(tr.source)
        else:
            found = load_one(p, tm, keep_astern, limits)
        if not rs.duration_s and found:
            rs.duration_s = sum(t.duration_s for t in found)
    except TrialDataError as exc:
        rs.error = str(exc)
        found = []
    return rs, found


def format_summary(rs: RecordingSummary) -> str:
    lines = [f'{rs.path}', f'  duration: {rs.duration_s:.1f} s']
    if rs.topics:
        lines.append('  topics:')
        for topic, (typ, n, hz) in rs.topics.items():
            lines.append(f'    {topic:28s} {typ:34s} {n:8d} msgs {hz:8.2f} Hz')
    if rs.reading:
        lines.append('  read as:')
        lines.extend(f'    {r}' for r in rs.reading)
    if rs.error:
        lines.append(f'  PROBLEM: {rs.error}')
    for ts in rs.trials:
        if ts.channels:   # a craft commanded per thruster: its own channels
            lines.append(f'  trial {ts.name}: {ts.maneuver}, {ts.duration_s:.1f} s at dt '
                         f'{ts.dt:g} s, u {ts.speed_range_ms[0]:.2f}..{ts.speed_range_ms[1]:.2f}'
                         ' m/s, ' + ', '.join(f'{n} {lo:+.1f}..{hi:+.1f} {u}'
                                              for n, (lo, hi, u) in ts.channels.items()))
            lines.extend(f'    - {n}' for n in ts.notes if n not in rs.reading)
            continue
        lines.append(f'  trial {ts.name}: {ts.maneuver}, {ts.duration_s:.1f} s at dt {ts.dt:g} s,'
                     f' u {ts.speed_range_ms[0]:.2f}..{ts.speed_range_ms[1]:.2f} m/s, rpm '
                     f'{ts.rpm_range[0]:.1f}..{ts.rpm_range[1]:.1f}, rudder '
                     f'{ts.rudder_range_deg[0]:+.1f}..{ts.rudder_range_deg[1]:+.1f} deg')
        for note in ts.notes:
            if note not in rs.reading:  # said once for the recording above
                lines.append(f'    - {note}')
    return '\n'.join(lines)
