"""The one door: any path (rosbag2 dir, .mcap, .csv, MARIN .dat, or a directory of them)
-> list of trials."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from mmg_tuner.core.limits import InputLimits
from mmg_tuner.data.assemble import assemble_trials
from mmg_tuner.data.bag import read_series
from mmg_tuner.data.csv_io import csv_recording
from mmg_tuner.data.files import check_regular_file, display_text, safe_name, unique_names
from mmg_tuner.data.esso import is_esso_csv, read_esso_csv
from mmg_tuner.data.marin import read_marin_dat
from mmg_tuner.data.topics import TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError


def find_inputs(path: Path) -> list[Path]:
    """A rosbag2 directory is one input; another directory yields every bag/file inside."""
    if path.is_dir() and not (path / 'metadata.yaml').is_file():
        found = []
        for p in sorted(path.iterdir()):
            if p.is_dir() and (p / 'metadata.yaml').is_file():
                found.append(p)
            elif p.suffix in ('.mcap', '.csv', '.dat') and not p.is_dir():
                found.append(p)  # a FIFO or device among them is refused by name, not skipped
        if not found:
            raise TrialDataError(f'{path}: no rosbag2, .mcap, .csv or .dat inside')
        return found
    return [path]


def load_trials(path: str | Path, tm: TopicMap | None = None,
                time_ranges: list[tuple[float, float]] | None = None,
                keep_astern: bool = False, limits: InputLimits | None = None) -> list[Trial]:
    """Every trial in path, validated and resampled on tm.dt (see :mod:`.assemble`).

    A CSV with the FRT-DS-ESSO columns goes to :mod:`.esso` (own 0.1 s rate); keep_astern
    keeps its astern propeller and u <= 0 samples (so far only that reader honours it).

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
    for p in find_inputs(path):
        found = load_one(p, tm, keep_astern, limits)
        if time_ranges:
            found = cut_time_ranges(found, time_ranges)
        trials.extend(found)
    return unique_names(trials)


def load_many(paths: list[str | Path], tm: TopicMap | None = None,
              time_ranges: list[tuple[float, float]] | None = None,
              keep_astern: bool = False, limits: InputLimits | None = None) -> list[Trial]:
    """load_trials over several paths, with trial names unique across all of them (two
    turning.csv from different folders become folder/turning, deterministically)."""
    trials: list[Trial] = []
    for p in paths:
        trials.extend(load_trials(p, tm, time_ranges, keep_astern, limits))
    return unique_names(trials)


def load_one(p: Path, tm: TopicMap, keep_astern: bool = False,
             limits: InputLimits | None = None) -> list[Trial]:
    """The trials of one input (a rosbag2 folder, .mcap, .csv or .dat), with safe names."""
    if not p.is_dir():
        check_regular_file(p, 'trial file')
    name = safe_name(p.name if p.is_dir() else p.stem)
    if p.suffix == '.dat':
        found = [read_marin_dat(p)]
    elif p.suffix == '.csv' and is_esso_csv(p):
        found = read_esso_csv(p, keep_astern=keep_astern)
    elif p.suffix == '.csv':
        found = assemble_trials(csv_recording(p), replace(tm, odom_topic='/odom',
                                odom_type='nav_msgs/msg/Odometry', rudder_topic='/rudder_angle',
                                rudder_type='std_msgs/msg/Float64', rudder_unit='rad',
                                rudder_sign=1.0, rpm_topic='/propeller_rpm',
                                rpm_type='std_msgs/msg/Float64', rpm_unit='rpm'), name=name,
                                limits=limits)
    else:
        found = assemble_trials(read_series(p, tm), tm, name=name, limits=limits)
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

