"""Tuning outputs: params.yaml, report.json, report.md and plots (recorded vs pre vs tuned)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np
import yaml

from mmg_tuner._atomic import write_atomic
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import simulate
from mmg_tuner.data.trial import Trial


def write_params_yaml(path: Path, ship: ShipConfig, values: dict[str, float], note: str) -> None:
    doc = {'ship': ship.name, 'ship_config': ship.source, 'note': note,
           'params': {k: float(v) for k, v in values.items()}}
    write_atomic(path, '# Tuned parameters; load with: simulate --params THIS or the sim_node\n'
                 '# params_file parameter. Values overlay the ship config.\n'
                 + yaml.safe_dump(doc, sort_keys=False))


def write_json(path: Path, doc: dict) -> None:
    write_atomic(path, json.dumps(doc, indent=2, default=_jsonable) + '\n')


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def simulate_trial(ship: ShipConfig, trial: Trial, params: np.ndarray, integrator: str = 'euler',
                   substeps: int = 1) -> np.ndarray:
    """States simulated from the trial's first state with its recorded controls (NaN after a
    failure)."""
    return simulate(ship, trial.states[0], trial.inputs, trial.dt, integrator, substeps,
                    params=params, check=False).states


def plot_trials(out_dir: Path, ship: ShipConfig, trials: Sequence[Trial],
                runs: dict[str, np.ndarray], prefix: str = '', integrator: str = 'euler',
                substeps: int = 1) -> list[Path]:
    """Per trial: trajectory (east-north) and psi/u/v/r time series, recorded vs each run."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written = []
    colors = {'recorded': 'k'}
    palette = ['tab:orange', 'tab:blue', 'tab:green', 'tab:red']
    for tr in trials:
        sims = {name: simulate_trial(ship, tr, p, integrator, substeps)
                for name, p in runs.items()}
        fig = plt.figure(figsize=(12, 6))
        ax = fig.add_subplot(1, 2, 1)
        ax.plot(tr['y'], tr['x'], colors['recorded'], lw=1.5, label='recorded')
        for (name, st), c in zip(sims.items(), palette):
            ax.plot(st[:, 1], st[:, 0], color=c, lw=1.2, label=name)
        ax.set_xlabel('y_E east [m]')
        ax.set_ylabel('x_E north [m]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.legend(fontsize=8)
        ax.set_title(tr.name)
        labels = [(2, 'psi [deg]', math.degrees(1)), (3, 'u [m/s]', 1.0), (4, 'v [m/s]', 1.0),
                  (5, 'r [deg/s]', math.degrees(1))]
        for i, (col, lab, f) in enumerate(labels):
            a = fig.add_subplot(4, 2, 2 * i + 2)
            a.plot(tr.t, tr.states[:, col] * f, 'k', lw=1.0)
            for (name, st), c in zip(sims.items(), palette):
                a.plot(tr.t, st[:, col] * f, color=c, lw=0.9)
            a.set_ylabel(lab, fontsize=8)
            a.tick_params(labelsize=7)
        a.set_xlabel('t [s]')
        fig.tight_layout()
        path = out_dir / f'{prefix}{tr.name}.png'
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    return written


def markdown_report(doc: dict) -> str:
    J = doc['J']

    def fmt(x):
        return '—' if x is None else f'{x:.4g}'

    def gain(a, b):
        return '—' if a is None or b is None or a == 0 else f'{100 * (1 - b / a):.1f} %'

    lines = [f"# Tuning report: {doc['ship']}", '',
             f"{doc['evaluations']} evaluations, {doc['restarts']} restarts, "
             f"{doc['wall_s']:.1f} s{' (interrupted: best so far)' if doc['interrupted'] else ''}.",
             '', '| J | tuning trials | test trials |', '|---|---|---|',
             f"| pre-determined | {fmt(J['pre']['tune'])} | {fmt(J['pre']['test'])} |",
             f"| tuned | {fmt(J['tuned']['tune'])} | {fmt(J['tuned']['test'])} |",
             f"| reduction | {gain(J['pre']['tune'], J['tuned']['tune'])} | "
             f"{gain(J['pre']['test'], J['tuned']['test'])} |", '',
             '| parameter | pre | tuned | box | on bound |', '|---|---|---|---|---|']
    for n, p in doc['params'].items():
        lines.append(f"| {n} | {p['pre']:.5g} | {p['tuned']:.5g} | [{p['lower']:.4g}, "
                     f"{p['upper']:.4g}] | {'**yes**' if p['on_bound'] else ''} |")
    lines += ['', '| trial | set | J pre | J tuned |', '|---|---|---|---|']
    for n, t in doc['per_trial'].items():
        lines.append(f"| {n} | {t['set']} | {t['J_pre']:.4g} | {t['J_tuned']:.4g} |")
    if doc['bounds_hit']:
        lines += ['', f"{len(doc['bounds_hit'])} parameter(s) ended on a bound of their box: "
                  f"{', '.join(doc['bounds_hit'])}. That is a hint that the model structure is "
                  'missing something (run `diagnose`), or that the box is too narrow.']
    return '\n'.join(lines) + '\n'
