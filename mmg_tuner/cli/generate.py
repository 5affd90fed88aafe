"""``generate``: synthetic trials of a ship (turning, zigzag, pull-out, random) with sensor noise,
written as rosbag2 (MCAP by default) with the default topics, plus CSV (in DIR/csv/).

--out may be a new or an existing folder; nothing in it is overwritten: a trial whose name is
taken (by a file already there or by an earlier manoeuvre of the same call) is written beside
it as NAME_2, NAME_3, ...

Example:
    generate --ship suzaku --out trials --maneuvers turning:35 turning:-35 zigzag:20 random:30
"""
from __future__ import annotations

import argparse
import math
import shutil
import sys
from pathlib import Path

from mmg_tuner._outdir import OutputDir
from mmg_tuner.cli.args import bounded, positive_float
from mmg_tuner.cli.common import SEED, Parser, UsageError, check_run, check_samples, run_command
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.ship import load_ship
from mmg_tuner.data.assemble import MIN_SAMPLES
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.csv_io import csv_text
from mmg_tuner.data.generate import SensorNoise, generate_trial, parse_maneuver
from mmg_tuner.errors import ConfigError, MmgTunerError, OutputError, SimulationError

# per trial: 1e6 samples is ~0.8 GB of bag (three topics a sample); a day at 10 Hz fits
MAX_TRIAL_SAMPLES = 1_000_000
DEFAULT_MANEUVERS = ('turning:10', 'turning:-20', 'turning:35', 'turning:-40', 'zigzag:20',
                     'random:30')
RATE_HZ = bounded(float, 1e-3, 1000.0, 'recording rate [Hz]')


def maneuver_spec(s: str) -> tuple[str, float, float | None]:
    """argparse type of 'turning:35', 'zigzag:20/10', ... (see parse_maneuver)."""
    try:
        return parse_maneuver(s)
    except SimulationError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def effect_spec(s: str) -> tuple[str, float]:
    """argparse type of NAME=VALUE with a finite VALUE."""
    name, eq, val = s.partition('=')
    try:
        v = float(val)
    except ValueError:
        v = math.nan
    if not eq or not name.strip() or not math.isfinite(v):
        raise argparse.ArgumentTypeError(f'{s!r}: expected NAME=VALUE with a finite VALUE, '
                                         'e.g. current_speed=0.3')
    return name.strip(), v


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='generate', description=__doc__.split('\n')[0],
                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay (e.g. true parameters moved)')
    ap.add_argument('--out', required=True,
                    help='output folder (new, or existing: nothing in it is overwritten)')
    ap.add_argument('--maneuvers', nargs='+', type=maneuver_spec, metavar='SPEC',
                    help='manoeuvre:rudder_deg[/check_deg] (zigzag only); default: '
                         + ' '.join(DEFAULT_MANEUVERS))
    ap.add_argument('--rpm', type=positive_float, default=106.0)
    ap.add_argument('--speed-kn', type=positive_float, default=6.0)
    ap.add_argument('--duration', type=positive_float, default=800.0, help='[s] per trial')
    ap.add_argument('--rate-hz', type=RATE_HZ, default=10.0,
                    help='sensor/recording rate (0.001-1000 Hz)')
    ap.add_argument('--no-noise', action='store_true', help='write the truth, no sensor noise')
    ap.add_argument('--effect', action='append', default=[], metavar='NAME=VALUE',
                    type=effect_spec,
                    help='hidden model extension parameter, e.g. current_speed=0.3 (repeatable)')
    ap.add_argument('--record-wind', action='store_true',
                    help='also record the (steady) true wind on /wind, as an anemometer would')
    ap.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    ap.add_argument('--seed', type=SEED, default=0)
    ap.add_argument('--from-advice', metavar='DIAGNOSIS_JSON',
                    help="the trials a diagnosis advised (its diagnosis.json or folder), in "
                    "place of --maneuvers (each spec sets its own rpm, speed and duration)")
    return ap


def trial_name(kind: str, rud: float, chk: float | None) -> str:
    name = f'{kind}_{rud:+g}'.replace('+', 'p').replace('-', 'm').replace('.', '_')
    if chk is not None:
        name += f'_{chk:g}'.replace('-', 'm').replace('.', '_')
    return name


def free_name(out: Path, name: str, taken: set[str]) -> str:
    """name, or name_2, name_3, ... : the first whose bag and CSV are both free in out."""
    cand, k = name, 1
    while (cand in taken or (out / cand).exists() or (out / 'csv' / f'{cand}.csv').exists()):
        k += 1
        cand = f'{name}_{k}'
    return cand


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.maneuvers:
        args.maneuvers = [parse_maneuver(m) for m in DEFAULT_MANEUVERS]
    ship = load_ship(args.ship, args.params)
    if args.effect:
        try:
            ship = ship.with_params(dict(args.effect))
        except ConfigError as exc:
            raise UsageError(f'--effect: {exc}') from None
    if args.from_advice:  # the trials a diagnosis advised (diagnosis/advice.py)
        return _from_advice(args, ship)
    n = check_samples(args.duration * args.rate_hz + 1,
                      f'--duration {args.duration:g} x --rate-hz {args.rate_hz:g}',
                      MAX_TRIAL_SAMPLES)
    if n < MIN_SAMPLES:
        raise UsageError(f'--duration {args.duration:g} x --rate-hz {args.rate_hz:g} gives '
                         f'{n} sample(s) per trial; a usable trial needs at least {MIN_SAMPLES}')
    check_run(ship, args.rpm, args.speed_kn * mv.KNOT, '--speed-kn',
              [(f'--maneuvers {k}:{r:g}', r) for k, r, _ in args.maneuvers])
    noise = SensorNoise.none() if args.no_noise else SensorNoise()
    out = OutputDir.open(args.out, resume=True)  # an existing folder is added to, not replaced
    written: list[str] = []
    try:
        for i, (kind, rud, chk) in enumerate(args.maneuvers):
            base = trial_name(kind, rud, chk)
            name = free_name(out.path, base, set(written))
            try:
                _, measured = generate_trial(ship, kind, rud, chk, args.rpm,
                                             args.speed_kn * mv.KNOT, args.duration,
                                             args.rate_hz, noise, args.seed + 100 * i, name,
                                             record_wind=args.record_wind)
                _write(out, measured, name, args.storage)
            except MmgTunerError as exc:
                done = ', '.join(f'{w}/ and csv/{w}.csv' for w in written) or 'nothing'
                raise type(exc)(f'{exc}; written so far in {out.path}: {done}') from None
            written.append(name)
            moved = f' ({base} is taken: written beside it)' if name != base else ''
            print(f'{name}: {len(measured)} samples at {args.rate_hz:g} Hz -> '
                  f'{out.path / name}/ and csv/{name}.csv{moved}'
                  f'{" (effects: " + str(dict(args.effect)) + ")" if args.effect else ""}')
    finally:
        out.close()
    return 0


def _write(out: OutputDir, trial, name: str, storage: str) -> None:
    """The bag, then the CSV; a bag left half-written by a failure (ours, of this run) is
    removed so that no corrupt recording stays behind."""
    bag = out.path / name
    try:
        write_trial_bag(trial, bag, storage)
    except (OutputError, OSError) as exc:
        if bag.exists():
            shutil.rmtree(bag, ignore_errors=True)  # created by this run, just now
        raise OutputError(f'writing {bag} failed ({getattr(exc, "strerror", None) or exc})'
                          ) from None
    out.write_text(Path('csv') / f'{name}.csv',
                   csv_text(trial.t, trial.states, trial.controls, trial.wind))


def _from_advice(args, ship) -> int:
    from mmg_tuner.diagnosis.advice import load_advice, trial_from_spec
    specs = load_advice(args.from_advice)
    noise = SensorNoise.none() if args.no_noise else SensorNoise()
    out = OutputDir.open(args.out, resume=True)
    written: list[str] = []
    try:
        for i, spec in enumerate(specs):
            name = free_name(out.path, spec.name, set(written))
            _, measured = trial_from_spec(ship, spec, args.rate_hz, noise, args.seed + 100 * i,
                                          name)
            _write(out, measured, name, args.storage)
            written.append(name)
            print(f'{name}: {spec.instruction()} -> {out.path / name}/ and csv/{name}.csv')
    finally:
        out.close()
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
