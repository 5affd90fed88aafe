"""CSV trials: header row t,x,y,psi,u,v,r,rpm,rudder, model frame, SI units, radians; optional
wind_n,wind_e: measured true wind as the air's velocity north/east [m/s]."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from mmg_tuner._atomic import write_atomic
from mmg_tuner.data.trial import CSV_COLUMNS, Trial
from mmg_tuner.errors import TrialDataError


WIND_COLUMNS = ('wind_n', 'wind_e')


def csv_text(t: np.ndarray, states: np.ndarray, controls: np.ndarray,
             wind: np.ndarray | None = None) -> str:
    buf = io.StringIO()
    cols = [t, states, controls] + ([] if wind is None else [wind])
    header = CSV_COLUMNS + (() if wind is None else WIND_COLUMNS)
    np.savetxt(buf, np.column_stack(cols), delimiter=',', header=','.join(header), comments='',
               fmt='%.10g')
    return buf.getvalue()


def write_trial_csv(trial: Trial, path: str | Path) -> None:
    write_atomic(path, csv_text(trial.t, trial.states, trial.controls, trial.wind))


def read_trial_csv(path: str | Path) -> Trial:
    """Read a CSV with a header naming at least t,x,y,psi,u,v,r,rpm,rudder (any order)."""
    path = Path(path)
    try:
        with open(path) as f:
            header = f.readline().strip().split(',')
            data = np.loadtxt(f, delimiter=',', ndmin=2)
    except (OSError, ValueError) as exc:
        raise TrialDataError(f'{path}: cannot read CSV ({exc})') from None
    header = [h.strip().lower() for h in header]
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise TrialDataError(f'{path}: missing columns {missing} (header: {header})')
    if data.shape[0] < 2:
        raise TrialDataError(f'{path}: fewer than 2 rows of data')
    col = {c: data[:, header.index(c)] for c in CSV_COLUMNS}
    wind = None
    if all(c in header for c in WIND_COLUMNS):
        wind = np.column_stack([data[:, header.index(c)] for c in WIND_COLUMNS])
    return Trial(col['t'], np.column_stack([col[c] for c in CSV_COLUMNS[1:7]]),
                 np.column_stack([col['rpm'], col['rudder']]), name=path.stem, source=str(path),
                 wind=wind)


def csv_recording(path: str | Path):
    """A model-frame CSV as a raw recording (ENU/FLU series), so that it passes through the
    same validation, repair and resampling as a bag."""
    from mmg_tuner.data.bag import RawRecording, Series
    path = Path(path)
    try:
        with open(path) as f:
            header = [h.strip().lower() for h in f.readline().strip().split(',')]
            data = np.genfromtxt(f, delimiter=',', ndmin=2, invalid_raise=False)
    except (OSError, ValueError) as exc:
        raise TrialDataError(f'{path}: cannot read CSV ({exc})') from None
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise TrialDataError(f'{path}: missing columns {missing} (header: {header})')
    if data.ndim != 2 or data.shape[0] < 2 or data.shape[1] != len(header):
        raise TrialDataError(f'{path}: fewer than 2 complete rows of {len(header)} columns')
    col = {c: data[:, header.index(c)] for c in CSV_COLUMNS}
    if not np.all(np.isfinite(col['t'])):
        k = int(np.argmax(~np.isfinite(col['t'])))
        raise TrialDataError(f'{path}: non-finite time in data row {k + 1}')
    ns = np.round(col['t'] * 1e9).astype(np.int64)
    odom = np.column_stack([col['y'], col['x'], np.pi / 2 - col['psi'], col['u'], -col['v'],
                            -col['r']])
    series = {
        'odom': Series('/odom', 'nav_msgs/msg/Odometry', ns, odom, ns),
        'rudder': Series('/rudder_angle', 'std_msgs/msg/Float64', ns,
                                col['rudder'][:, None], ns),
        'rpm': Series('/propeller_rpm', 'std_msgs/msg/Float64', ns,
                                 col['rpm'][:, None], ns),
    }
    if all(c in header for c in WIND_COLUMNS):  # as true wind in ENU: (east, north)
        enu = np.column_stack([data[:, header.index('wind_e')], data[:, header.index('wind_n')]])
        series['wind'] = Series('/wind', 'geometry_msgs/msg/Vector3Stamped', ns, enu, ns,
                                frame='true_enu')
    return RawRecording(str(path), series, {v.topic: (v.msgtype, len(ns))
                                            for v in series.values()},
                        int(ns.min()), int(ns.max()))
