"""
The guide's ``tune --model auto`` on the 33 pond runs, timed; its interval with other members.

    python -m bench run interval_members [--quick]

Registered in bench/interval_members_preregistration.md (issue 46 item 5: an interval whose
factors are near 1 because the members' spread reflects the error, coverage 80-95 %). Runs
the user's command (doc/guides/hybrid.md): ``tune data/esso_osaka_frt/{turning,zigzag,random,
berthing} --ship esso_osaka_3m --dt 0.5 --model auto --residual-seeds 3``, prints its wall
time, then calibrates the recommended model's 90 % interval (``calibrate_interval``, restarts
every 100 s, on the validation part of the 33 runs: the last quarter of each) with each
registered member set and prints the factors and the coverage on the seven fresh runs
(data/esso_osaka_frt_extra, read as the command reads them, 0.5 s grid):

* M1: the recommended model's own networks (each with the tuned physics): today's interval;
* M2: M1 and the tuned physics alone (members that differ in physics);
* M3: M2 and the published physics alone;
* N1-N3: M1-M3 with the recorded start's error in the spread (amendment 2:
  ``calibrate_interval(start_error=True)``).

Success (registered): the largest factor <= 3 and the fresh coverage in [0.80, 0.95]; the
first set of M1-M3, and (amendment 2) of N1-N3, within the factor bound is the choice.
``--quick``: the zigzag and random runs, 3 epochs per network (a check that it runs).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import tempfile
import time

import mmg_tuner as mt
from mmg_tuner.cli.tune import command as tune
from mmg_tuner.errors import TuningError
from mmg_tuner.learn.model import as_model, Model
from mmg_tuner.learn.train import ResidualConfig, split_validation
from mmg_tuner.tuning.evaluate import INDEX_STATES
from mmg_tuner.tuning.interval import (calibrate_interval, coverage, ensemble_members,
                                       model_interval)

ROOT = Path(__file__).resolve().parents[1]
PONDS = ROOT / 'data' / 'esso_osaka_frt'
FRESH = ROOT / 'data' / 'esso_osaka_frt_extra'
SHIP = 'esso_osaka_3m'
MAX_FACTOR = 3.0
COVERAGE = (0.80, 0.95)


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run interval_members``."""
    return main((['--quick'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(prog='python -m bench run interval_members')
    ap.add_argument('--quick', action='store_true')
    args = ap.parse_args(argv)
    kinds = ('zigzag', 'random') if args.quick else ('turning', 'zigzag', 'random', 'berthing')
    paths = [str(PONDS / k) for k in kinds]
    extra = ['--residual-epochs', '3'] if args.quick else []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'auto'
        t0 = time.perf_counter()
        code = tune([*paths, '--ship', SHIP, '--dt', '0.5', '--model', 'auto',
                     '--residual-seeds', '3', '--out', str(out), *extra])
        auto_s = time.perf_counter() - t0
        if code != 0:
            raise SystemExit(f'tune --model auto exited with {code}')
        report = json.loads((out / 'report.json').read_text())
        model = as_model(mt.load_model(SHIP, out / 'params.yaml'))
    chosen = report['model_choice']['chosen']
    print(f'tune --model auto: {auto_s:.0f} s wall; recommended: {chosen}')
    figures: dict = {'auto_wall_s': auto_s, 'recommended': chosen, 'quick': args.quick}
    if model.residual is None:
        print('the physics alone was recommended: no interval to compare')
        return figures
    window = ResidualConfig().window
    val = split_validation(mt.load_trials(paths, model.ship, dt=0.5), 0.25, window)[1]
    fresh = mt.load_trials([FRESH], model.ship, dt=0.5)
    if chosen != 'blend':   # the registered sets are the blend's six networks and more
        print(f'the {chosen} was recommended: the registered member sets (the blend of hybrid '
              'and network seeds) do not apply; nothing compared')
        figures['registered_sets'] = False
        return figures
    own = list(ensemble_members(model))
    physics = Model(model.ship, None)
    published = Model(mt.load_ship(SHIP), None)
    sets = {'M1': own, 'M2': own + [physics], 'M3': own + [physics, published]}
    print('| members | ' + ' | '.join(INDEX_STATES) + ' | largest | fresh coverage |')
    print('|---|' + '---|' * (len(INDEX_STATES) + 2))
    rows = {}
    for name, mem, start in [(n, m, False) for n, m in sets.items()] + \
            [('N' + n[1:], m, True) for n, m in sets.items()]:
        try:
            iv = calibrate_interval(model, val, 0.9, members=mem, start_error=start)
        except TuningError as exc:
            print(f'| {name} | not calibrated: {exc} |')
            continue
        cov = coverage(iv, fresh)
        ok = max(iv.scale) <= MAX_FACTOR and COVERAGE[0] <= cov['all'] <= COVERAGE[1]
        rows[name] = {'members': len(mem), 'scale': dict(zip(INDEX_STATES, iv.scale)),
                      'largest': max(iv.scale), 'fresh_coverage': cov['all'],
                      'fresh_coverage_states': cov['states'], 'success': ok,
                      'start_sigma': iv.to_dict().get('start_sigma')}
        print(f'| {name} ({len(mem)}) | ' + ' | '.join(f'{c:.2f}' for c in iv.scale)
              + f' | {max(iv.scale):.2f} | {cov["all"]:.3f} |')
    written = model_interval(model)   # the interval tune --model auto wrote (N3's rule)
    if written is not None:
        cov = coverage(written, fresh)
        rows['written'] = {'members': len(written.members),
                           'scale': dict(zip(INDEX_STATES, written.scale)),
                           'largest': max(written.scale), 'fresh_coverage': cov['all'],
                           'fresh_coverage_states': cov['states']}
        print(f'| written by tune ({len(written.members)}) | '
              + ' | '.join(f'{c:.2f}' for c in written.scale)
              + f' | {max(written.scale):.2f} | {cov["all"]:.3f} |')
    for group in 'MN':
        first = next((n for n, r in rows.items() if n[0] == group
                      and r['largest'] <= MAX_FACTOR), None)
        print(f'registered choice among {group}1-{group}3 (the first set with every factor '
              '<= 3): ' + (f'{first}, fresh coverage {rows[first]["fresh_coverage"]:.3f} '
                           f'({"pass" if rows[first]["success"] else "fail"})' if first else
                           'none: item 5 not met by these member sets'))
        figures[f'first_within_bound_{group}'] = first
    figures.update({'sets': rows, 'first_within_bound': figures['first_within_bound_M']})
    return figures


if __name__ == '__main__':
    main()
