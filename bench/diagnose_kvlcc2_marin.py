"""
The diagnosis on real data: KVLCC2 (standard MMG, model scale) on MARIN's free-running tests.

Tunes on both 35 deg turns and the two 10/10 zigzags and holds out the two 20/20 zigzags (the
turns must both be in the tuning set, or the port/starboard asymmetry cannot show in the tuning
error). Two runs:
  A. the ship's 12 targets, which include the asymmetric flow-straightening coefficients
     gamma_R+ / gamma_R- (they can bend to make port and starboard turns differ);
  B. the same without gamma_R+ / gamma_R- (held at their captive-model values), so that an
     asymmetry must come from an effect.
For each it prints what is named, what would fit but is impossible in a towing tank (wind,
current; an antenna offset: MARIN's positions are of the model's reference point), the advised
trials, the time per stage, and the starboard/port tactical-diameter ratio of the resulting
model against MARIN's (1.087). The setting is declared (--setting tank,reference), as the
MARIN reader's notes also say.

    python -m bench run diagnose_kvlcc2_marin [--quick] [--budget quick|standard] [--runs A B]
        [--dt 0.1]

--quick: run B only.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time

from mmg_tuner.cli.diagnose import command as diagnose
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.marin import compare_with_marin, marin_data_dir, MARIN_FILES

OUT = Path(__file__).resolve().parent / 'out' / 'kvlcc2_marin_diagnosis'
OUT = OUT / time.strftime('%Y%m%d-%H%M%S')  # a new folder per run: --out refuses a used one
TD = 'tactical_diameter_L'


def td_ratio(ship) -> tuple[float, float]:
    by = {r['manoeuvre']: r for r in compare_with_marin(ship, 'hold_speed')
          if r['manoeuvre'].startswith('turn')}
    m = by['turn_starboard_35']['measured'][TD] / by['turn_port_35']['measured'][TD]
    s = by['turn_starboard_35']['simulated'][TD] / by['turn_port_35']['simulated'][TD]
    return m, s


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run diagnose_kvlcc2_marin`` (``--quick``: run B only)."""
    return main((['--runs', 'B'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('--budget', default='quick')
    ap.add_argument('--runs', nargs='+', default=['A', 'B'], choices=['A', 'B'])
    ap.add_argument('--dt', default='0.1', help='resampling step [s] (full scale)')
    ap.add_argument('--retune', default='lsq', choices=['lsq', 'cmaes'])
    args = ap.parse_args(argv)
    d = marin_data_dir()
    tune = [str(d / MARIN_FILES[k]) for k in MARIN_FILES
            if k.startswith('turn') or '10' in k]
    test = [str(d / MARIN_FILES[k]) for k in MARIN_FILES if k.startswith('zigzag') and '20' in k]
    ship = load_ship('kvlcc2')
    all_targets = list(ship.tuning_targets)
    runs = {'A_all_targets': all_targets,
            'B_without_gamma_R': [t for t in all_targets if not t.startswith('gamma_R')]}
    m, s0 = td_ratio(ship)
    print(f'starboard/port tactical diameter: MARIN {m:.3f}; pre-determined model {s0:.3f}')
    figures = {'starboard_over_port_TD_MARIN': m, 'starboard_over_port_TD_pre': s0, 'runs': []}
    for name, targets in runs.items():
        if name[0] not in args.runs:
            continue
        out = OUT / name
        t0 = time.perf_counter()
        rc = diagnose(tune + ['--test'] + test + [
            '--ship', 'kvlcc2', '--trial-scale', 'full', '--dt', args.dt, '--budget',
            args.budget, '--targets', *targets, '--out', str(out), '--no-plots',
            '--setting', 'tank,reference', '--retune', args.retune])
        if rc:
            sys.exit(rc)
        doc = json.loads((out / 'diagnosis.json').read_text())
        tuned = load_ship('kvlcc2', out / 'params.yaml')
        base = ship.with_params(doc['baseline']['params'])
        print(f'\n== {name}: named {[c["summary"] for c in doc["causes"]] or "nothing"} '
              f'({time.perf_counter() - t0:.0f} s; stages {doc["timings_s"]})')
        for x in doc['would_fit_but_impossible']:
            print(f"   would fit, but impossible here: {x['effect']} (gain "
                  f"{100 * x['gain']:.1f} %): {x['reason']}")
        for a in doc['advice']:
            print(f"   advice ({a['about']}): {a['instruction']} (separation "
                  f"{a['separation']:.3g} vs recorded {a['separation_recorded']}; "
                  f"{'settles it' if a['settles'] else 'degenerate for these manoeuvres'})")
        print(f"   held-out J {doc['baseline']['J_test']:.4g} -> {doc['final']['J_test']:.4g}")
        print(f'   starboard/port TD ratio: tuned base {td_ratio(base)[1]:.3f}, final model '
              f'{td_ratio(tuned)[1]:.3f} (MARIN {m:.3f})')
        gam = {k: round(v, 3) for k, v in doc['baseline']['params'].items()
               if k.startswith('gamma_R')}
        figures['runs'].append({
            'run': name, 'named': ', '.join(c['summary'] for c in doc['causes']) or 'nothing',
            'wall_s': time.perf_counter() - t0, 'J_test_base': doc['baseline']['J_test'],
            'J_test_final': doc['final']['J_test'], 'TD_ratio_tuned_base': td_ratio(base)[1],
            'TD_ratio_final': td_ratio(tuned)[1]})
        if gam:
            print(f'   tuned gamma_R: {gam} (pre-determined '
                  f"{ship['gamma_Rp']:.3f} / {ship['gamma_Rn']:.3f})")
    return figures


if __name__ == '__main__':
    main()
