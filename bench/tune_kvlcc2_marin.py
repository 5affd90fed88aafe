"""
Tune KVLCC2 on MARIN's two 35 deg turns and test it on the four MARIN zigzags.

KVLCC2 (standard MMG, model scale) tuned on MARIN's two 35 deg turns, tested on the four MARIN
zigzags: J and manoeuvring indices before and after. Runs the `tune` command.
    python -m bench run tune_kvlcc2_marin [--quick] [--evals N]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time

from mmg_tuner.cli.tune import command as tune
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.marin import compare_with_marin, marin_data_dir, MARIN_FILES

OUT = Path(__file__).resolve().parent / 'out' / 'kvlcc2_marin'
OUT = OUT / time.strftime('%Y%m%d-%H%M%S')  # a new folder per run: --out refuses a used one


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run tune_kvlcc2_marin`` (``--quick``: 2000 evaluations)."""
    return main((['--evals', '2000'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser()
    ap.add_argument('--evals', type=int, default=20_000)
    args = ap.parse_args(argv)
    d = marin_data_dir()
    turns = [str(d / MARIN_FILES[k]) for k in ('turn_port_35', 'turn_starboard_35')]
    zigzags = [str(d / f) for k, f in MARIN_FILES.items() if k.startswith('zigzag')]
    rc = tune(turns + ['--test'] + zigzags + [
        '--ship', 'kvlcc2', '--trial-scale', 'full', '--dt', '0.1', '--integrator', 'rk4',
        '--out', str(OUT), '--max-evals', str(args.evals), '--quiet'])
    if rc:
        sys.exit(rc)
    rep = json.loads((OUT / 'report.json').read_text())
    J = rep['J']
    print(f"J tune (35 deg turns): {J['pre']['tune']:.4g} -> {J['tuned']['tune']:.4g} "
          f"({100 * (1 - J['tuned']['tune'] / J['pre']['tune']):.1f} % lower)")
    print(f"J test (zigzags):      {J['pre']['test']:.4g} -> {J['tuned']['test']:.4g} "
          f"({100 * (1 - J['tuned']['test'] / J['pre']['test']):.1f} % lower)")
    print(f"on a bound: {rep['bounds_hit']}; {rep['evaluations']} evaluations, "
          f"{rep['wall_s']:.0f} s")
    pre = load_ship('kvlcc2')
    tuned = load_ship('kvlcc2', OUT / 'params.yaml')
    rows_pre = {r['manoeuvre']: r for r in compare_with_marin(pre, 'recorded')}
    rows_hold = {r['manoeuvre']: r for r in compare_with_marin(pre, 'hold_speed')}
    rows_tuned = {r['manoeuvre']: r for r in compare_with_marin(tuned, 'recorded')}
    print('| manoeuvre | index | MARIN | pre, recorded rpm | pre, speed-holding rpm | tuned, '
          'recorded rpm |')
    print('|---|---|---|---|---|---|')
    table = []
    for key, r in rows_pre.items():
        for idx, meas in r['measured'].items():
            table.append({'manoeuvre': key, 'index': idx, 'MARIN': meas,
                          'pre, recorded rpm': r['simulated'][idx],
                          'pre, speed-holding rpm': rows_hold[key]['simulated'][idx],
                          'tuned, recorded rpm': rows_tuned[key]['simulated'][idx]})
            print(f"| {key} | {idx} | {meas:.2f} | {r['simulated'][idx]:.2f} | "
                  f"{rows_hold[key]['simulated'][idx]:.2f} | "
                  f"{rows_tuned[key]['simulated'][idx]:.2f} |")
    return {'evaluations': rep['evaluations'], 'tuning_s': rep['wall_s'],
            'J_tune_lower_percent': 100 * (1 - J['tuned']['tune'] / J['pre']['tune']),
            'J_test_lower_percent': 100 * (1 - J['tuned']['test'] / J['pre']['test']),
            'on_bound': rep['bounds_hit'], 'indices': table}


if __name__ == '__main__':
    main()
