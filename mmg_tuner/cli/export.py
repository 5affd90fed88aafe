"""
``export``: an identified tug model for model-predictive control (CasADi, do-mpc, acados).

Writes into a new folder model.json (M, C(nu), D(nu), the thruster map, units and frames),
dynamics.casadi (the simulator's step and the continuous-time model as one CasADi function),
nu_dot.casadi, linear.json (A, B at an operating point) and a README saying how to load them
without mmg_tuner. Families driven by one actuator with a CasADi form (api/exporting.py:
today the twin-azimuth tugs, e.g. qiuxin_tug).

Examples
--------
export --ship qiuxin_tug --params tuned/params.yaml --out mpc/
export --ship qiuxin_tug --out mpc_slow/ --at u=0.6,v=0,r=0 --dt 0.1

"""
from __future__ import annotations

import argparse
import sys

from mmg_tuner.cli.args import bounded
from mmg_tuner.cli.common import Parser, run_command

DT = bounded(float, 1e-4, 60.0, 'the discrete model step dt [s]')


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog='export', description=__doc__.strip().split('\n')[0])
    ap.add_argument('--ship', required=True,
                    help='ship config name or YAML (a family driven by one actuator with a CasADi '
                         'form; others are refused naming those that are)')
    ap.add_argument('--params', help='params.yaml overlay (e.g. the output of tune)')
    ap.add_argument('--out', required=True, help='new (or empty) output folder')
    ap.add_argument('--at', metavar='KEY=V,...',
                    help='operating point of the linearisation: u, v [m/s], r [rad/s], psi '
                         "[rad] and optionally the actuator's values acting (model.json's "
                         'nu_dot_input: its channel names, SI units); those not given '
                         'are trimmed to steady motion (default: the service speed straight '
                         "ahead, at 80 %% of the actuator's largest propulsion)")
    ap.add_argument('--dt', type=DT, default=0.2,
                    help='step of the discrete model and of A, B [s]')
    ap.add_argument('--integrator', choices=('rk4', 'euler'), default='rk4',
                    help="the simulator's integrator the discrete step reproduces (rk4: "
                         "sim_node's and the API's default)")
    return ap


def command(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from mmg_tuner.api.exporting import export_model, parse_operating_point
    at = parse_operating_point(args.at)
    res = export_model(args.ship, args.out, params=args.params, at=at, dt=args.dt,
                       integrator=args.integrator)
    op = res.operating_point
    state = ', '.join(f'{k} {v:.4g}' for k, v in op.state.items())
    acting = ', '.join(f'{k} {v:.4g}' for k, v in op.inputs.items())
    print(f'exported {res.model["ship"]} ({res.model["family"]}, {args.integrator} dt = '
          f'{args.dt:g} s) to {res.out}')
    print(f'  linearised at {state}; {acting}'
          + (f' (trimmed: {", ".join(op.trimmed)}; |nu_dot| {op.residual:.2g})'
             if op.trimmed else f' (|nu_dot| {op.residual:.2g})'))
    for path in res.files:
        print(f'  wrote {path}')
    if op.residual > 1e-6:
        print(f'WARNING: no steady motion at the operating point within the command limits '
              f'(|nu_dot| = {op.residual:.3g}): A, B hold about a point that is not an '
              f'equilibrium (the f0, F0 of linear.json)', file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> None:
    sys.exit(run_command(command, argv))


if __name__ == '__main__':
    main()
