"""Index layout of the flat parameter vector and of the state and control arrays.

The compiled kernels read parameters by fixed index from one float64 vector, so that a batch
of candidates is simply a 2-D array ``(n_candidates, N_PARAMS)``. Both model structures
(``container`` = the fine-tuning paper's SUZAKU model, ``standard`` = Yasukawa & Yoshimura 2015)
share one layout; a coefficient a structure does not use is ignored by its kernel.

Axis convention: batch axes lead, the state/parameter axis is last.
"""
from __future__ import annotations

STATE_NAMES = ('x', 'y', 'psi', 'u', 'v', 'r')
"""Model-frame state: x_E north [m], y_E east [m], psi clockwise from north [rad],
u surge [m/s], v sway at midship (starboard +) [m/s], r yaw rate (starboard +) [rad/s]."""
CONTROL_NAMES = ('rpm', 'rudder')
"""Controls: propeller revolutions [rev/min], rudder angle [rad] (+ turns to starboard)."""

_PARTICULARS = ('rho', 'L_pp', 'B', 'd', 'm', 'x_G', 'I_zG', 'D_P', 'H_R', 'A_R', 'x_R')
_ADDED_MASS = ('m_x', 'm_y', 'J_z')
_HULL = ('R_0', 'X_vv', 'X_vr', 'X_rr', 'X_vvvr', 'X_vvvv',
         'Y_v', 'Y_r', 'Y_vvv', 'Y_vvr', 'Y_vrr', 'Y_rrr',
         'N_v', 'N_r', 'N_vvv', 'N_vvr', 'N_vrr', 'N_rrr')
_PROPELLER = ('t_P', 'w_P0',
              # container (paper) propeller model
              'C_w', 'l_P', 'KT_0', 'KT_1', 'KT_2', 'KT_3', 'CPY_0', 'CPY_1', 'CPY_2',
              'CPN_lo_0', 'CPN_lo_1', 'CPN_hi_0', 'CPN_hi_1', 'phi_switch',
              # standard method propeller model
              'k_0', 'k_1', 'k_2', 'C_1', 'C_2p', 'C_2n', 'x_P')
_RUDDER = ('t_R', 'a_H', 'x_H', 'epsilon', 'kappa', 'u_R0', 'l_R', 'gamma_Rp', 'gamma_Rn',
           'f_alpha', 'f_alpha2', 'C_l01', 'C_l03', 'flap_ratio')
# Above-water hull and superstructure for wind loads (Blendermann 1994); all zero: no windage.
_WINDAGE = ('rho_air', 'A_F', 'A_L', 'L_OA', 's_L', 'CD_t', 'CD_lAF_bow', 'CD_lAF_stern',
            'wind_delta')
# Model extensions (effects); their neutral values make them vanish.
_EFFECTS = ('current_speed', 'current_dir', 'rudder_offset', 'rudder_lag_tau', 'rpm_scale',
            'yaw_moment_bias', 'antenna_x', 'antenna_y', 'time_offset', 'wind_speed', 'wind_dir',
            'prop_side_force')
EFFECT_NEUTRAL = {'current_speed': 0.0, 'current_dir': 0.0, 'rudder_offset': 0.0,
                  'rudder_lag_tau': 0.0, 'rpm_scale': 1.0, 'yaw_moment_bias': 0.0,
                  'antenna_x': 0.0, 'antenna_y': 0.0, 'time_offset': 0.0, 'wind_speed': 0.0,
                  'wind_dir': 0.0, 'prop_side_force': 0.0}

PARAM_NAMES: tuple[str, ...] = (_PARTICULARS + _ADDED_MASS + _HULL + _PROPELLER + _RUDDER
                                 + _WINDAGE + _EFFECTS)
PARAM_INDEX: dict[str, int] = {name: i for i, name in enumerate(PARAM_NAMES)}
N_PARAMS = len(PARAM_NAMES)

# Model structures (the kernels branch on these integer codes).
MODEL_CONTAINER = 0
MODEL_STANDARD = 1
MODEL_KINDS = {'container': MODEL_CONTAINER, 'standard': MODEL_STANDARD}

# Integrators.
EULER = 0
RK4 = 1
INTEGRATORS = {'euler': EULER, 'rk4': RK4}

# Simulation status codes returned by the kernels.
OK = 0
DIVERGED = 1        # non-finite state
SURGE_NOT_POSITIVE = 2  # u <= 0: outside the model's range
RPM_NOT_POSITIVE = 3    # n_P <= 0: outside the model's range
STATUS_TEXT = {OK: 'ok', DIVERGED: 'diverged (non-finite state)',
               SURGE_NOT_POSITIVE: 'surge speed u <= 0 (outside the MMG model range u > 0)',
               RPM_NOT_POSITIVE: 'propeller rpm <= 0 (outside the model range n_P > 0)'}
