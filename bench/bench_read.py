"""
Time to read and resample one hour of 50 Hz odometry plus 50 Hz commands.

Per storage format (rosbag2 sqlite3, rosbag2 MCAP, bare MCAP). Target: under 5 s each.

  python -m bench run bench_read [--quick] [--duration S]

--quick reads ten minutes instead of an hour (the target applies to the hour).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import tempfile
import time

from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.load import load_trials
from mmg_tuner.data.trial import Trial
import numpy as np


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run bench_read`` (``--quick``: 600 s of recording)."""
    return main((['--duration', '600'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--duration', type=float, default=3600.0, help='recording length [s]')
    args = ap.parse_args(argv)
    ship = load_ship('suzaku')
    spec = mv.ManeuverSpec('random', rudder_deg=30, duration_s=args.duration, dt=0.02, seed=1,
                           random_rpm_frac=0.1)
    tr = mv.run(ship, spec)
    trial = Trial(tr.t, tr.states, tr.controls, name='hour')
    n_msgs = 3 * len(trial)
    tmp = Path(tempfile.mkdtemp())
    rows = []
    try:
        for storage in ('sqlite3', 'mcap'):
            bag = tmp / storage
            t0 = time.perf_counter()
            write_trial_bag(trial, bag, storage)
            t_write = time.perf_counter() - t0
            targets = [('rosbag2 ' + storage, bag)]
            if storage == 'mcap':
                targets.append(('bare MCAP', next(bag.glob('*.mcap'))))
            for label, path in targets:
                t0 = time.perf_counter()
                (back,) = load_trials(path)
                wall = time.perf_counter() - t0
                size = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
                print(f'{label:16s}: read + resample {wall:5.2f} s for {n_msgs:,} messages '
                      f'({n_msgs / wall:,.0f} msg/s), {len(back)} samples at 1 s; '
                      f'{size:.0f} MB; written in {t_write:.1f} s')
                assert np.isfinite(back.states).all()
                rows.append({'storage': label, 'read_and_resample_s': wall,
                             'messages_per_s': n_msgs / wall, 'size_MB': size,
                             'written_s': t_write})
    finally:
        shutil.rmtree(tmp)
    return {'recording_s': args.duration, 'messages': n_msgs, 'storage': rows}


if __name__ == '__main__':
    main()
