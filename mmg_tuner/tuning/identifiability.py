"""
Which tuned parameters do the trials determine.

Gauss-Newton standard errors at the optimum.

The weighted residuals r(theta) of all trials are linearised by central differences in the
unit box; cov = s^2 (J'J + s^2 / BOX_VARIANCE I)^-1 with s^2 = SSR / (n - p): the data's
information and the box's (:data:`BOX_VARIANCE`). A parameter whose standard error is a
small fraction of its box is identified by the data; one near the box's own (0.29 of its
width) means the data cannot tell it apart from others (a correlated combination), so its
tuned value carries no information.
Residuals along a trajectory are correlated, so these errors are optimistic: use them to rank,
not as confidence intervals.
"""
from __future__ import annotations

from typing import Any

from mmg_tuner.core.integrate import residuals_many
from mmg_tuner.tuning.objective import Objective
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

BOX_VARIANCE = 1.0 / 12.0
"""The box as prior information: the variance of a uniform distribution over it (unit box).
Its information (1 / BOX_VARIANCE per parameter, in units of s^2) is added to the data's, so a
direction the trials leave undetermined gets the box's own standard error (0.29 of its width)
and one they determine is unchanged (its variance changes by a relative 12 SE^2, SE in box
widths); no error exceeds the box's own. The estimate itself is not pulled by it (the tuning
has no such term): the errors rank what the trials determine. Without
it the paper's problem (four SUZAKU turns; t_R, a_H, x_H and the rudder inflow coefficients
leave a direction undetermined) had an eigenvalue of J'J at rounding level, and the
pseudo-inverse gave a_H 0.051 or 264 box widths depending on the differences' step
(bench/identifiability_steps_preregistration.md)."""


def residuals(objective: Objective, params: np.ndarray) -> np.ndarray:
    """
    Return the weighted residual vectors (N, n) of each candidate over all trials.

    Weighted residual vectors (N, n) of each candidate over all trials (NaN-free: a failed run
    gives large residuals). Each trial's residuals carry the square root of its factor in the
    objective (``trial_weights``: the segmented objective's balance) and the prior's terms
    come last, so the sum of squares is what the objective minimises, its restarts
    (``shoot_every``, from the states the objective restarts from) included.
    """
    b = objective.batch
    params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
    sw = np.sqrt(objective.weights)
    chans = np.flatnonzero(sw > 0).astype(np.int64)
    tw = (np.ones(len(b.lengths)) if objective.trial_weights is None
          else objective.trial_weights)   # the balance of trials, pieces or groups
    sw_trial = np.ascontiguousarray(sw[None, :] * np.sqrt(tw)[:, None])
    offsets = np.concatenate([[0], np.cumsum((b.lengths - 1) * len(chans))]).astype(np.int64)
    r = np.empty((params.shape[0], int(offsets[-1])))
    k_fail = np.empty((params.shape[0], len(b.lengths)), dtype=np.int64)
    # compiled: the errors go straight into r, no trajectories are kept (the old route through
    # simulate_batch spent a third of a least-squares fit building and masking them)
    residuals_many(objective.ship.kind, params, objective.kernel_meas, objective.ctrls,
                   b.lengths, b.dt, objective.substeps, objective.method, sw_trial, chans,
                   objective.shoot_every, offsets, r, k_fail)
    r[~np.isfinite(r)] = 1e6
    pr = objective.prior
    if pr is None:
        return r
    z = (np.atleast_2d(params)[:, pr.indices] - pr.centre) / pr.scale
    return np.hstack([r, np.sqrt(pr.weight) * z])


def jacobian(objective: Objective, space: ParameterSpace, theta: np.ndarray, h: float
             ) -> tuple[np.ndarray, float]:
    """Central-difference Jacobian of the weighted residuals in the unit box, and s^2."""
    z0 = space.to_unit(theta)
    Z = [z0]
    for i in range(space.dim):
        for sgn in (1, -1):
            z = z0.copy()
            z[i] += sgn * h
            Z.append(z)
    theta_all = space.lower + np.array(Z) * (space.upper - space.lower)  # no clipping at bounds
    R = residuals(objective, space.full_params(objective.ship.params, theta_all))
    Jac = np.column_stack([(R[1 + 2 * i] - R[2 + 2 * i]) / (2 * h) for i in range(space.dim)])
    n, p = Jac.shape
    return Jac, float(R[0] @ R[0]) / max(n - p, 1)


def standard_errors(objective: Objective, space: ParameterSpace, theta: np.ndarray,
                    h: float = 1e-3) -> np.ndarray:
    """Return standard error of each tuned parameter (in its own units) at theta."""
    Jac, s2 = jacobian(objective, space, theta, h)
    cov = s2 * inverse_information(Jac, s2)
    se: np.ndarray = np.sqrt(np.clip(np.diag(cov), 0, None)) * (space.upper - space.lower)
    return se


def inverse_information(Jac: np.ndarray, s2: float) -> np.ndarray:
    """
    Return (J'J + s^2 / BOX_VARIANCE I)^-1: the unit box's covariance per s^2.

    The data's information J'J and the box's (:data:`BOX_VARIANCE`), inverted through J'J's
    eigenvalues (clipped at 0: rounding leaves an undetermined direction's slightly negative)
    with no cut-off: a pseudo-inverse's (1e-15 of the largest) would drop the box's term where
    it is smaller than that (nearly noise-free residuals). With s^2 = 0 (residuals that
    vanish: nothing to weigh the box against) the pseudo-inverse of J'J.
    """
    A = Jac.T @ Jac
    if not s2 > 0.0:
        return np.asarray(np.linalg.pinv(A))
    lam, V = np.linalg.eigh(A)
    out: np.ndarray = (V / (np.clip(lam, 0.0, None) + s2 / BOX_VARIANCE)) @ V.T
    return out


def trial_robust_standard_errors(objective: Objective, space: ParameterSpace,
                                 theta: np.ndarray, h: float = 1e-3
                                 ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return (Gauss-Newton, trial-robust) standard errors at theta, from one Jacobian.

    Gauss-Newton's (:func:`standard_errors`) take the residuals as independent; along a
    simulated trajectory they are not (the start-state error, a sensor's drift), and within a
    trial they share one error. The trial-robust ones are the sandwich (cluster-robust, one
    cluster per trial; the infinitesimal jackknife over trials) covariance
    H^-1 (n / (n - 1) sum_i g_i g_i') H^-1, with H = J'J + s^2 / BOX_VARIANCE I (the box's
    information too, as :func:`standard_errors`) and g_i trial i's gradient J_i' r_i
    at theta (a prior's rows count in H only). The g_i are not centred: a fit stopped short of
    its optimum (a least-squares fit stopped by its tolerance, a coefficient held on a bound)
    has sum_i g_i != 0, and the step it leaves counts as error too. Along a direction the
    trials leave undetermined no g_i points, so the trial-robust error there is near 0 while
    Gauss-Newton's is the box's: take the larger. Needs two trials or more (NaN otherwise).
    Both in the parameters' own units.
    """
    Jac, s2 = jacobian(objective, space, theta, h)
    Hi = inverse_information(Jac, s2)
    width = space.upper - space.lower
    gn = np.sqrt(np.clip(s2 * np.diag(Hi), 0, None)) * width
    b = objective.batch
    n = len(b.lengths)
    if n < 2:
        return gn, np.full(space.dim, np.nan)
    r = residuals(objective, space.full_params(objective.ship.params, np.atleast_2d(theta)))[0]
    per = (b.lengths - 1) * int(np.count_nonzero(objective.weights > 0))  # residuals' layout
    off = np.concatenate([[0], np.cumsum(per)])
    G = np.array([Jac[off[i]:off[i + 1]].T @ r[off[i]:off[i + 1]] for i in range(n)])
    V = Hi @ (n / (n - 1) * (G.T @ G)) @ Hi
    return gn, np.sqrt(np.clip(np.diag(V), 0, None)) * width


def identified(space: ParameterSpace, se: np.ndarray, frac: float = 0.05) -> list[str]:
    """Names whose standard error is below frac of their box width."""
    return [n for n, s, w in zip(space.names, se, space.upper - space.lower) if s < frac * w]


def stiff_directions(objective: Objective, space: ParameterSpace, theta: np.ndarray,
                     max_se: float = 0.02, h: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """
    Parameter combinations the trials determine.

    unit-box eigen-directions of J'J whose standard error is below max_se (fraction of the box),
    from the trials alone (the box's information, 0.29 of its width, is far above max_se).
    Returns (directions (k, d) as rows, their standard errors (k,)).
    """
    Jac, s2 = jacobian(objective, space, theta, h)
    lam, V = np.linalg.eigh(Jac.T @ Jac)
    se = np.sqrt(s2 / np.clip(lam, 1e-300, None))
    keep = se < max_se
    return V[:, keep].T, se[keep]


def aliasing(objective: Objective, space: ParameterSpace, theta: np.ndarray,
             probe: list[str], h: float = 1e-3) -> dict[str, dict[str, Any]]:
    """
    How well the trials separate each probe parameter from the parameters not probed.

    Probe parameter j's Jacobian column is split into the part the other parameters can mimic
    (least squares on their columns) and the rest; only the rest is evidence. Returns
    {name: {'r2': share mimicked, 'se': standard error of j with the others free (own units;
    the trials alone, no box's information: what they cannot tell apart must show),
    'mimicked_by': the three largest contributors}}. A standard error above the magnitudes
    worth finding means the trials cannot identify the parameter while the others are tuned
    (e.g. an rpm scale error against wake fraction and thrust deduction).
    """
    Jac, s2 = jacobian(objective, space, theta, h)
    others = [i for i, n in enumerate(space.names) if n not in probe]
    A = Jac[:, others]
    width = space.upper - space.lower
    out = {}
    for j, n in enumerate(space.names):
        if n not in probe:
            continue
        y = Jac[:, j]
        ss = float(y @ y)
        if ss == 0.0:
            out[n] = {'r2': float('nan'), 'se': float('inf'), 'mimicked_by': []}
            continue
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        r = y - A @ coef
        rr = float(r @ r)
        contrib = np.abs(coef) * np.linalg.norm(A, axis=0)
        top = [space.names[others[k]] for k in np.argsort(-contrib)[:3]]
        out[n] = {'r2': 1 - rr / ss, 'se': float(np.sqrt(s2 / max(rr, 1e-300)) * width[j]),
                  'mimicked_by': top}
    return out
