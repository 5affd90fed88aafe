"""
Tune KVLCC2 on MARIN's two 35 deg turns and test it on the four MARIN zigzags.

KVLCC2 (standard MMG, model scale) tuned on MARIN's two 35 deg turns, tested on the four MARIN
zigzags: J and manoeuvring indices before and after. Runs the `tune` command. python
bench/tune_kvlcc2_marin.py [--evals N]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mmg_tuner.cli.tune import command as tune  # noqa: E402
from mmg_tuner.core.ship import load_ship  # noqa: E402
from mmg_tuner.data.marin import compare_with_marin, marin_data_dir, MARIN_FILES  # noqa: E402

OUT = Path(__file__).resolve().parent / 'out' / 'kvlcc2_marin'
OUT = OUT / time.strftime('%Y%m%d-%H%M%S')  # a new folder per run: --out refuses a used one


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--evals', type=int, default=20_000)
    args = ap.parse_args()
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
    for key, r in rows_pre.items():
        for idx, meas in r['measured'].items():
            print(f"| {key} | {idx} | {meas:.2f} | {r['simulated'][idx]:.2f} | "
                  f"{rows_hold[key]['simulated'][idx]:.2f} | "
                  f"{rows_tuned[key]['simulated'][idx]:.2f} |")


if __name__ == '__main__':
    main()
