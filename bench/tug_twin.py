"""
The twin-azimuth tug's published models, sailed: steady speeds and turns (issue 24, part A).

Prints, for config/qiuxin_tug.yaml (Table 3, surge_decoupled) under both Coriolis forms and
for config/qiuxin_tug_simplified6.yaml (Table 4), the steady surge speed at the paper's
straight-line shaft speeds and the steady yaw rate and drift of a 20 deg azimuth turn at
7 rev/s; and for config/otter_usv.yaml the speed at 10 rev/s and the turn under 10/5 rev/s of
differential thrust. Thrust curve and azimuth drive are the configs' stand-ins (ASSUMPTION).

    python -m bench run tug_twin
"""
import argparse
import math

import mmg_tuner as mt
from mmg_tuner.core.simulate import simulate
import numpy as np

DT, T = 0.2, 901   # 5 Hz, 180 s: every run here is steady by then


def run(ship, n_port, n_stbd, az_deg=0.0, substeps=1):
    a = math.radians(az_deg)
    cmd = {'n_port': np.full(T, n_port), 'n_stbd': np.full(T, n_stbd),
           'azimuth_port': np.full(T, a), 'azimuth_stbd': np.full(T, a)}
    out = simulate(ship, [0, 0, 0, 0.0, 0, 0], cmd, DT, 'rk4', substeps=substeps)
    return out.states[-1] if out.ok else np.full(6, np.nan)


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run tug_twin`` (quick already)."""
    return main(argv)


def main(argv: list[str] | None = None) -> dict:
    argparse.ArgumentParser(description=__doc__.strip().split('\n')[0]).parse_args(argv)
    figures = {'steady_surge_speed_ms': [], 'steady_turn_7_rps_az_20_deg': []}
    tug = mt.load_ship('qiuxin_tug')
    s6 = mt.load_ship('qiuxin_tug_simplified6')
    models = [('Table 3, Pedersen C', tug, 1), ('Table 3, Fossen C', tug.with_params(
        {'coriolis_form': 1}), 1), ('Table 4 (6 coef.)', s6, 8)]
    print('steady surge speed u [m/s] at n rev/s on both thrusters, azimuth 0')
    print(f'{"model":22s}' + ''.join(f'{n:>8g}' for n in (3, 5, 7, 10)))
    for label, ship, sub in models:
        u = {f'{n} rev/s': run(ship, n, n, 0.0, sub)[3] for n in (3, 5, 7, 10)}
        print(f'{label:22s}' + ''.join(f'{x:8.3f}' for x in u.values()))
        figures['steady_surge_speed_ms'].append({'model': label, **u})
    print('\nsteady turn, 7 rev/s, both azimuths +20 deg: u [m/s], v [m/s], r [deg/s]')
    for label, ship, sub in models:
        s = run(ship, 7, 7, 20.0, sub)
        print(f'{label:22s}{s[3]:8.3f}{s[4]:8.3f}{math.degrees(s[5]):10.2f}')
        figures['steady_turn_7_rps_az_20_deg'].append(
            {'model': label, 'u_ms': s[3], 'v_ms': s[4], 'r_deg_s': math.degrees(s[5])})
    otter = mt.load_ship('otter_usv')
    s = run(otter, 10, 10)
    print(f'\notter_usv: u = {s[3]:.3f} m/s at 10 rev/s; ', end='')
    figures['otter_u_ms_at_10_rps'] = s[3]
    s = run(otter, 10, 5)
    print(f'port 10 / starboard 5 rev/s: u = {s[3]:.3f} m/s, r = {math.degrees(s[5]):+.2f} '
          'deg/s (to starboard)')
    figures['otter_port_10_stbd_5_rps'] = {'u_ms': s[3], 'r_deg_s': math.degrees(s[5])}
    return figures


if __name__ == '__main__':
    main()
