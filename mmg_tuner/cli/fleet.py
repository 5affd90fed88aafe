"""
``fleet``: tune and diagnose many ships on a Dask cluster (a LocalCluster by default).

Examples
--------
fleet fleet.yaml --out fleet_out                          # this machine, one worker per core
fleet fleet.yaml --out fleet_out --scheduler tcp://10.0.0.5:8786
fleet fleet.yaml --out fleet_out                          # again: up-to-date ships skipped

Exit status 0 when every ship ran or was up to date, 1 when some failed (each with its reason
in fleet.md and OUT/<ship>/fleet_ship.json), 2 on a usage or manifest error.

"""
from __future__ import annotations

import argparse
import sys
from typing import Any, cast, TYPE_CHECKING

from mmg_tuner.cli.args import positive_int
from mmg_tuner.cli.common import Parser, progress_bar, run_command, UsageError

if TYPE_CHECKING:   # annotations only: Dask and the fleet load when the command runs
    from distributed import Client

    from mmg_tuner.fleet.graph import ShipOutcome


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='fleet', description=__doc__.strip().split('\n')[0])
    ap.add_argument('manifest', help='fleet manifest YAML (ships, their trials and options)')
    ap.add_argument('--out', required=True,
                    help='output folder: new, empty, or an earlier fleet run (then resumed)')
    ap.add_argument('--scheduler', metavar='ADDRESS',
                    help='a running Dask scheduler, e.g. tcp://127.0.0.1:8786 (default: start '
                    'a LocalCluster here and close it at the end)')
    ap.add_argument('--workers', type=positive_int,
                    help='LocalCluster worker processes (default: one per core)')
    ap.add_argument('--timeout', type=positive_int, default=30,
                    help='seconds to wait for the scheduler and for a worker to appear')
    ap.add_argument('--no-fan-out', action='store_true',
                    help="run each diagnosis's candidate re-tunes inside its own task")
    ap.add_argument('--quiet', action='store_true', help='no progress bar')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.scheduler and args.workers:
        raise UsageError('fleet: --workers sizes a LocalCluster; with --scheduler the cluster '
                         'has its own workers')
    from mmg_tuner.fleet import _require_dask, local_cluster
    from mmg_tuner.fleet.graph import run
    from mmg_tuner.fleet.manifest import load_manifest
    from mmg_tuner.fleet.resume import check_fleet_dir

    _require_dask()
    manifest = load_manifest(args.manifest)       # every option checked before any work
    resumed = check_fleet_dir(args.out)
    from distributed import Client
    cluster = None
    try:
        if args.scheduler:
            try:
                client = Client(args.scheduler, timeout=args.timeout)
            except (OSError, TimeoutError) as exc:
                raise UsageError(f'--scheduler {args.scheduler}: cannot connect within '
                                 f'{args.timeout} s ({exc})') from None
        else:
            cluster = local_cluster(args.workers)
            client = Client(cluster)
        try:
            try:
                client.wait_for_workers(1, timeout=args.timeout)
            except (OSError, TimeoutError):
                raise UsageError(f'--scheduler {args.scheduler}: no worker joined within '
                                 f'{args.timeout} s (start some with: dask worker '
                                 f'{args.scheduler})') from None
            info = client.scheduler_info(n_workers=-1)
            print(f"fleet: {len(manifest)} ship(s) on {len(info['workers'])} worker(s); "
                  f'dashboard {_dashboard(client, info)}'
                  f"{'; resuming ' + args.out if resumed else ''}", file=sys.stderr)
            bar = None if args.quiet else progress_bar(len(manifest), 'ship', _show_outcome)
            try:
                res = run(manifest, args.out, client, fan_out=not args.no_fan_out,
                          progress=bar)
            finally:
                if bar is not None:
                    bar.close()
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()
    for name, o in res.ships.items():
        rec = o.record
        if o.status == 'failed':
            failure = cast('dict[str, str]', rec.failure)   # (a failed record has its failure)
            print(f"{name}: FAILED at {failure['stage']}: {failure['reason']}")
            continue
        dg = (rec.summary or {}).get('diagnose')
        causes = '; '.join(c['summary'] for c in dg['causes']) if dg else '-'
        print(f"{name}: {o.status}; causes: {causes or 'none'}")
    d = res.summary
    print(f"{d['counts']['done']} run, {d['counts']['skipped']} up to date, "
          f"{d['counts']['failed']} failed in {res.wall_s:.0f} s; wrote {args.out}/fleet.json, "
          'fleet.md, fleet.png')
    return 1 if res.failed else 0


def _dashboard(client: Client, info: dict[str, Any]) -> str:
    """Return the scheduler's dashboard address, when it serves one (it needs bokeh)."""
    if 'dashboard' not in info.get('services', {}):
        return 'not served by this scheduler (it needs bokeh)'
    return cast(str, client.dashboard_link)   # (distributed's property has no annotation)


def _show_outcome(bar: Any, outcome: ShipOutcome) -> None:   # bar: tqdm's (no annotations)
    bar.set_postfix_str(f'{outcome.name} {outcome.status}', refresh=False)
    bar.update(1)


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
