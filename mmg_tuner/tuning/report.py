"""
Tuning outputs.

params.yaml, report.json, report.md and plots (recorded vs pre vs tuned), and the one way to
simulate a recorded trial (:func:`simulate_recorded`).

Text and images are returned as str/bytes; the caller writes them (an OutputDir in the CLI),
so a failed write can say what was written. Plots use matplotlib's object API (Figure +
its Agg canvas): no global backend is set here.
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
import re
from typing import Any, Mapping, Sequence, TYPE_CHECKING

from mmg_tuner._atomic import write_atomic
from mmg_tuner._limits import json_default
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.trial import Trial
from mmg_tuner.tuning import plots
from mmg_tuner.tuning.objective import TrialBatch
import numpy as np
import yaml

if TYPE_CHECKING:   # annotations only: matplotlib is imported where a figure is drawn
    from matplotlib.figure import Figure


def display_name(name: str) -> str:
    r"""
    Return a trial name safe in UTF-8 text.

    Undecodable bytes of a file name (surrogate escapes) become \xNN.
    """
    return name.encode('utf-8', 'surrogateescape').decode('utf-8', 'backslashreplace')


def file_stem(name: str) -> str:
    """Return a trial name safe as a file name part (ASCII letters, digits, ._+- kept)."""
    return re.sub(r'[^A-Za-z0-9._+-]', '_', display_name(name)).lstrip('.') or 'trial'


def file_stems(names: Sequence[str]) -> list[str]:
    """
    Return :func:`file_stem` of each name, distinct wherever the names are.

    ``run 1`` and ``run_1``, or two Japanese names (every character replaced), would share one
    file and the second figure would overwrite the first. A stem shared by several names (also
    up to case: macOS and Windows file systems ignore it) keeps its plain form for the name it
    spells exactly; the others get 8 hex digits of the name's SHA-256, which stays the same
    whatever the other trials are; a counter settles what is left. A stem no other name shares
    is unchanged.
    """
    plain = [file_stem(n) for n in names]
    count: dict[str, int] = {}
    for s in plain:
        count[s.casefold()] = count.get(s.casefold(), 0) + 1
    stems = []
    for n, s in zip(names, plain):
        if count[s.casefold()] > 1 and s != display_name(n):
            s = f'{s}-{hashlib.sha256(display_name(n).encode()).hexdigest()[:8]}'
        stems.append(s)
    taken: set[str] = set()
    out = []
    for s in stems:
        k, cand = 1, s
        while cand.casefold() in taken:   # 'Zig' and 'zig': both spelled exactly
            k += 1
            cand = f'{s}_{k}'
        taken.add(cand.casefold())
        out.append(cand)
    return out


def unique_names(trials: Sequence[Trial]) -> list[str]:
    """
    Display names, with ' (2)', ' (3)' added to repeats.

    Trials of the same name from different folders must not overwrite each other in a report.
    """
    seen: dict[str, int] = {}
    out = []
    for t in trials:
        n = display_name(t.name)
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f'{n} ({seen[n]})')
    return out


def params_yaml_text(ship: ShipConfig, values: dict[str, float], note: str) -> str:
    doc = {'ship': ship.name, 'ship_config': ship.source, 'note': display_name(note),
           'params': {k: float(v) for k, v in values.items()}}
    return ('# Tuned parameters; load with: simulate --params THIS or the sim_node\n'
            '# params_file parameter. Values overlay the ship config.\n'
            + yaml.safe_dump(doc, sort_keys=False))


def json_text(doc: dict[str, Any]) -> str:
    """
    Strict JSON with NumPy scalars/arrays converted.

    JSON has no inf or NaN: a non-finite number (a diverged run's J, a gain against it) is written
    as null; the document says why beside it (e.g. per_trial's *_failed_at_s).
    """
    return json.dumps(_finite(doc), indent=2, default=json_default, allow_nan=False) + '\n'


def _finite(o: object) -> object:
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, np.ndarray):
        return _finite(o.tolist())
    if isinstance(o, (float, np.floating)):
        return float(o) if math.isfinite(o) else None
    return o


def write_params_yaml(path: str | Path, ship: ShipConfig, values: dict[str, float],
                      note: str) -> None:
    write_atomic(path, params_yaml_text(ship, values, note))


def write_json(path: str | Path, doc: dict[str, Any]) -> None:
    write_atomic(path, json_text(doc))


def start_state(trial: Trial) -> np.ndarray:
    """
    Return the state a simulation of a recorded trial starts from.

    The tuning objective's rule (a quadratic fit over the first seconds,
    :func:`~mmg_tuner.tuning.objective.initial_state` as TrialBatch packs it), so reports describe
    the run that was tuned.
    """
    state: np.ndarray = TrialBatch.from_trials([trial]).meas[0, 0].copy()
    return state


def simulate_recorded(ship: ShipConfig, trial: Trial, params: np.ndarray | None = None,
                      integrator: str = 'euler', substeps: int = 1) -> Trial:
    """
    Return the one way to simulate a recorded trial.

    From :func:`start_state`, driven by the recorded controls (and measured wind), zero-order hold;
    NaN after a failure, with ``status`` and ``fail_time_s`` saying so.
    """
    traj = simulate(ship, start_state(trial), trial, trial.dt, integrator, substeps,
                    t0=float(trial.t[0]), params=params, check=False)
    traj.t = trial.t.copy()
    return traj


def simulate_trial(ship: ShipConfig, trial: Trial, params: np.ndarray, integrator: str = 'euler',
                   substeps: int = 1) -> np.ndarray:
    """States (T, 6) of :func:`simulate_recorded` (NaN after a failure)."""
    return simulate_recorded(ship, trial, params, integrator, substeps).states


def png_bytes(fig: Figure) -> bytes:
    """Render a Figure to PNG bytes (kept here for callers; see :mod:`mmg_tuner.tuning.plots`)."""
    return plots.png_bytes(fig)


def plot_trials(ship: ShipConfig, trials: Sequence[Trial], runs: dict[str, np.ndarray],
                prefix: str = '', integrator: str = 'euler', substeps: int = 1,
                sets: Mapping[str, str] | None = None,
                J: Mapping[str, Mapping[str, float]] | None = None) -> dict[str, bytes]:
    """
    Plot each trial: track, states and inputs, measured vs each simulated run.

    ``runs``: model name -> parameter vector. ``sets``: trial name (as :func:`unique_names`
    gives it) -> 'tune' or 'test', named in the title; ``J``: model name -> {trial name: J},
    shown in the title. Returns {file name: PNG bytes}.
    """
    images = {}
    labels = unique_names(trials)
    for tr, label, stem in zip(trials, labels, file_stems(labels)):
        sims = {name: simulate_trial(ship, tr, p, integrator, substeps)
                for name, p in runs.items()}
        errs = {m: per.get(label, per.get(tr.name)) for m, per in (J or {}).items()}
        which = (sets or {}).get(label, (sets or {}).get(tr.name))
        fig = plots.trial_figure(tr, sims, plots.trial_title(label, which, errs))
        images[f'{prefix}{stem}.png'] = plots.png_bytes(fig)
    return images


def fmt_J(x: float | None) -> str:
    """J for text: '—' when absent, 'inf (diverged)' when a run diverged."""
    if x is None:
        return '—'
    if not math.isfinite(x):
        return 'inf (diverged)' if x > 0 else str(x)
    return f'{x:.4g}'


def fmt_gain(a: float | None, b: float | None) -> str:
    """1 - b/a as a percentage; never 'nan %'."""
    if a is None or b is None:
        return '—'
    if not math.isfinite(b):
        return 'worse (diverged)'
    if not math.isfinite(a):
        return 'fixes a divergence'
    if a == 0:
        return '—'
    return f'{100 * (1 - b / a):.1f} %'


def markdown_report(doc: Mapping[str, Any]) -> str:
    J = doc['J']
    lines = [f"# Tuning report: {doc['ship']}", '',
             f"{doc['evaluations']} evaluations, {doc['restarts']} restarts, "
             f"{doc['wall_s']:.1f} s"
             f"{' (interrupted: best so far)' if doc['interrupted'] else ''}.",
             '', '| J | tuning trials | test trials |', '|---|---|---|',
             f"| pre-determined | {fmt_J(J['pre']['tune'])} | {fmt_J(J['pre']['test'])} |",
             f"| tuned | {fmt_J(J['tuned']['tune'])} | {fmt_J(J['tuned']['test'])} |",
             f"| reduction | {fmt_gain(J['pre']['tune'], J['tuned']['tune'])} | "
             f"{fmt_gain(J['pre']['test'], J['tuned']['test'])} |", '',
             '| parameter | pre | tuned | box | on bound |', '|---|---|---|---|---|']
    for n, p in doc['params'].items():
        lines.append(f"| {n} | {p['pre']:.5g} | {p['tuned']:.5g} | [{p['lower']:.4g}, "
                     f"{p['upper']:.4g}] | {'**yes**' if p['on_bound'] else ''} |")
    lines += ['', '| trial | set | J pre | J tuned |', '|---|---|---|---|']
    for n, t in doc['per_trial'].items():
        lines.append(f"| {display_name(n)} | {t['set']} | {fmt_J(t['J_pre'])} | "
                     f"{fmt_J(t['J_tuned'])} |")
    if doc['bounds_hit']:
        lines += ['', f"{len(doc['bounds_hit'])} parameter(s) ended on a bound of their box: "
                  f"{', '.join(doc['bounds_hit'])}. That is a hint that the model structure is "
                  'missing something (run `diagnose`), or that the box is too narrow.']
    return '\n'.join(lines) + '\n'
