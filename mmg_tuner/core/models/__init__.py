"""
Model families: the registry.

One family = one module here + one entry in :data:`REGISTRY`.

A family is the part of the MMG model that differs between ship models: the hull, propeller
and rudder forces and the inputs they need. Everything else is shared and family-blind: the
equations of motion and mass matrix, wind loads and current kinematics (``core/dynamics.py``),
effects (``core/effects.py``), integrators, ``advance``, simulation and the tuning cost
(``core/integrate.py``), and everything above the core (objective, tuning, diagnosis, nodes,
commands), which only ever passes ``ship.kind`` along.

How to add a family ``myship`` (look at ``standard.py``, the shortest, as the template):

1. Write ``core/models/myship.py`` declaring, at the top, in this order:

   * ``PARAMS = ('X_0', ...)`` -- a literal tuple of the parameter names your forces read that
     are not shared (shared: ``layout.SHARED_PARAMS``: particulars, added masses, windage,
     effects). Names another family also declares are the same slot. It must be a literal:
     the layout reads it without importing the module (the kernels need the finished layout).
   * ``REQUIRED``: the keys a ship YAML of this family must give; ``DEFAULTS``: values for
     keys it may omit.
   * ``INPUTS``: the input channels it reads (names from ``core/channels.py``; add a new
     actuator there, appended).
   * ``ASTERN_RPM`` (bool): whether it covers propeller revolutions <= 0; ``ASTERN_SURGE``
     (bool): whether it covers surge u <= 0. When False, the kernels stop a run there with a
     status (``layout.RPM_NOT_POSITIVE`` / ``SURGE_NOT_POSITIVE``), the data layer and the
     node refuse such inputs; ask via :func:`family`.
   * ``DESCRIPTION``: one line with the source.
   * ``forces(p, u, v, r, act) -> (X, Y, N)``: an ``@njit(cache=True, fastmath=FASTMATH)``
     function returning hull + propeller + rudder (+ thruster) force [N] and yaw moment [N m]
     about midship in body axes, for velocities u, v_m [m/s] through the water, yaw rate r
     [rad/s], the flat parameter vector p (read it by index: ``_X0 = PARAM_INDEX['X_0']`` at
     module level, so numba folds the index in) and the actuator tuple ``act`` indexed by
     ``channels.ACT_*`` (n_P [rev/s], actual rudder [rad], thrusters [rev/s]). No inertia
     terms (the shared equations of motion add them) and no effects (shared hooks add them).
   * optionally its own wind model: ``wind(p, wx, wy) -> (X, Y, N)``, an njit function of the
     apparent wind given as the air's velocity relative to the ship in body axes [m/s]
     (without one the shared Blendermann loads act), and ``AIR_DRAG`` (bool, default False):
     whether wind loads act even when the true wind is zero (the ship's own air drag).
2. Append ``'myship'`` to :data:`REGISTRY` (its position is its integer code ``ship.kind``).
3. A ship YAML with ``model: myship``.

Nothing else changes. The whole-run kernels (simulation, tuning cost, manoeuvres) are compiled
once per family: their entry points pass the family's tag (``dynamics.FAMILY_TAGS``, a type
numba specialises on), so only that family's ``forces`` and ``wind`` are inlined, without a
branch. Kernels called with the plain code (``derivative(ship.kind, ...)`` from other compiled
code) branch over the registered families with one ``literal_unroll``. The on-disk kernel cache
is keyed by a hash of the core sources (``core/_numba_cache.py``), so a new or edited family
never runs stale compiled code.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass, field
import importlib
from pathlib import Path
from typing import Any, Callable

REGISTRY: tuple[str, ...] = ('container', 'standard', 'lowspeed')
"""Registered families, by module name in this package; the position is the family's code."""


@dataclass(frozen=True)
class Family:
    """What the rest of the package may ask about a family (see the module docstring)."""

    name: str
    code: int
    params: tuple[str, ...]
    required: tuple[str, ...]
    defaults: dict[str, float]
    inputs: tuple[str, ...]
    astern_rpm: bool
    astern_surge: bool
    description: str
    forces: Callable[..., Any] = field(repr=False)
    wind: Callable[..., Any] | None = field(default=None, repr=False)  # None: Blendermann
    air_drag: bool = False


def declared_params(name: str) -> tuple[str, ...]:
    """Return a family's ``PARAMS`` read from its source without importing it."""
    path = Path(__file__).with_name(f'{name}.py')
    for node in ast.parse(path.read_text()).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and getattr(node.targets[0], 'id', None) == 'PARAMS'):
            return tuple(ast.literal_eval(node.value))
    raise ImportError(f'{path}: no literal PARAMS = (...) at module level')


_CACHE: dict[str, Family] = {}


def family(name: str) -> Family:
    """Return the registered family called ``name`` (KeyError if there is none)."""
    if name not in _CACHE:
        code = REGISTRY.index(name) if name in REGISTRY else None
        if code is None:
            raise KeyError(name)
        mod = importlib.import_module(f'{__name__}.{name}')
        _CACHE[name] = Family(name, code, tuple(mod.PARAMS), tuple(mod.REQUIRED),
                              dict(getattr(mod, 'DEFAULTS', {})), tuple(mod.INPUTS),
                              bool(mod.ASTERN_RPM), bool(mod.ASTERN_SURGE), mod.DESCRIPTION,
                              mod.forces, getattr(mod, 'wind', None),
                              bool(getattr(mod, 'AIR_DRAG', False)))
    return _CACHE[name]


def families() -> list[Family]:
    """All registered families, in code order."""
    return [family(n) for n in REGISTRY]


def family_of_code(code: int) -> Family:
    return family(REGISTRY[code])
