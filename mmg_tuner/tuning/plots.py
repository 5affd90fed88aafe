"""
Figures of recorded and simulated trials that a ROS user reads without a manual.

One layout for the tuning report, the diagnosis overlays and ``evaluate``: the track in the
horizontal plane, the states over time, and beside them the inputs that drove the ship (rudder,
propeller, thrusters and measured wind when present): a zigzag cannot be read without the
rudder. Every axis states its unit, sign and frame (model frame: x_E north, y_E east, psi
clockwise from north, rudder + to starboard; ``doc/conventions.md`` has the conventions).
Titles say whether a trial was used for tuning or held out, with its error.

matplotlib is imported inside the functions (it is optional for the core), and only its object
API is used (Figure + the Agg canvas): no global backend is set here.
"""
from __future__ import annotations

import io
import logging
import math
import re
from typing import Any, cast, Mapping, Sequence, TYPE_CHECKING
import warnings

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.trial import Trial
import numpy as np

if TYPE_CHECKING:   # annotations only: matplotlib is imported where a figure is drawn
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

DEG = 180.0 / math.pi
logger = logging.getLogger(__name__)

STATE_AXES: dict[str, tuple[str, float]] = {
    'x': ('x_E [m, north]', 1.0),
    'y': ('y_E [m, east]', 1.0),
    'psi': ('psi [deg, + clockwise\nfrom north]', DEG),
    'u': ('u [m/s, surge,\n+ forward]', 1.0),
    'v': ('v [m/s, sway at midship,\n+ to starboard]', 1.0),
    'r': ('r [deg/s, yaw rate,\n+ turning to starboard]', DEG),
}
"""Axis label and factor from SI (model frame) for each state."""

INPUT_AXES: dict[str, str] = {
    'rudder': 'rudder delta [deg,\n+ to starboard]',
    'rpm': 'propeller [rpm,\n+ ahead]',
    'thrusters': 'thrusters [rev/s, + pushes\nto starboard]',
    'wind': 'measured true wind\n[m/s, air over ground]',
}
"""Axis labels of the input panels."""

SET_WORDS = {'tune': 'tuning trial', 'test': 'held-out trial (not used for tuning)'}
"""How a title names the set a trial belongs to."""

MEASURED_STYLE: dict[str, Any] = {'color': 'k', 'lw': 1.6}
PALETTE = ('tab:orange', 'tab:blue', 'tab:green', 'tab:red', 'tab:purple')
INPUT_COLORS = {'rudder': 'tab:green', 'rpm': 'tab:red', 'bow': 'tab:purple',
                'stern': 'tab:brown', 'wind_n': 'tab:cyan', 'wind_e': 'tab:olive'}


def png_bytes(fig: Figure) -> bytes:
    """
    Render a matplotlib Figure to PNG bytes through the Agg canvas (no global backend).

    matplotlib's "Glyph ... missing from font(s)" warnings (a trial name in a script the font
    lacks) are said once per process in our words instead; other warnings pass through.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        fig.savefig(buf, format='png', dpi=90)
    missing = set()
    for w in caught:
        m = _GLYPH.match(str(w.message))
        if m:
            missing.add(chr(int(m.group(1))))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    new = missing - _SAID_MISSING
    if new:
        _SAID_MISSING.update(new)
        logger.warning('WARNING: plots: the plot font has no glyph for %s (in a trial name or '
                       'title); shown as empty boxes in the figures, the data are unaffected',
                       ' '.join(sorted(new)[:20]) + (' ...' if len(new) > 20 else ''))
    return buf.getvalue()


_GLYPH = re.compile(r'Glyph (\d+) .*missing from')
_SAID_MISSING: set[str] = set()


def trial_title(name: str, set_name: str | None = None,
                errors: Mapping[str, float | None] | None = None,
                error_name: str = 'J (eq. 43, lower is better)') -> str:
    """
    Title of a trial's figure: its name, the set it belongs to and its error per model.

    ``set_name``: 'tune' or 'test' (other words are shown as given); ``errors``: model name ->
    error (J, or the evaluate index), None or inf when the run failed.
    """
    parts = [name]
    if set_name:
        parts.append(SET_WORDS.get(set_name, set_name))
    if errors:
        parts.append(f'{error_name}: ' + ', '.join(f'{model} {_fmt(e)}'
                                                   for model, e in errors.items()))
    return ' \u2014 '.join(parts)


def _fmt(e: float | None) -> str:
    if e is None:
        return 'failed'
    if not math.isfinite(e):
        return 'inf (diverged)'
    return f'{e:.3g}'


_KNOWN = ('rudder', 'rpm', 'bow_thruster', 'stern_thruster', 'wind_n', 'wind_e')


def input_panels(trial: Trial) -> list[str]:
    """
    Return the input panels a trial needs.

    Rudder and rpm (always for a screw-and-rudder trial), thrusters and wind when recorded;
    any other channels (e.g. a twin-azimuth tug's shaft speeds and angles) one panel per
    unit, named ``unit:<unit>``.
    """
    from mmg_tuner.core.channels import TABLE

    others = [c for c in trial.inputs if c not in _KNOWN]
    panels = [k for k in ('rudder', 'rpm') if k in trial.inputs or not others]
    if trial.thrusters is not None:
        panels.append('thrusters')
    if trial.wind is not None and not np.all(np.isnan(trial.wind)):
        panels.append('wind')
    for unit in dict.fromkeys(TABLE[c].unit for c in others
                              if np.any(np.isfinite(trial.inputs[c]))):
        panels.append(f'unit:{unit}')
    return panels


def trial_figure(trial: Trial, runs: Mapping[str, np.ndarray], title: str = '',
                 states: Sequence[str] = ('psi', 'r', 'u', 'v'), track: bool = True,
                 restarts_s: Sequence[float] | np.ndarray = ()) -> Figure:
    """
    Build the figure of one trial: measured vs simulated states with the inputs beside them.

    ``runs``: model name -> simulated states (T, 6) on the trial's grid (NaN after a failure).
    ``states``: the state panels, in the order of STATE_NAMES' names; ``track``: add the
    horizontal track (y_E east right, x_E north up); ``restarts_s``: times [s, trial clock]
    where the simulation restarted from the measured state (drawn as grey lines).
    Returns the matplotlib Figure (its axes carry the labels; :func:`png_bytes` renders it).
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    inputs = input_panels(trial)
    n_state_cols = 1 if len(states) <= 4 else 2
    per_col = math.ceil(len(states) / n_state_cols)
    widths = ([1.25] if track else []) + [1.0] * n_state_cols + [1.0]
    fig = Figure(figsize=(4.2 * sum(widths) + 0.6, 2.0 * max(per_col, len(inputs)) + 1.4),
                 layout='constrained')
    outer = fig.add_gridspec(1, len(widths), width_ratios=widths)
    col = 0
    colors = {n: PALETTE[i % len(PALETTE)] for i, n in enumerate(runs)}
    # a restarted run is drawn in pieces: the jump back to the measurement is not motion
    cuts = [0] + sorted({int(np.searchsorted(trial.t, s)) for s in restarts_s}) + [len(trial)]
    segments = [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]
    if track:
        ax = fig.add_subplot(outer[0, 0])
        ax.plot(trial['y'], trial['x'], **MEASURED_STYLE)
        for name, st in runs.items():
            for seg in segments:
                ax.plot(st[seg, 1], st[seg, 0], color=colors[name], lw=1.2)
        ax.plot(trial['y'][:1], trial['x'][:1], 'o', color='k', ms=6)
        ax.annotate('start', (trial['y'][0], trial['x'][0]), textcoords='offset points',
                    xytext=(6, -12), fontsize=8)
        ax.set_xlabel(STATE_AXES['y'][0])
        ax.set_ylabel(STATE_AXES['x'][0])
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_title('track (north up)', fontsize=10)
        ax.grid(alpha=0.3)
        col = 1
    t = trial.t
    time_axes, bottoms = [], []
    share = None
    for c in range(n_state_cols):
        names = list(states[c * per_col:(c + 1) * per_col])
        sub = outer[0, col + c].subgridspec(per_col, 1)
        for i, k in enumerate(names):
            label, f = STATE_AXES[k]
            a = fig.add_subplot(sub[i, 0], sharex=share)
            share = share or a
            j = STATE_NAMES.index(k)
            a.plot(t, f * trial.states[:, j], **MEASURED_STYLE)
            for name, st in runs.items():
                for seg in segments:
                    a.plot(t[seg], f * st[seg, j], color=colors[name], lw=1.0)
            a.set_ylabel(label, fontsize=8)
            time_axes.append(a)
            if i == 0:
                a.set_title('states', fontsize=10)
        bottoms.append(a)
    sub = outer[0, col + n_state_cols].subgridspec(max(per_col, len(inputs)), 1)
    for i, k in enumerate(inputs):
        a = fig.add_subplot(sub[i, 0], sharex=share)
        share = share or a
        _plot_input(a, trial, k)
        a.set_ylabel(INPUT_AXES.get(k) or _unit_label(k[5:]), fontsize=8)
        time_axes.append(a)
        if i == 0:
            a.set_title('recorded inputs (drive every simulation)', fontsize=10)
    bottoms.append(a)
    for a in time_axes:
        a.grid(alpha=0.3)
        a.tick_params(labelsize=7)
        for tk in restarts_s:
            a.axvline(tk, color='0.75', lw=0.7, zorder=0)
    for a in bottoms:
        a.set_xlabel('t [s]', fontsize=8)
    for a in set(time_axes) - set(bottoms):
        a.tick_params(labelbottom=False)
    handles = [Line2D([], [], **MEASURED_STYLE, label='measured')]
    handles += [Line2D([], [], color=colors[n], lw=1.2, label=f'simulated: {n}') for n in runs]
    if len(restarts_s):
        handles.append(Line2D([], [], color='0.75', lw=0.7,
                              label='restart from the measured state'))
    fig.legend(handles=handles, loc='outside lower center', ncol=len(handles), fontsize=9,
               frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def _plot_input(a: Axes, trial: Trial, k: str) -> None:
    """Draw one input panel with a small legend when it holds several lines."""
    t = trial.t
    if k == 'rudder':
        a.plot(t, DEG * trial['rudder'], color=INPUT_COLORS['rudder'], lw=1.0)
        a.axhline(0.0, color='0.5', lw=0.5)
        _min_span(a, DEG * trial['rudder'], 10.0)
    elif k == 'rpm':
        a.plot(t, trial['rpm'], color=INPUT_COLORS['rpm'], lw=1.0)
        _min_span(a, trial['rpm'], 0.1 * float(np.nanmax(np.abs(trial['rpm']), initial=10.0)))
    elif k == 'thrusters':   # (a panel input_panels gives only when recorded: not None)
        thr = cast(np.ndarray, trial.thrusters)
        a.plot(t, thr[:, 0], color=INPUT_COLORS['bow'], lw=1.0, label='bow')
        a.plot(t, thr[:, 1], color=INPUT_COLORS['stern'], lw=1.0, label='stern')
        a.legend(fontsize=7, loc='best')
    elif k.startswith('unit:'):
        from mmg_tuner.core.channels import TABLE
        unit = k[5:]
        f = DEG if unit == 'rad' else 1.0
        for c, v in trial.inputs.items():
            if c not in _KNOWN and TABLE[c].unit == unit and np.any(np.isfinite(v)):
                a.plot(t, f * v, lw=1.0, label=c)
        a.legend(fontsize=7, loc='best')
    elif k == 'wind':   # (as the thrusters: only when measured)
        wind = cast(np.ndarray, trial.wind)
        a.plot(t, wind[:, 0], color=INPUT_COLORS['wind_n'], lw=1.0,
               label='toward north')
        a.plot(t, wind[:, 1], color=INPUT_COLORS['wind_e'], lw=1.0, label='toward east')
        a.legend(fontsize=7, loc='best')


def _unit_label(unit: str) -> str:
    """Axis label of a panel of other input channels: their unit (radians shown in degrees)."""
    return 'angles [deg]' if unit == 'rad' else f'inputs [{unit}]'


def _min_span(a: Axes, y: np.ndarray, span: float) -> None:
    """Widen the y range to at least ``span`` so that sensor noise does not look like a signal."""
    y = y[np.isfinite(y)]
    if y.size == 0:
        return
    lo, hi = float(y.min()), float(y.max())
    if hi - lo < span:
        mid = 0.5 * (lo + hi)
        a.set_ylim(mid - 0.5 * span, mid + 0.5 * span)
