"""
Compile the simulator's kernels into numba's on-disk cache ahead of their first use.

A kernel compiles on its first call (about 15 s each on a 2-core machine) and is cached per
installation (core/_numba_cache.py). The nodes and ``simulate`` call two: the whole-run kernel
(:func:`~mmg_tuner.core.simulate.simulate`, compiled once per model family) and the stepper's
(:class:`ShipSimulator`, the ``sim_node``'s engine, one for all families). Compiling them once
after ``colcon build`` makes the first ``ros2 run mmg_tuner sim_node`` start in seconds
instead of half a minute.
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


def kernels() -> dict[str, Callable[[], None]]:
    """
    Return what to run, by name: each family's whole-run kernel, then each family's stepper.

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
