"""
Fleet scale: many ships, each with its trials, tuned and diagnosed on a Dask cluster.

    >>> import mmg_tuner as mt
    >>> res = mt.fleet('fleet.yaml', 'fleet_out')                   # a LocalCluster here
    >>> from distributed import Client
    >>> res = mt.fleet('fleet.yaml', 'fleet_out', client=Client('tcp://scheduler:8786'))
    >>> res.failed, res.summary['causes']

Imports only the layers below it (core, data, tuning, diagnosis, api); Dask is imported when
a fleet runs, so ``import mmg_tuner`` stays light. See :mod:`.manifest` for the manifest,
:mod:`.graph` for the task graph and threads, :mod:`.resume` for what is skipped.
"""
from __future__ import annotations

import logging
from pathlib import Path
import sys
import types
from typing import Any, Callable, TYPE_CHECKING

from mmg_tuner.errors import ConfigError

if TYPE_CHECKING:   # annotations only: Dask and the fleet's modules load when a fleet runs
    from distributed import Client, LocalCluster

    from mmg_tuner.fleet.graph import FleetResult, ShipOutcome
    from mmg_tuner.fleet.manifest import Manifest

__all__ = ['fleet', 'load_manifest', 'manifest_from_dict', 'local_cluster']

logger = logging.getLogger(__name__)


def load_manifest(path: str | Path) -> Manifest:
    from mmg_tuner.fleet.manifest import load_manifest as _load
    return _load(path)


def manifest_from_dict(doc: Any, path: str | Path | None = None) -> Manifest:
    from mmg_tuner.fleet.manifest import manifest_from_dict as _from
    return _from(doc, path)


def _require_dask() -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise ConfigError('the fleet needs Dask: pip install dask distributed (versions in '
                          'requirements.txt)') from None


def local_cluster(n_workers: int | None = None, dashboard: bool = True) -> LocalCluster:
    """
    Return a LocalCluster on 127.0.0.1 that does not oversubscribe the cores.

    n_workers processes (default: one per core) with one task thread each, and NUMBA_NUM_THREADS =
    cores // n_workers in their environment.
    """
    _require_dask()
    from distributed import LocalCluster

    from mmg_tuner.fleet.jobs import cpu_count
    cores = cpu_count()
    n = n_workers or cores
    if n < 1:
        raise ConfigError(f'--workers {n}: must be >= 1')
    numba_threads = max(1, cores // n)
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host='127.0.0.1',
                        dashboard_address='127.0.0.1:0' if dashboard else None,
                        env={'NUMBA_NUM_THREADS': str(numba_threads),
                             'OMP_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1',
                             'OPENBLAS_NUM_THREADS': '1'},
                        silence_logs=logging.WARNING)


def fleet(manifest: Any, out: str | Path, client: Client | None = None, *,
          n_workers: int | None = None, fan_out: bool = True,
          progress: Callable[[ShipOutcome], None] | None = None) -> FleetResult:
    """
    Run a fleet: every ship of ``manifest`` (a YAML path, a dict, or a.

    :class:`~mmg_tuner.fleet.manifest.Manifest`) loaded, tuned, diagnosed and evaluated as
    Dask tasks, results in ``out``/<ship>/ and the fleet summary in ``out``/fleet.json,
    fleet.md, fleet.png.

    ``client``: a ``distributed.Client`` of your cluster; without one a LocalCluster
    (:func:`local_cluster`, ``n_workers`` processes) is started and closed. ``out`` must be
    new, empty, or an earlier fleet's output: then ships whose inputs and options are
    unchanged are skipped (content hashes) and the rest (changed, failed, unfinished) are
    run. One ship's failure is recorded with its reason; the others go on.
    Returns a :class:`~mmg_tuner.fleet.graph.FleetResult`.
    """
    _require_dask()
    from mmg_tuner.fleet.graph import run
    from mmg_tuner.fleet.manifest import Manifest
    from mmg_tuner.fleet.manifest import load_manifest as _load
    from mmg_tuner.fleet.manifest import manifest_from_dict as _from
    from mmg_tuner.fleet.resume import check_fleet_dir

    if isinstance(manifest, (str, Path)):
        manifest = _load(manifest)
    elif isinstance(manifest, dict):
        manifest = _from(manifest)
    elif not isinstance(manifest, Manifest):
        raise ConfigError(f'manifest: expected a YAML path, a dict or a Manifest, got '
                          f'{type(manifest).__name__}')
    resumed = check_fleet_dir(Path(out))
    if client is not None:
        return run(manifest, out, client, fan_out=fan_out, progress=progress,
                   resumed=resumed)
    from distributed import Client
    with local_cluster(n_workers) as cluster, Client(cluster) as own:
        logger.info('LocalCluster: %d worker(s); dashboard %s', len(cluster.workers),
                    cluster.dashboard_link)
        return run(manifest, out, own, fan_out=fan_out, progress=progress, resumed=resumed)


class _CallableModule(types.ModuleType):
    """
    Make ``mt.fleet(manifest, out)`` callable although ``mt.fleet`` is a package.

    ``mt.fleet`` is this package once it is imported (Python binds a subpackage to its parent's
    attribute), so the package itself calls :func:`fleet`: ``mt.fleet(manifest, out)`` works either
    way.
    """

    def __call__(self, manifest: Any, out: str | Path, client: Client | None = None,
                 **kw: Any) -> FleetResult:
        return fleet(manifest, out, client, **kw)


sys.modules[__name__].__class__ = _CallableModule
