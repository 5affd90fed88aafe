"""
Compile the simulator's kernels into numba's on-disk cache ahead of their first use.

A kernel compiles on its first call (about 15 s each on a 2-core machine) and is cached per
installation's sources (core/_numba_cache.py). The nodes and ``simulate`` call two: the
whole-run kernel (:func:`~mmg_tuner.core.simulate.simulate`) and the stepper's
(:class:`ShipSimulator`, the ``sim_node``'s engine); ``tune`` and ``diagnose`` call the batched
cost and residuals (:func:`~mmg_tuner.core.integrate.cost_many`, ``residuals_many``). Each is
compiled per model family. Compiling them once after ``colcon build`` makes the first
``ros2 run mmg_tuner sim_node`` or ``tune`` start in seconds instead of minutes.
"""
from __future__ import annotations

from functools import partial
from pathlib import Path
import time
from typing import Callable

import numpy as np


def ships_by_family() -> dict[str, Path]:
    """One embedded ship YAML per model family (the first by name in the config folders)."""
    from mmg_tuner.core.ship import embedded_ship_files, load_ship
    found: dict[str, Path] = {}
    for f in embedded_ship_files():
        found.setdefault(load_ship(f).model, f)
    return found


def _whole_run(ship_yaml: Path) -> None:
    from mmg_tuner.core.channels import TABLE
    from mmg_tuner.core.ship import load_ship
    from mmg_tuner.core.simulate import simulate
    ship = load_ship(ship_yaml)
    inputs = ship.family.inputs
    ctrl: np.ndarray | dict[str, np.ndarray] = np.tile([60.0, 0.1], (3, 1))
    if 'rpm' not in inputs:   # another actuator (twin thrusters): its required channels
        ctrl = {c: np.full(3, 0.1) for c in inputs if TABLE[c].default is None}
    simulate(ship, [0.0, 0.0, 0.0, 1.0, 0.0, 0.0], ctrl, 1.0, 'rk4')


def _stepper(ship_yaml: Path) -> None:
    from mmg_tuner.core.ship import load_ship
    from mmg_tuner.core.stepper import ShipSimulator
    ShipSimulator(load_ship(ship_yaml), dt=0.1).step(2)


def _batched(ship_yaml: Path) -> None:
    """Run the tuning kernels with the argument types tuning/objective.py passes."""
    from mmg_tuner.core.integrate import cost_many, residuals_many
    from mmg_tuner.core.ship import load_ship
    ship = load_ship(ship_yaml)
    M, T, C = 1, 3, len(ship.family.channels)
    params = np.ascontiguousarray(np.atleast_2d(ship.params), dtype=float)
    meas = np.zeros((M, T, 6))
    meas[:, :, 3] = 1.0
    ctrls = np.full((M, T, C), 0.1)
    lengths = np.full(M, T, dtype=np.int64)
    J = np.empty((1, M))
    k_fail = np.empty((1, M), dtype=np.int64)
    cost_many(ship.kind, params, meas, ctrls, lengths, 1.0, 1, 0, np.ones(6), 0, J, k_fail)
    chans = np.arange(6, dtype=np.int64)
    offsets = np.array([0, (T - 1) * 6], dtype=np.int64)
    r = np.empty((1, (T - 1) * 6))
    residuals_many(ship.kind, params, meas, ctrls, lengths, 1.0, 1, 0, np.ones((M, 6)), chans,
                   0, offsets, r, k_fail)


def kernels() -> dict[str, Callable[[], None]]:
    """
    Return what to run, by name: each family's whole-run kernel, stepper and tuning kernels.

    The stepper too is compiled per family (the family's tag is part of its type), so one
    warm-up per family: with a single one, sim_node compiled at its first start for every
    other family (about a minute each). Families sim_node cannot drive (no screw and rudder
    first, see core.stepper) have none.
    """
    from mmg_tuner.core.ship import load_ship
    ships = ships_by_family()
    jobs: dict[str, Callable[[], None]] = {
        f'simulate, {family} family (simulate, replay_node)': partial(_whole_run, f)
        for family, f in ships.items()}
    for family, f in ships.items():
        if load_ship(f).family.inputs[:2] == ('rpm', 'rudder'):   # what sim_node drives
            jobs[f'stepper, {family} family (sim_node)'] = partial(_stepper, f)
    for family, f in ships.items():
        jobs[f'cost and residuals, {family} family (tune, diagnose)'] = partial(_batched, f)
    return jobs


def precompile(report: Callable[[str, float], None] | None = None) -> dict[str, float]:
    """
    Compile (or load from the cache) every kernel in :func:`kernels`.

    Returns the seconds each took (about 0.1 s when already cached); report(name, seconds) is
    called after each.
    """
    took = {}
    for name, run in kernels().items():
        t0 = time.perf_counter()
        run()
        took[name] = time.perf_counter() - t0
        if report is not None:
            report(name, took[name])
    return took
