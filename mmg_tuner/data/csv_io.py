"""
CSV trials: a header row, model frame, SI units, radians.

CSV trials: header row t,x,y,psi,u,v,r,rpm,rudder, model frame, SI units, radians; optional
wind_n,wind_e: measured true wind as the air's velocity north/east [m/s]; optional
bow_thruster,stern_thruster: thruster speeds [rev/s], + pushes the ship to starboard (one alone:
the other is 0).

A trial of another actuator (no rpm and rudder columns) is a *channel CSV*: t,x,y,psi,u,v,r and
its input channels by their names (``core/channels.TABLE``, units there), e.g. the twin-azimuth
tug's n_port,n_stbd,azimuth_port,azimuth_stbd[,azimuth_cmd_port,azimuth_cmd_stbd]. It is read
at its own (uniform) rate, like a MARIN .dat: :func:`read_channel_csv`. Whether it has the
channels a ship needs is checked where a ship meets it (a missing one is named then).
"""
from __future__ import annotations

import io
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING
import warnings

from mmg_tuner._atomic import write_atomic
from mmg_tuner._limits import check_lines
from mmg_tuner.core import frames
from mmg_tuner.core.channels import TABLE
from mmg_tuner.data.files import brief, check_regular_file, display_text, safe_name
from mmg_tuner.data.trial import CSV_COLUMNS, STATE_COLUMNS, Trial
from mmg_tuner.errors import TrialDataError
import numpy as np

if TYPE_CHECKING:   # the reader of bags imports this module
    from mmg_tuner.data.bag import RawRecording


logger = logging.getLogger(__name__)
WIND_COLUMNS = ('wind_n', 'wind_e')
THRUSTER_COLUMNS = ('bow_thruster', 'stern_thruster')  # rev/s, the channels' own names
# what the notes name for each role of a CSV read as a recording: its columns, not the topics
# a bag would have (a CSV has no /odom)
CSV_FIELDS = {'odom': 'columns x, y, psi, u, v, r', 'rudder': 'column rudder',
              'rpm': 'column rpm', 'wind': 'columns wind_n, wind_e',
              **{c: f'column {c}' for c in THRUSTER_COLUMNS}}


def csv_text(t: np.ndarray, states: np.ndarray, controls: np.ndarray,
             wind: np.ndarray | None = None, thrusters: np.ndarray | None = None) -> str:
    """Return a trial's samples as CSV text (see the module docstring for the columns)."""
    buf = io.StringIO()
    cols = [t, states, controls] + ([] if wind is None else [wind]) + \
        ([] if thrusters is None else [thrusters])
    header = CSV_COLUMNS + (() if wind is None else WIND_COLUMNS) + \
        (() if thrusters is None else THRUSTER_COLUMNS)
    np.savetxt(buf, np.column_stack(cols), delimiter=',', header=','.join(header), comments='',
               fmt='%.10g')
    return buf.getvalue()


def trial_csv_text(trial: Trial) -> str:
    """
    Return csv_text of a trial, with its measured wind and thrusters when it has them.

    A trial without rpm and rudder (another actuator's) is written as a channel CSV: the states,
    then each of its input channels under its own name.
    """
    if not all(c in trial.inputs for c in CSV_COLUMNS[7:]):
        return channel_csv_text(trial)
    return csv_text(trial.t, trial.states, trial.controls, trial.wind, trial.thrusters)


def channel_csv_text(trial: Trial) -> str:
    """Return a trial as a channel CSV: t, the states, every input channel by name."""
    names = tuple(trial.inputs)
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([trial.t, trial.states] + [trial.inputs[n] for n in names]),
               delimiter=',', header=','.join(STATE_COLUMNS + names), comments='',
               fmt='%.10g')
    return buf.getvalue()


def write_trial_csv(trial: Trial, path: str | Path) -> None:
    write_atomic(path, trial_csv_text(trial))


def _thruster_columns(header: list[str], data: np.ndarray) -> np.ndarray | None:
    """
    Return the (T, 2) bow and stern thruster [rev/s] of a CSV table.

    A missing column is 0; None when the file has neither.
    """
    if not any(c in header for c in THRUSTER_COLUMNS):
        return None
    return np.column_stack([data[:, header.index(c)] if c in header else np.zeros(len(data))
                            for c in THRUSTER_COLUMNS])


MAX_CSV_BYTES = 1 << 30  # 1 GiB: a day of 50 Hz samples is ~0.5 GB; more is not one trial
MAX_CSV_ROWS = 20_000_000
MAX_TIME_S = 1e10  # ~300 years: a larger time is no trial time (and overflows int64 ns)


def read_csv_table(path: str | Path) -> tuple[list[str], np.ndarray, list[str]]:
    """
    (lower-case header, data (rows, columns), notes) of a CSV trial file.

    Only a regular file of at most MAX_CSV_BYTES is read; a UTF-8 byte-order mark is skipped;
    rows with a wrong number of fields are dropped with a note, as are rows whose time (column
    't') is not a number; other non-numeric fields become NaN (dropped later, with a note).
    """
    path = Path(path)
    size = check_regular_file(path, 'CSV file', MAX_CSV_BYTES)
    try:
        with open(path, 'rb') as f:   # not a buffer of the limit's size for a small file
            raw = f.read(min(size, MAX_CSV_BYTES) + 1)
        text = raw.decode('utf-8-sig')
    except OSError as exc:
        raise TrialDataError(f'{path}: cannot read CSV ({exc.strerror or exc})') from None
    except UnicodeDecodeError as exc:
        raise TrialDataError(f'{path}: not UTF-8 text (byte {exc.start}): not a CSV '
                             'trial') from None
    if len(raw) > MAX_CSV_BYTES:
        raise TrialDataError(f'{path}: more than {MAX_CSV_BYTES / 1e6:.0f} MB: not one trial')
    lines = text.splitlines()
    if not lines:
        raise TrialDataError(f'{path}: empty file, no CSV header')
    check_lines(lines, path, 'CSV trial', error=TrialDataError)   # before any line is split
    header = [h.strip().strip('"').strip().lower() for h in lines[0].split(',')]
    for k, h in enumerate(header):   # which of two 'u' columns is the speed? never guess
        if h and h in header[:k]:
            raise TrialDataError(f'{path}: column {h!r} appears twice in the header (columns '
                                 f'{header.index(h) + 1} and {k + 1}, names compared without '
                                 'case); rename or remove one')
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing and not (set(STATE_COLUMNS) <= set(header) and is_channel_header(header)):
        raise TrialDataError(f'{path}: missing columns {missing} (header: {header})')
    rows = [(k, ln) for k, ln in enumerate(lines[1:], 1) if ln.strip()]
    if len(rows) > MAX_CSV_ROWS:
        raise TrialDataError(f'{path}: {len(rows)} rows, more than the {MAX_CSV_ROWS} a trial '
                             'may have')
    notes = []
    good = [(k, ln) for k, ln in rows if ln.count(',') == len(header) - 1]
    if len(good) < len(rows):
        bad = [k for k, ln in rows if ln.count(',') != len(header) - 1]
        notes.append(f'{path.name}: dropped {len(bad)} row(s) without {len(header)} fields, '
                     f'first data row {bad[0]}')
    body = [ln for _, ln in good]
    data = np.empty((0, len(header)))
    if body:
        try:
            data = np.loadtxt(body, delimiter=',', ndmin=2, dtype=float)
        except ValueError:  # empty or non-numeric fields: NaN there, dropped with a note later
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                data = np.genfromtxt(body, delimiter=',', ndmin=2, dtype=float)
        data = data.reshape(len(body), len(header))
    t = data[:, header.index('t')]
    with np.errstate(invalid='ignore'):
        bad_t = ~(np.abs(t) <= MAX_TIME_S)
    if bad_t.any():
        idx = [good[k][0] for k in np.nonzero(bad_t)[0]]
        notes.append(f'{path.name}: dropped {len(idx)} row(s) whose time t is not a number '
                     f'(or beyond {MAX_TIME_S:.0e} s), first data row {idx[0]}')
        data = data[~bad_t]
    if data.shape[0] < 2:
        raise TrialDataError(f'{path}: fewer than 2 complete rows of {len(header)} columns'
                             + (f' ({brief(notes)})' if notes else ''))
    for w in unit_warnings(header, data):   # read as it is: the user decides
        logger.warning('WARNING: %s: %s', display_text(str(path)), w)
    return header, data, notes


# ----------------------------------------------------------------- unit sanity (issue 28)
# The values say which unit a column is in, checked against the format's (s, rad, rad/s):
# positions in metres move at the speed u, v give whatever t's unit; the course over ground
# (from the track, radians whatever the file says) turns with the heading; the heading turns
# as the yaw rate integrates. The bands are wide: 180/pi or 1000 apart, never near 1.
_DEG_BAND = (25.0, 120.0)         # a ratio here is 180/pi = 57.3: degrees for radians
_RAD_BAND = (0.5, 2.0)            # a ratio here: the same unit


def _slope(a: np.ndarray, b: np.ndarray) -> tuple[float, float] | None:
    """Return (k, misfit) of a ~ k b, both centred; misfit: rms(a - k b) / rms(a)."""
    a, b = a - a.mean(), b - b.mean()
    aa, bb = float(a @ a), float(b @ b)
    if not (aa > 0 and bb > 0):
        return None
    k = float(a @ b) / bb
    return k, math.sqrt(float(((a - k * b) ** 2).sum()) / aa)


def _heading_unit(psi: np.ndarray, x: np.ndarray, y: np.ndarray, u: np.ndarray
                  ) -> tuple[bool | None, np.ndarray, str]:
    """
    Return (degrees? (None: cannot tell), the heading unwrapped, the evidence) of column psi.

    A heading wrapping at 360 is in degrees; else one turning 57 times as far as the course
    over ground (chords of the track ten times longer than its noise, ahead motion only) is.
    """
    steps, top = np.abs(np.diff(psi)), float(np.max(np.abs(psi)))
    if top <= 361 and np.any((steps > 300) & (steps < 420)):
        return True, np.unwrap(psi, period=360.0), 'it wraps at 360'
    if top <= 2 * math.pi + 0.1 and np.any((steps > 5.5) & (steps < 7.0)):
        return False, np.unwrap(psi), ''
    if not np.mean(u > 0.05) > 0.9:   # astern or stopped: the course says nothing
        return None, psi, ''
    noise = math.sqrt((np.var(np.diff(x, 2)) + np.var(np.diff(y, 2))) / 12)   # [m], 1 sigma
    for m in {max(1, len(psi) // k): None for k in (100, 50, 25, 12)}:   # shortest first
        dx, dy = x[m:] - x[:-m], y[m:] - y[:-m]
        if np.quantile(np.hypot(dx, dy), 0.1) > 10 * noise:
            break
    else:
        return None, psi, ''
    course = np.unwrap(np.arctan2(dy, dx))
    fit = _slope(psi[m // 2: m // 2 + len(course)], course)
    # the drift angle comes and goes (a zigzag's misfit reaches 0.5): the ratio still tells
    if np.ptp(course) < 0.5 or fit is None or fit[1] > 0.6:
        return None, psi, ''
    k = fit[0]
    if _DEG_BAND[0] <= k <= _DEG_BAND[1]:
        return True, psi, f'it turns {k:.0f} times as far as the track does'
    return (False, psi, '') if _RAD_BAND[0] <= k <= _RAD_BAND[1] else (None, psi, '')


def unit_warnings(header: list[str], data: np.ndarray) -> list[str]:
    """
    Return what the values say about a column given in another unit than the format's.

    t in milliseconds, psi in degrees, r in deg/s, rudder in degrees, each with the fix; empty
    when nothing looks wrong (or too little moves to tell). Rows with a non-finite field are
    left out.
    """
    names = ('t', 'x', 'y', 'psi', 'u', 'v', 'r', 'rudder')
    cols = np.column_stack([data[:, header.index(c)] if c in header else np.zeros(len(data))
                            for c in names])   # a channel CSV has no rudder: 0 says nothing
    cols = cols[np.all(np.isfinite(cols), axis=1)]
    if len(cols) < 20:
        return []
    t, x, y, psi, u, v, r, rudder = cols[np.argsort(cols[:, 0], kind='stable')].T
    out = []
    m = max(1, len(t) // 100)   # chords of 1 % of the trial: clear of position noise
    dt = np.diff(t)
    dt_med = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 0.0
    speed, span = float(np.median(np.hypot(u, v))), t[m:] - t[:-m]
    seconds = 1.0
    if speed > 0.05 and dt_med >= 5 and np.any(span > 0):
        moved = float(np.median(np.hypot(x[m:] - x[:-m], y[m:] - y[:-m])[span > 0]
                                / span[span > 0]))
        if moved < 0.02 * speed:
            seconds = 1e-3
            out.append(f"column 't': samples {dt_med:g} apart, and the positions move "
                       f'{speed / max(moved, 1e-300):.0f} times slower than u, v say: t looks '
                       'like milliseconds; the format wants seconds (divide t by 1000)')
    top = float(np.max(np.abs(rudder)))
    if 1.2 < top <= 45:
        out.append(f"column 'rudder': up to {top:g}, more than any rudder turns in radians "
                   '(1.2 rad = 69 deg): it looks like degrees; the format wants radians '
                   '(multiply by pi/180)')
    deg, psi_u, why = _heading_unit(psi, x, y, u)
    if deg:
        out.append(f"column 'psi': {why}: it looks like degrees; the format wants radians "
                   '(multiply by pi/180)')
    heading = psi_u / (180 / math.pi) if deg else psi_u
    turned = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t) * seconds)])
    fit = _slope(heading, turned)
    if fit is not None and fit[1] < 0.3 and np.ptp(heading) > 0.2 and np.ptp(turned) > 0:
        k = fit[0]
        if k > 0 and _DEG_BAND[0] <= 1 / k <= _DEG_BAND[1]:
            out.append(f"column 'r': the heading turns {1 / k:.0f} times less than r "
                       'integrates to: r looks like deg/s; the format wants rad/s (multiply by '
                       'pi/180)')
        elif deg is None and _DEG_BAND[0] <= k <= _DEG_BAND[1]:
            out.append(f"column 'psi': it turns {k:.0f} times as far as r integrates to: it "
                       'looks like degrees; the format wants radians (multiply by pi/180)')
    return out


def read_trial_csv(path: str | Path) -> Trial:
    """
    Read a CSV with a header naming at least t,x,y,psi,u,v,r,rpm,rudder (any order).

    As it stands (no resampling or repair beyond read_csv_table's; see csv_recording for that).
    """
    path = Path(path)
    header, data, notes = read_csv_table(path)
    if is_channel_header(header):
        return read_channel_csv(path)
    col = {c: data[:, header.index(c)] for c in CSV_COLUMNS}
    wind = None
    if all(c in header for c in WIND_COLUMNS):
        wind = np.column_stack([data[:, header.index(c)] for c in WIND_COLUMNS])
    return Trial(col['t'], np.column_stack([col[c] for c in CSV_COLUMNS[1:7]]),
                 np.column_stack([col['rpm'], col['rudder']]), name=safe_name(path.stem),
                 source=display_text(str(path)), wind=wind,
                 thrusters=_thruster_columns(header, data), notes=notes)


def is_channel_header(header: list[str]) -> bool:
    """Whether a CSV header is a channel CSV's: no rpm and rudder, another known channel."""
    return (not all(c in header for c in CSV_COLUMNS[7:])
            and any(h in TABLE for h in header if h not in CSV_COLUMNS))


def is_channel_csv(path: str | Path) -> bool:
    """Whether the file's header row is a channel CSV's (see the module docstring)."""
    try:
        with open(path, 'rb') as f:
            first = f.readline(100_000).decode('utf-8-sig', errors='replace')
    except OSError:
        return False
    return is_channel_header([h.strip().strip('"').strip().lower() for h in first.split(',')])


UNIFORM_TOL = 0.01   # a sample interval off the median by more than 1 %: not a uniform grid


def read_channel_csv(path: str | Path) -> Trial:
    """
    Read a channel CSV (module docstring) as a trial on its own uniform time grid.

    Every column named like a known input channel becomes that channel; other columns are
    ignored with a note. Refused, naming the column and time: a non-uniform or decreasing time
    column, a non-finite state, a non-finite command in a channel that must be recorded (only
    channels whose default is "not recorded", e.g. an azimuth command, may hold NaN).
    """
    path = Path(path)
    header, data, notes = read_csv_table(path)
    where = display_text(str(path))
    t = data[:, header.index('t')]
    dt = np.diff(t)
    med = float(np.median(dt))
    if not med > 0 or np.any(np.abs(dt - med) > UNIFORM_TOL * med):
        k = int(np.argmax(np.abs(dt - med))) if med > 0 else 0
        raise TrialDataError(f'{where}: column t is not a uniform increasing grid (median step '
                             f'{med:g} s, step {dt[k]:g} s at t = {t[k]:g} s); a channel CSV is '
                             'read at its own rate: resample it first')
    states = np.column_stack([data[:, header.index(c)] for c in STATE_COLUMNS[1:]])
    bad = ~np.all(np.isfinite(states), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        col = STATE_COLUMNS[1 + int(np.argmax(~np.isfinite(states[k])))]
        raise TrialDataError(f'{where}: column {col} is not a finite number at t = {t[k]:g} s')
    inputs = {}
    for h in header:
        if h in STATE_COLUMNS or h not in TABLE:
            continue
        a = data[:, header.index(h)]
        ch = TABLE[h]
        optional = ch.default is not None and ch.default != ch.default
        bad = ~np.isfinite(a) if not optional else np.isinf(a)
        if bad.any():
            k = int(np.argmax(bad))
            raise TrialDataError(f'{where}: column {h} ({ch.description} [{ch.unit}]) is '
                                 f'{a[k]} at t = {t[k]:g} s')
        inputs[h] = a
    ignored = [h for h in header if h not in STATE_COLUMNS and h not in TABLE]
    if ignored:
        notes.append(f'{path.name}: columns {", ".join(ignored)} are no known channel: ignored')
    return Trial(t - t[0], states, name=safe_name(path.stem), source=where, notes=notes,
                 start_s=float(t[0]), inputs=inputs)


def csv_recording(path: str | Path) -> RawRecording:
    """
    Return a model-frame CSV as a raw recording (ENU/FLU series).

    So that it passes through the same validation, repair and resampling as a bag.
    """
    from mmg_tuner.data.bag import RawRecording, Series
    path = Path(path)
    header, data, notes = read_csv_table(path)
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:   # a channel CSV: read_channel_csv reads it, not the bag-like path
        raise TrialDataError(f'{path}: missing columns {missing} (header: {header})')
    col = {c: data[:, header.index(c)] for c in CSV_COLUMNS}
    ns = np.round(col['t'] * 1e9).astype(np.int64)
    odom = np.column_stack([col['y'], col['x'], frames.psi_to_enu_yaw(col['psi']), col['u'],
                            -col['v'], -col['r']])
    series = {
        'odom': Series(CSV_FIELDS['odom'], 'nav_msgs/msg/Odometry', ns, odom, ns),
        'rudder': Series(CSV_FIELDS['rudder'], 'std_msgs/msg/Float64', ns,
                         col['rudder'][:, None], ns),
        'rpm': Series(CSV_FIELDS['rpm'], 'std_msgs/msg/Float64', ns, col['rpm'][:, None], ns),
    }
    if all(c in header for c in WIND_COLUMNS):  # as true wind in ENU: (east, north)
        enu = np.column_stack([data[:, header.index('wind_e')], data[:, header.index('wind_n')]])
        series['wind'] = Series(CSV_FIELDS['wind'], 'geometry_msgs/msg/Vector3Stamped', ns,
                                enu, ns, frame='true_enu')
    for c in THRUSTER_COLUMNS:  # rev/s, read as the default thruster topics (unit rps)
        if c in header:
            series[c] = Series(CSV_FIELDS[c], 'std_msgs/msg/Float64', ns,
                               data[:, header.index(c)][:, None], ns)
    return RawRecording(str(path), series, {v.topic: (v.msgtype, len(ns))
                                            for v in series.values()},
                        int(ns.min()), int(ns.max()), notes)
