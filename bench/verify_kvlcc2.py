"""
KVLCC2 (standard MMG method, model scale) against MARIN's free-running tests.

Prints the table of the benchmark page.
    python -m bench run verify_kvlcc2 [--rpm hold_speed|recorded]
"""
from __future__ import annotations

import argparse

from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.marin import compare_with_marin


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run verify_kvlcc2`` (quick already)."""
    return main(argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--rpm', choices=('hold_speed', 'recorded'), default='hold_speed')
    args = ap.parse_args(argv)
    ship = load_ship('kvlcc2')
    rows = compare_with_marin(ship, args.rpm)
    print(f'KVLCC2 vs MARIN (SIMMAN 2008), rpm = {args.rpm}; lengths in L_pp, angles in deg')
    print('| manoeuvre | index | MARIN | MMG | diff |')
    print('|---|---|---|---|---|')
    table = []
    for r in rows:
        for k, meas in r['measured'].items():
            sim = r['simulated'][k]
            diff = f'{100 * (sim / meas - 1):+.1f} %' if k.endswith('_L') \
                else f'{sim - meas:+.1f} deg'
            print(f"| {r['manoeuvre']} (rpm {r['rpm']:.0f}) | {k} | {meas:.2f} | {sim:.2f} | "
                  f'{diff} |')
            table.append({'manoeuvre': r['manoeuvre'], 'rpm': r['rpm'], 'index': k,
                          'MARIN': meas, 'MMG': sim, 'diff': diff})
    td = 'tactical_diameter_L'
    by = {r['manoeuvre']: r for r in rows}
    m = by['turn_starboard_35']['measured'][td] / by['turn_port_35']['measured'][td]
    s = by['turn_starboard_35']['simulated'][td] / by['turn_port_35']['simulated'][td]
    print(f'starboard/port tactical diameter: MARIN {m:.3f}, standard MMG {s:.3f}')
    return {'rpm': args.rpm, 'indices': table, 'starboard_over_port_TD_MARIN': m,
            'starboard_over_port_TD_MMG': s}


if __name__ == '__main__':
    main()
