r"""
The fleet as a Dask task graph, built as it runs (futures).

    digest(ship) -> [up to date: skipped]
                 -> load(ship) -> tune(ship)     -> evaluate(ship) -> client writes OUT/<ship>/
                              \-> diagnose(ship) -/
                                   \-> re-tune candidate 1..k (when the diagnosis offers the
                                       map_fn hook: each round's independent re-tunes are tasks)

Tune and diagnose of a ship are independent and run side by side; ships run in any order.
Only the client writes: each ship's files when its evaluate task completes (atomically,
its record last), the fleet summary at the end.

Threads: every worker runs one task per thread, and each task sets numba's thread count to
the host's cores divided by the task threads on that host (:class:`NumbaThreads`), so
numba threads x task threads never exceed the cores; a LocalCluster started here has one
thread per worker process and NUMBA_NUM_THREADS set in the workers' environment.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import datetime as _dt
import logging
from pathlib import Path
import time
from typing import Any, Callable, cast, Sequence, TYPE_CHECKING
from urllib.parse import urlparse
import uuid

from mmg_tuner._outdir import OutputDir
from mmg_tuner.fleet import jobs
from mmg_tuner.fleet.manifest import Manifest, ShipJob
from mmg_tuner.fleet.resume import (FLEET_MARK, input_digest, read_record, RECORD, ShipRecord,
                                    up_to_date)

if TYPE_CHECKING:   # annotations only: Dask is imported when a fleet runs
    from dask.typing import Key
    from distributed import Client, Worker

logger = logging.getLogger(__name__)

try:  # an optional dependency of the package: only the fleet needs it
    from distributed.diagnostics.plugin import WorkerPlugin
except ImportError:  # pragma: no cover - the fleet refuses to start without it
    # (the base when distributed is missing: mypy types the name as distributed's class)
    WorkerPlugin = object  # type: ignore[misc,assignment]


class NumbaThreads(WorkerPlugin):
    """
    Caps numba's threads per task on each worker.

    Host cores // task threads on the host (``host_threads``: the sum of the workers' nthreads per
    host, as the scheduler saw them when the fleet started; a worker not in it counts its own
    threads).
    """

    name = 'mmg-tuner-numba-threads'

    def __init__(self, host_threads: dict[str, int]):
        self.host_threads = dict(host_threads)

    def setup(self, worker: Worker) -> None:
        host = urlparse(worker.address).hostname or ''
        total = max(self.host_threads.get(host, 0), worker.state.nthreads, 1)
        jobs.NUMBA_THREADS = max(1, jobs.cpu_count() // total)


def host_threads(client: Client) -> dict[str, int]:
    out: dict[str, int] = {}
    for addr, w in client.scheduler_info(n_workers=-1)['workers'].items():
        host = urlparse(addr).hostname or ''
        out[host] = out.get(host, 0) + int(w.get('nthreads', 1))
    return out


@dataclass
class ShipOutcome:
    name: str
    status: str                        # 'done' | 'skipped' | 'failed'
    record: ShipRecord


@dataclass
class FleetResult:
    """What a fleet run did, per ship; ``summary`` is fleet.json's content."""

    out: Path
    ships: dict[str, ShipOutcome] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0

    def names(self, status: str) -> list[str]:
        return [n for n, o in self.ships.items() if o.status == status]

    @property
    def failed(self) -> list[str]:
        return self.names('failed')

    @property
    def skipped(self) -> list[str]:
        return self.names('skipped')

    @property
    def done(self) -> list[str]:
        return self.names('done')


def run(manifest: Manifest, out: str | Path, client: Client, *, fan_out: bool = True,
        progress: Callable[[ShipOutcome], None] | None = None, resumed: bool = False
        ) -> FleetResult:
    """
    Run every ship of ``manifest`` on ``client``'s cluster into ``out``.

    (checked by the caller: new, empty or an earlier fleet's output). Returns when every ship is
    done, skipped or failed; the fleet summary is written last.
    """
    from distributed import as_completed

    t0 = time.perf_counter()
    out = Path(out)
    result = FleetResult(out)
    client.register_plugin(NumbaThreads(host_threads(client)))
    run_id = uuid.uuid4().hex[:8]
    with OutputDir.open(out, resume=True) as od:
        od.write_text(FLEET_MARK, 'mmg_tuner fleet output\n')
        # future key -> (kind, job, digest, the ship's (tune, diagnose, evaluate) futures)
        meta: dict[Key, tuple[str, ShipJob, Any, tuple[Any, ...]]] = {}
        ac = as_completed()
        for job in manifest.ships:
            f = client.submit(input_digest, job, key=f'digest-{job.name}-{run_id}', pure=False,
                              priority=20)
            meta[f.key] = ('digest', job, None, ())
            ac.add(f)
        for fut in ac:
            kind, job, digest, deps = meta.pop(fut.key)
            if kind == 'digest':
                try:
                    digest = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker fails one ship
                    _finish(od, result, job.name, '', jobs.Failure('hash', _reason(exc)),
                            None, progress)
                    continue
                rec = up_to_date(out / job.name, digest)
                if rec is not None:
                    result.ships[job.name] = ShipOutcome(job.name, 'skipped', rec)
                    if progress:
                        progress(result.ships[job.name])
                    continue
                key = f'{job.name}-{digest[:12]}'
                ld = client.submit(jobs.load, job, key=f'load-{key}', priority=10)
                tu = (client.submit(jobs.tune, job, ld, key=f'tune-{key}')
                      if 'tune' in job.steps else None)
                dg = (client.submit(jobs.diagnose, job, ld, fan_out, key=f'diagnose-{key}')
                      if 'diagnose' in job.steps else None)
                ev = client.submit(jobs.evaluate, job, ld, tu, dg, key=f'evaluate-{key}')
                meta[ev.key] = ('evaluate', job, digest, (tu, dg, ev))
                ac.add(ev)
            else:
                tu, dg, ev = deps
                try:
                    steps = client.gather([tu, dg, ev])  # None entries pass through
                except Exception as exc:  # noqa: BLE001 - a lost worker fails one ship
                    steps = [None, None, jobs.Failure('worker', _reason(exc))]
                _finish(od, result, job.name, digest, steps[2], steps[:2], progress)
                for f in (tu, dg, ev):
                    if f is not None:
                        f.release()
        result.wall_s = time.perf_counter() - t0
        from mmg_tuner.fleet.summary import write_summary
        result.summary = write_summary(od, manifest, result)
    return result


def _reason(exc: BaseException) -> str:
    return f'{type(exc).__name__}: {exc}'


def _finish(od: OutputDir, result: FleetResult, name: str, digest: str,
            final: jobs.StepOutput | jobs.Failure,
            steps: Sequence[jobs.StepOutput | None] | None,
            progress: Callable[[ShipOutcome], None] | None) -> None:
    """Write a ship's files (when it succeeded) and its record, last."""
    ship_dir = od.path / name
    old = read_record(ship_dir)
    if old is not None:  # the old record goes first: a kill mid-write leaves the ship undone
        (ship_dir / RECORD).unlink()
    written: list[str] = []
    failure = final if isinstance(final, jobs.Failure) else None
    if failure is None:
        # (no failure: the steps are given, the evaluate step's and the others' outputs)
        outputs = cast('Sequence[jobs.StepOutput | None]', steps)
        for sub, step in (('tune', outputs[0]), ('diagnose', outputs[1]),
                          ('', cast(jobs.StepOutput, final))):
            if step is None:
                continue
            for rel, data in step.files.items():
                path = Path(name, sub, rel) if sub else Path(name, rel)
                od.write_bytes(path, data)
                written.append(str(path.relative_to(name)))
    if old is not None:  # files of the previous run that this run did not rewrite (ours)
        for rel in old.files:
            if rel not in written and (ship_dir / rel).is_file():
                (ship_dir / rel).unlink()
    stage_s = {k: s.wall_s for k, s in zip(('tune', 'diagnose', 'evaluate'),
                                           [*(steps or (None, None)), final])
               if s is not None and not isinstance(s, jobs.Failure)}
    rec = ShipRecord(name, digest, 'failed' if failure else 'ok', written,
                     summary=None if failure else cast(jobs.StepOutput, final).summary,
                     failure=None if failure is None else {
                         'stage': failure.stage, 'reason': failure.reason,
                         'detail': failure.detail},
                     wall_s=sum(stage_s.values()), stage_s=stage_s,
                     finished=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec='seconds'))
    od.write_text(Path(name, RECORD), rec.to_json())
    result.ships[name] = ShipOutcome(name, 'failed' if failure else 'done', rec)
    if failure:
        logger.info('%s failed at %s: %s', name, failure.stage, failure.reason)
    if progress:
        progress(result.ships[name])
