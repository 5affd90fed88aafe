"""
KVLCC2 (standard MMG method, model scale) against MARIN's free-running tests.

Prints the table in the README.  python bench/verify_kvlcc2.py [--rpm hold_speed|recorded]
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mmg_tuner.core.ship import load_ship  # noqa: E402
from mmg_tuner.data.marin import compare_with_marin  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--rpm', choices=('hold_speed', 'recorded'), default='hold_speed')
    args = ap.parse_args()
    ship = load_ship('kvlcc2')
    rows = compare_with_marin(ship, args.rpm)
    print(f'KVLCC2 vs MARIN (SIMMAN 2008), rpm = {args.rpm}; lengths in L_pp, angles in deg')
    print('| manoeuvre | index | MARIN | MMG | diff |')
    print('|---|---|---|---|---|')
    for r in rows:
        for k, meas in r['measured'].items():
            sim = r['simulated'][k]
            diff = f'{100 * (sim / meas - 1):+.1f} %' if k.endswith('_L') \
                else f'{sim - meas:+.1f} deg'
            print(f"| {r['manoeuvre']} (rpm {r['rpm']:.0f}) | {k} | {meas:.2f} | {sim:.2f} | "
                  f'{diff} |')
    td = 'tactical_diameter_L'
    by = {r['manoeuvre']: r for r in rows}
    m = by['turn_starboard_35']['measured'][td] / by['turn_port_35']['measured'][td]
    s = by['turn_starboard_35']['simulated'][td] / by['turn_port_35']['simulated'][td]
    print(f'starboard/port tactical diameter: MARIN {m:.3f}, standard MMG {s:.3f}')


if __name__ == '__main__':
    main()
