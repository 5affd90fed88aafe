"""``generate``: synthetic trials of a ship (turning, zigzag, pull-out, random) with sensor noise,
written as rosbag2 (MCAP by default) with the default topics, plus CSV (in DIR/csv/).

Example:
    generate --ship suzaku --out trials --maneuvers turning:35 turning:-35 zigzag:20 random:30
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mmg_tuner.cli.common import run_command
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.csv_io import write_trial_csv
from mmg_tuner.data.generate import SensorNoise, generate_trial, parse_maneuver
from mmg_tuner.errors import ConfigError


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog='generate', description=__doc__.split('\n')[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay (e.g. true parameters moved)')
    ap.add_argument('--out', required=True, help='output directory')
    ap.add_argument('--maneuvers', nargs='+',
                    default=['turning:10', 'turning:-20', 'turning:35', 'turning:-40',
                             'zigzag:20', 'random:30'],
                    help='manoeuvre:rudder_deg[/check_deg]')
    ap.add_argument('--rpm', type=float, default=106.0)
    ap.add_argument('--speed-kn', type=float, default=6.0)
    ap.add_argument('--duration', type=float, default=800.0, help='[s] per trial')
    ap.add_argument('--rate-hz', type=float, default=10.0, help='sensor/recording rate')
    ap.add_argument('--no-noise', action='store_true', help='write the truth, no sensor noise')
    ap.add_argument('--effect', action='append', default=[], metavar='NAME=VALUE',
                    help='hidden model extension parameter, e.g. current_speed=0.3 (repeatable)')
    ap.add_argument('--record-wind', action='store_true',
                    help='also record the (steady) true wind on /wind, as an anemometer would')
    ap.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    ap.add_argument('--seed', type=int, default=0)
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    ship = load_ship(args.ship, args.params)
    effects = {}
    for item in args.effect:
        k, _, v = item.partition('=')
        try:
            effects[k.strip()] = float(v)
        except ValueError:
            raise ConfigError(f'--effect {item!r}: expected NAME=VALUE') from None
    if effects:
        ship = ship.with_params(effects)
    out = Path(args.out)
    noise = SensorNoise.none() if args.no_noise else SensorNoise()
    for i, spec in enumerate(args.maneuvers):
        kind, rud, chk = parse_maneuver(spec)
        name = f'{kind}_{rud:+g}'.replace('+', 'p').replace('-', 'm').replace('.', '_')
        if chk is not None:
            name += f'_{chk:g}'
        _, measured = generate_trial(ship, kind, rud, chk, args.rpm, args.speed_kn * mv.KNOT,
                                     args.duration, args.rate_hz, noise, args.seed + 100 * i,
                                     name, record_wind=args.record_wind)
        bag = out / name
        if bag.exists():
            import shutil
            shutil.rmtree(bag)
        write_trial_bag(measured, bag, args.storage)
        write_trial_csv(measured, out / 'csv' / f'{name}.csv')
        print(f'{name}: {len(measured)} samples at {args.rate_hz:g} Hz -> {bag}/ and '
              f'csv/{name}.csv'
              f'{" (effects: " + str(effects) + ")" if effects else ""}')
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
