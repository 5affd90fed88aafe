"""
Compatibility re-exports.

The kernels now live in ``core/dynamics.py`` (family dispatch, equations of motion, wind) and
``core/integrate.py`` (integrators, simulation, cost); the families in ``core/models/``. Import
from there in new code.
"""
from mmg_tuner.core.dynamics import (accelerations, derivative,  # noqa: F401
                                     external_accelerations, family_forces, wind_loads)
from mmg_tuner.core.integrate import (advance, cost_many, observe, run_maneuver,  # noqa: F401
                                      simulate_many, simulate_one, start_state, step, to_water,
                                      trajectory_cost)
