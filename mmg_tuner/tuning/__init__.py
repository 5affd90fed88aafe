"""
CMA-ES fine-tuning of MMG parameters inside boxes around their pre-determined values.

(Suyama et al. 2023, section 4). Imports core, data and cmaes; never rclpy.
"""
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.tuner import Tuner, TuningResult

__all__ = ['Objective', 'ParameterSpace', 'TrialBatch', 'Tuner', 'TuningResult']
