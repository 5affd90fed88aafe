"""
The hybrid model's training: physics plus a neural residual, through the simulation (issue 14).

Importing this package needs no JAX; :func:`train_residual` imports JAX, equinox and optax on
first use and raises :class:`~mmg_tuner.errors.MissingDependencyError` (saying how to install
them) when they are missing. Inference needs none of them: ``mmg_tuner.core.residual``.
"""
from mmg_tuner.tuning.hybrid.train import (
    ensemble, require_jax, ResidualConfig, ResidualFit, train_residual)

__all__ = ['ResidualConfig', 'ResidualFit', 'ensemble', 'require_jax', 'train_residual']
