"""mmg_tuner: learn, diagnose and serve a ship's 3-DOF MMG manoeuvring model.

Layers, each importing only those before it:
``core`` (model, integrators, manoeuvres; NumPy/numba only) -> ``data`` (trials in/out) ->
``tuning`` (CMA-ES) -> ``diagnosis`` -> ``cli``; ``ros`` (rclpy nodes) sits on top and is the
only place that imports rclpy.
"""
from mmg_tuner.errors import (ConfigError, DiagnosisError, MmgTunerError, SimulationError,
                              TrialDataError, TuningError)

__all__ = ['ConfigError', 'DiagnosisError', 'MmgTunerError', 'SimulationError',
           'TrialDataError', 'TuningError']
__version__ = '0.1.0'
