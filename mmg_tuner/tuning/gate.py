"""
The gate before a tuned or identified model is written: can it be a ship and does it run.

One function, :func:`check_before_writing`, used by every writer of ``params.yaml`` (``tune``
with CMA-ES and with ``--method lo``/``go``/``lo-go``, ``diagnose``): the model's plausibility
(``core/plausibility.py``: impossible -> a failure, implausible -> a warning) and a simulation of
each identification trial the one way the package simulates a recorded trial
(``tuning.report.simulate_recorded``): a run that diverges, or whose state leaves what the ship
can physically do (``core/limits.py``: beyond Fn 1.5 or its yaw-rate cap), is a failure. A
failure refuses the write with one ``ERROR`` line naming what failed, unless the caller opts in
(``--write-unphysical``): the model is then written and every failure is marked in the report
and in params.yaml's note.
"""
from __future__ import annotations

import logging
from typing import Mapping, Sequence

from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.plausibility import check_model
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.trial import Trial
from mmg_tuner.errors import ConfigError, MmgTunerError, TuningError
from mmg_tuner.tuning.report import simulate_recorded
import numpy as np

logger = logging.getLogger(__name__)
OPT_IN = '--write-unphysical'


def check_before_writing(ship: ShipConfig, values: Mapping[str, float],
                         trials: Sequence[Trial], what: str = 'tuned parameters',
                         write_unphysical: bool = False, integrator: str = 'rk4',
                         substeps: int = 1) -> list[str]:
    """
    Check the model ``ship`` + ``values`` before it is written; return the lines to mark.

    Raises a TuningError naming the first failure (and how many more) when the model is
    impossible or diverges on one of ``trials``, unless ``write_unphysical``; the returned
    lines (warnings, and the failures written anyway) go into the report. Each is logged once.
    """
    failures: list[str] = []
    warnings: list[str] = []
    try:
        model = ship.with_params(dict(values), source=what)
    except ConfigError as exc:
        model, failures = None, [str(exc)]
    if model is not None:
        for f in check_model(model):
            (failures if f.level == 'error' else warnings).append(f.text)
    if model is not None and not failures:
        failures += _trial_failures(model, trials, integrator, substeps)
    if failures and not write_unphysical:
        more = f' (and {len(failures) - 1} more)' if len(failures) > 1 else ''
        raise TuningError(f'{what} of {ship.name} not written: {failures[0]}{more}; this model '
                          f'cannot be a ship or does not run; give {OPT_IN} to write it anyway '
                          '(marked in the report)')
    marks = [f'UNPHYSICAL, written with {OPT_IN}: {t}' for t in failures]
    marks += [f'implausible: {t}' for t in warnings]
    for m in marks:
        logger.warning('WARNING: %s: %s', what, m)
    return marks


def _trial_failures(model: ShipConfig, trials: Sequence[Trial], integrator: str,
                    substeps: int) -> list[str]:
    """Return why the model fails on each trial that it cannot run ('' for none)."""
    lim = input_limits(model)
    out = []
    for tr in trials:
        try:
            run = simulate_recorded(model, tr, None, integrator, substeps)
        except (MmgTunerError, ZeroDivisionError) as exc:
            out.append(f'trial {tr.name}: cannot be simulated ({exc})')
            continue
        if run.status.startswith('diverged'):
            out.append(f'trial {tr.name}: the simulation diverges at t = '
                       f'{run.fail_time_s:.1f} s ({run.status})')
            continue
        states = run.states
        ok = np.all(np.isfinite(states[:, 3:6]), axis=1)
        for k in np.flatnonzero(ok):
            problem = lim.state_problem(*map(float, states[k, 3:6]))
            if problem:
                out.append(f'trial {tr.name}: at t = {run.t[k]:.1f} s the simulated {problem}')
                break
    return out


def mark_note(note: str, marks: Sequence[str]) -> str:
    """Return params.yaml's note with the failures written anyway (the opt-in) appended."""
    bad = [m for m in marks if m.startswith('UNPHYSICAL')]
    return note + ('; ' + '; '.join(bad) if bad else '')


def markdown(marks: Sequence[str]) -> str:
    """Return the report's section on the model's plausibility ('' when there is nothing)."""
    if not marks:
        return ''
    return ('\n## Model plausibility\n\n' + ''.join(f'- {m}\n' for m in marks)
            + '\n(core/plausibility.py; doc/concepts/plausibility.md)\n')
