"""
Time to read and resample one hour of 50 Hz odometry plus 50 Hz commands.

Per storage format (rosbag2 sqlite3, rosbag2 MCAP, bare MCAP). Target: under 5 s each.

  python bench/bench_read.py
"""
from __future__ import annotations

from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mmg_tuner.core import maneuvers as mv  # noqa: E402, I100
from mmg_tuner.core.ship import load_ship  # noqa: E402
from mmg_tuner.data.bag import write_trial_bag  # noqa: E402
from mmg_tuner.data.load import load_trials  # noqa: E402
from mmg_tuner.data.trial import Trial  # noqa: E402


def main() -> None:
    ship = load_ship('suzaku')
    spec = mv.ManeuverSpec('random', rudder_deg=30, duration_s=3600.0, dt=0.02, seed=1,
                           random_rpm_frac=0.1)
    tr = mv.run(ship, spec)
    trial = Trial(tr.t, tr.states, tr.controls, name='hour')
    n_msgs = 3 * len(trial)
    tmp = Path(tempfile.mkdtemp())
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
    finally:
        shutil.rmtree(tmp)


if __name__ == '__main__':
    main()
