"""
Runs inside the benchmark's own environment with the public `shipmmg` package.

Its KVLCC2 35 deg turn (standard MMG method) with a fixed step, timing right-hand-side evaluations.
Prints one JSON line. Not part of mmg_tuner; no code of shipmmg is copied.
"""
import json
import math
import sys
import time

import numpy as np
from shipmmg.mmg_3dof import Mmg3DofBasicParams, Mmg3DofManeuveringParams, simulate_mmg_3dof

dt, duration = float(sys.argv[1]), float(sys.argv[2])
rho, L, d, disp = 1025.0, 7.00, 0.46, 3.27
q2 = 0.5 * rho * L * L * d
basic = Mmg3DofBasicParams(
    L_pp=L, B=1.27, d=d, x_G=0.25, D_p=0.216, m=rho * disp, I_zG=rho * disp * (0.25 * L) ** 2,
    A_R=0.0539, η=0.216 / 0.345, m_x=0.022 * q2, m_y=0.223 * q2, J_z=0.011 * q2 * L * L,
    f_α=2.747, ϵ=1.09, t_R=0.387, x_R=-0.5 * L, a_H=0.312, x_H=-0.464 * L, γ_R_minus=0.395,
    γ_R_plus=0.640, l_R=-0.710, κ=0.50, t_P=0.220, w_P0=0.40, x_P=-0.48)
man = Mmg3DofManeuveringParams(
    k_0=0.2931, k_1=-0.2753, k_2=-0.1385, R_0_dash=0.022, X_vv_dash=-0.040, X_vr_dash=0.002,
    X_rr_dash=0.011, X_vvvv_dash=0.771, Y_v_dash=-0.315, Y_r_dash=0.083, Y_vvv_dash=-1.607,
    Y_vvr_dash=0.379, Y_vrr_dash=-0.391, Y_rrr_dash=0.008, N_v_dash=-0.137, N_r_dash=-0.049,
    N_vvv_dash=-0.030, N_vvr_dash=-0.294, N_vrr_dash=0.055, N_rrr_dash=-0.013)
t = np.arange(0.0, duration + dt / 2, dt)
delta = np.full(t.size, math.radians(35.0))
nps = np.full(t.size, 711.0 / 60.0)
best = None
for _ in range(3):
    t0 = time.perf_counter()
    sol = simulate_mmg_3dof(basic, man, t, delta, nps, u0=1.179, method='RK45', first_step=dt,
                            max_step=dt, rtol=1e9, atol=1e9)  # tolerances off: fixed step dt
    wall = time.perf_counter() - t0
    rate = sol.nfev / wall
    best = rate if best is None else max(best, rate)
print(json.dumps({'rhs_per_s': best, 'nfev': int(sol.nfev)}))
