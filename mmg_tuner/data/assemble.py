"""Raw topic series -> validated trials on a uniform grid in the model frame.

Repairs are documented in each trial's notes: non-finite samples dropped, unsorted stamps
sorted, duplicate stamps dropped, gaps longer than max_gap_s split the trial, samples outside
the model's range (rpm <= 0, u <= 0) split it too. Anything unrepairable raises
TrialDataError naming the file, topic and time.
"""
from __future__ import annotations

import math

import numpy as np

from mmg_tuner.core.limits import RUDDER_HARD_CAP_RAD, InputLimits
from mmg_tuner.data.bag import RawRecording, Series
from mmg_tuner.data.topics import TopicMap
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError

MIN_SAMPLES = 10
MAX_SAMPLES = 20_000_000  # ~230 days at 1 s: more means corrupt stamps
MAX_WIND_MS = 100.0  # no anemometer reading beyond it is wind (the strongest gusts ~110 m/s)


# Without a ship the readers still refuse what no ship can do (a unit error, corrupt data);
# with one (load_trials(..., limits=input_limits(ship))) the ranges are the ship's own.
GENERIC_LIMITS = InputLimits(
    rpm_max=1e5, rudder_max_rad=RUDDER_HARD_CAP_RAD, rudder_plausible_rad=RUDDER_HARD_CAP_RAD,
    top_speed_ms=50.0, speed_max_ms=100.0, yaw_rate_max_rad_s=2 * math.pi, dt_min_s=1e-3,
    dt_max_s=60.0, rpm_basis='no ship given: the generic cap of 1e5 rpm')


def _implausible(s: Series, role: str, tm: TopicMap, lim: InputLimits) -> tuple[np.ndarray, str]:
    """(mask of samples no ship of these limits can show, what is wrong with them)."""
    v = s.values
    none = np.zeros(len(v), dtype=bool)
    if role == 'rudder':
        return (np.abs(v[:, 0] * tm.rudder_to_rad) > lim.rudder_plausible_rad,
                f'|rudder| > {math.degrees(lim.rudder_plausible_rad):.0f} deg')
    if role == 'rpm':
        return (np.abs(v[:, 0] * tm.rpm_factor) > lim.rpm_max,
                f'|rpm| > {lim.rpm_max:.0f} ({lim.rpm_basis})')
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
    return none, ''


def clean_series(s: Series, path: str, t0_ns: int, role: str = '', tm: TopicMap | None = None,
                 limits: InputLimits | None = None) -> Series:
    """Drop non-finite, implausible (outside limits, see core/limits.py) and duplicate
    samples, sort unsorted stamps; say what was done."""
    def t(ns):
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
            s.notes.append(f'{s.topic}: dropped {bad.size} implausible sample(s) ({what}), '
                           f'first at t = {t(s.stamps_ns[bad[0]]):.3f} s, value '
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
                             + (f' ({"; ".join(s.notes)})' if s.notes else ''))
    return s


def _segments(rec: RawRecording, series: list[Series], tm: TopicMap, t0_ns: int, notes: list[str]
              ) -> list[tuple[float, float]]:
    """Time ranges [s] covered by every topic without a gap longer than max_gap_s."""
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
                    limits: InputLimits | None = None) -> list[Trial]:
    """Frame, resample and split one recording into trials (see module docstring).
    limits: plausibility ranges of the ship (core.limits.input_limits); default generic."""
    needed = ['odom', 'rudder', 'rpm']
    for role in needed:
        if role not in rec.series:
            topic = getattr(tm, f'{role}_topic')
            found = ', '.join(f'{t} ({ty}, {n} msgs)' for t, (ty, n) in sorted(
                rec.topics_found.items())) or 'nothing'
            raise TrialDataError(f'{rec.path}: topic {topic} missing or empty; found: {found}. '
                                 'Use --topics MAP.yaml to map other names.')
    t0_ns = int(min(s.stamps_ns.min() for s in rec.series.values()))
    series = [clean_series(rec.series[t], rec.path, t0_ns, t, tm, limits) for t in needed]
    twist = None
    if 'twist' in rec.series:
        twist = clean_series(rec.series['twist'], rec.path, t0_ns, 'twist', tm, limits)
        series.append(twist)
    wind = None
    if 'wind' in rec.series:
        wind = clean_series(rec.series['wind'], rec.path, t0_ns, 'wind', tm, limits)
        if not wind.frame:
            wind.frame = tm.wind_frame
    notes = list(rec.notes) + [n for s in series for n in s.notes] + \
        (wind.notes if wind is not None else [])
    if any(not np.array_equal(s.stamps_ns, s.receive_ns) for s in series[:1]):
        notes.append(f'{tm.odom_topic}: header stamps used (not receive time)')
    trials = []
    for lo, hi in _segments(rec, series, tm, t0_ns, notes):
        n = int(math.floor((hi - lo) / tm.dt + 1e-9)) + 1
        if n > MAX_SAMPLES:
            raise TrialDataError(f'{rec.path}: segment {lo:.1f}-{hi:.1f} s would need {n} '
                                 f'samples at dt = {tm.dt:g} s: corrupt stamps?')
        if n < MIN_SAMPLES:
            notes.append(f'segment {lo:.1f}-{hi:.1f} s shorter than {MIN_SAMPLES} samples: '
                         'dropped')
            continue
        grid = lo + tm.dt * np.arange(n)
        trials.extend(_resample(series, twist, tm, t0_ns, grid, rec.path, name, notes, wind))
    if not trials:
        raise TrialDataError(f'{rec.path}: no usable trial ({"; ".join(notes) or "too short"})')
    if len(trials) > 1:  # one recording split into several: number them in time order
        for i, tr in enumerate(trials, 1):
            tr.name = f'{name}_{i}'
    return trials


def _interp(s: Series, t0_ns: int, grid: np.ndarray, col: int) -> np.ndarray:
    return np.interp(grid, (s.stamps_ns - t0_ns) * 1e-9, s.values[:, col])


def _resample(series, twist, tm: TopicMap, t0_ns, grid, path, name, notes, wind=None
              ) -> list[Trial]:
    odom, rud, rpm = series[:3]
    t_odom = (odom.stamps_ns - t0_ns) * 1e-9
    yaw = np.unwrap(odom.values[:, 2])
    # ENU map / FLU base_link (REP-103/105) -> MMG: x_E = y_map, y_E = x_map, psi = pi/2 - yaw
    x = np.interp(grid, t_odom, odom.values[:, 1])
    y = np.interp(grid, t_odom, odom.values[:, 0])
    psi = np.pi / 2 - np.interp(grid, t_odom, yaw)
    if odom.values.shape[1] == 6:
        u = np.interp(grid, t_odom, odom.values[:, 3])
        v = -np.interp(grid, t_odom, odom.values[:, 4])
        r = -np.interp(grid, t_odom, odom.values[:, 5])
    elif twist is not None:
        u, v, r = (_interp(twist, t0_ns, grid, 0), -_interp(twist, t0_ns, grid, 1),
                   -_interp(twist, t0_ns, grid, 2))
    else:
        u, v, r = body_velocities_from_poses(grid, x, y, psi)
        notes.append('no twist recorded: u, v, r derived from positions and heading '
                     '(central differences)')
    rudder = _interp(rud, t0_ns, grid, 0) * tm.rudder_to_rad
    rpm_v = _interp(rpm, t0_ns, grid, 0) * tm.rpm_factor
    states = np.column_stack([x, y, psi, u, v, r])
    controls = np.column_stack([rpm_v, rudder])
    wind_ne = None if wind is None else _true_wind(wind, t0_ns, grid, psi, u, v)
    good = (rpm_v > 0) & (u > 0)
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
                         'MMG model range, left out')
            k = j
            continue
        j = k
        while j < grid.size and good[j]:
            j += 1
        if j - k >= MIN_SAMPLES:
            out.append(Trial(grid[k:j] - grid[k], states[k:j], controls[k:j], name=name,
                             source=str(path), start_s=float(grid[k]),
                             wind=None if wind_ne is None else wind_ne[k:j],
                             notes=list(notes) + [f'resampled on dt = {tm.dt:g} s, linear '
                                                  f'interpolation; starts at {grid[k]:.2f} s '
                                                  'of the recording']))
        k = j
    return out


def _true_wind(wind: Series, t0_ns: int, grid, psi, u, v) -> np.ndarray:
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


def body_velocities_from_poses(t, x, y, psi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-frame u, v and yaw rate r from earth positions and heading (central differences)."""
    dx, dy, dpsi = np.gradient(x, t), np.gradient(y, t), np.gradient(psi, t)
    c, s = np.cos(psi), np.sin(psi)
    return dx * c + dy * s, -dx * s + dy * c, dpsi
