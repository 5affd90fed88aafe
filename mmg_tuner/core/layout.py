"""
Index layout of the flat parameter vector and of the state and control arrays.

The compiled kernels read parameters by fixed index from one float64 vector, so that a batch
of candidates is simply a 2-D array ``(n_candidates, N_PARAMS)``. The vector is the union of
the shared slots (particulars, added masses, windage, effects) and every registered model
family's own parameters (``core/models``); a slot a family does not read is ignored by it.
Effect slots and their neutral values come from the effect registry (``core/effects.py``).

Axis convention: batch axes lead, the state/parameter axis is last.
"""
from __future__ import annotations

from mmg_tuner.core.channels import CONTROL_NAMES  # noqa: F401  (re-exported)
from mmg_tuner.core.effects import PARAM_NEUTRAL
from mmg_tuner.core.models import declared_params, REGISTRY

STATE_NAMES = ('x', 'y', 'psi', 'u', 'v', 'r')
"""Model-frame state: x_E north [m], y_E east [m], psi clockwise from north [rad],
u surge [m/s], v sway at midship (starboard +) [m/s], r yaw rate (starboard +) [rad/s]."""

_PARTICULARS = ('rho', 'L_pp', 'B', 'd', 'm', 'x_G', 'I_zG', 'D_P', 'H_R', 'A_R', 'x_R')
_ADDED_MASS = ('m_x', 'm_y', 'J_z')
# Above-water hull and superstructure for wind loads (Blendermann 1994); all zero: no windage.
_WINDAGE = ('rho_air', 'A_F', 'A_L', 'L_OA', 's_L', 'CD_t', 'CD_lAF_bow', 'CD_lAF_stern',
            'wind_delta')
# Model extensions (effects); their neutral values make them vanish.
_EFFECTS = tuple(PARAM_NEUTRAL)
EFFECT_NEUTRAL: dict[str, float] = dict(PARAM_NEUTRAL)

SHARED_PARAMS: tuple[str, ...] = _PARTICULARS + _ADDED_MASS + _WINDAGE + _EFFECTS
"""Slots every family has: the shared kernels (equations of motion, wind, effects) read them."""


def _union() -> tuple[str, ...]:
    names = list(_PARTICULARS + _ADDED_MASS)
    for fam in REGISTRY:
        names += [n for n in declared_params(fam) if n not in names and n not in SHARED_PARAMS]
    return tuple(names) + _WINDAGE + _EFFECTS


PARAM_NAMES: tuple[str, ...] = _union()
PARAM_INDEX: dict[str, int] = {name: i for i, name in enumerate(PARAM_NAMES)}
N_PARAMS = len(PARAM_NAMES)

# Model families (the kernels dispatch on these integer codes = registry positions).
MODEL_KINDS = {name: code for code, name in enumerate(REGISTRY)}
MODEL_CONTAINER = MODEL_KINDS['container']
MODEL_STANDARD = MODEL_KINDS['standard']
MODEL_LOWSPEED = MODEL_KINDS['lowspeed']

# Integrators.
EULER = 0
RK4 = 1
INTEGRATORS = {'euler': EULER, 'rk4': RK4}

# Simulation status codes returned by the kernels.
OK = 0
DIVERGED = 1        # non-finite state
SURGE_NOT_POSITIVE = 2  # u <= 0: outside the family's range (families without ASTERN_SURGE)
RPM_NOT_POSITIVE = 3    # n_P <= 0: outside the family's range (families without ASTERN_RPM)
STATUS_TEXT = {OK: 'ok', DIVERGED: 'diverged (non-finite state)',
               SURGE_NOT_POSITIVE: 'surge speed u <= 0 (outside the MMG model range u > 0)',
               RPM_NOT_POSITIVE: 'propeller rpm <= 0 (outside the model range n_P > 0)'}
