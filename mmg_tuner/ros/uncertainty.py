"""
How sure the simulated ship is: ``Odometry`` covariance from an ensemble model's members.

A model tuned with ``--residual-seeds N`` (N >= 2) carries a calibrated prediction interval
(``tuning/interval.py``): its members (``learn.members``) and a factor c_i per state. The
simulator node steps the members alongside its own simulator, with the same commands from the
same initial state, and publishes as variance of each state (c_i x the members' standard
deviation about the model's prediction)^2: the members' spread *propagated* through the
simulation, not a growth law fitted once. Why: the spread then answers for the commands actually
given (it grows where the manoeuvre leaves what the training runs covered, and stays small where
they pinned the networks down), and it is exactly the quantity whose coverage ``evaluate``
reports on held-out runs. Caveat: c_i was calibrated on 100 s runs restarted from the
measurement; over a longer free run it is extrapolated.

An interval calibrated with the start error (``calibrate_interval(start_error=True)``) also
carries sigma_j, the recorded state's error: the node then steps, beside the members, the
model started with state j raised by sigma_j, and adds their departures and sigma_i itself in
quadrature, as the calibration did (the start the node is given is taken to be a recorded one;
as at a calibration restart, nothing at the start itself; a raised start that fails, or that
the simulator refuses, counts as no departure).

Mapping (REP-103/105, the node's frames): pose covariance over (x east, y north, z, roll,
pitch, yaw) in ``odom`` gets the variances of the model's y (east), x (north) and psi; twist
covariance over (vx forward, vy left, ..., wz) in ``base_link`` those of u, v and r. Only the
diagonal is filled. Zeros mean *not modelled*: z, roll and pitch everywhere (a planar model),
and every entry for a model without an interval (the physics alone, or one network), whose
prediction carries no estimate of its own error. A member that fails (diverges) leaves the
spread until the next run; with fewer than 2 members left the covariance is zero again.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from mmg_tuner.core.layout import STATE_NAMES
from mmg_tuner.core.stepper import ShipSimulator
from mmg_tuner.errors import SimulationError
from mmg_tuner.learn.model import Model
from mmg_tuner.tuning.interval import model_interval
import numpy as np

# Odometry covariance slots (row-major 6 x 6 diagonals) of each model state
_POSE = {'y': 0, 'x': 7, 'psi': 35}     # ENU x = east = model y; ENU y = north = model x
_TWIST = {'u': 0, 'v': 7, 'r': 35}      # FLU: the sign flips of v and r do not change a variance
_PSI = STATE_NAMES.index('psi')


@dataclass
class EnsembleSpread:
    """The members of an ensemble model, stepped with the node's simulator (see the module)."""

    members: list[ShipSimulator]
    scale: np.ndarray          # (6,) c_i in STATE_NAMES order (x, y, psi, u, v, r)
    alive: list[bool]
    run: object = None         # the node's run the members follow (a new one resets them)
    # with the start error: the model from a start raised by sigma_j (one per state j with
    # sigma_j > 0), after the members in ``members`` and ``alive``; sigma (6,), else zeros
    n_start: int = 0
    start_sigma: np.ndarray = field(default_factory=lambda: np.zeros(6))

    @classmethod
    def of(cls, sim: ShipSimulator, integrator: str) -> 'EnsembleSpread | None':
        """Return the members of the simulator's model, or None when it has no interval."""
        if sim.residual is None:
            return None
        iv = model_interval(Model(sim.ship, sim.residual))
        if iv is None:
            return None
        by_name = dict(zip(('x', 'u', 'y', 'v', 'psi', 'r'), iv.scale))   # INDEX_STATES
        scale = np.array([by_name[n] for n in STATE_NAMES])
        # a craft commanded channel by channel starts from the commands held (at the start:
        # the initial ones); a screw and rudder from its initial rpm and rudder
        start = None if sim.rpm_rudder else sim.commands
        members = [ShipSimulator(m.ship, sim.dt, sim.x0, sim.rpm0, sim.rudder0, integrator,
                                 sim.substeps, residual=m.residual, commands=start)
                   for m in iv.members]
        sigma = np.zeros(6) if iv.start_sigma is None else np.asarray(iv.start_sigma)
        raised = []
        for j in np.flatnonzero(sigma > 0):
            x0 = np.array(sim.x0, dtype=float)
            x0[j] += sigma[j]
            try:
                raised.append(ShipSimulator(sim.ship, sim.dt, x0, sim.rpm0, sim.rudder0,
                                            integrator, sim.substeps, residual=sim.residual,
                                            commands=start))
            except SimulationError:   # e.g. a raised speed beyond the ship's limits
                continue
        every = members + raised
        return cls(every, scale, [True] * len(every), n_start=len(raised), start_sigma=sigma)

    def follow(self, sim: ShipSimulator, run: object) -> None:
        """
        Step the members to the simulator's step count with its current commands.

        Called where the node publishes: commands only change between timer ticks, so the
        members see the commands the simulator saw. A new ``run`` (a reset, a failure) starts
        them again from the initial state.
        """
        if run != self.run or any(m.steps > sim.steps for m in self.members):
            for m in self.members:
                m.reset()
            self.alive = [True] * len(self.members)
            self.run = run
        for i, m in enumerate(self.members):
            if not self.alive[i] or m.steps == sim.steps:
                continue
            for channel, value in sim.commands.items():   # validated by the simulator
                m.set_command(channel, value)
            self.alive[i] = m.step(sim.steps - m.steps)

    def sigma(self, centre: np.ndarray) -> np.ndarray | None:
        """
        Return c_i x the spread about ``centre`` (6,), or None.

        The spread: the members' standard deviation, with the start error's departures and
        sigma added in quadrature when the interval carries them (after the first step; a
        raised start that failed counts as no departure).
        """
        k = len(self.members) - self.n_start
        states = [m.observed() for m, ok in zip(self.members[:k], self.alive[:k]) if ok]
        if len(states) < 2:
            return None

        def dev(x: list[np.ndarray]) -> np.ndarray:
            d: np.ndarray = np.array(x).reshape(len(x), 6) - centre[None]
            d[:, _PSI] = (d[:, _PSI] + np.pi) % (2 * np.pi) - np.pi
            return d

        var = np.sum(dev(states) ** 2, axis=0) / (len(states) - 1)
        if self.n_start and self.members[0].steps > 0:   # nothing at the start itself
            raised = [m.observed() for m, ok in zip(self.members[k:], self.alive[k:]) if ok]
            var += np.sum(dev(raised) ** 2, axis=0) + self.start_sigma ** 2
        s: np.ndarray = self.scale * np.sqrt(var)
        return s


def fill_covariance(msg: Any, spread: EnsembleSpread | None, sim: ShipSimulator, run: object,
                    centre: np.ndarray) -> None:   # msg: an Odometry (messages are Any)
    """
    Fill an Odometry's pose and twist covariance from ``spread`` (zeros without one).

    ``centre``: the observed state the message carries; ``run``: the node's run counter.
    """
    pose = np.zeros(36)
    twist = np.zeros(36)
    if spread is not None:
        spread.follow(sim, run)
        s = spread.sigma(centre)
        if s is not None:
            var = dict(zip(STATE_NAMES, s * s))
            for n, k in _POSE.items():
                pose[k] = var[n]
            for n, k in _TWIST.items():
                twist[k] = var[n]
    msg.pose.covariance = pose.tolist()
    msg.twist.covariance = twist.tolist()
