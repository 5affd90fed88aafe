"""
Read the FRT-DS-ESSO free-running pond tests of the Esso Osaka 3 m model.

Reader for the FRT-DS-ESSO free-running pond tests of the Esso Osaka 3 m model
(data/esso_osaka_frt, CC BY-NC-SA 4.0; see its README), and cutting trials at events.

Layout (one CSV per run, 10 Hz, header line): ``t [s]``, ``x_position_mid [m]``,
``y_position_mid [m]``, ``u_velo [m/s]``, ``vm_velo [m/s]``, ``psi_hat [rad]``,
``r_angvelo [rad/s]``, ``n_prop [rps]``, ``delta_rudder [rad]`` and optionally
``wind_velo_true [m/s]``, ``wind_dir_true [rad]`` (true wind, direction it blows FROM,
clockwise from x0) and ``wind_velo_relative_mid [m/s]``, ``wind_dir_relative_mid [rad]``
(apparent wind at midship, FROM, clockwise from the bow).

Conventions, checked on all 33 files (test/data/test_esso.py keeps the checks):
- the pond frame O0-x0y0 is the MMG earth frame: x_E = x0 ("north"), y_E = y0 ("east"),
  psi clockwise from x0. dx/dt = u cos psi - v sin psi fits to 0.03-0.19 m/s rms, the
  counter-clockwise reading is worse in every file;
- v (midship) to starboard, r clockwise, rudder + to starboard (r has the rudder's sign in
  the steady part of every turning run);
- n_prop in rps, signed (astern < 0): the Trial holds rpm = 60 n;
- the true wind becomes Trial.wind = the air's velocity over ground toward (north, east) =
  -U_T (cos zeta_T, sin zeta_T); the relative columns equal the true wind minus the ship's
  velocity to ~1e-4 m/s rms (:func:`apparent_wind`), so they are only used when the true
  ones are missing.

By default a trial keeps only rpm > 0 and u > 0, as every other reader does (the standard
and container models cannot run outside it) and says what it left out; ``keep_astern=True``
keeps the whole run for families that handle astern propeller and u <= 0 (``lowspeed``).
The data are read at their own rate (0.1 s), not resampled onto a topic map's dt.
"""
from __future__ import annotations

import io
import math
from pathlib import Path
from typing import TypedDict, Unpack
import warnings

from mmg_tuner._limits import check_lines, read_text
from mmg_tuner.core import frames
from mmg_tuner.data.consistency import (check_motion, clock_resets, keep_slices, Motion,
                                        reset_findings, split_at, unusable_reason,
                                        UnusableRecordingError, warn)
from mmg_tuner.data.csv_io import MAX_CSV_BYTES
from mmg_tuner.data.files import brief
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np

MIN_SAMPLES = 10  # as data/assemble.py: shorter pieces are dropped with a note

#: our name -> the FRT-DS-ESSO header
ESSO_COLUMNS = {
    't': 't [s]',
    'x': 'x_position_mid [m]',
    'y': 'y_position_mid [m]',
    'psi': 'psi_hat [rad]',
    'u': 'u_velo [m/s]',
    'v': 'vm_velo [m/s]',
    'r': 'r_angvelo [rad/s]',
    'n': 'n_prop [rps]',
    'delta': 'delta_rudder [rad]',
}
ESSO_WIND_TRUE = ('wind_velo_true [m/s]', 'wind_dir_true [rad]')
ESSO_WIND_REL = ('wind_velo_relative_mid [m/s]', 'wind_dir_relative_mid [rad]')
STATE_KEYS = ('x', 'y', 'psi', 'u', 'v', 'r')


def _norm(h: str) -> str:
    return ' '.join(h.strip().strip('"').lower().split())


def is_esso_header(header: list[str]) -> bool:
    """Return True when a CSV header names every required FRT-DS-ESSO column."""
    names = {_norm(h) for h in header}
    return all(c in names for c in ESSO_COLUMNS.values())


def is_esso_csv(path: str | Path) -> bool:
    """
    Return True when path is a readable CSV with an FRT-DS-ESSO header.

    True when path is a readable CSV whose first line is an FRT-DS-ESSO header (anything unreadable
    says False, so the generic CSV reader reports it).
    """
    try:
        with open(path, encoding='utf-8', errors='replace') as f:
            first = f.readline(10_000)
    except OSError:
        return False
    return is_esso_header(first.split(','))


def read_esso_table(path: str | Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """
    Return the file's columns by FRT-DS-ESSO header name, with notes.

    The file's columns by FRT-DS-ESSO header name (float arrays, NaN where a field is empty or not
    a number), rows with a non-finite value in a required column removed, and notes saying what was
    removed. Raises TrialDataError naming the file when nothing usable is left.
    """
    path = Path(path)
    # at most MAX_CSV_BYTES, lines of at most MAX_LINE_CHARS (_limits.py)
    text = read_text(path, 'FRT-DS-ESSO CSV', limit=MAX_CSV_BYTES, error=TrialDataError)
    lines = text.splitlines()
    check_lines(lines, path, 'FRT-DS-ESSO CSV', error=TrialDataError)
    if not lines or not lines[0].strip():
        raise TrialDataError(f'{path}: empty file (expected an FRT-DS-ESSO header line)')
    header = [_norm(h) for h in lines[0].split(',')]
    missing = [c for c in ESSO_COLUMNS.values() if c not in header]
    if missing:
        raise TrialDataError(f'{path}: not an FRT-DS-ESSO CSV, missing columns {missing}')
    ncol = len(header)
    notes: list[str] = []
    good, bad_lines = [], []
    for i, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        if line.count(',') != ncol - 1:
            bad_lines.append(i)
            continue
        good.append(line)
    if bad_lines:
        notes.append(f'{path.name}: {len(bad_lines)} line(s) without {ncol} fields dropped '
                     f'(cut or malformed), first at line {bad_lines[0]}')
    if not good:
        raise TrialDataError(f'{path}: no data rows after the header')
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        data = np.genfromtxt(io.StringIO('\n'.join(good)), delimiter=',', ndmin=2,
                             dtype=float, invalid_raise=False)
    if data.shape != (len(good), ncol):  # pragma: no cover - field count checked above
        raise TrialDataError(f'{path}: cannot parse the data rows (shape {data.shape})')
    cols = {h: data[:, j] for j, h in enumerate(header)}
    t = cols[ESSO_COLUMNS['t']]
    bad_t = ~np.isfinite(t)
    if bad_t.any():
        finite = np.nonzero(~bad_t)[0]
        trailing = t.size - 1 - int(finite[-1]) if finite.size else t.size
        isolated = int(bad_t.sum()) - trailing
        notes.append(f'{path.name}: {trailing} trailing and {isolated} isolated row(s) with no '
                     'time (NaN) trimmed')
    required = [cols[c] for c in ESSO_COLUMNS.values()]
    ok = np.all(np.isfinite(np.column_stack(required)), axis=1)
    other = ok != ~bad_t
    if other.any():
        k = int(np.argmax(other))
        notes.append(f'{path.name}: {int(other.sum())} row(s) with a non-finite state, '
                     f'propeller or rudder value dropped, first at t = {t[k]:.2f} s')
    cols = {h: c[ok] for h, c in cols.items()}
    if cols[ESSO_COLUMNS['t']].size < 2:
        raise TrialDataError(f'{path}: fewer than 2 complete data rows')
    return cols, notes


def apparent_wind(true_speed: np.ndarray, true_from: np.ndarray, psi: np.ndarray, u: np.ndarray,
                  v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the apparent wind at a point moving with body velocity (u, v) on heading psi.

    Apparent wind (speed [m/s], FROM-angle clockwise from the bow [rad] in [0, 2pi)) at a point
    moving with body velocity (u, v) on heading psi, from the true wind (speed, FROM-direction
    clockwise from x_E). The air's velocity relative to the ship in body axes is w = -U_T (cos(zeta
    - psi), sin(zeta - psi)) - (u, v).
    """
    wx = -true_speed * np.cos(true_from - psi) - u
    wy = -true_speed * np.sin(true_from - psi) - v
    return np.hypot(wx, wy), np.mod(np.arctan2(-wy, -wx), 2.0 * np.pi)


def true_wind_ne(true_speed: np.ndarray, true_from: np.ndarray) -> np.ndarray:
    """(T, 2) the air's velocity over ground toward north (x_E) and east (y_E) [m/s]."""
    return np.column_stack([-true_speed * np.cos(true_from), -true_speed * np.sin(true_from)])


def _wind_from_table(cols: dict[str, np.ndarray], psi: np.ndarray, u: np.ndarray, v: np.ndarray,
                     notes: list[str], name: str) -> np.ndarray | None:
    if all(c in cols for c in ESSO_WIND_TRUE):
        ne = true_wind_ne(cols[ESSO_WIND_TRUE[0]], cols[ESSO_WIND_TRUE[1]])
        what = 'true wind columns'
    elif all(c in cols for c in ESSO_WIND_REL):
        # apparent FROM-angle gamma, speed U_A: air velocity rel. to the ship in body axes
        ua, ga = cols[ESSO_WIND_REL[0]], cols[ESSO_WIND_REL[1]]
        bx, by = -ua * np.cos(ga) + u, -ua * np.sin(ga) + v
        c, s = np.cos(psi), np.sin(psi)
        ne = np.column_stack([bx * c - by * s, bx * s + by * c])
        what = 'relative wind columns plus the ship velocity (no true wind columns)'
    else:
        return None
    ok = np.all(np.isfinite(ne), axis=1)
    if not ok.any():
        notes.append(f'{name}: wind columns hold no finite value: no measured wind')
        return None
    if not ok.all():
        k = np.nonzero(ok)[0]
        notes.append(f'{name}: {int((~ok).sum())} non-finite wind sample(s) interpolated')
        idx = np.arange(ok.size)
        ne = np.column_stack([np.interp(idx, k, ne[k, i]) for i in range(2)])
    notes.append(f'{name}: measured wind from the {what}')
    return ne


def read_esso_csv(path: str | Path, keep_astern: bool = False, max_gap_s: float = 1.0,
                  dt: float | None = None, length_m: float = 0.0) -> list[Trial]:
    """
    One FRT-DS-ESSO run -> trials in the model frame (SI, rpm = 60 n, wind north/east).

    keep_astern: keep astern propeller (rpm <= 0) and u <= 0 samples (for a family that
    handles them); by default the run is split around them with a note, as every reader does.
    Gaps longer than max_gap_s split the run. dt: resampling step [s] (default the file's
    median step, 0.1 s). Every repair is in the trials' notes. The channels are checked against
    each other first (:mod:`.consistency`, length_m the ship's length, 0 if not known): a
    clock reset splits the run, a short fault is cut out, a long one leaves it unused; each is
    a WARNING line.
    """
    path = Path(path)
    name = path.stem
    cols, notes = read_esso_table(path)
    t = cols[ESSO_COLUMNS['t']]
    resets = clock_resets(t)
    if not resets.size:
        return _esso_trials(path, name, cols, notes, keep_astern, max_gap_s, dt, length_m)
    found = reset_findings(name, t, resets)
    warn(found)
    trials: list[Trial] = []
    why: list[str] = []
    for i, sl in enumerate(split_at(t.size, resets)):
        part = {h: c[sl] for h, c in cols.items()}
        try:
            trials.extend(_esso_trials(path, f'{name}_part{i + 1}', part,
                                       notes + [f.note() for f in found], keep_astern,
                                       max_gap_s, dt, length_m))
        except TrialDataError as exc:   # one stretch too short or faulty: the others count
            why.append(f'stretch {i + 1} of {resets.size + 1}: {exc}')
    if not trials:
        raise TrialDataError(f'{path}: no usable trial ({brief(why)})')
    for i, tr in enumerate(trials, 1):
        tr.name = f'{name}_{i}' if len(trials) > 1 else name
        tr.notes.extend(why)
    return trials


def _esso_trials(path: Path, name: str, cols: dict[str, np.ndarray], notes: list[str],
                 keep_astern: bool, max_gap_s: float, dt: float | None, length_m: float
                 ) -> list[Trial]:
    """Return the trials of one stretch of a run without clock resets (read_esso_csv)."""
    notes = list(notes)
    t = cols[ESSO_COLUMNS['t']]
    order = np.argsort(t, kind='stable')
    if np.any(np.diff(t) < 0):   # out of order by less than a reset: delivery, sorted
        notes.append(f'{name}: time not sorted; sorted')
        cols = {h: c[order] for h, c in cols.items()}
        t = cols[ESSO_COLUMNS['t']]
    dup = np.concatenate([[False], np.diff(t) == 0])
    if dup.any():
        notes.append(f'{name}: {int(dup.sum())} duplicate time(s) dropped, first at '
                     f't = {t[np.argmax(dup)]:.2f} s')
        cols = {h: c[~dup] for h, c in cols.items()}
        t = cols[ESSO_COLUMNS['t']]
    if t.size < 2:
        raise TrialDataError(f'{path}: fewer than 2 distinct times')
    step = float(np.median(np.diff(t))) if dt is None else float(dt)
    if not step > 0 or not math.isfinite(step):
        raise TrialDataError(f'{path}: cannot resample with dt = {step}')
    raw = {k: cols[ESSO_COLUMNS[k]] for k in ESSO_COLUMNS}
    raw['psi'] = frames.unwrap(raw['psi'])
    wind = _wind_from_table(cols, raw['psi'], raw['u'], raw['v'], notes, name)
    notes.append(f'{name}: FRT-DS-ESSO CSV, pond frame = MMG earth frame, n_prop [rps] x 60 '
                 '-> rpm')
    # the channels against each other, at the file's own samples
    findings = check_motion(name, Motion(t, raw['x'], raw['y'], raw['psi'], raw['u'],
                                         raw['v'], raw['r'], 60.0 * raw['n']), length_m)
    warn(findings)
    notes.extend(f.note() for f in findings)
    if any(f.long for f in findings):
        raise UnusableRecordingError(f'{path}: not used: {unusable_reason(findings)}')
    # segments between gaps and around the faults cut out
    gaps = np.nonzero(np.diff(t) > max_gap_s)[0]
    for gap in gaps:
        notes.append(f'{name}: gap of {t[gap + 1] - t[gap]:.1f} s at t = {t[gap]:.1f} s '
                     f'(> {max_gap_s:g} s): trial split there')
    spans: list[tuple[int, int]] = []
    for sl in keep_slices(t, findings):
        edges = [sl.start] + [int(g) + 1 for g in gaps if sl.start < g + 1 < sl.stop] + [sl.stop]
        spans.extend(zip(edges[:-1], edges[1:]))
    trials: list[Trial] = []
    for a, b in spans:
        ts = t[a:b]
        n = int(math.floor((ts[-1] - ts[0]) / step + 1e-6)) + 1   # 1e-6: float time stamps
        if n < MIN_SAMPLES:
            notes.append(f'{name}: segment {ts[0]:.1f}-{ts[-1]:.1f} s shorter than '
                         f'{MIN_SAMPLES} samples: dropped')
            continue
        grid = ts[0] + step * np.arange(n)
        if n == ts.size and np.allclose(grid, ts, rtol=0, atol=1e-6 * step):
            g = {k: raw[k][a:b] for k in raw if k != 't'}   # already uniform: values as read
            w = None if wind is None else wind[a:b]
        else:
            g = {k: np.interp(grid, ts, raw[k][a:b]) for k in raw if k != 't'}
            w = None if wind is None else np.column_stack(
                [np.interp(grid, ts, wind[a:b, i]) for i in range(2)])
        states = np.column_stack([g[k] for k in STATE_KEYS])
        controls = np.column_stack([60.0 * g['n'], g['delta']])
        good = np.ones(n, bool) if keep_astern else (controls[:, 0] > 0) & (states[:, 3] > 0)
        k = 0
        while k < n:
            j = k
            while j < n and good[j] == good[k]:
                j += 1
            if not good[k]:
                what = ('rpm <= 0 (reverse or stopped propeller)'
                        if np.any(controls[k:j, 0] <= 0) else 'u <= 0 (going astern or stopped)')
                notes.append(f'{what} from t = {grid[k]:.1f} to {grid[j - 1]:.1f} s: outside '
                             'the MMG model range, left out (keep_astern=True keeps it for the '
                             'lowspeed family)')
            elif j - k >= MIN_SAMPLES:
                trials.append(Trial(grid[k:j] - grid[k], states[k:j], controls[k:j], name=name,
                                    source=str(path), start_s=float(grid[k]),
                                    wind=None if w is None else w[k:j], notes=[]))
            k = j
    if not trials:
        raise TrialDataError(f'{path}: no usable trial ({brief(notes[-3:])})')
    for i, tr in enumerate(trials, 1):
        tr.notes = list(notes) + [f'starts at {tr.start_s:.2f} s of the recording']
        if len(trials) > 1:
            tr.name = f'{name}_{i}'
    if keep_astern:
        for tr in trials:
            astern = float(np.mean((tr.controls[:, 0] <= 0) | (tr.states[:, 3] <= 0)))
            tr.notes.append(f'astern propeller or u <= 0 kept ({100 * astern:.0f} % of samples)')
    return trials


def read_esso(path: str | Path, keep_astern: bool = False) -> list[Trial]:
    """
    Every FRT-DS-ESSO run in path.

    One CSV, or a folder searched recursively (sorted), such as data/esso_osaka_frt itself.
    """
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.rglob('*.csv') if p.is_file())
        if not files:
            raise TrialDataError(f'{path}: no .csv files inside')
        return [tr for p in files for tr in read_esso_csv(p, keep_astern=keep_astern)]
    if not path.exists():
        raise TrialDataError(f'{path}: no such file or directory')
    return read_esso_csv(path, keep_astern=keep_astern)


def esso_data_dir() -> Path:
    """Return the FRT-DS-ESSO runs shipped with the package (data/esso_osaka_frt)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        for cand in (parent / 'data' / 'esso_osaka_frt',
                     parent / 'share' / 'mmg_tuner' / 'data' / 'esso_osaka_frt'):
            if cand.is_dir():
                return cand
    raise TrialDataError('Esso Osaka data not found (data/esso_osaka_frt)')


# --- events ---------------------------------------------------------------------------

EVENTS = ('rudder_first_over', 'propeller_first_astern')


def event_time(trial: Trial, event: str = 'rudder_first_over', hold_s: float = 3.0,
               min_deg: float | None = None) -> float | None:
    """
    Trial time [s] of an event, or None when it does not occur.

    rudder_first_over: the rudder's first move to a held helm angle (held within 1 deg for
    hold_s) of at least min_deg; by default min_deg is 90 % of the largest angle held anywhere
    in the trial, since the manual approach steering of the pond runs reaches 22 deg but is
    never held. The time returned is where the move toward that angle began.
    propeller_first_astern: the first sample with rpm < 0.
    """
    if event == 'propeller_first_astern':
        astern = np.nonzero(trial.controls[:, 0] < 0)[0]
        return float(trial.t[astern[0]]) if astern.size else None
    if event != 'rudder_first_over':
        raise TrialDataError(f'{trial.name}: unknown event {event!r} (one of {EVENTS})')
    d = np.degrees(trial.controls[:, 1])
    w = max(1, int(round(hold_s / trial.dt))) if len(trial) > 1 else 1
    if d.size <= w:
        return None
    # running max/min over the window [k, k + w]
    win = np.lib.stride_tricks.sliding_window_view(d, w + 1)
    held = (win.max(axis=1) - win.min(axis=1)) <= 1.0
    level = np.abs(d[:held.size])
    if not held.any():
        return None
    thr = 0.9 * float(level[held].max()) if min_deg is None else float(min_deg)
    cand = np.nonzero(held & (level >= max(thr, 1.0)))[0]
    if cand.size == 0:
        return None
    k = int(cand[0])
    h = d[k]
    while k > 0 and np.sign(h - d[k - 1]) * (d[k] - d[k - 1]) > 0:
        k -= 1
    return float(trial.t[k])


class EventOptions(TypedDict, total=False):
    """The options of :func:`event_time` that :func:`cut_from_event` passes on."""

    hold_s: float
    min_deg: float | None


def cut_from_event(trial: Trial, event: str = 'rudder_first_over', before_s: float = 5.0,
                   **kw: Unpack[EventOptions]) -> Trial:
    """
    Return the trial from before_s seconds before the event to its end.

    The trial from before_s seconds before the event to its end, time restarting at 0 (start_s and
    notes say where it was cut). Raises TrialDataError when the event does not occur. kw go to
    :func:`event_time` (hold_s, min_deg).
    """
    te = event_time(trial, event, **kw)
    if te is None:
        raise TrialDataError(f'{trial.name}: event {event!r} not found; cannot cut')
    start = max(float(trial.t[0]), te - before_s)
    part = trial.slice(start, None)
    if len(part) < 2:
        raise TrialDataError(f'{trial.name}: fewer than 2 samples after the cut at {start:.2f} s')
    part.notes.append(f'cut from {before_s:g} s before {event} (at {te:.2f} s): starts at '
                      f'{start:.2f} s of the trial')
    part.start_s = trial.start_s + float(part.t[0])
    part.t = part.t - part.t[0]
    return part


# --- the benchmarks' split ----------------------------------------------------------------

RUN_KINDS = ('turning', 'zigzag', 'random', 'berthing')
"""The run kinds of FRT-DS-ESSO, one folder each."""
FOLDS = (0, 1, 2)
"""Held-out offsets of the split rule; fold 1 is the split every table uses unless a fold is
named (bench/esso_hybrid_cv.py scores all three: each run is held out exactly once)."""


def runs_by_kind(folder: str | Path | None = None) -> dict[str, list[Path]]:
    """
    Return the run files of each kind, sorted by file name.

    A ``turn_cut_X`` file is a trimmed copy of ``turn_X``: it is dropped when ``turn_X`` is
    present (it would put the same data on both sides of a split). ``folder`` defaults to
    :func:`esso_data_dir`.
    """
    root = esso_data_dir() if folder is None else Path(folder)
    out = {}
    for kind in RUN_KINDS:
        files = sorted((root / kind).glob('*.csv'))
        names = {f.name for f in files}
        out[kind] = [f for f in files
                     if not (f.name.startswith('turn_cut_')
                             and f.name.replace('turn_cut_', 'turn_') in names)]
    return out


def split_runs(files: list[Path], fold: int | None = 1) -> tuple[list[Path], list[Path]]:
    """
    Return (tuning files, held-out files): positions i with i mod 3 == fold are held out.

    The rule fixed before any tuning (33 runs: 21 tune, 11 held out for fold 1), applied to
    one kind's files in :func:`runs_by_kind` order. ``fold`` None holds out nothing.
    """
    if fold is None:
        return list(files), []
    held = [f for i, f in enumerate(files) if i % 3 == fold]
    return [f for f in files if f not in held], held


def read_run(path: str | Path, kind: str) -> Trial:
    """
    Return one run as the benchmarks use it: read whole, astern kept, manoeuvres cut.

    Turning and zigzag runs start 5 s before the rudder is first put over (every run starts
    with a manually steered approach); random and berthing runs are kept whole.
    """
    tr = read_esso_csv(path, keep_astern=True)[0]
    if kind in ('turning', 'zigzag'):
        tr = cut_from_event(tr, 'rudder_first_over', before_s=5.0)
    return tr


def load_split(fold: int | None = 1, folder: str | Path | None = None
               ) -> tuple[list[Trial], list[Trial], dict[str, str]]:
    """Return (training runs, held-out runs, kind of each run by name) of a fold's split."""
    train: list[Trial] = []
    test: list[Trial] = []
    kind_of: dict[str, str] = {}
    for kind, files in runs_by_kind(folder).items():
        a, b = split_runs(files, fold)
        for f in a + b:
            tr = read_run(f, kind)
            kind_of[tr.name] = kind
            (train if f in a else test).append(tr)
    return train, test, kind_of
