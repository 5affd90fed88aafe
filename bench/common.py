"""Shared set-ups for the benchmarks: the paper's synthetic SUZAKU turning trials."""
from __future__ import annotations

from pathlib import Path
import sys

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mmg_tuner.core import maneuvers as mv  # noqa: E402, I100
from mmg_tuner.core.ship import load_ship  # noqa: E402
from mmg_tuner.data.generate import SensorNoise  # noqa: E402
from mmg_tuner.data.trial import Trial  # noqa: E402
from mmg_tuner.tuning import ParameterSpace  # noqa: E402

PAPER_TUNE = (10, -20, 35, -40)
PAPER_TEST = (-10, 20, -35, 40)


def paper_turning_trials(truth, angles, duration_s=800.0, seed=0, noise=None):
    """
    Return turning tests at 6 kn, 106 rpm, sampled at 1 s (as the paper's data).

    With the steering gear's rate limit and sensor noise.
    """
    noise = SensorNoise() if noise is None else noise
    out = []
    for i, a in enumerate(angles):
        tr = mv.run(truth, mv.ManeuverSpec('turning', rudder_deg=a, rpm=106.0,
                                           speed_ms=6 * mv.KNOT, duration_s=duration_s, dt=1.0,
                                           approach_s=10.0, integrator='rk4', substeps=10))
        out.append(noise.apply(Trial(tr.t, tr.states, tr.controls, name=f'turn{a:+d}'),
                               np.random.default_rng(seed + i)))
    return out


def moved_truth(seed=5, spread=0.6, extra=None):
    """SUZAKU with its 12 targets moved inside the a_r = 0.5 box (up to spread x half-width)."""
    ship = load_ship('suzaku')
    space = ParameterSpace.around(ship)
    rng = np.random.default_rng(seed)
    theta = space.pre + (space.upper - space.pre) * rng.uniform(-spread, spread, space.dim)
    values = dict(zip(space.names, theta))
    values.update(extra or {})
    return ship, ship.with_params(values), space, theta
