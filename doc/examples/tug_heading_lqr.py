"""
Hold a heading change with an LQR designed on an ``export`` folder, on mmg_tuner's simulator.

The controller reads only the exported linear.json (A, B at the operating point, numpy and
scipy); the plant is the package's own ShipSimulator for the same ship (azimuth drive, rate
limit and the full nonlinear model included). Run after ``export``:

    export --ship qiuxin_tug --out mpc/
    python doc/examples/tug_heading_lqr.py mpc/ --ship qiuxin_tug --heading-deg 20

Prints one JSON line (settling time, final error, the largest commands) and exits 1 when the
heading did not settle or a command left the limits. test/api/test_export.py runs it.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

import numpy as np
from scipy.linalg import solve_discrete_are

KEEP = slice(2, 10)   # psi, u, v, r and the azimuth states: x, y enter nothing else


def lqr(lin: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (K, x_op, u_op) of a discrete LQR on the exported model without x and y."""
    A = np.array(lin['discrete']['A'])[KEEP, KEEP]
    B = np.array(lin['discrete']['B'])[KEEP, :]
    # Bryson's rule: the largest acceptable excursion of each state and input
    x_max = np.array([math.radians(2.0), 0.1, 0.2, 0.05, 0.5, 1.0, 0.5, 1.0])
    u_max = np.array([3.0, 3.0, 0.3, 0.3])
    Q = np.diag(1.0 / x_max ** 2)
    R = np.diag(1.0 / u_max ** 2)
    P = solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    return K, np.array(lin['x_op'])[KEEP], np.array(lin['u_op'])


def run(folder: Path, ship_name: str, params: str | None, heading_deg: float,
        duration_s: float, tol_deg: float) -> dict:
    from mmg_tuner.api import load_ship
    from mmg_tuner.core.stepper import ShipSimulator

    lin = json.loads((folder / 'linear.json').read_text())
    limits = json.loads((folder / 'model.json').read_text())['thrusters']['limits']
    K, x_op, u_op = lqr(lin)
    dt = lin['discrete']['dt']
    names = lin['inputs']
    ship = load_ship(ship_name, params)
    sim = ShipSimulator(ship, dt=dt, x0=[0.0, 0.0, x_op[0], x_op[1], x_op[2], x_op[3]],
                        integrator=lin['discrete']['integrator'],
                        commands={'n_port': u_op[0], 'n_stbd': u_op[1],
                                  'azimuth_port': u_op[2], 'azimuth_stbd': u_op[3]})
    channel = {'n_port': 'n_port', 'n_stbd': 'n_stbd', 'azimuth_cmd_port': 'azimuth_port',
               'azimuth_cmd_stbd': 'azimuth_stbd'}
    x_ref = x_op.copy()
    x_ref[0] += math.radians(heading_deg)
    lo = -np.array([limits['n_max_rev_s']] * 2 + [limits['azimuth_max_rad']] * 2)
    steps = int(round(duration_s / dt))
    psi = np.empty(steps + 1)
    psi[0] = sim.observed()[2]
    demand_max = np.zeros(4)
    applied_max = np.zeros(4)
    alpha_max = 0.0
    problems = []
    for k in range(steps):
        a = sim.actuator_states()
        x = np.concatenate([sim.observed()[2:], [a['alpha_port'], a['alpha_rate_port'],
                                                 a['alpha_stbd'], a['alpha_rate_stbd']]])
        e = x - x_ref
        e[0] = math.remainder(e[0], 2 * math.pi)
        demand = u_op - K @ e
        cmd = np.clip(demand, lo, -lo)   # saturate at the limits, as a real drive would
        demand_max = np.maximum(demand_max, np.abs(demand))
        applied_max = np.maximum(applied_max, np.abs(cmd))
        for name, value in zip(names, cmd):
            if problem := sim.set_command(channel[name], float(value)):
                problems.append(problem)
        if not sim.step():
            raise SystemExit(f'the simulation failed: {sim.failure}')
        alpha_max = max(alpha_max, abs(a['alpha_port']), abs(a['alpha_stbd']))
        psi[k + 1] = sim.observed()[2]
    err = np.degrees(np.abs(np.remainder(psi - x_ref[0] + math.pi, 2 * math.pi) - math.pi))
    outside = np.nonzero(err > tol_deg)[0]
    settled = None if outside.size and outside[-1] == steps else \
        float((outside[-1] + 1) * dt if outside.size else 0.0)
    within = bool(applied_max[0] <= limits['n_max_rev_s'] + 1e-12
                  and applied_max[1] <= limits['n_max_rev_s'] + 1e-12
                  and max(applied_max[2:]) <= limits['azimuth_max_rad'] + 1e-12
                  and alpha_max <= limits['azimuth_max_rad'] + 1e-9 and not problems)
    return {'heading_change_deg': heading_deg, 'settling_time_s': settled,
            'tolerance_deg': tol_deg, 'final_error_deg': float(err[-1]),
            'overshoot_deg': float(max(0.0, np.degrees(np.max(psi - x_ref[0])))),
            'max_n_rev_s': float(max(applied_max[:2])),
            'max_azimuth_cmd_deg': float(np.degrees(max(applied_max[2:]))),
            'max_azimuth_deg': float(np.degrees(alpha_max)),
            'max_demand': [float(v) for v in demand_max],
            'saturated': bool(np.any(demand_max > -lo)), 'within_limits': within,
            'problems': problems[:3], 'speed_end_ms': float(sim.observed()[3])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    ap.add_argument('folder', type=Path, help='an export folder (linear.json, model.json)')
    ap.add_argument('--ship', default='qiuxin_tug')
    ap.add_argument('--params', help='the params.yaml the export was made from')
    ap.add_argument('--heading-deg', type=float, default=20.0)
    ap.add_argument('--duration', type=float, default=60.0, help='[s]')
    ap.add_argument('--tolerance-deg', type=float, default=1.0)
    args = ap.parse_args(argv)
    out = run(args.folder, args.ship, args.params, args.heading_deg, args.duration,
              args.tolerance_deg)
    print(json.dumps(out))
    return 0 if out['settling_time_s'] is not None and out['within_limits'] else 1


if __name__ == '__main__':
    sys.exit(main())
