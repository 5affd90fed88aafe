"""A stateful ship for interactive simulation (the ROS node's engine; no ROS here).

It steps the same compiled :func:`~mmg_tuner.core.mmg.advance` as the offline simulation, so
a command history held per step reproduces :func:`~mmg_tuner.core.simulate.simulate` exactly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mmg_tuner.core.layout import INTEGRATORS, OK, STATUS_TEXT
from mmg_tuner.core.mmg import advance, observe, start_state
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.errors import SimulationError


@dataclass
class CommandCheck:
    """The outcome of validating a command: the value to apply (or None) and why."""

    value: float | None
    problem: str = ''


class ShipSimulator:
    """Fixed-step simulation of one ship driven by held rpm and rudder commands.

    Example:
        >>> sim = ShipSimulator(load_ship('suzaku'), dt=0.1, x0=[0, 0, 0, 3.0, 0, 0], rpm=106)
        >>> sim.set_rudder(math.radians(10)); sim.step(100)
        >>> sim.observed()  # x, y, psi, u, v, r in the model frame
    """

    def __init__(self, ship: ShipConfig, dt: float = 0.1, x0=None, rpm: float = 100.0,
                 rudder_rad: float = 0.0, integrator: str = 'rk4', substeps: int = 1):
        if not dt > 0:
            raise SimulationError(f'dt must be positive, got {dt}')
        self.ship = ship
        self.dt = float(dt)
        self.method = INTEGRATORS[integrator]
        self.substeps = int(substeps)
        self.x0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0] if x0 is None else x0, dtype=float)
        if self.x0[3] <= 0:
            raise SimulationError('initial surge speed must be positive (the MMG model covers '
                                  'u > 0)')
        self.rpm0 = float(rpm)
        self.rudder0 = float(rudder_rad)
        self._work = [np.empty(6) for _ in range(5)]
        self._obs = np.empty(6)
        self.reset()
        self.step(1)  # compile (or load from cache) now, not in the middle of a real-time loop
        self.reset()

    def reset(self) -> None:
        self.t = 0.0
        self.steps = 0
        self.rpm = self.rpm0
        self.rudder = self.rudder0
        self.s = np.empty(6)
        start_state(self.ship.params, self.x0, self.s)
        self.delta_act = self.rudder + self.ship['rudder_offset']
        self.status = 'ok'

    def check_rudder(self, rudder_rad: float) -> CommandCheck:
        lim = self.ship.max_rudder_rad
        if not math.isfinite(rudder_rad):
            return CommandCheck(None, f'rudder command {rudder_rad} is not finite: ignored')
        if abs(rudder_rad) > lim:
            clamped = math.copysign(lim, rudder_rad)
            return CommandCheck(clamped, f'rudder command {math.degrees(rudder_rad):.1f} deg '
                                f'beyond the {math.degrees(lim):.1f} deg limit: clamped')
        return CommandCheck(rudder_rad)

    @staticmethod
    def check_rpm(rpm: float) -> CommandCheck:
        if not math.isfinite(rpm):
            return CommandCheck(None, f'rpm command {rpm} is not finite: ignored')
        if rpm <= 0:
            return CommandCheck(None, f'rpm command {rpm:.1f} <= 0 is outside the MMG model '
                                '(forward propeller revolutions only): ignored')
        return CommandCheck(rpm)

    def set_rudder(self, rudder_rad: float) -> str:
        """Apply a rudder command (validated); returns a problem description or ''."""
        c = self.check_rudder(rudder_rad)
        if c.value is not None:
            self.rudder = c.value
        return c.problem

    def set_rpm(self, rpm: float) -> str:
        c = self.check_rpm(rpm)
        if c.value is not None:
            self.rpm = c.value
        return c.problem

    def step(self, n: int = 1) -> bool:
        """Advance n steps of dt with the held commands. False (and status says why) if the
        simulation left the model's range or diverged; the state is then left unchanged."""
        k1, k2, k3, k4, tmp = self._work
        for _ in range(n):
            s = self.s.copy()
            status, delta = advance(self.ship.kind, self.ship.params, s, self.delta_act,
                                    self.rpm, self.rudder, self.dt, self.substeps, self.method,
                                    k1, k2, k3, k4, tmp)
            if status != OK:
                self.status = STATUS_TEXT[status]
                return False
            self.s, self.delta_act = s, delta
            self.steps += 1
            self.t = self.steps * self.dt
        return True

    def observed(self) -> np.ndarray:
        """x, y, psi, u, v, r as measured (antenna position, velocities over ground)."""
        observe(self.ship.params, self.s, self._obs)
        return self._obs.copy()
