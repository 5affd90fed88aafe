"""
Recorded trials in and out: the one door through which tuning, diagnosis and replay read data.

Imports the core layer, NumPy, rosbags and mcap; never rclpy.
"""
from mmg_tuner.data.trial import Trial

__all__ = ['Trial']
