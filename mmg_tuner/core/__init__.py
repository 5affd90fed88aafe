"""Pure numerical core: ship configs, MMG equations, integrators, manoeuvres, indices.

Imports NumPy, numba and PyYAML only; never rclpy, never the data/tuning layers.
"""
from mmg_tuner.core.layout import PARAM_NAMES, STATE_NAMES
from mmg_tuner.core.ship import ShipConfig, load_ship
from mmg_tuner.core.simulate import Trajectory, simulate, simulate_batch

__all__ = ['PARAM_NAMES', 'STATE_NAMES', 'ShipConfig', 'Trajectory', 'load_ship', 'simulate',
           'simulate_batch']
