"""The one door: any path (rosbag2 dir, .mcap, .csv, MARIN .dat, or a directory of them)
-> list of trials."""
from __future__ import annotations

from pathlib import Path

from mmg_tuner.data.assemble import assemble_trials
from mmg_tuner.data.bag import read_series
from mmg_tuner.data.csv_io import read_trial_csv
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


def load_trials(path: str | Path, tm: TopicMap | None = None) -> list[Trial]:
    tm = tm or TopicMap()
    path = Path(path)
    if not path.exists():
        raise TrialDataError(f'{path}: no such file or directory')
    trials: list[Trial] = []
    for p in find_inputs(path):
        if p.suffix == '.csv':
            trials.append(read_trial_csv(p))
        elif p.suffix == '.dat':
            trials.append(read_marin_dat(p))
        else:
            trials.extend(assemble_trials(read_series(p, tm), tm, name=p.stem if p.is_file()
                                          else p.name))
    return trials
