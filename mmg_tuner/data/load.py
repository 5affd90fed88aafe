"""
The one door: any path -> list of trials.

The one door: any path (rosbag2 dir, .mcap, .csv, MARIN .dat, or a folder of them, searched
recursively) -> list of trials.
"""
from __future__ import annotations

from dataclasses import replace
import functools
import logging
import math
from pathlib import Path

from mmg_tuner.core.limits import InputLimits
from mmg_tuner.data.assemble import assemble_trials
from mmg_tuner.data.bag import IncompleteMcapError, read_series
from mmg_tuner.data.consistency import checked_parts, UnusableRecordingError
from mmg_tuner.data.csv_io import CSV_FIELDS, csv_recording, is_channel_csv, read_channel_csv
from mmg_tuner.data.esso import cut_from_event, EVENTS, is_esso_csv, read_esso_csv
from mmg_tuner.data.files import check_regular_file, display_text, safe_name, unique_names
from mmg_tuner.data.marin import read_marin_dat
from mmg_tuner.data.topics import recorded_units, TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, TrialDataError
import numpy as np

TRIAL_SUFFIXES = ('.mcap', '.csv', '.dat')
MAX_DEPTH = 8  # folders below the one given; deeper is not a data set layout
logger = logging.getLogger(__name__)


def _is_bag(p: Path) -> bool:
    return p.is_dir() and (p / 'metadata.yaml').is_file()


def find_inputs(path: Path) -> list[Path]:
    """
    Return the trial inputs in path.

    A rosbag2 folder is one input; another folder is searched recursively (sorted by name at
    every level, so the order is deterministic) for rosbag2 folders and .mcap, .csv and .dat
    files.

    Skipped: names starting with '.', files of other suffixes (README.md, LICENSE), folders
    reached through a symbolic link (no loops) and, below the folder given, ``generate``'s
    CSV copies: a NAME.csv whose folder's parent holds the rosbag2 folder NAME (the same
    trial twice). A FIFO or device with a trial suffix is refused by name, not skipped.
    """
    if not path.is_dir() or _is_bag(path):
        return [path]
    found: list[Path] = []

    def walk(folder: Path, depth: int) -> None:
        try:
            entries = sorted(folder.iterdir(), key=lambda q: q.name)
        except OSError as exc:
            raise TrialDataError(f'{folder}: cannot list folder ({exc.strerror or exc})'
                                 ) from None
        for p in entries:
            if p.name.startswith('.'):
                continue
            if _is_bag(p):
                found.append(p)
            elif p.is_dir():
                if not p.is_symlink() and depth < MAX_DEPTH:
                    walk(p, depth + 1)
            elif p.suffix in TRIAL_SUFFIXES:
                if depth > 0 and p.suffix == '.csv' and _is_bag(folder.parent / p.stem):
                    continue  # generate's CSV copy of the bag folder.parent/NAME
                found.append(p)

    walk(path, 0)
    if not found:
        raise TrialDataError(f'{path}: no rosbag2, .mcap, .csv or .dat inside (searched '
                             'its subfolders too)')
    return found


def parse_event_cut(text: str) -> tuple[str, float]:
    """
    Parse a cut at an event.

    'EVENT' or 'EVENT:BEFORE_S' (e.g. 'rudder_first_over:5') -> (event, seconds kept before
    it, default 5); anything else is a ConfigError naming the events.
    """
    event, _, before = str(text).partition(':')
    event = event.strip()
    if event not in EVENTS:
        raise ConfigError(f'cut event {text!r}: the event must be one of {list(EVENTS)}, '
                          'optionally with :SECONDS kept before it (e.g. rudder_first_over:5)')
    try:
        before_s = float(before) if before.strip() else 5.0
    except ValueError:
        before_s = math.nan
    if not (math.isfinite(before_s) and 0 <= before_s <= 1e6):
        raise ConfigError(f'cut event {text!r}: the seconds kept before the event must be a '
                          'finite number in [0, 1e6]')
    return event, before_s


def cut_at_event(trials: list[Trial], event: str, before_s: float = 5.0) -> list[Trial]:
    """
    Cut each trial from before_s seconds before event (:func:`.esso.cut_from_event`).

    A trial in which the event does not occur is kept whole, with a note saying so.
    """
    out = []
    for tr in trials:
        try:
            out.append(cut_from_event(tr, event, before_s))
        except TrialDataError as exc:
            tr.notes.append(f'not cut: {exc}; kept whole')
            out.append(tr)
    return out


def load_trials(path: str | Path, tm: TopicMap | None = None,
                time_ranges: list[tuple[float, float]] | None = None,
                keep_astern: bool = False, limits: InputLimits | None = None) -> list[Trial]:
    """
    Return every trial in path, validated and resampled on tm.dt.

    Every trial in path (a folder: searched recursively, see :func:`find_inputs`), validated and
    resampled on tm.dt (see :mod:`.assemble`).

    A CSV with the FRT-DS-ESSO columns goes to :mod:`.esso` (own 0.1 s rate). keep_astern
    keeps astern propeller and u <= 0 samples (for a family that covers them), in every
    format; by default they are left out with a note.

    A CSV (model frame) passes through the same checks as a bag; a MARIN .dat is read at its
    own 0.135 s rate, full scale. time_ranges (seconds from each recording's start) cut
    several trials out of one long recording. limits (core.limits.input_limits(ship)): samples
    the ship cannot show are dropped with a note (default: generic limits, see assemble).
    Trial names are printable UTF-8 and unique within the call (see :func:`load_many` for
    several paths).
    """
    tm = tm or TopicMap()
    path = Path(path)
    if not path.exists():
        raise TrialDataError(f'{path}: no such file or directory')
    trials: list[Trial] = []
    inputs = find_inputs(path)
    skipped: list[TrialDataError] = []
    for p in inputs:
        try:
            found = load_one(p, tm, keep_astern, limits)
        except (IncompleteMcapError, UnusableRecordingError) as exc:
            if inputs == [path]:   # the file (or bag) asked for: its error
                raise
            # one recorder that stopped at once must not cost the whole folder
            logger.warning('WARNING: %s; skipped, reading the other files of %s', exc,
                           display_text(str(path)))
            skipped.append(exc)
            continue
        if time_ranges:
            found = cut_time_ranges(found, time_ranges)
        trials.extend(found)
    if skipped and not trials:
        raise skipped[0]
    return unique_names(drop_repeats(trials))


def load_many(paths: list[str | Path], tm: TopicMap | None = None,
              time_ranges: list[tuple[float, float]] | None = None,
              keep_astern: bool = False, limits: InputLimits | None = None) -> list[Trial]:
    """
    load_trials over several paths.

    With trial names unique across all of them (two turning.csv from different folders become
    folder/turning, deterministically).
    """
    trials: list[Trial] = []
    for p in paths:
        trials.extend(load_trials(p, tm, time_ranges, keep_astern, limits))
    return unique_names(drop_repeats(trials))


def _same_data(a: Trial, b: Trial) -> bool:
    """Whether two trials hold the same samples (to the 10 digits a written CSV keeps)."""
    if a.t.shape != b.t.shape or a.states.shape != b.states.shape or \
            set(a.inputs) != set(b.inputs):
        return False
    same = functools.partial(np.allclose, rtol=1e-7, atol=1e-7, equal_nan=True)
    return same(a.t, b.t) and same(a.states, b.states) and all(
        np.shape(a.inputs[k]) == np.shape(b.inputs[k]) and same(a.inputs[k], b.inputs[k])
        for k in a.inputs)


def drop_repeats(trials: list[Trial]) -> list[Trial]:
    """
    Keep the first of trials that hold the same data under two names, with a WARNING.

    ``inspect bags --csv out`` then ``tune bags out`` reads every trial twice (the recording
    and its CSV); tuned twice it would count double. Compared by samples (time, states and
    inputs, to 1e-7), not by name or file.
    """
    kept: list[Trial] = []
    groups: dict[tuple[object, ...], list[Trial]] = {}
    for tr in trials:
        key = (tr.t.shape, round(float(tr.t[0]), 6) if len(tr.t) else None)
        first = next((k for k in groups.get(key, []) if _same_data(k, tr)), None)
        if first is not None:
            logger.warning('WARNING: %s (%s) holds the same data as %s (%s): read once, as %s',
                           tr.name, display_text(tr.source or '?'), first.name,
                           display_text(first.source or '?'), first.name)
            first.notes.append(f'the same data was also given as {tr.source or tr.name}; '
                               'read once')
            continue
        groups.setdefault(key, []).append(tr)
        kept.append(tr)
    return kept


# a model-frame CSV is read in its own units and names (its columns), whatever the user's map says
def _csv_topics(tm: TopicMap) -> TopicMap:
    """Return the map a model-frame CSV is read with: its columns, in the channels' units."""
    channels = {c: replace(d, topic=CSV_FIELDS[c], msgtype='std_msgs/msg/Float64',
                           unit=next(iter(recorded_units(c))), sign=1.0)
                if c in CSV_FIELDS else d for c, d in tm.channels.items()}
    return replace(tm, odom_topic=CSV_FIELDS['odom'], odom_type='nav_msgs/msg/Odometry',
                   channels=channels)


def load_one(p: Path, tm: TopicMap, keep_astern: bool = False,
             limits: InputLimits | None = None) -> list[Trial]:
    """Return the trials of one input (a rosbag2 folder, .mcap, .csv or .dat), with safe names."""
    if not p.is_dir():
        check_regular_file(p, 'trial file')
    name = safe_name(p.name if p.is_dir() else p.stem)
    if p.suffix == '.dat':
        found = [read_marin_dat(p)]
    elif p.suffix == '.csv' and is_esso_csv(p):
        found = read_esso_csv(p, keep_astern=keep_astern,
                              length_m=limits.length_m if limits is not None else 0.0)
    elif p.suffix == '.csv' and is_channel_csv(p):   # another actuator's channels, own rate
        found = checked_parts(read_channel_csv(p),   # GNSS spikes, jumps: as a bag's
                              limits.length_m if limits is not None else 0.0)
    elif p.suffix == '.csv':
        found = assemble_trials(csv_recording(p), _csv_topics(tm), name=name,
                                limits=limits, keep_astern=keep_astern)
    else:
        found = assemble_trials(read_series(p, tm), tm, name=name, limits=limits,
                                keep_astern=keep_astern)
    for tr in found:  # a name or path that is not UTF-8 must not break a report
        tr.name = safe_name(tr.name)
        tr.source = display_text(tr.source)
    return found


def cut_time_ranges(trials: list[Trial], ranges: list[tuple[float, float]]) -> list[Trial]:
    """Trials cut to [start, end] seconds of the recording each came from."""
    out = []
    for tr in trials:
        start = tr.start_s
        for i, (a, b) in enumerate(ranges, 1):
            part = tr.slice(a - start, b - start, name=f'{tr.name}_r{i}')
            if len(part) >= 2:
                part.notes.append(f'cut to {a:g}-{b:g} s of the recording')
                part.start_s = tr.start_s + float(part.t[0])
                part.t = part.t - part.t[0]
                out.append(part)
    if not out:
        raise TrialDataError(f'no samples inside the time ranges {ranges}')
    return out
