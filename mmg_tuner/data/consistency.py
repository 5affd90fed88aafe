"""
Cross-channel consistency of a recording: the channels checked against each other.

Each reader checks its channels one by one (finite, plausible, sorted); a fault that real ships
produce passes those checks and poisons everything downstream. Here the channels are checked
against each other, at the recording's own sample times (before any resampling smears a fault),
in the model frame (x north, y east, psi clockwise from north, u, v, r body axes):

- ``velocity spike``: a sample or a few of u, v or r off their neighbours by more than the
  whole recording's largest sustained value (a ship cannot gain or lose its full speed in a
  sample and come back: a corrupted message, a byte flipped in a bag).
- ``clock reset``: the time goes backwards. The recording is split there (each part keeps its
  own order); sorting would splice two stretches of the run into a jump (issue 28: 580 m in 1 s).
- ``heading vs yaw rate``: the heading departs from the integrated yaw rate and comes back
  (a GNSS compass flipping by 180 deg for a few samples).
- ``position outlier``: positions off the track the logged velocities and heading dead-reckon
  (a single fix km off), and ``position jump``: the track shifting against that dead
  reckoning and staying there (a GNSS receiver re-converging, a datum change).
- ``track vs velocities``: the positions move at a speed or in a direction the logged body
  velocities and heading do not give, for longer than the check's window.
- ``astern with propeller ahead``: the ship sails astern for longer than it takes to cover a
  ship length while the propeller turns ahead (a heading 180 deg off with velocities derived
  from it).

Thresholds come from the data's own noise (a robust MAD of what is checked, scaled to a
Gaussian sigma), from the ship's size when known and from its speed over the recording, so a
clean recording of any ship stays silent. Each fault is one :class:`Finding`; the readers log
it as one ``WARNING:`` line (the same path as the CSV unit warnings, so ``inspect``, ``tune``,
``evaluate`` and ``diagnose`` show it), and cut a short fault out (the trial split around it,
with a note) or, when it covers more than :data:`LONG_FRACTION` of the recording, leave the
recording unused with the reason. ``--strict`` on those commands turns any such warning into
an error (:class:`WarningLog`).
"""
from __future__ import annotations

from dataclasses import dataclass
import logging
import math
import sys
from typing import TYPE_CHECKING

from mmg_tuner.core import frames
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.core.ship import ShipConfig

logger = logging.getLogger(__name__)

K_SIGMA = 8.0           # a finding lies this many robust sigmas beyond the data's own noise
MAD_TO_SIGMA = 1.4826   # MAD -> sigma of a Gaussian
HALF_WINDOW_S = 10.0    # reference window half-width [s] (at least MIN_HALF samples)
MIN_HALF = 20           # samples each side: a fault of a few samples never moves the median
HEADING_FLOOR_RAD = math.radians(15.0)  # less off the integrated yaw rate: compass noise
OUTLIER_FLOOR_S = 5.0   # [s] of sailing at the recording's top speed: see check_motion
JUMP_FLOOR_S = 1.0      # [s] likewise
LONG_FRACTION = 0.2     # a fault covering more of the recording leaves it unusable
SPIKE_HALF = 5          # samples each side of the running median a velocity spike stands off
SPIKE_MAX_SAMPLES = 3   # longer than this, a departure is motion or another check's fault
SPIKE_R_FLOOR = math.radians(3.0)   # [rad/s] r spikes below this: a gyro's noise at sea
ASTERN_LENGTHS = 1.0    # sailing astern this many ship lengths with the propeller ahead
ASTERN_MIN_S = 30.0     # ... or, the ship's length unknown, this long


class UnusableRecordingError(TrialDataError):
    """
    A recording whose channels disagree over too much of it to be used (a long finding).

    A folder of recordings skips it with a WARNING line naming it (:func:`.load.load_trials`).
    """


@dataclass(frozen=True)
class Finding:
    """
    One inconsistency between channels of one recording.

    trial: the recording's (trial's) name; check: which check found it (see the module
    docstring); start_s, end_s: where [s] on the recording's time (as its t column or stamps
    from the first sample); size and unit: how large (deg, m, m/s, s); detail: what was seen
    and the threshold it passed; long: whether it covers so much of the recording that it is
    unusable (else it is cut out); cut_from_s, cut_to_s: the last good sample before it and the
    first good one after it (what lies strictly between is cut out; NaN at a recording's end).
    """

    trial: str
    check: str
    start_s: float
    end_s: float
    size: float
    unit: str
    detail: str
    long: bool = False
    cut_from_s: float = math.nan
    cut_to_s: float = math.nan

    @property
    def when(self) -> str:
        if self.end_s - self.start_s < 1e-9:
            return f't = {self.start_s:.2f} s'
        return f't = {self.start_s:.2f}-{self.end_s:.2f} s'

    @property
    def action(self) -> str:
        if self.check == 'clock reset':
            return 'the trial is split there (not sorted)'
        if self.long:
            return (f'covers more than {100 * LONG_FRACTION:.0f} % of the recording: not '
                    'used')
        return 'cut out, the trial split around it'

    def line(self) -> str:
        """Return the finding as one ``WARNING:`` line: trial, check, times, size, action."""
        return (f'WARNING: {self.trial}: {self.check} at {self.when}: {self.size:.3g} '
                f'{self.unit} ({self.detail}); {self.action}')

    def note(self) -> str:
        """Return the finding as a trial note: its line without the prefix."""
        return self.line()[len('WARNING: '):]


@dataclass(frozen=True)
class Motion:
    """
    The motion channels of one recording at its own sample times, model frame, SI units.

    t [s] strictly increasing; x, y [m] north, east; psi [rad] clockwise from north (wrapped
    or not); u, v [m/s] body axes (v to starboard); r [rad/s] clockwise; rpm [rev/min] (+
    ahead).
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    rpm: np.ndarray


# ------------------------------------------------------------------------------ the clock

def clock_resets(t: np.ndarray, max_back_s: float | None = None) -> np.ndarray:
    """
    Return the indices k where t[k] < t[k - 1] by more than stamp jitter (a clock reset).

    A step back by more than max_back_s (default five median sample steps) is a reset;
    smaller ones are messages delivered out of order, which sorting repairs.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return np.zeros(0, dtype=int)
    d = np.diff(t)
    pos = d[d > 0]
    if max_back_s is None:
        max_back_s = 5.0 * float(np.median(pos)) if pos.size else 0.0
    return np.nonzero(d < -max_back_s)[0] + 1


def reset_findings(name: str, t: np.ndarray, resets: np.ndarray, t0: float = 0.0
                   ) -> list[Finding]:
    """Return a 'clock reset' Finding per reset index (times relative to t0 [s])."""
    return [Finding(name, 'clock reset', float(t[k - 1] - t0), float(t[k - 1] - t0),
                    float(t[k - 1] - t[k]), 's', f'the next sample is stamped '
                    f't = {t[k] - t0:.2f} s, {t[k - 1] - t[k]:.3g} s earlier')
            for k in resets]


def split_at(n: int, cuts: np.ndarray) -> list[slice]:
    """Return the slices of range(n) between the cut indices (each cut starts a new part)."""
    edges = [0] + [int(c) for c in cuts] + [n]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


# ---------------------------------------------------------------------------- the checks

def _rolling_median(a: np.ndarray, half: int) -> np.ndarray:
    """Return the running median of a over 2 half + 1 samples (edges padded by the edge)."""
    if a.size == 0:
        return a.copy()
    pad = np.pad(a, half, mode='edge')
    win = np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1)
    out = np.empty(a.size)
    for c0 in range(0, a.size, 4096):   # bounded memory on long recordings
        out[c0:c0 + 4096] = np.median(win[c0:c0 + 4096], axis=1)
    return out


def _cumtrapz(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])


def _runs(mask: np.ndarray, bridge: int = 0) -> list[tuple[int, int]]:
    """
    Return the [start, end] index pairs (inclusive) of the True runs of mask.

    Runs fewer than bridge samples apart are joined.
    """
    idx = np.nonzero(mask)[0]
    if idx.size == 0:
        return []
    out = [[int(idx[0]), int(idx[0])]]
    for k in idx[1:]:
        if k - out[-1][1] <= bridge + 1:
            out[-1][1] = int(k)
        else:
            out.append([int(k), int(k)])
    return [(a, b) for a, b in out]


def _robust_sigma(a: np.ndarray) -> float:
    a = a[np.isfinite(a)]
    return MAD_TO_SIGMA * float(np.median(np.abs(a - np.median(a)))) if a.size else 0.0


def _half(t: np.ndarray) -> int:
    dt = float(np.median(np.diff(t)))
    return max(MIN_HALF, int(round(HALF_WINDOW_S / dt))) if dt > 0 else MIN_HALF


def check_motion(name: str, m: Motion, length_m: float = 0.0, t0: float = 0.0
                 ) -> list[Finding]:
    """
    Return the inconsistencies between the motion channels of one recording, in time order.

    length_m: the ship's length between perpendiculars [m] (0: unknown; the speed over the
    recording then sets the scale alone). t0: the recording's time origin [s] (times in the
    findings are t - t0). A fault found by an earlier check (heading) is taken out before the
    next (positions) looks, so one fault gives one finding.
    """
    t = np.asarray(m.t, dtype=float)
    n = t.size
    if n < 2 * MIN_HALF:
        return []
    dt = float(np.median(np.diff(t)))
    span = float(t[-1] - t[0])
    half = _half(t)
    found: list[Finding] = []

    def add(check: str, a: int, b: int, size: float, unit: str, detail: str,
            between: bool = False) -> None:
        ta, tb = float(t[a] - t0), float(t[b] - t0)
        long = (tb - ta) > LONG_FRACTION * span
        if between:   # a jump: the track is good on both sides, cut between the two samples
            c0, c1 = ta, tb
        else:
            c0 = float(t[a - 1] - t0) if a > 0 else -math.inf
            c1 = float(t[b + 1] - t0) if b + 1 < n else math.inf
        found.append(Finding(name, check, ta, tb, float(size), unit, detail, long, c0, c1))

    # 0. velocity spikes, taken out (replaced by their neighbours' median) before the other
    #    checks integrate the velocities: off the running median by more than the data's
    #    noise allows and by more than the largest value the channel holds for a window
    #    (a speed or yaw rate a ship sustains, it cannot gain and lose within a sample)
    sustained = {ch: _rolling_median(np.asarray(getattr(m, ch), dtype=float), SPIKE_HALF)
                 for ch in ('u', 'v', 'r')}
    top = float(np.max(np.hypot(sustained['u'], sustained['v'])))
    floors = {'u': top, 'v': top,
              'r': max(float(np.max(np.abs(sustained['r']))), SPIKE_R_FLOOR)}
    vel = {}
    for ch, unit in (('u', 'm/s'), ('v', 'm/s'), ('r', 'rad/s')):
        vals = np.asarray(getattr(m, ch), dtype=float)
        dev = vals - sustained[ch]
        thr = max(K_SIGMA * _robust_sigma(dev), floors[ch])
        spike = np.zeros(n, dtype=bool)
        for a0, b0 in _runs(np.abs(dev) > thr):
            if b0 - a0 + 1 > SPIKE_MAX_SAMPLES:
                continue
            spike[a0:b0 + 1] = True
            k = a0 + int(np.argmax(np.abs(dev[a0:b0 + 1])))
            add('velocity spike', a0, b0, abs(dev[k]), unit,
                f'{b0 - a0 + 1} sample(s) of {ch} = {vals[k]:.3g} {unit} against '
                f'{sustained[ch][k]:.3g} {unit} around them; threshold {thr:.2g} {unit}, the '
                'most the recording sustains')
        vel[ch] = np.where(spike, sustained[ch], vals)
    m = Motion(t, m.x, m.y, m.psi, vel['u'], vel['v'], vel['r'], m.rpm)
    speed = np.hypot(m.u, m.v)
    u_ref = float(np.median(speed))     # the recording's typical speed [m/s]
    u_top = float(np.quantile(speed, 0.9))   # its sailing speed, stops left out [m/s]

    # 1. heading against the yaw rate: psi - integral(r) is constant up to noise and a slow
    #    drift (the gyro's bias); its running circular median is the reference
    turned = _cumtrapz(np.asarray(m.r, dtype=float), t)
    c = frames.wrap_angle(np.asarray(m.psi, dtype=float) - turned)
    ref = np.arctan2(_rolling_median(np.sin(c), half), _rolling_median(np.cos(c), half))
    dev = frames.wrap_angle(c - ref)
    sig_h = _robust_sigma(dev)
    thr_h = max(K_SIGMA * sig_h, HEADING_FLOOR_RAD)
    bad_h = np.abs(dev) > thr_h
    for a, b in _runs(bad_h, bridge=2):
        k = a + int(np.argmax(np.abs(dev[a:b + 1])))
        rate = abs(dev[k]) / dt
        add('heading vs yaw rate', a, b, math.degrees(abs(dev[k])), 'deg',
            f'{b - a + 1} sample(s) off the integrated yaw rate, a heading change of '
            f'{rate:.3g} rad/s the yaw rate does not show; threshold '
            f'{math.degrees(thr_h):.2g} deg')
    psi = np.where(bad_h, ref + turned, np.asarray(m.psi, dtype=float))

    # 2. positions against the velocities and heading: what dead reckoning does not explain,
    #    D = p - integral(R(psi) (u, v)), is constant up to noise and a slow drift (current,
    #    a velocity bias)
    cp, sp = np.cos(psi), np.sin(psi)
    vn, ve = m.u * cp - m.v * sp, m.u * sp + m.v * cp
    dx = np.asarray(m.x, dtype=float) - _cumtrapz(vn, t)
    dy = np.asarray(m.y, dtype=float) - _cumtrapz(ve, t)
    rx, ry = _rolling_median(dx, half), _rolling_median(dy, half)
    off = np.hypot(dx - rx, dy - ry)
    sig_p = float(np.median(off)) / 1.1774    # Rayleigh median -> per-axis sigma
    # off and back by less than the ship sails in OUTLIER_FLOOR_S, or a quarter of its length:
    # a receiver holding its last fix for a few seconds (pond runs do), not a fault
    thr_o = max(K_SIGMA * sig_p, OUTLIER_FLOOR_S * u_top, 0.25 * length_m)
    bad_p = off > thr_o
    for a, b in _runs(bad_p, bridge=2):
        k = a + int(np.argmax(off[a:b + 1]))
        add('position outlier', a, b, off[k], 'm',
            f'{b - a + 1} sample(s) off the track the velocities and heading give; threshold '
            f'{thr_o:.2g} m')
    # jumps: the median of D after a step against the median before, less the trend seen on
    # either side (a current drifts D steadily); outliers left out
    keep = ~bad_p
    jump = np.zeros(n)
    w = half
    if keep.sum() > 4 * w:
        kx, ky, kt = dx[keep], dy[keep], np.nonzero(keep)[0]
        nk = kx.size
        mx = [_block_medians(kx, w), _block_medians(ky, w)]   # median of [j, j + w)
        j = np.arange(2 * w, nk - 2 * w + 1)
        s = np.zeros((j.size, 2))
        for i, med in enumerate(mx):
            step = med[j] - med[j - w]
            trend = 0.5 * ((med[j - w] - med[j - 2 * w]) + (med[j + w] - med[j]))
            s[:, i] = step - trend
        size = np.hypot(s[:, 0], s[:, 1])
        jump[kt[j]] = size     # at the first sample after the step
    sig_j = sig_p * 1.2533 * math.sqrt(2.0 / w) * math.sqrt(1.5)   # two medians + trend
    # a shift of less than a second's sailing or 4 % of the length: not worth a cut
    thr_j = max(K_SIGMA * sig_j, JUMP_FLOOR_S * u_top, 0.04 * length_m)
    step1 = np.concatenate([[0.0], np.hypot(np.diff(dx), np.diff(dy))])   # D's one-step change
    for a, b in _runs(jump > thr_j, bridge=w):
        k = a + int(np.argmax(jump[a:b + 1]))
        # the medians place a step within a sample or two: the largest one-step change of
        # D nearby (outliers aside) is where it is
        lo, hi = max(1, k - w // 2), min(n, k + w // 2 + 1)
        k = lo + int(np.argmax(np.where(keep[lo:hi] & keep[lo - 1:hi - 1], step1[lo:hi], -1.0)))
        add('position jump', k - 1, k, jump[k], 'm',
            f'the track shifts by {jump[k]:.3g} m against the velocities and heading between '
            f'two samples; threshold {thr_j:.2g} m', between=True)

    # 3. sustained disagreement: the drift of D over the window, as a speed, against the
    #    speed itself
    if n > 4 * half:
        vel_x = (rx[2 * half:] - rx[:-2 * half]) / (t[2 * half:] - t[:-2 * half])
        vel_y = (ry[2 * half:] - ry[:-2 * half]) / (t[2 * half:] - t[:-2 * half])
        drift = np.zeros(n)
        drift[half:n - half] = np.hypot(vel_x, vel_y)
        sig_d = _robust_sigma(drift[half:n - half])
        thr_d = max(K_SIGMA * sig_d, u_ref, 0.05 * math.sqrt(9.81 * length_m))
        fast = drift > thr_d
        for (a, b) in _runs(fast, bridge=half):
            if found and any(f.start_s <= t[b] - t0 and t[a] - t0 <= f.end_s
                             and f.check != 'astern with propeller ahead' for f in found):
                continue   # a jump or outlier already explains it
            k = a + int(np.argmax(drift[a:b + 1]))
            add('track vs velocities', a, b, drift[k], 'm/s',
                f'the positions move {drift[k]:.3g} m/s apart from what the velocities and '
                f'heading give over {2 * half * dt:.0f} s; threshold {thr_d:.2g} m/s')

    # 4. astern with the propeller ahead: thrust and resistance both brake astern motion, so
    #    it dies out; sailing on astern for a ship length, or (length unknown) for
    #    ASTERN_MIN_S without slowing to half its speed, is a heading 180 deg off
    sig_u = _robust_sigma(np.diff(m.u)) / math.sqrt(2.0)
    astern = (m.u < -max(4.0 * sig_u, 0.05 * u_ref)) & (m.rpm > 0)
    for a, b in _runs(astern, bridge=2):
        ua = -np.asarray(m.u[a:b + 1], dtype=float)
        dist = float(_cumtrapz(np.maximum(ua, 0.0), t[a:b + 1])[-1])
        dur = float(t[b] - t[a])
        q = max(1, ua.size // 4)
        steady = float(np.mean(ua[-q:])) >= 0.5 * float(np.mean(ua[:q]))
        if length_m > 0:
            bad, what = (dist > ASTERN_LENGTHS * length_m,
                         f'{dist:.3g} m astern, more than {ASTERN_LENGTHS:g} ship length(s)')
        else:
            bad, what = (dur > ASTERN_MIN_S and steady,
                         f'longer than {ASTERN_MIN_S:g} s without slowing down')
        if bad:
            add('astern with propeller ahead', a, b, dur, 's',
                f'u < 0 at rpm > 0 for {100 * dur / span:.0f} % of the recording, {what}: a '
                'heading 180 deg off (and velocities derived from it)?')
    found.sort(key=lambda f: f.start_s)
    return found


def _block_medians(a: np.ndarray, w: int) -> np.ndarray:
    """Return med[j] = median(a[j:j + w]) for j = 0 .. len(a) - w (NaN past the end)."""
    win = np.lib.stride_tricks.sliding_window_view(a, w)
    out = np.full(a.size + 1, np.nan)
    out[:win.shape[0]] = np.median(win, axis=1)
    return out


# ----------------------------------------------------------------------- applying them

def cuts(findings: list[Finding]) -> list[tuple[float, float]]:
    """Return the open time ranges (cut_from_s, cut_to_s) the short findings cut out."""
    return [(f.cut_from_s, f.cut_to_s) for f in findings
            if not f.long and f.check != 'clock reset']


def keep_slices(t: np.ndarray, findings: list[Finding], t0: float = 0.0) -> list[slice]:
    """
    Return the index slices of t left around the findings' cuts (none when one is long).

    A sample is kept when it lies outside every cut's open range; a cut splits the samples
    on its two sides into separate slices even when it holds none (a jump).
    """
    if any(f.long for f in findings):
        return []
    rel = np.asarray(t, dtype=float) - t0
    keep = np.ones(rel.size, dtype=bool)
    starts = set()
    for a, b in cuts(findings):
        keep &= ~((rel > a) & (rel < b))
        starts.add(int(np.searchsorted(rel, b, side='left')))
    out, k = [], 0
    while k < rel.size:
        if not keep[k]:
            k += 1
            continue
        j = k + 1
        while j < rel.size and keep[j] and j not in starts:
            j += 1
        out.append(slice(k, j))
        k = j
    return out


def unusable_reason(findings: list[Finding]) -> str:
    """Return why the long findings leave a recording unusable ('' when none is long)."""
    return '; '.join(f.note() for f in findings if f.long)


def warn(findings: list[Finding]) -> None:
    """Log each finding as its ``WARNING:`` line (the path the unit warnings take)."""
    for f in findings:
        logger.warning(f.line())


def refuse_warnings(lines: list[str]) -> None:
    """Raise a TrialDataError counting the WARNING lines and quoting the first (strict)."""
    if lines:
        raise TrialDataError(f'--strict: {len(lines)} WARNING(s) about the recordings, each '
                             f'an error under --strict; first: {lines[0][len("WARNING: "):]}')


class WarningLog(logging.Handler):
    """
    Collect the ``WARNING:`` lines the readers log while recordings are read (``--strict``).

    Use as a context manager around the reading: ``with WarningLog() as log: ...`` then
    ``log.lines``. Where nothing else handles the package's log (``inspect``, a script),
    Python prints warnings through its last-resort handler, which a handler of ours would
    silence: then the lines are printed on stderr here, as that handler would.
    """

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []
        self._print = False

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if text.startswith('WARNING:'):
            self.lines.append(text)
        if self._print:
            sys.stderr.write(text + '\n')

    def __enter__(self) -> 'WarningLog':
        log = logging.getLogger('mmg_tuner')
        self._print = not log.hasHandlers()
        log.addHandler(self)
        return self

    def __exit__(self, *exc: object) -> None:
        logging.getLogger('mmg_tuner').removeHandler(self)


# ------------------------------------------- a trial read at its own rate (a channel CSV)

MIN_PART_SAMPLES = 10   # as data/assemble.py: a shorter piece left between cuts is dropped


def checked_parts(trial: Trial, length_m: float = 0.0) -> list[Trial]:
    """
    Check a trial read as it stands (a channel CSV: the tug's) as the readers check theirs.

    The same :func:`check_motion` at its own samples (no propeller channel: the astern check
    is off); each finding logged as its ``WARNING:`` line and kept as a note; a short one cut
    out (the trial split around it, the parts named ``<name>_1``, ...), a long one an
    :class:`UnusableRecordingError`.
    """
    s = trial.states
    rpm = trial.inputs.get('rpm', np.full(len(trial), np.nan))
    findings = check_motion(trial.name, Motion(trial.t, s[:, 0], s[:, 1], s[:, 2], s[:, 3],
                                               s[:, 4], s[:, 5], rpm), length_m)
    if not findings:
        return [trial]
    warn(findings)
    if any(f.long for f in findings):
        raise UnusableRecordingError(f'{trial.source or trial.name}: not used: '
                                     f'{unusable_reason(findings)}')
    notes = [f.note() for f in findings]
    parts = []
    for sl in keep_slices(trial.t, findings):
        if sl.stop - sl.start < MIN_PART_SAMPLES:
            notes.append(f'segment {trial.t[sl.start]:.1f}-{trial.t[sl.stop - 1]:.1f} s '
                         f'shorter than {MIN_PART_SAMPLES} samples: dropped')
            continue
        parts.append(trial.slice(float(trial.t[sl.start]), float(trial.t[sl.stop - 1])))
    if not parts:
        raise UnusableRecordingError(f'{trial.source or trial.name}: no usable part left: '
                                     + '; '.join(notes))
    for i, part in enumerate(parts, 1):
        part.start_s = trial.start_s + float(part.t[0])
        part.t = part.t - part.t[0]
        part.notes.extend(notes)
        if len(parts) > 1:
            part.name = f'{trial.name}_{i}'
    return parts


# ------------------------------------------------- propeller speed unit: rpm or rev/s?

RPS_BAND = (25.0, 150.0)   # rpm the balance needs / rpm logged: 60 means rev/s logged
STEADY_FROUDE = 0.05       # steady running: at least this Froude number ...
STEADY_RUDDER_RAD = math.radians(5.0)   # ... the rudder within this ...
STEADY_R_PRIME = 0.05      # ... |r| L / u, |v| / u below this ...
STEADY_ACCEL_PRIME = 0.05  # ... and |du/dt| L / u^2 below this (speed smoothed over 10 s)
STEADY_MIN_SAMPLES = 6
BALANCE_SAMPLES = 25       # at most this many steady samples solved for the balance


def _balance_rps(ship: ShipConfig, u: float) -> float:
    """Return the shaft speed [rev/s] at which the family's surge force is 0 at u (NaN: none)."""
    fam = ship.family
    outs = fam.outputs

    def surge(n: float) -> float:
        return float(fam.forces(ship.params, u, 0.0, 0.0,
                                tuple(n if o == 'n_P' else 0.0 for o in outs))[0])
    lo, hi = 1e-3, 1e3
    if not (surge(lo) < 0.0 < surge(hi)):
        return math.nan
    for _ in range(30):   # bisection in log n: thrust grows with n (to 1e-8 relative)
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if surge(mid) < 0.0 else (lo, mid)
    return math.sqrt(lo * hi)


def _median_slope(u: np.ndarray, t: np.ndarray, half: int, idx: np.ndarray) -> np.ndarray:
    """
    Return d/dt of u's running median (2 half + 1 samples) at the indices idx only.

    As ``np.gradient(_rolling_median(u, half), t)[idx]`` on a uniform grid (central
    differences, one-sided at the ends), the medians taken at idx and its neighbours only.
    """
    n = u.size
    lo, hi = np.maximum(idx - 1, 0), np.minimum(idx + 1, n - 1)
    need = np.unique(np.concatenate([lo, hi]))
    win = np.lib.stride_tricks.sliding_window_view(np.pad(u, half, mode='edge'), 2 * half + 1)
    u_s = np.empty(n)
    for c0 in range(0, need.size, 4096):   # bounded memory on long recordings
        part = need[c0:c0 + 4096]
        u_s[part] = np.median(win[part], axis=1)
    slope: np.ndarray = (u_s[hi] - u_s[lo]) / (t[hi] - t[lo])
    return slope


def rpm_unit_warning(trial: Trial, ship: ShipConfig) -> str:
    """
    Say when a trial's rpm channel looks like rev/s, from the ship's own force balance ('' if not).

    In steady straight running (rudder near 0, v and r small, speed steady, Froude number at
    least STEADY_FROUDE) the propeller's thrust balances the resistance: the family's own
    surge force (hull, propeller, rudder: ``Family.forces``) is 0 at the logged speed for one
    shaft speed n*. Logged in rpm, 60 n* / rpm is about 1; logged in rev/s, about 60 (the
    thrust, ~n^2, 60^2 too small). A record faster than the ship's Froude number 0.5 of a
    model ship (``scale_ratio``) is taken as full scale and Froude-scaled first. '' when the
    ship has no screw (``n_P``), the trial no rpm or too little steady running to tell.
    """
    if 'rpm' not in trial.inputs or 'rudder' not in trial.inputs or \
            'n_P' not in ship.family.outputs or len(trial) < STEADY_MIN_SAMPLES:
        return ''
    L = ship.L_pp
    if ship.scale_ratio != 1.0 and float(np.max(trial['u'])) > 0.5 * math.sqrt(9.81 * L):
        trial = trial.froude_scaled(ship.scale_ratio)   # a full-scale record of a model ship
    t = trial.t
    u, v, r = trial['u'], trial['v'], trial['r']
    rpm, rudder = trial['rpm'], trial['rudder']
    k = max(1, int(round(5.0 / trial.dt))) if trial.dt > 0 else 1
    with np.errstate(divide='ignore', invalid='ignore'):
        steady = ((u > STEADY_FROUDE * math.sqrt(9.81 * L)) & (rpm > 0)
                  & (np.abs(rudder) < STEADY_RUDDER_RAD) & (np.abs(r) * L / u < STEADY_R_PRIME)
                  & (np.abs(v) / u < STEADY_R_PRIME))
    idx = np.nonzero(steady)[0]
    if idx.size >= STEADY_MIN_SAMPLES:   # the smoothed speed's slope only where it is needed
        du = _median_slope(u, t, k, idx)
        with np.errstate(divide='ignore', invalid='ignore'):
            idx = idx[np.abs(du) * L / u[idx] ** 2 < STEADY_ACCEL_PRIME]
    if idx.size < STEADY_MIN_SAMPLES:
        return ''
    idx = idx[np.linspace(0, idx.size - 1, min(BALANCE_SAMPLES, idx.size)).astype(int)]
    ratio = []
    for i in idx:
        n_star = _balance_rps(ship, float(u[i]))
        if math.isfinite(n_star):
            ratio.append(60.0 * n_star / float(rpm[i]))
    if len(ratio) < STEADY_MIN_SAMPLES // 2:
        return ''
    q = float(np.median(ratio))   # rpm the balance needs per rpm logged
    if not RPS_BAND[0] <= q <= RPS_BAND[1]:
        return ''
    i = idx[len(idx) // 2]
    return (f"channel 'rpm': in steady straight running ({idx.size} samples, e.g. "
            f'u = {u[i]:.3g} m/s) the resistance of {ship.name} balances its propeller at '
            f'{q:.3g} times the logged rpm (logged {float(rpm[i]):.4g}): read as rpm the '
            f'thrust is about 1/{q * q:.3g} of the resistance, read as rev/s it balances '
            f'within x{(60.0 / q) ** 2:.2f}: it looks like rev/s; the format wants rpm '
            '(multiply by 60; a bag: rpm unit rps in the topic map)')


def warn_rpm_units(trials: list[Trial], ship: ShipConfig) -> list[str]:
    """Log a ``WARNING:`` line for each trial whose rpm looks like rev/s; return the lines."""
    out = []
    for tr in trials:
        w = rpm_unit_warning(tr, ship)
        if w:
            line = f'WARNING: {tr.name}: {w}'
            logger.warning(line)
            out.append(line)
    return out
