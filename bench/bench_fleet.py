"""
Fleet throughput.

ships/hour on this machine with 1 and 2 Dask worker processes, and a scaling model from the
measured task sizes to 100 ships x 50 trials on N machines.

Each ship: SUZAKU with a hidden effect (a current, a rudder offset, or none), 6 trials of
240 s at 1 Hz (3 tune, 3 held out), tune (1500 evaluations) and diagnose (quick budget, three
candidate effects, one cause at most), as test/fleet/test_fleet.py runs them. A LocalCluster as
`fleet` starts it: one task thread per worker process, NUMBA_NUM_THREADS = cores // workers.

    python -m bench run bench_fleet [--quick] [--ships 4] [--workers 1 2]

--quick: 2 ships, 2 workers (about a minute; the scaling model needs 1 and 2 workers).

The model: a ship is a load task, then tune and diagnose side by side, then evaluate; the
client hashes, schedules and writes (serial). Per ship at 50 trials the tasks grow with the
trials (every evaluation simulates every trial), so
    T(N machines x c cores) = t_start + S t_client + max(S W / (N c eff), t_path)
with W the measured compute per ship scaled by trials, eff the measured parallel efficiency
on this machine, and t_path one ship's longest chain (load + diagnose + evaluate): a fleet
can never finish faster than its slowest ship.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
from pathlib import Path
import shutil
import sys
import tempfile
import time

from mmg_tuner.cli.generate import command as generate
from mmg_tuner.fleet import fleet, local_cluster
from mmg_tuner.fleet.jobs import cpu_count

KINDS = {'cur': ['--effect', 'current_speed=0.3', '--effect', 'current_dir=2.0'],
         'rud': ['--effect', 'rudder_offset=0.05'], 'clean': []}
MANEUVERS = ['turning:35', 'zigzag:20', 'turning:-25', 'random:30', 'zigzag:-15', 'turning:-35']
TUNE = ['turning_p35', 'turning_m25', 'zigzag_m15']
TEST = ['zigzag_p20', 'random_p30', 'turning_m35']
OPTIONS = {'budget': 'quick', 'max_effects': 1, 'max_evals': 1500,
           'effects': ['current', 'rudder_offset', 'yaw_moment_bias'], 'plots': False}
TRIALS_HERE = 6


def make_fleet(root: Path, n: int) -> dict:
    ships = []
    for i in range(n):
        kind = list(KINDS)[i % len(KINDS)]
        d = root / f'ship{i}'
        with contextlib.redirect_stdout(io.StringIO()):
            assert generate(['--out', str(d), '--duration', '240', '--rate-hz', '1',
                             '--seed', str(i), '--maneuvers', *MANEUVERS, *KINDS[kind]]) == 0
        ships.append({'name': f'ship{i}_{kind}', 'ship': 'suzaku',
                      'tune': [str(d / t) for t in TUNE], 'test': [str(d / t) for t in TEST]})
    return {'defaults': OPTIONS, 'ships': ships}


def run_fleet(manifest: dict, out: Path, workers: int) -> dict:
    from distributed import Client
    t0 = time.perf_counter()
    with local_cluster(workers, dashboard=False) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers, timeout=120)
        t_start = time.perf_counter() - t0
        t1 = time.perf_counter()
        res = fleet(manifest, out, client=client)
        wall = time.perf_counter() - t1
    recs = [json.loads((out / n / 'fleet_ship.json').read_text()) for n in res.ships]
    stage = {k: sum(r['stage_s'].get(k, 0.0) for r in recs) / len(recs)
             for k in ('tune', 'diagnose', 'evaluate')}
    stage['load'] = sum(r['summary']['inspect']['load_s'] for r in recs) / len(recs)
    return {'workers': workers, 'start_s': t_start, 'wall_s': wall, 'ships': len(recs),
            'ships_per_hour': 3600 * len(recs) / wall, 'stage_s': stage,
            'failed': res.failed}


def model_table(r1: dict, r2: dict, ships: int = 100, trials: int = 50,
                machines=(1, 2, 4, 8, 16, 32, 64, 128), cores: int = 2) -> list[str]:
    st = r2['stage_s']
    W = sum(st.values())                       # compute per ship here (one thread per task)
    scale = trials / TRIALS_HERE
    W50 = W * scale
    path50 = (st['load'] + st['diagnose'] + st['evaluate']) * scale
    # the serial part: what the fleet wall time holds beyond the compute spread over workers
    t_client = max(0.0, r2['wall_s'] - r2['ships'] * W / r2['workers']) / r2['ships']
    eff = r2['ships'] * W / (r2['workers'] * r2['wall_s'])
    lines = [f'per ship here ({TRIALS_HERE} trials): load {st["load"]:.2f} s, tune '
             f'{st["tune"]:.1f} s, diagnose {st["diagnose"]:.1f} s, evaluate '
             f'{st["evaluate"]:.2f} s (W = {W:.1f} s of compute)',
             f'serial (client: hash, schedule, write) ~{t_client:.2f} s per ship; parallel '
             f'efficiency with 2 workers {100 * eff:.0f} %; worker start-up '
             f'{r2["start_s"]:.1f} s',
             f'{ships} ships x {trials} trials: W = {W50 / 60:.1f} min per ship, longest chain '
             f'{path50 / 60:.1f} min', '',
             '| machines (2 cores) | task slots | predicted wall | ships/hour | bound by |',
             '|---|---|---|---|---|']
    for n in machines:
        slots = n * cores
        work = ships * W50 / (slots * eff)
        T = r2['start_s'] + ships * t_client + max(work, path50)
        bound = 'compute' if work >= path50 else "one ship's chain"
        if slots > 2 * ships:
            bound += '; idle slots (200 tasks)'
        lines.append(f'| {n} | {slots} | {T / 3600:.2f} h | {3600 * ships / T:.0f} | {bound} |')
    return lines


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run bench_fleet`` (``--quick``: 2 ships, 2 workers)."""
    return main((['--ships', '2', '--workers', '2'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--ships', type=int, default=4)
    ap.add_argument('--workers', type=int, nargs='+', default=[1, 2])
    args = ap.parse_args(argv)
    figures = {'ships': args.ships}
    root = Path(tempfile.mkdtemp(prefix='bench_fleet_'))
    try:
        manifest = make_fleet(root / 'trials', args.ships)
        print(f'{args.ships} synthetic ships, {cpu_count()} cores', flush=True)
        results = {}
        for w in args.workers:
            r = run_fleet(manifest, root / f'out{w}', w)
            results[w] = r
            print(f"{w} worker(s): {r['ships']} ships in {r['wall_s']:.1f} s "
                  f"(+{r['start_s']:.1f} s cluster start) = {r['ships_per_hour']:.0f} "
                  f"ships/hour; failed: {r['failed'] or 'none'}", flush=True)
        if 1 in results and 2 in results:
            print(f'speed-up 1 -> 2 workers: '
                  f"{results[1]['wall_s'] / results[2]['wall_s']:.2f} x")
            print('\n'.join(model_table(results[1], results[2])))
        figures['workers'] = [{k: v for k, v in r.items() if k != 'stage_s'}
                              for r in results.values()]
        figures['stage_s'] = {w: r['stage_s'] for w, r in results.items()}
    finally:
        shutil.rmtree(root, ignore_errors=True)  # our own temporary folder
    return figures


if __name__ == '__main__':
    main()
    sys.exit(0)
