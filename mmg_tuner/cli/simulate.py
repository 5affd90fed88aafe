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
from mmg_tuner.core.dynamics import family_tag, N_ACT_STATES
from mmg_tuner.core.integrate import advance, observe, start_actuators, start_state
from mmg_tuner.core.layout import OK, STATUS_TEXT
from mmg_tuner.core.limits import input_limits
from mmg_tuner.core.simulate import integrator_code
from mmg_tuner.core.stepper import apparent_wind_body
from mmg_tuner.core.trial import Trial
from mmg_tuner.data.csv_io import csv_text
from mmg_tuner.learn.model import load_model, Model
from mmg_tuner.learn.residual import N_FEATURES, simulate_hybrid_one
import numpy as np


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


def hybrid_maneuver(model: Model, spec: mv.ManeuverSpec) -> Trial:
    """
    One manoeuvre of a ship that carries a residual network (hybrid or pure network).

    The programme's inputs come from the physics run (mv.run): open-loop manoeuvres (turning,
    pull-out, random, the low-speed programmes, whose phase ends the physics decides) replay
    its rpm, actual rudder angle and thrusters through the hybrid from the same first state,
    as a recorded trial is replayed; a zigzag closes the loop on the hybrid's own heading,
    step by step (the residual held over each sample, the steering gear per substep).
    """
    ship, net = model.ship, model.residual
    phys = mv.run(ship, spec)
    if spec.maneuver == 'zigzag':
        return _hybrid_zigzag(model, spec, phys)
    ctrl = np.ascontiguousarray(phys.input_array(ship.family.channels))
    if not phys.ok:   # past the physics' failure the programme is undefined: hold its last
        n_cmd = len(ship.family.inputs)
        k = max(1, int(np.argmax(~np.all(np.isfinite(ctrl[:, :n_cmd]), axis=1))))
        ctrl[k:] = ctrl[k - 1]
    T = len(phys)
    out = np.empty((T, 6))
    res = np.empty((T, 3))
    sizes, flat = net.packed()
    status, k_fail = simulate_hybrid_one(
        family_tag(ship.kind), np.ascontiguousarray(ship.params, dtype=float),
        phys.states[0].copy(),
        np.zeros((max(1, net.window - 1), N_FEATURES)), 0, ctrl, T, float(spec.dt),
        int(spec.substeps), integrator_code(spec.integrator), int(net.window), sizes, flat,
        net.x_mean, net.x_std, net.y_scale, float(net.physics), out, res)
    kw = {} if status == OK else {'status': STATUS_TEXT[status],
                                  'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, name=spec.maneuver, inputs=phys.inputs, **kw)


def _hybrid_zigzag(model: Model, spec: mv.ManeuverSpec, phys: Trial) -> Trial:
    """Return the IMO zigzag of integrate.run_maneuver, closed on the hybrid's heading."""
    ship, net = model.ship, model.residual
    tag = family_tag(ship.kind)
    p = np.ascontiguousarray(ship.params, dtype=float)
    T, dt, n_sub = len(phys), float(spec.dt), int(spec.substeps)
    h = dt / n_sub
    amp = math.radians(spec.rudder_deg)
    check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                             else spec.rudder_deg))
    rate = ship.rudder_rate_rad_s if spec.rudder_rate_deg_s is None \
        else math.radians(spec.rudder_rate_deg_s)
    max_move = rate * h if rate > 0 else math.inf
    rpm = phys['rpm']
    method = integrator_code(spec.integrator)
    s = np.empty(6)
    start_state(p, phys.states[0].copy(), s)
    out = np.full((T, 6), np.nan)
    rudder = np.full(T, np.nan)
    observe(p, s, out[0])
    delta = 0.0
    rudder[0] = delta
    # one sample of the input array: rpm, rudder (the logged angle), thrusters 0, no wind
    row = np.full((1, len(ship.family.channels)), np.nan)
    row[0, :len(ship.family.inputs)] = 0.0
    act_states = np.zeros(N_ACT_STATES)
    start_actuators(tag, p, row, 0.0, 1, act_states)
    started, cmd_zz, psi0 = False, amp, s[2]
    stepper = net.stepper()
    status, k_fail = OK, T
    for k in range(T - 1):
        a0, a1, a2 = stepper.accelerations(s, (rpm[k], delta), apparent_wind_body(ship, s))
        for _ in range(n_sub):
            if not started and phys.t[k] >= spec.approach_s:
                started, psi0 = True, s[2]
            cmd = 0.0
            if started:
                if cmd_zz > 0 and s[2] - psi0 >= check:
                    cmd_zz = -abs(amp)
                elif cmd_zz < 0 and s[2] - psi0 <= -check:
                    cmd_zz = abs(amp)
                cmd = cmd_zz
            row[0, 0], row[0, 1] = rpm[k], delta
            status = advance(tag, p, s, act_states, row, 0, 0.0, 1, h, 1, method, a0, a1, a2,
                             float(net.physics))
            if status != OK:
                break
            delta += min(max_move, max(-max_move, cmd - delta))
        if status != OK:
            k_fail = k + 1
            break
        observe(p, s, out[k + 1])
        rudder[k + 1] = delta
    kw = {} if status == OK else {'status': STATUS_TEXT[status],
                                  'fail_time_s': float(phys.t[min(k_fail, T - 1)])}
    return Trial(phys.t.copy(), out, np.column_stack([rpm, rudder]), name=spec.maneuver, **kw)


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
