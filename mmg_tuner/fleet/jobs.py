"""
One ship's work, as the Dask tasks run it: load and inspect, tune, diagnose, evaluate.

This module is the fleet's only door to the per-ship work (:mod:`mmg_tuner.api`, the same
calls the ``tune`` and ``diagnose`` commands make, with the same defaults), so a fleet run
gives the results of running the ships one by one, to the bit.

Every task is a plain function of picklable inputs. A task never raises for a ship's own
problem (a bad bag, a diverging model): it returns a :class:`Failure` naming the stage and
the reason, and the later tasks pass it on, so one bad ship never stops the fleet. Outputs are
not written by the workers: each step returns its files as bytes (:class:`StepOutput`) and the
client writes them atomically into OUT/<ship>/, so workers need no access to OUT and a killed
worker leaves no half-written folder.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
import datetime as _dt
import inspect
import logging
import math
import os
from pathlib import Path
import shutil
import tempfile
import time
import traceback
from typing import Any, Callable, cast, Iterable, TypeVar

from mmg_tuner import api
from mmg_tuner._outdir import LOCK_NAME
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.summary import summarize_trial
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.settings import MapFn
from mmg_tuner.errors import MmgTunerError, TrialDataError
from mmg_tuner.fleet.manifest import ShipJob
from mmg_tuner.tuning.report import json_text
import numpy as np

logger = logging.getLogger(__name__)

# numba threads per task, set on each worker by graph.NumbaThreads (None: leave numba's own)
NUMBA_THREADS: int | None = None
# the diagnosis fans its independent re-tunes out as tasks when it offers this hook
_DIAGNOSE_HOOK = 'map_fn'
T = TypeVar('T')
R = TypeVar('R')


@dataclass
class Failure:
    """Why a ship failed, at which stage; passed on by the later tasks."""

    stage: str
    reason: str
    detail: str = ''


@dataclass
class Loaded:
    """A ship's config and trials, as loaded on a worker, with an inspection summary."""

    ship: ShipConfig
    tune: list[Trial]
    test: list[Trial]
    dates: dict[int, str | None]          # index in tune + test -> ISO date (or None)
    inspect: dict[str, Any]


@dataclass
class StepOutput:
    """
    A step's summary (for the fleet report) and its files, in writing order.

    The file whose presence means the set is complete comes last (report.json, diagnosis.json).
    """

    summary: dict[str, Any]
    files: dict[str, bytes] = field(default_factory=dict)
    wall_s: float = 0.0


def _numba_threads() -> None:
    if NUMBA_THREADS:
        import numba
        # (numba.config sets its attributes at run time: none is declared)
        limit = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
        numba.set_num_threads(min(NUMBA_THREADS, limit))


def _guard(stage: str, fn: Callable[..., R], *args: Any) -> R | Failure:
    """Run one stage; a ship's own problem becomes a Failure (passed on, never raised)."""
    for a in args:
        if isinstance(a, Failure):
            return a
    _numba_threads()
    try:
        return fn(*args)
    except MmgTunerError as exc:
        return Failure(stage, str(exc))
    except Exception as exc:  # noqa: BLE001 - any crash of one ship is that ship's failure
        return Failure(stage, f'{type(exc).__name__}: {exc}', traceback.format_exc())


# ----------------------------------------------------------------------------- stages
def load(job: ShipJob) -> Loaded | Failure:
    """
    Load the ship and its trials and summarise them as ``inspect`` does.

    Load the ship and its trials (each source separately, so dates stay with their trials), and
    summarise them as ``inspect`` does.
    """
    return _guard('load', _load, job)


def _load(job: ShipJob) -> Loaded:
    t0 = time.perf_counter()
    ship = api.load_ship(job.ship, job.params)
    kw: dict[str, Any] = {'ship': ship, 'dt': job.dt, 'topics': job.topics,
                          'trial_scale': job.trial_scale}
    sets: dict[str, list[Trial]] = {'tune': [], 'test': []}
    dates: dict[int, str | None] = {}
    for which, sources in (('tune', job.tune), ('test', job.test)):
        for src in sources:
            found = api.load_trials([src.path], **kw)
            if not found:
                raise TrialDataError(f'{src.path}: no usable trial in it')
            for t in found:
                dates[len(sets['tune']) + len(sets['test'])] = (
                    src.date.isoformat() if src.date else None)
                sets[which].append(t)
    summaries = [asdict(summarize_trial(t)) for t in sets['tune'] + sets['test']]
    for i, s in enumerate(summaries):
        s['set'] = 'tune' if i < len(sets['tune']) else 'test'
        s['date'] = dates[i]
    return Loaded(ship, sets['tune'], sets['test'], dates,
                  {'ship': ship.name, 'ship_config': ship.source, 'trials': summaries,
                   'load_s': time.perf_counter() - t0})


def tune(job: ShipJob, loaded: Loaded | Failure) -> StepOutput | Failure:
    """``tune TUNE --test TEST`` with the ship's options; its files as ``tune`` writes them."""
    return _guard('tune', _tune, job, loaded)


def _tune(job: ShipJob, ld: Loaded) -> StepOutput:
    t0 = time.perf_counter()
    fit = api.tune(ld.ship, ld.tune, ld.test or None, job.tune_config)
    files = _capture(lambda d: fit.write(d, plots=job.plots))
    summary = {'params': fit.params, 'J_pre': {'tune': fit.J_pre.tune, 'test': fit.J_pre.test},
               'J': {'tune': fit.J.tune, 'test': fit.J.test}, 'bounds_hit': fit.bounds_hit,
               'evaluations': fit.evaluations,
               'heldout_gain': _gain(fit.J_pre.test, fit.J.test)}
    return StepOutput(summary, files, time.perf_counter() - t0)


def diagnose(job: ShipJob, loaded: Loaded | Failure, fan_out: bool = True
             ) -> StepOutput | Failure:
    """
    ``diagnose TUNE --test TEST`` with the ship's options; its files as ``diagnose`` writes them.

    With ``fan_out`` on a Dask worker, the candidate re-tunes run as tasks of their own when the
    diagnosis offers the hook.
    """
    return _guard('diagnose', _diagnose, job, loaded, fan_out)


def _diagnose(job: ShipJob, ld: Loaded, fan_out: bool) -> StepOutput:
    t0 = time.perf_counter()
    hook = _fan_out_hook() if fan_out else None
    if hook is not None:
        with hook as map_fn:
            dx = api.diagnose(ld.ship, ld.tune, ld.test or None, job.diagnose_config,
                              # (the hook by name: a dict[str, Any], as mypy would check a
                              # typed value against every keyword of diagnose)
                              **cast('dict[str, Any]', {_DIAGNOSE_HOOK: map_fn}))
    else:
        dx = api.diagnose(ld.ship, ld.tune, ld.test or None, job.diagnose_config)
    files = _capture(lambda d: dx.write(d, plots=job.plots))
    summary = {'causes': [{'effect': c.effect, 'summary': c.summary,
                           'parameters': c.parameters, 'heldout_gain': c.heldout_gain,
                           'indistinguishable_from': list(c.indistinguishable_from)}
                          for c in dx.causes],
               'undecided': [{'effect': c.effect, 'summary': c.summary,
                              'indistinguishable_from': list(c.indistinguishable_from)}
                             for c in dx.undecided],
               'params': dx.params,
               'J_test': {'base': dx.baseline.J_test, 'final': dx.final.J_test},
               'heldout_gain': dx.final.heldout_gain_total}
    return StepOutput(summary, files, time.perf_counter() - t0)


def evaluate(job: ShipJob, loaded: Loaded | Failure, tuned: StepOutput | Failure | None,
             diagnosed: StepOutput | Failure | None) -> StepOutput | Failure:
    """
    Return the ship's fleet record.

    The record holds the inspection, the held-out gains of each step and, when its trials carry
    two or more dates, ``trend_parameter`` fitted per date (a rising resistance R_0 is hull
    fouling: the model degrades over time). Writes evaluation.json.
    """
    for step in (tuned, diagnosed):
        if isinstance(step, Failure):
            return step
    return _guard('evaluate', _evaluate, job, loaded, tuned, diagnosed)


def _evaluate(job: ShipJob, ld: Loaded, tuned: StepOutput | None, diagnosed: StepOutput | None
              ) -> StepOutput:
    t0 = time.perf_counter()
    doc: dict[str, Any] = {'name': job.name, 'ship': ld.ship.name, 'inspect': ld.inspect,
                           'tune': tuned.summary if tuned else None,
                           'diagnose': diagnosed.summary if diagnosed else None,
                           'trend': None}
    if job.dated:
        # (one of them is there where it is checked)
        params = (cast(StepOutput, diagnosed or tuned).summary['params'] if (diagnosed or tuned)
                  else {})
        doc['trend'] = trend(job, ld, params)
    return StepOutput(doc, {'evaluation.json': json_text(doc).encode()},
                      time.perf_counter() - t0)


def trend(job: ShipJob, ld: Loaded, params: dict[str, float], threshold: float = 0.05
          ) -> dict[str, Any]:
    """
    ``job.trend_parameter`` fitted alone on each dated group of trials.

    Every other parameter at the ship's final model; a linear trend over the dates. ``drifts`` when
    the fitted change over the whole span exceeds ``threshold`` of the mean value.
    """
    name = job.trend_parameter
    ship = ld.ship.with_params(params)
    trials = ld.tune + ld.test
    groups: dict[str, list[Trial]] = {}
    for i, t in enumerate(trials):
        d = ld.dates.get(i)
        if d is not None:
            groups.setdefault(d, []).append(t)
    cfg = api.TuneConfig(targets=(name,), max_evals=600, seed=job.tune_config.seed,
                         integrator=job.diagnose_config.integrator)
    rows: list[dict[str, Any]] = []
    for d in sorted(groups):
        fit = api.tune(ship, groups[d], None, cfg)
        rows.append({'date': d, 'value': fit.params[name], 'J': fit.J.tune,
                     'trials': len(groups[d])})
    days = np.array([(_dt.date.fromisoformat(r['date']) - _dt.date.fromisoformat(
        rows[0]['date'])).days for r in rows], float)
    vals = np.array([r['value'] for r in rows])
    slope = float(np.polyfit(days, vals, 1)[0]) if len(rows) >= 2 and days[-1] > 0 else 0.0
    mean = float(np.mean(np.abs(vals))) or 1.0
    change = slope * float(days[-1]) / mean if len(rows) >= 2 else 0.0
    return {'parameter': name, 'groups': rows, 'slope_per_year': slope * 365.25,
            'relative_change': change, 'drifts': bool(abs(change) > threshold),
            'direction': 'rising' if change > 0 else 'falling',
            'threshold': threshold}


# ----------------------------------------------------------------------------- helpers
def _gain(before: float | None, after: float | None) -> float | None:
    if before is None or after is None or not math.isfinite(before) or before <= 0:
        return None
    return float(1 - after / before)


def _capture(write: Callable[[Path], list[Path]]) -> dict[str, bytes]:
    """
    Run a result's ``write`` into a private temporary folder and return its files.

    (in the order written: the completion marker last).
    """
    tmp = Path(tempfile.mkdtemp(prefix='mmg_fleet_'))
    try:
        paths = write(tmp / 'out')
        return {str(Path(p).relative_to(tmp / 'out')): Path(p).read_bytes() for p in paths
                if Path(p).name != LOCK_NAME}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # our own temporary folder


class _FanOut:
    """
    ``map_fn`` for the diagnosis on a Dask worker.

    The independent re-tunes become tasks (the calling task secedes from the worker's thread pool
    while it waits, so the worker's slot runs one of them instead of idling).
    """

    def __enter__(self) -> MapFn[Any, Any]:
        from distributed import worker_client
        self._ctx = worker_client()
        client = self._ctx.__enter__()

        def map_fn(fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
            items = list(items)
            if len(items) <= 1:
                return [fn(x) for x in items]
            futs = client.map(_threads_then(fn), items, pure=False)
            # (distributed's gather has no annotations: a list for a list of futures)
            return cast(list[Any], client.gather(futs))
        return map_fn

    def __exit__(self, *exc: Any) -> bool | None:
        return self._ctx.__exit__(*exc)


def _threads_then(fn: Callable[[T], R]) -> Callable[[T], R]:
    def run(x: T) -> R:
        _numba_threads()
        return fn(x)
    return run


def _fan_out_hook() -> _FanOut | None:
    """Return the fan-out context when the diagnosis accepts the hook and this runs on a worker."""
    if _DIAGNOSE_HOOK not in inspect.signature(api.diagnose).parameters:
        return None
    try:
        from distributed import get_worker
        get_worker()
    except (ImportError, ValueError):
        return None
    return _FanOut()


def diagnose_hook_available() -> bool:
    return _DIAGNOSE_HOOK in inspect.signature(api.diagnose).parameters


def cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1
