"""
``generate``: synthetic trials of a ship (turning, zigzag, pull-out, random) with sensor noise.

Written as rosbag2 (MCAP by default) with the default topics, plus CSV (in DIR/csv/).

For a ship whose family covers astern propeller, u <= 0 and thrusters (lowspeed, e.g.
esso_osaka_3m) also low-speed trials: berthing:RUDDER (approach with RUDDER deg of helm, stop,
astern, thrusters push toward the side of RUDDER's sign) and random_astern:RUDDER (random
rudder, propeller ahead and astern, thruster steps); the thrusters go on their own topics.

--out may be a new or an existing folder; nothing in it is overwritten: a trial whose name is
taken (by a file already there or by an earlier manoeuvre of the same call) is written beside
it as NAME_2, NAME_3, ...

Examples
--------
A craft whose actuator declares its own catalogue (``TRIALS``, core/actuators/__init__.py)
sails that instead, at its rate with its sensors' noise (--only picks manoeuvres by name),
written as channel CSVs (DIR/csv/NAME.csv: t, the states, its input channels), its tables and
DIR/trials.yaml (which trial is for identification, which for validation; the stand-ins
used). Two thrusters (twin_azimuth: qiuxin_tug, otter_usv): the MBPE-LOGO paper's 12
identification manoeuvres, then mirrored zigzags, turns, random command sequences and
differential thrust, at 5 Hz with RTK-class noise, and a bollard-pull table
(DIR/bollard_pull.csv: n,thrust in rev/s and N per thruster).

generate --ship suzaku --out trials --maneuvers turning:35 turning:-35 zigzag:20 random:30
generate --ship esso_osaka_3m --out berth --maneuvers berthing:20 random_astern:30 \
    --duration 300
generate --ship qiuxin_tug --out tug
generate --ship qiuxin_tug --out tug_fouled --effect thrust_scale_stbd=0.85 \
    --effect azimuth_offset_port=0.0524 --effect current_speed=0.2 --effect current_dir=1.05

--effect hides any effect of the library (core/effects.py) in the truth, the tug's own among
them (azimuth_offset_port/_stbd [rad], thrust_scale_port/_stbd); --scale moves one coefficient
(e.g. N_r=1.45) outside the library.

"""
from __future__ import annotations

import argparse
from dataclasses import replace
import math
from pathlib import Path
import shutil
import sys
from types import ModuleType

from mmg_tuner._outdir import OutputDir
from mmg_tuner._ship_params import load_ship_with_params
from mmg_tuner.cli.args import bounded, positive_float
from mmg_tuner.cli.common import check_run, check_samples, Parser, run_command, SEED, UsageError
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.noise import Sigmas
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import self_propulsion_rpm
from mmg_tuner.data.assemble import MIN_SAMPLES
from mmg_tuner.data.bag import write_trial_bag
from mmg_tuner.data.csv_io import trial_csv_text
from mmg_tuner.data.generate import (generate_trial, out_of_library, parse_maneuver,
                                     SensorNoise, trial_kit)
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import ConfigError, MmgTunerError, OutputError, SimulationError
import yaml

# per trial: 1e6 samples is ~0.8 GB of bag (three topics a sample); a day at 10 Hz fits
MAX_TRIAL_SAMPLES = 1_000_000
DEFAULT_MANEUVERS = ('turning:10', 'turning:-20', 'turning:35', 'turning:-40', 'zigzag:20',
                     'random:30')
RATE_HZ = bounded(float, 1e-3, 1000.0, 'recording rate [Hz]')
THRUSTER_RPS = bounded(float, 0.0, 200.0, 'thruster speed [rev/s]')
DEFAULT_RPM = 106.0      # SUZAKU's approach (Suyama et al. 2023)
DEFAULT_SPEED_KN = 6.0
FALLBACK_FROUDE = 0.07   # approach of a ship for which 6 kn is implausible (a pond model)


def maneuver_spec(s: str) -> tuple[str, float, float | None]:
    """Argparse type of 'turning:35', 'zigzag:20/10', ... (see parse_maneuver)."""
    try:
        return parse_maneuver(s)
    except SimulationError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def effect_spec(s: str) -> tuple[str, float]:
    """Argparse type of NAME=VALUE with a finite VALUE."""
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
    ap = Parser(prog='generate', description=__doc__.strip().split('\n')[0])
    ap.add_argument('--ship', default='suzaku')
    ap.add_argument('--params', help='params.yaml overlay (e.g. true parameters moved)')
    ap.add_argument('--out', required=True,
                    help='output folder (new, or existing: nothing in it is overwritten)')
    ap.add_argument('--maneuvers', nargs='+', type=maneuver_spec, metavar='SPEC',
                    help='manoeuvre:rudder_deg[/check_deg] (zigzag only); default: '
                         + ' '.join(DEFAULT_MANEUVERS))
    ap.add_argument('--rpm', type=positive_float,
                    help=f'approach rpm (default {DEFAULT_RPM:g}; for a ship that cannot make '
                    f'{DEFAULT_SPEED_KN:g} kn, the rpm that holds the approach speed)')
    ap.add_argument('--speed-kn', type=positive_float,
                    help=f'approach speed [kn] (default {DEFAULT_SPEED_KN:g}, or Froude number '
                    f'{FALLBACK_FROUDE:g} for a ship that cannot make it, e.g. a pond model)')
    ap.add_argument('--thruster-rps', type=THRUSTER_RPS, default=20.0,
                    help='thruster speed of berthing / random_astern [rev/s] (0-200)')
    ap.add_argument('--duration', type=positive_float,
                    help='[s] per trial (default 800; a craft with its own catalogue: each '
                    "manoeuvre's own)")
    ap.add_argument('--rate-hz', type=RATE_HZ,
                    help='sensor/recording rate (0.001-1000 Hz; default 10, a craft with its own '
                    "catalogue: its actuator's, e.g. 5)")
    ap.add_argument('--only', nargs='+', metavar='NAME',
                    help='a craft with its own catalogue: only these manoeuvres of it')
    ap.add_argument('--no-noise', action='store_true', help='write the truth, no sensor noise')
    ap.add_argument('--effect', action='append', default=[], metavar='NAME=VALUE',
                    type=effect_spec,
                    help='hidden model extension parameter, e.g. current_speed=0.3 (repeatable)')
    ap.add_argument('--hull-scale', type=positive_float, default=1.0, metavar='FACTOR',
                    help='every hull force and moment x FACTOR, a change outside the effects '
                    'library (the polynomial hull coefficients; e.g. 1.45)')
    ap.add_argument('--scale', action='append', default=[], metavar='NAME=FACTOR',
                    type=effect_spec,
                    help='one parameter x FACTOR, e.g. N_r=1.45 (repeatable; outside the '
                    'effects library)')
    ap.add_argument('--record-wind', action='store_true',
                    help='also record the (steady) true wind on /wind, as an anemometer would')
    ap.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    ap.add_argument('--seed', type=SEED, default=0)
    ap.add_argument('--from-advice', metavar='DIAGNOSIS_JSON',
                    help='the trials a diagnosis advised (its diagnosis.json or folder), in '
                    'place of --maneuvers (each spec sets its own rpm, speed and duration); '
                    'each with its mirror to the other side: tune on one, hold the other out')
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


def approach(ship: ShipConfig, rpm: float | None, speed_kn: float | None
             ) -> tuple[float, float, str]:
    """
    Return (rpm, speed [m/s], note) of the approach.

    Options not given: 106 rpm and 6 kn (SUZAKU's), unless the ship cannot plausibly make
    6 kn (a pond model): then Froude number FALLBACK_FROUDE and the rpm that holds the speed
    (core.simulate.self_propulsion_rpm), with a note saying so.
    """
    small = DEFAULT_SPEED_KN * mv.KNOT > input_limits(ship).top_speed_ms
    notes = []
    if speed_kn is not None:
        speed = speed_kn * mv.KNOT
    elif small:
        speed = FALLBACK_FROUDE * math.sqrt(9.80665 * ship.L_pp)
        notes.append(f'{ship.name} cannot plausibly make {DEFAULT_SPEED_KN:g} kn: approach at '
                     f'{speed:.3f} m/s (Froude number {FALLBACK_FROUDE:g}; --speed-kn sets it)')
    else:
        speed = DEFAULT_SPEED_KN * mv.KNOT
    if rpm is None and small:
        try:
            rpm = self_propulsion_rpm(ship, speed)
        except SimulationError as exc:
            raise UsageError(f'--rpm not given and {exc}: give --rpm') from None
        notes.append(f'--rpm not given: {rpm:.1f} rpm holds {speed:.3f} m/s')
    elif rpm is None:
        rpm = DEFAULT_RPM
    return rpm, speed, '; '.join(notes)


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    maneuvers_given = bool(args.maneuvers)
    if not args.maneuvers:
        args.maneuvers = [parse_maneuver(m) for m in DEFAULT_MANEUVERS]
    ship = load_ship_with_params(args.ship, args.params)   # refuses another ship's params
    if args.effect:
        try:
            ship = ship.with_params(dict(args.effect))
        except ConfigError as exc:
            raise UsageError(f'--effect: {exc}') from None
    if args.hull_scale != 1.0 or args.scale:
        try:
            ship = out_of_library(ship, args.hull_scale, dict(args.scale))
        except ConfigError as exc:
            raise UsageError(f'--hull-scale/--scale: {exc}') from None
    kit = trial_kit(ship)
    if kit is not None and args.from_advice:   # catalogue manoeuvres a diagnosis advised
        args.rate_hz = float(kit.RATE_HZ) if args.rate_hz is None else args.rate_hz
        return _from_advice(args, ship, kit.Noise)
    if kit is not None:   # its actuator's own catalogue, channel CSVs, tables
        return _catalogue(args, ship, kit, maneuvers_given)
    if args.only:
        raise UsageError(f'--only: {ship.name} has no catalogue of its own; use --maneuvers')
    args.duration = 800.0 if args.duration is None else args.duration
    args.rate_hz = 10.0 if args.rate_hz is None else args.rate_hz
    if args.from_advice:  # the trials a diagnosis advised (diagnosis/advice.py)
        return _from_advice(args, ship)
    for kind, rud, _ in args.maneuvers:
        if kind in mv.LOWSPEED_MANEUVERS:
            try:
                mv.check_lowspeed(ship, kind)
            except SimulationError as exc:
                raise UsageError(f'--maneuvers {kind}:{rud:g}: {exc}') from None
    rpm, speed_ms, note = approach(ship, args.rpm, args.speed_kn)
    n = check_samples(args.duration * args.rate_hz + 1,
                      f'--duration {args.duration:g} x --rate-hz {args.rate_hz:g}',
                      MAX_TRIAL_SAMPLES)
    if n < MIN_SAMPLES:
        raise UsageError(f'--duration {args.duration:g} x --rate-hz {args.rate_hz:g} gives '
                         f'{n} sample(s) per trial; a usable trial needs at least {MIN_SAMPLES}')
    check_run(ship, rpm, speed_ms, '--speed-kn',
              [(f'--maneuvers {k}:{r:g}', r) for k, r, _ in args.maneuvers])
    if note:
        print(note)
    noise = SensorNoise.none() if args.no_noise else SensorNoise()
    out = OutputDir.open(args.out, resume=True)  # an existing folder is added to, not replaced
    written: list[str] = []
    try:
        for i, (kind, rud, chk) in enumerate(args.maneuvers):
            base = trial_name(kind, rud, chk)
            name = free_name(out.path, base, set(written))
            try:
                _, measured = generate_trial(ship, kind, rud, chk, rpm, speed_ms,
                                             args.duration, args.rate_hz, noise,
                                             args.seed + 100 * i, name,
                                             record_wind=args.record_wind,
                                             thruster_rps=args.thruster_rps)
                _write(out, measured, name, args.storage)
            except MmgTunerError as exc:
                done = ', '.join(f'{w}/ and csv/{w}.csv' for w in written) or 'nothing'
                raise type(exc)(f'{exc}; written so far in {out.path}: {done}') from None
            written.append(name)
            moved = f' ({base} is taken: written beside it)' if name != base else ''
            print(f'{name}: {len(measured)} samples at {args.rate_hz:g} Hz -> '
                  f'{out.path / name}/ and {out.path / "csv" / name}.csv{moved}'
                  f'{" (effects: " + str(dict(args.effect)) + ")" if args.effect else ""}')
    finally:
        out.close()
    return 0


def _write(out: OutputDir, trial: Trial, name: str, storage: str) -> None:
    """
    Write the bag, then the CSV.

    A bag left half-written by a failure (ours, of this run) is removed so that no corrupt
    recording stays behind.
    """
    bag = out.path / name
    try:
        write_trial_bag(trial, bag, storage)
    except (OutputError, OSError) as exc:
        if bag.exists():
            shutil.rmtree(bag, ignore_errors=True)  # created by this run, just now
        raise OutputError(f'writing {bag} failed ({getattr(exc, "strerror", None) or exc})'
                          ) from None
    out.write_text(Path('csv') / f'{name}.csv', trial_csv_text(trial))


def _from_advice(args: argparse.Namespace, ship: ShipConfig,
                 noise_model: type[Sigmas] = SensorNoise) -> int:
    """Sail the trials a diagnosis advised (``noise_model``: the craft's sensors)."""
    from mmg_tuner.diagnosis.advice import load_advice, trial_from_spec
    specs = load_advice(args.from_advice)
    noise = noise_model.none() if args.no_noise else noise_model()
    out = OutputDir.open(args.out, resume=True)
    written: list[str] = []
    try:
        for i, spec in enumerate(specs):
            name = free_name(out.path, spec.name, set(written))
            _, measured = trial_from_spec(ship, spec, args.rate_hz, noise, args.seed + 100 * i,
                                          name)
            _write(out, measured, name, args.storage)
            written.append(name)
            print(f'{name}: {spec.instruction()} -> {out.path / name}/ and '
                  f'{out.path / "csv" / name}.csv')
    finally:
        out.close()
    return 0


def _free_file(out: Path, stem: str, suffix: str) -> str:
    """stem, or stem_2, stem_3, ...: the first whose file stem + suffix is free in out."""
    cand, k = stem, 1
    while (out / f'{cand}{suffix}').exists():
        k += 1
        cand = f'{stem}_{k}'
    return cand


def _catalogue(args: argparse.Namespace, ship: ShipConfig, kit: ModuleType,
               maneuvers_given: bool) -> int:
    """Sail the catalogue the ship's actuator declares; write channel CSVs, tables, trials.yaml."""
    for flag, given in (('--maneuvers', maneuvers_given), ('--rpm', args.rpm),
                        ('--speed-kn', args.speed_kn), ('--record-wind', args.record_wind)):
        if given:
            raise UsageError(f"{flag}: {ship.name} sails its actuator's own catalogue "
                             '(--only NAME ... picks some)')
    catalogue = kit.catalogue(ship)
    if args.only:
        names = [m.name for m in catalogue]
        unknown = [n for n in args.only if n not in names]
        if unknown:
            raise UsageError(f'--only: no manoeuvre {", ".join(unknown)} in the catalogue of '
                             f'{ship.name}: {", ".join(names)}')
        catalogue = [m for m in catalogue if m.name in args.only]
    if args.duration is not None:
        catalogue = [replace(m, duration_s=args.duration) for m in catalogue]
    rate = float(kit.RATE_HZ) if args.rate_hz is None else args.rate_hz
    for m in catalogue:
        n = check_samples(m.duration_s * rate + 1, f'{m.name}: duration {m.duration_s:g} s x '
                          f'--rate-hz {rate:g}', MAX_TRIAL_SAMPLES)
        if n < MIN_SAMPLES:
            raise UsageError(f'{m.name}: {n} sample(s); a usable trial needs {MIN_SAMPLES}')
    noise = kit.Noise.none() if args.no_noise else kit.Noise()
    out = OutputDir.open(args.out, resume=True)
    roles: dict[str, list[str]] = {'identification': [], 'validation': []}
    taken: set[str] = set()
    try:
        for i, m in enumerate(catalogue):
            name = free_name(out.path, m.name, taken)
            _, measured = kit.generate(ship, replace(m, name=name), rate, noise,
                                       args.seed + 100 * i)
            out.write_text(Path('csv') / f'{name}.csv', trial_csv_text(measured))
            taken.add(name)
            roles.setdefault(m.role, []).append(name)
            print(f'{name}: {len(measured)} samples at {rate:g} Hz ({m.role}) -> '
                  f'{out.path / "csv" / name}.csv')
        written: dict[str, str] = {}
        for key, (header, rows, what) in kit.tables(ship, noise, args.seed).items():
            stem = _free_file(out.path, key, '.csv')
            out.write_text(f'{stem}.csv', header + '\n' + ''.join(
                ','.join(f'{v:.10g}' for v in row) + '\n' for row in rows))
            written[key] = f'{stem}.csv'
            print(f'{stem}.csv: {len(rows)} rows ({what})')
        listing = _free_file(out.path, 'trials', '.yaml')
        out.write_text(f'{listing}.yaml', yaml.safe_dump({
            'ship': ship.name, 'rate_hz': rate, 'noise': 'none' if args.no_noise else
            {k: float(v) for k, v in noise.__dict__.items()}, 'seed': args.seed,
            **written, **roles,
            'assumptions': str(kit.ASSUMPTIONS).format(source=ship.source or ship.name)},
            sort_keys=False))
        print(f'{len(roles["identification"])} identification and '
              f'{len(roles["validation"])} validation trials listed in '
              f'{out.path / listing}.yaml')
    finally:
        out.close()
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
