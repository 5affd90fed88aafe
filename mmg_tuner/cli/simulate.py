r"""
``simulate``: one manoeuvre of a ship config, written as CSV, with its manoeuvring indices.

Examples
--------
simulate --ship suzaku --maneuver turning --rudder-deg 35 --rpm 106 --speed-kn 6 \
    --duration 900 --dt 1.0 --integrator euler --out run.csv

"""
from __future__ import annotations

import argparse
import math
import sys

from mmg_tuner.cli.args import bounded, finite_float, nonneg_float, positive_float
from mmg_tuner.cli.common import (check_new_file, check_run, check_samples, Parser, run_command,
                                  SEED, UsageError, write_new_file)
from mmg_tuner.core import indices as ix
from mmg_tuner.core import maneuvers as mv
from mmg_tuner.core.limits import input_limits
from mmg_tuner.data.csv_io import csv_text
from mmg_tuner.learn.maneuver import hybrid_maneuver
from mmg_tuner.learn.model import load_model


SUBSTEPS = bounded(int, 1, 1000, 'number of substeps')


def check_angle(s: str) -> float:
    """Return a zigzag check angle [deg]: 0 < |angle| <= 90 (its sign is not used)."""
    v = finite_float(s)
    if not 0 < abs(v) <= 90:
        raise argparse.ArgumentTypeError(f'check angle {s!r} must satisfy 0 < |angle| <= 90 deg')
    return v


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='simulate', description=__doc__.strip().split('\n')[0])
    ap.add_argument('--ship', default='suzaku', help='ship config name or YAML path')
    ap.add_argument('--params', help='params.yaml with tuned values to overlay')
    ap.add_argument('--maneuver', choices=mv.MANEUVERS, default='turning')
    ap.add_argument('--rudder-deg', type=finite_float, default=35.0,
                    help="rudder angle (zigzag amplitude); + = starboard; within the ship's limit")
    ap.add_argument('--check-deg', type=check_angle,
                    help='zigzag check angle (default = rudder)')
    ap.add_argument('--rpm', type=positive_float, default=106.0,
                    help="propeller revolutions [rpm], up to the ship's plausible maximum")
    speed = ap.add_mutually_exclusive_group()
    speed.add_argument('--speed-kn', type=positive_float, default=6.0, help='approach speed [kn]')
    speed.add_argument('--speed-ms', type=positive_float, help='approach speed [m/s]')
    ap.add_argument('--duration', type=positive_float, default=900.0, help='[s]')
    ap.add_argument('--dt', type=positive_float, default=1.0,
                    help='output sample step [s]; dt / substeps is the integration step')
    ap.add_argument('--substeps', type=SUBSTEPS, default=1,
                    help='integration steps per sample (1-1000)')
    ap.add_argument('--integrator', choices=('euler', 'rk4'), default='euler')
    ap.add_argument('--approach', type=nonneg_float, default=0.0,
                    help='straight run before the rudder is executed [s], < duration')
    ap.add_argument('--pullout-after', type=positive_float, default=300.0,
                    help='pull-out: time the rudder is held before returning to 0 [s]')
    ap.add_argument('--rudder-rate', type=nonneg_float,
                    help="steering-gear rate [deg/s]; 0 = instantaneous; default: the ship's")
    ap.add_argument('--seed', type=SEED, default=0, help='random manoeuvre seed')
    ap.add_argument('--out', help='new CSV file to write (t,x,y,psi,u,v,r,rpm,rudder); an '
                                  'existing file is never overwritten')
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    model = load_model(args.ship, args.params)   # with the network the params name, if any
    ship, net = model.ship, model.residual
    speed = args.speed_ms if args.speed_ms is not None else args.speed_kn * mv.KNOT
    check_run(ship, args.rpm, speed, '--speed-ms' if args.speed_ms is not None else '--speed-kn',
              [('--rudder-deg', args.rudder_deg)])
    step = args.dt / args.substeps
    problem = input_limits(ship).check_dt(step)
    if problem:
        raise UsageError(f'--dt {args.dt:g} / --substeps {args.substeps}: integration step '
                         f'{problem} for {ship.name}')
    check_samples(args.duration / args.dt + 1, f'--duration {args.duration:g} / --dt {args.dt:g}')
    if args.approach >= args.duration:
        raise UsageError(f'--approach {args.approach:g} s must be shorter than --duration '
                         f'{args.duration:g} s (the rudder would never be executed)')
    if args.out:
        check_new_file(args.out, '--out')
    spec = mv.ManeuverSpec(
        maneuver=args.maneuver, rudder_deg=args.rudder_deg, check_deg=args.check_deg,
        rpm=args.rpm, speed_ms=speed, duration_s=args.duration, dt=args.dt,
        approach_s=args.approach, pullout_s=args.pullout_after,
        rudder_rate_deg_s=args.rudder_rate, integrator=args.integrator,
        substeps=args.substeps, seed=args.seed)
    if net is not None:   # the params.yaml names a residual network
        if abs(args.dt - net.dt_s) > 1e-9 * net.dt_s:
            raise UsageError(f'--dt {args.dt:g}: the residual network of {args.params} was '
                             f'trained on {net.dt_s:g} s samples; use --dt {net.dt_s:g}')
        traj = hybrid_maneuver(model, spec)
    else:
        traj = mv.run(ship, spec)
    if args.out:
        write_new_file(args.out, csv_text(traj.t, traj.states, traj.controls), '--out')
        print(f'wrote {args.out} ({traj.t.size} samples)')
    if not traj.ok:
        print(f'WARNING: simulation stopped at t = {traj.fail_time_s:.1f} s: {traj.status}',
              file=sys.stderr)
    L = ship.L_pp
    k_exec = ix.execution_index(traj['rudder'])
    kind = '' if net is None else (' + residual network' if net.physics else ', pure network')
    print(f'{ship.name} ({ship.model} model{kind}), {args.maneuver} {args.rudder_deg:+g} deg, '
          f'{args.rpm:g} rpm, u0 = {speed:.3f} m/s, {args.integrator} dt = {args.dt:g} s')
    if args.maneuver in ('turning', 'pullout'):
        ti = ix.turning_indices(traj['x'], traj['y'], traj['psi'], k_exec)
        print(f'  turn to {ti.direction}: advance {ti.advance_m:.1f} m ({ti.advance_m / L:.2f} L),'
              f' transfer {ti.transfer_m:.1f} m ({ti.transfer_m / L:.2f} L), tactical diameter '
              f'{ti.tactical_diameter_m:.1f} m ({ti.tactical_diameter_m / L:.2f} L)')
    elif args.maneuver == 'zigzag':
        check = math.radians(abs(args.check_deg if args.check_deg is not None
                                 else args.rudder_deg))
        zi = ix.zigzag_indices(traj['psi'], traj['rudder'], check, k_exec)
        print(f'  zigzag, first rudder to {zi.direction}: first overshoot '
              f'{zi.first_overshoot_deg:.1f} deg, '
              f'second overshoot {zi.second_overshoot_deg:.1f} deg')
    final = traj.states[-1]
    print(f'  final: u = {final[3]:.3f} m/s, v = {final[4]:.3f} m/s, '
          f'r = {math.degrees(final[5]):.3f} deg/s')
    return 0 if traj.ok else 1


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
