"""
Pure numerical core: ship configs, model families, integrators, manoeuvres, indices.

Imports NumPy, numba and PyYAML only; never rclpy, never the data/tuning layers.

Where things go:
  models/      one module per model family (forces and the inputs they need) + the registry
  channels.py  named input channels (rpm, rudder, measured wind, thrusters)
  effects.py   the effect registry (parameters, neutral values, boxes, descriptions)
  layout.py    the flat parameter vector, state names, status codes (derived from the above)
  dynamics.py  family dispatch, effect forces, wind loads, equations of motion (numba)
  integrate.py integrators, advance, simulation, manoeuvre and cost kernels (numba)
  frames.py    ENU <-> MMG frames, quaternion -> yaw, heading wrap/unwrap
  trial.py     the one time-history type (recorded, generated or simulated)
  ship.py      ship YAML -> ShipConfig (validated); simulate.py, maneuvers.py, indices.py,
  stepper.py   the Python entry points over the kernels
"""
from mmg_tuner.core import _numba_cache

_numba_cache.configure()  # before any kernel module is imported: cache keyed by the sources

from mmg_tuner.core.layout import PARAM_NAMES, STATE_NAMES  # noqa: E402
from mmg_tuner.core.ship import load_ship, ShipConfig  # noqa: E402
from mmg_tuner.core.simulate import simulate, simulate_batch  # noqa: E402
from mmg_tuner.core.trial import Trial  # noqa: E402

__all__ = ['PARAM_NAMES', 'STATE_NAMES', 'ShipConfig', 'Trial', 'load_ship',
           'simulate', 'simulate_batch']
