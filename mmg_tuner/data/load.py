"""The one door: any path (rosbag2 dir, .mcap, .csv, MARIN .dat, or a directory of them)
-> list of trials."""
from __future__ import annotations

from pathlib import Path

from mmg_tuner.data.assemble import assemble_trials
from mmg_tuner.data.bag import read_series
from dataclasses import replace

from mmg_tuner.data.csv_io import csv_recording
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
            elif p.suffix in ('.mcap', '.csv', '.dat') and p.is_file():
                found.append(p)
        if not found:
            raise TrialDataError(f'{path}: no rosbag2, .mcap, .csv or .dat inside')
        return found
    return [path]


def load_trials(path: str | Path, tm: TopicMap | None = None,
                time_ranges: list[tuple[float, float]] | None = None) -> list[Trial]:
    """Every trial in path, validated and resampled on tm.dt (see :mod:`.assemble`).

    A CSV (model frame) passes through the same checks as a bag; a MARIN .dat is read at its
    own 0.135 s rate, full scale. time_ranges (seconds from each recording's start) cut
    several trials out of one long recording.
    """
    tm = tm or TopicMap()
    path = Path(path)
    if not path.exists():
        raise TrialDataError(f'{path}: no such file or directory')
    trials: list[Trial] = []
    for p in find_inputs(path):
        name = p.stem if p.is_file() else p.name
        if p.suffix == '.dat':
            trials.append(read_marin_dat(p))
            continue
        if p.suffix == '.csv':
            found = assemble_trials(csv_recording(p), replace(tm, odom_topic='/odom',
                                    odom_type='nav_msgs/msg/Odometry', rudder_topic='/rudder_angle',
                                    rudder_type='std_msgs/msg/Float64', rudder_unit='rad',
                                    rudder_sign=1.0, rpm_topic='/propeller_rpm',
                                    rpm_type='std_msgs/msg/Float64', rpm_unit='rpm'), name=name)
        else:
            found = assemble_trials(read_series(p, tm), tm, name=name)
        if time_ranges:
            found = cut_time_ranges(found, time_ranges)
        trials.extend(found)
    return trials


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

