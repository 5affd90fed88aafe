"""
Learning: neural residuals on the accelerations and their training through the simulation.

A model is (ship, parameters, optional residual network): the network lives here, never in a
ship config. ``residual.py`` is the inference half (NumPy and numba only: a ROS install without
JAX runs trained hybrids); ``train.py`` trains through the simulation and imports JAX, equinox
and optax on first use, raising :class:`~mmg_tuner.errors.MissingDependencyError` (saying how
to install them) when they are missing.
"""
from mmg_tuner.learn.residual import load_residual, ResidualNet
from mmg_tuner.learn.train import (
    ensemble, JointCoefficients, members, require_jax, ResidualConfig, ResidualFit,
    train_residual)

__all__ = ['ResidualConfig', 'ResidualFit', 'ResidualNet', 'ensemble', 'load_residual',
           'JointCoefficients', 'members', 'require_jax', 'train_residual']
