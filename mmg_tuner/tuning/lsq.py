"""
Local bounded least squares: warm-started re-tunes, and the polish after CMA-ES.

Next to an optimum, a trust-region least-squares method on the weighted residuals needs far
fewer simulations than CMA-ES: each iteration costs one batched simulation of the d
forward-difference vectors (one multi-core compiled call) plus one of the new point.
"""
from __future__ import annotations

from dataclasses import dataclass

from mmg_tuner.tuning.identifiability import residuals
from mmg_tuner.tuning.objective import Objective
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np


@dataclass(frozen=True)
class LocalFit:
    """theta: the values (never worse than the start by J); simulations: what it cost."""

    theta: np.ndarray
    simulations: int
    J: float


def local_least_squares(space: ParameterSpace, obj: Objective, theta0: np.ndarray,
                        max_sims: int, h: float = 1e-4, ftol: float = 1e-4) -> LocalFit:
    """
    Bounded least squares (SciPy's trust-region reflective) on the objective's weighted residuals.

    From theta0, in the unit box. The forward-difference Jacobian is one batched, multi-core
    simulation of all d perturbed vectors (stepping inward at an upper bound). max_sims caps the
    simulations (each iteration costs d + 1). ftol: stop when an iteration lowers J by less than
    this fraction (on a benchmark case 1e-4 halved the re-tunes' time against 1e-6, same name,
    estimate within 0.01 deg; gains are judged at the 10 % level). Returns the better of the result
    and theta0 by J (a local method never makes a warm start worse), with the number of
    simulations (one per parameter vector) it ran. The residuals carry the objective's
    balance and prior (:func:`~mmg_tuner.tuning.identifiability.residuals`).
    """
    from scipy.optimize import least_squares

    d = space.dim
    width = space.upper - space.lower
    base = obj.ship.params
    cache: dict[bytes, np.ndarray] = {}
    sims = [0]

    def res_many(Z: np.ndarray) -> np.ndarray:
        theta = space.lower + np.clip(Z, 0.0, 1.0) * width
        sims[0] += Z.shape[0]
        return residuals(obj, space.full_params(base, theta))

    def fun(z: np.ndarray) -> np.ndarray:
        k = z.tobytes()
        if k not in cache:
            cache.clear()
            cache[k] = res_many(z[None])[0]
        return cache[k]

    def jac(z: np.ndarray) -> np.ndarray:
        r0 = fun(z)
        step = np.where(z + h <= 1.0, h, -h)
        Z = np.tile(z, (d, 1))
        Z[np.arange(d), np.arange(d)] += step
        R = res_many(Z)
        return ((R - r0[None]) / step[:, None]).T

    z0 = np.clip(space.to_unit(np.asarray(theta0, float)), 0.0, 1.0)
    max_nfev = max(3, int(max_sims) // (d + 1))
    sol = least_squares(fun, z0, jac=jac, bounds=(0.0, 1.0), method='trf', x_scale='jac',
                        ftol=ftol, xtol=1e-7, gtol=1e-8, max_nfev=max_nfev)
    theta = space.from_unit(sol.x)
    J = obj(space.full_params(base, np.vstack([theta, space.from_unit(z0)])))
    sims[0] += 2
    if J[0] <= J[1]:
        return LocalFit(theta, sims[0], float(J[0]))
    return LocalFit(space.from_unit(z0), sims[0], float(J[1]))
